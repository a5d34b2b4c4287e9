//! The PLC application, shared by the application task and the link task.
//!
//! Both run in the thread-mode executor, so they never preempt each other: a thread-mode
//! mutex (no interrupt masking) and a `RefCell` borrowed for one synchronous call suffice.

use core::cell::RefCell;
use core::mem::MaybeUninit;

use embassy_sync::blocking_mutex::ThreadModeMutex;
use embassy_time::Instant;
use firmware_plc::app::PlcApp;
use shared_protocol::link::LinkConfig;
use shared_protocol::units::Micros;
use static_cell::StaticCell;

use super::eeprom::I2cEeprom;
use super::lcd;

/// The application as bound to this board.
pub type App = PlcApp<I2cEeprom>;

/// The shared application, handed to each task that needs it.
pub type SharedApp = &'static ThreadModeMutex<RefCell<&'static mut App>>;

/// Builds the application in static memory (`.bss`), then powers it up: it loads the slot
/// last run from the EEPROM (and starts RUN if it was running).
///
/// The application is 17 KiB, half the RAM, so it must be built in its static slot, not on
/// the stack and moved. `build` is kept out of line so that CI's stack step (no frame over
/// 2 KiB) sees its frame: the by-value `PlcApp::new` needed about 33 KiB, so the board uses
/// `new_cold` (fills the struct) and an in-place `power_up`. Its largest parts (the
/// program, the VM) start as zero bytes, which the compiler writes straight into the
/// slot; anything else of that size built by value shows as a multi-KiB frame here.
pub fn install(eeprom: I2cEeprom, link: LinkConfig) -> SharedApp {
    static MEMORY: StaticCell<App> = StaticCell::new();
    static SHARED: StaticCell<ThreadModeMutex<RefCell<&'static mut App>>> = StaticCell::new();
    let app: &'static mut App = build(MEMORY.uninit(), eeprom, link);
    // Power-up (EEPROM reads, the fault log, the program's load and compile) runs after
    // `build` has returned, not nested under its frame (when that frame was 7.6 KiB, the
    // nesting overflowed the stack: HardFault in `reload_fault_log`).
    // The real clock times the EEPROM's write cycles (before the watchdog runs).
    app.power_up_clocked(now(), &mut now);
    SHARED.init(ThreadModeMutex::new(RefCell::new(app)))
}

#[inline(never)]
fn build(
    slot: &'static mut MaybeUninit<App>,
    eeprom: I2cEeprom,
    link: LinkConfig,
) -> &'static mut App {
    slot.write(PlcApp::new_cold(eeprom, link, lcd::COLS, lcd::ROWS))
}

/// Runs `f` on the application.
pub fn with<R>(app: SharedApp, f: impl FnOnce(&mut App) -> R) -> R {
    app.lock(|cell| f(&mut cell.borrow_mut()))
}

/// The application's clock: microseconds since boot.
pub fn now() -> Micros {
    Micros(Instant::now().as_micros())
}
