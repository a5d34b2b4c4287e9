//! Drive board layer: brings up the STM32G431 and binds the peripherals to the
//! `firmware_drive` application ([`DriveApp`]: core + link endpoint); no drive logic lives
//! here.
//!
//! Start-up order matters for safety: the power stage's pins go from reset (analog, the
//! gate driver's pull-downs hold them off) straight to TIM1 with MOE = 0; the comparators
//! and ADC are set up before TIM1's interrupts are unmasked, and the break input is armed
//! before any code could set MOE.

pub mod analog;
pub mod control;
#[cfg(feature = "dwt-cycles")]
pub mod cycles;
pub mod fault;
pub mod hw_protection;
pub mod link;
pub mod opamps;
pub mod power_stage;
pub mod pwm_isr;
pub mod shared;

/// The watchdog supervisor (`board_common::supervisor`), with this board's name for its
/// main task's alive bit.
pub mod supervisor {
    /// Alive bit of the 1 ms control task.
    pub use board_common::supervisor::TASK_MAIN as TASK_CONTROL;
    pub use board_common::supervisor::*;
}

use board_common::clocks;

use embassy_executor::{SpawnError, SpawnToken, Spawner};
use embassy_stm32::gpio::{Level, Output, Speed};
use firmware_drive::config::DriveConfig;
use shared_protocol::link::LinkConfig;
use static_cell::StaticCell;

use crate::pins;

/// Name in the boot line and in probe-rs logs.
pub const IMAGE: &str = "firmware-drive";

/// Which board profile this image was built for (`BoardProfile::key`, zero-padded), for
/// tools that run the image: hil-sim's emulator reads it to put that profile's voltages on
/// the pins.
#[no_mangle]
#[used]
pub static DRIVE_BOARD_PROFILE: [u8; 8] = firmware_drive::config::IMAGE_BOARD.key_bytes();

/// Brings the board up and starts every task.
pub async fn start(spawner: Spawner) {
    static ANALOG: StaticCell<analog::Converters> = StaticCell::new();
    static HW: StaticCell<hw_protection::HwProtection> = StaticCell::new();
    static PWM: StaticCell<power_stage::Tim1Pwm> = StaticCell::new();

    let (p, cause) = board_common::boot::init(IMAGE, env!("CARGO_PKG_VERSION"));

    let cfg = DriveConfig::image();
    if cfg.timer_clock_hz != clocks::SYSCLK_HZ {
        fault::fatal("TIM1 clock differs from the core's");
    }
    let link_cfg = LinkConfig::default();
    let app = shared::app_in_place(cfg, cause, link_cfg);
    let timing = app.pwm_timing();

    defmt::info!("board profile: {}", cfg.board.name);
    let board = pins::split(p);
    let (hw, trim) = hw_protection::init(board.protection, cfg.board, app.core().comparator_dacs());
    HW.init(hw);
    // The thresholds from the trimmed zeros (a failed trim ends BOOT in `BOOT`).
    app.set_comparator_trim(trim);
    hw_protection::write_dacs(app.boot_dacs());
    ANALOG.init(analog::init(board.analog, &cfg.board.front_end));
    PWM.init(power_stage::init(board.power, timing));
    // PB5 is the chopper's gate only on a board that has one; on the ESC1 it is
    // `GPIO_BEMF` and stays as reset leaves it.
    let brake = cfg
        .board
        .brake_chopper
        .then(|| Output::new(board.misc.brake, Level::Low, Speed::Low));
    shared::install(shared::Shared { app, brake });
    power_stage::arm_break(&hw_protection::break_comparators(cfg.board));
    power_stage::arm_sto_input();
    power_stage::route_system_faults_to_break();
    power_stage::record_bdtr();
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
    let tasks = supervisor::TASK_LINK | supervisor::TASK_CONTROL;
    spawner.spawn(spawned(
        board_common::supervisor::run(board.misc.iwdg, board.misc.led.into(), tasks),
        "spawn supervisor",
    ));
    spawner.spawn(spawned(link::run(port), "spawn link"));
    spawner.spawn(spawned(control::run(), "spawn control"));
}

/// Puts each `(port, pin)` in analog mode (GPIOx_MODER = 11; the pulls stay off as reset
/// leaves them): the converters', amplifiers' and comparators' inputs.
fn analog_pins(pins: &[(embassy_stm32::pac::gpio::Gpio, usize)]) {
    for &(port, n) in pins {
        port.moder()
            .modify(|w| w.set_moder(n, embassy_stm32::pac::gpio::vals::Moder::ANALOG));
    }
}

/// A task's spawn token, or [`fault::fatal`] with `what` (its pool is full: a start-up
/// bug). Not `expect`: that formats the `SpawnError` through `core::fmt` for a message the
/// panic handler does not print (docs/size.md).
fn spawned<S>(token: Result<SpawnToken<S>, SpawnError>, what: &'static str) -> SpawnToken<S> {
    match token {
        Ok(t) => t,
        Err(_) => fault::fatal(what),
    }
}
