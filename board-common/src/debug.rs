//! What stops while a debugger halts the core (DBGMCU, RM0440 §47.16), and [`halt`], the
//! end of both images' panic and fault handlers.
//!
//! Review D15: the IWDG keeps counting while the core is halted, so about 100 ms after a
//! breakpoint (or the `bkpt` after a panic) the MCU resets, every breakpoint reboots the
//! board and probe-rs can lose the backtrace. In **debug builds** (`debug_assertions`) the
//! IWDG is frozen while halted; release builds keep it running, as a field unit must
//! (a release image with a probe attached still resets after a halt of 100 ms). The
//! drive's TIM1 freeze (D1) is the drive board's own (`power_stage`), in every build.

use core::sync::atomic::{AtomicBool, Ordering};

use embassy_stm32::pac;

/// Freezes the IWDG while the core is halted, in debug builds only. Call before the
/// watchdog starts.
pub fn freeze_watchdog_when_halted() {
    if cfg!(debug_assertions) {
        pac::DBGMCU.apb1lfzr().modify(|w| w.set_iwdg(true));
    }
}

/// After a panic or fault (the board has already made its outputs safe and logged):
/// stops for a debugger (`bkpt`: probe-rs then prints the backtrace) or, without one,
/// resets the MCU at once. The reset cause then reads as a software reset. It does not
/// wait for the watchdog, which may not have been started yet (a panic during start-up).
pub fn halt() -> ! {
    // C_DEBUGEN: a debugger is attached.
    const DHCSR: *const u32 = 0xE000_EDF0 as *const u32;
    // SAFETY: DHCSR is a core debug register, always mapped and readable.
    let debugger = unsafe { core::ptr::read_volatile(DHCSR) } & 1 != 0;
    if debugger {
        cortex_m::asm::bkpt();
    }
    cortex_m::peripheral::SCB::sys_reset()
}

/// Logs a `core::panic!` without `core::fmt`: the message if it is a plain string (every
/// `panic!("text")`, `expect("text")`, `unreachable!()`), else only that it had arguments,
/// and the source location. Formatting the whole `PanicInfo` would link `core::fmt`
/// (about 2.8 KiB of the drive's 64 KiB budget) for a message probe-rs's backtrace already
/// locates.
pub fn log_panic(info: &core::panic::PanicInfo) {
    let message = info.message().as_str().unwrap_or("(formatted message)");
    match info.location() {
        Some(at) => defmt::error!(
            "panic: {=str} at {=str}:{=u32}:{=u32}",
            message,
            at.file(),
            at.line(),
            at.column()
        ),
        None => defmt::error!("panic: {=str}", message),
    }
}

/// A fault path is logging (or has logged).
static FAULT_LOGGED: AtomicBool = AtomicBool::new(false);

/// Whether this is the first fault path to log: the fault handlers log only then and go
/// straight to [`halt`] otherwise. Review N11: a fault inside a defmt frame (the logger
/// taken) makes the handler's own log panic with "defmt logger taken reentrantly"; that
/// nested panic, and any fault while logging, must reach `halt` (the reset), not recurse
/// into the logger until the core locks up.
pub fn first_fault() -> bool {
    !FAULT_LOGGED.swap(true, Ordering::Relaxed)
}
