//! PLC board layer: brings up the STM32G431 and binds the peripherals to the
//! `firmware_plc` core's ports; its tasks await and call the core's task bodies
//! (`firmware_plc::task`, `docs/board.md` "Task bodies"); no PLC logic lives here.

pub mod analog;
pub mod app;
#[cfg(feature = "dwt-cycles")]
pub mod cycles;
pub mod eeprom;
pub mod fault;
pub mod i2c_bus;
pub mod inputs;
pub mod keypad;
pub mod lcd;
pub mod link;
#[cfg(not(feature = "shield-plc01a1"))]
pub mod outputs;
pub mod rtc;
pub mod service;
pub mod shared;
#[cfg(feature = "shield-plc01a1")]
pub mod shield;
mod wide_div;

/// The watchdog supervisor (`board_common::supervisor`), with this board's name for its
/// main task's alive bit.
pub mod supervisor {
    /// Alive bit of the application task (scan loop).
    pub use board_common::supervisor::TASK_MAIN as TASK_SCAN;
    pub use board_common::supervisor::*;
}

use embassy_executor::Spawner;
use shared_protocol::link::LinkConfig;

use crate::pins;

/// Name in the boot line and in probe-rs logs.
pub const IMAGE: &str = "firmware-plc";

/// Brings the board up and starts every task.
pub async fn start(spawner: Spawner) {
    rtc::prepare();
    let (p, _cause) = board_common::boot::init_with(IMAGE, env!("CARGO_PKG_VERSION"), rtc::LS);
    let board = pins::split(p);
    // Outputs off before anything else can take time.
    #[cfg(not(feature = "shield-plc01a1"))]
    let outputs = outputs::DigitalOutputs::new(board.outputs);
    #[cfg(feature = "shield-plc01a1")]
    let outputs = shield::ShieldIo::new(board.shield);
    let bus = i2c_bus::open(board.bus);
    let mut lcd = lcd::Lcd::new(bus);
    let lcd_up = lcd
        .power_on()
        .inspect_err(|e| {
            defmt::warn!(
                "lcd: no answer at {=u8:#x} ({}), retrying every {=u64} ms",
                lcd::ADDRESS,
                e,
                app::LCD_RETRY_US / 1000
            )
        })
        .is_ok();
    let io = app::PlcIo {
        inputs: inputs::DigitalInputs::new(board.inputs),
        outputs,
        analog: analog::AnalogInputs::new(board.analog),
        keypad: keypad::KeypadScanner::new(board.keypad),
    };
    let link_cfg = LinkConfig::default();
    let port = link::open(board.link, link_cfg.baud);
    let (service_port, svc) = service::open(board.service);
    // Power-up of the application: loads the slot last run from the EEPROM (and starts RUN
    // if it was running).
    let app = shared::install(eeprom::I2cEeprom::new(bus), link_cfg);
    defmt::info!("application up: {}", shared::with(app, |a| a.run_state()));

    let tasks = supervisor::TASK_LINK | supervisor::TASK_SCAN;
    spawner.spawn(
        board_common::supervisor::run(board.misc.iwdg, board.misc.led, tasks)
            .expect("spawn supervisor"),
    );
    spawner.spawn(link::run(port, app).expect("spawn link"));
    spawner.spawn(app::run(io, lcd, lcd_up, app, svc).expect("spawn app"));
    // Spawned last: below the application and the link (service.md 5).
    spawner.spawn(service::run(service_port, svc, app).expect("spawn service"));
}
