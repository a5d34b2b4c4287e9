//! Drive board layer: brings up the STM32G431 and binds the peripherals to the
//! `firmware_drive` application ([`DriveApp`]: core + link endpoint); no drive logic lives
//! here.
//!
//! Start-up order matters for safety: the power stage's pins go from reset (analog, the
//! gate driver's pull-downs hold them off) straight to TIM1 with MOE = 0; the comparators
//! and ADC are set up before TIM1's interrupts are unmasked, and the break input is armed
//! before any code could set MOE.

pub mod analog;
pub mod clocks;
pub mod control;
#[cfg(feature = "dwt-cycles")]
pub mod cycles;
pub mod fault;
pub mod hw_protection;
pub mod link;
pub mod power_stage;
pub mod pwm_isr;
pub mod reset_cause;
pub mod shared;
pub mod supervisor;

use embassy_executor::Spawner;
use embassy_stm32::gpio::{Level, Output, Speed};
use firmware_drive::app::DriveApp;
use firmware_drive::config::DriveConfig;
use shared_protocol::link::LinkConfig;
use static_cell::StaticCell;

use crate::pins;

/// Name in the boot line and in probe-rs logs.
pub const IMAGE: &str = "firmware-drive";

/// Brings the board up and starts every task.
pub async fn start(spawner: Spawner) {
    static ANALOG: StaticCell<analog::Converters> = StaticCell::new();
    static HW: StaticCell<hw_protection::HwProtection> = StaticCell::new();
    static PWM: StaticCell<power_stage::Tim1Pwm> = StaticCell::new();

    let cause = reset_cause::take();
    let p = embassy_stm32::init(clocks::config());
    defmt::info!(
        "{=str} {=str} boot: {} MHz, reset cause {}",
        IMAGE,
        env!("CARGO_PKG_VERSION"),
        clocks::SYSCLK_HZ / 1_000_000,
        cause
    );
    #[cfg(feature = "dwt-cycles")]
    cycles::enable();

    let cfg = DriveConfig::default();
    if cfg.timer_clock_hz != clocks::SYSCLK_HZ {
        fault::fatal("TIM1 clock differs from the core's");
    }
    let link_cfg = LinkConfig::default();
    let app = DriveApp::new(cfg, cause, link_cfg);
    let timing = app.pwm_timing();
    let min_dead_counts =
        power_stage::min_dead_time_counts(cfg.timer_clock_hz, cfg.min_dead_time_ns);

    let mut board = pins::split(p);
    let a = &mut board.analog;
    HW.init(hw_protection::init(
        board.protection,
        cfg.board,
        (
            a.current_a.reborrow(),
            a.current_b.reborrow(),
            a.dc_link.reborrow(),
        ),
        app.core().comparator_dacs(),
    ));
    ANALOG.init(analog::init(board.analog));
    PWM.init(power_stage::init(board.power, timing, min_dead_counts));
    let brake = Output::new(board.misc.brake, Level::Low, Speed::Low);
    shared::install(shared::Shared {
        app,
        brake,
        min_dead_counts,
    });
    power_stage::arm_break(&hw_protection::break_comparators(cfg.board));
    power_stage::route_system_faults_to_break();
    pwm_isr::enable();
    defmt::info!(
        "TIM1: PSC {} ARR {} DTG {=u8:#x} ({} counts), {} mHz",
        timing.psc,
        timing.arr,
        timing.dtg,
        timing.dead_time_counts,
        timing.pwm_millihertz
    );

    let port = link::open(board.link, link_cfg.baud);
    spawner
        .spawn(supervisor::run(board.misc.iwdg, board.misc.led.into()).expect("spawn supervisor"));
    spawner.spawn(link::run(port).expect("spawn link"));
    spawner.spawn(control::run().expect("spawn control"));
}
