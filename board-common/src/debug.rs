//! What stops while a debugger halts the core (DBGMCU, RM0440 §47.16), and [`halt`], the
//! end of both images' panic and fault handlers.
//!
//! The IWDG keeps counting while the core is halted, so about 100 ms after a
//! breakpoint (or the `bkpt` after a panic) the MCU resets, every breakpoint reboots the
//! board and probe-rs can lose the backtrace. So the IWDG is frozen while halted whenever a
//! debugger is attached (DHCSR.C_DEBUGEN, which only a probe sets), in every build: a
//! release image under a probe stops like a debug build. Without a probe the core can never
//! halt, so the freeze changes nothing on a field unit, whose watchdog runs as before.
//! [`freeze_watchdog_when_halted`] runs when the watchdog starts and at every supervision
//! check, so a probe attached later (probe-rs `attach`) is seen within 20 ms. While the PLC
//! is halted its outputs keep their levels (bench rule: `firmware-plc/docs/board.md`); the
//! drive's TIM1 freeze (D1) is the drive board's own (`power_stage`), in every build.

use core::sync::atomic::{AtomicBool, Ordering};

use embassy_stm32::pac;

/// DHCSR (ARMv7-M "Debug Halting Control and Status Register").
const DHCSR: *const u32 = 0xE000_EDF0 as *const u32;

/// A debugger is attached (DHCSR.C_DEBUGEN, bit 0: set by the probe only).
fn debugger_attached() -> bool {
    // SAFETY: DHCSR is a core debug register, always mapped and readable.
    let dhcsr = unsafe { core::ptr::read_volatile(DHCSR) };
    dhcsr & 1 != 0
}

/// Freezes the IWDG while the core is halted (DBGMCU_APB1FZR1.DBG_IWDG_STOP, RM0440
/// §47.16) if a debugger is attached. Call when the watchdog starts and periodically.
pub fn freeze_watchdog_when_halted() {
    if debugger_attached() {
        pac::DBGMCU.apb1lfzr().modify(|w| w.set_iwdg(true));
    }
}

/// After a panic or fault (the board has already made its outputs safe and logged):
/// stops for a debugger (`bkpt`: probe-rs then prints the backtrace) or, without one,
/// resets the MCU at once. The reset cause then reads as a software reset. It does not
/// wait for the watchdog, which may not have been started yet (a panic during start-up).
pub fn halt() -> ! {
    if debugger_attached() {
        cortex_m::asm::bkpt();
    }
    cortex_m::peripheral::SCB::sys_reset()
}

/// Logs that a panic happened, without its message or location. Reading anything from
/// `PanicInfo` keeps, for every panic site in the image (core's bounds checks, embassy's
/// `unwrap`s), its location, file name and message, and links `core::fmt`: 5.1 KiB of the
/// drive's flash (docs/size.md). The log is read only with a probe attached, and then the
/// panic handler's `halt` stops at `bkpt`, where probe-rs prints the backtrace with each
/// frame's file and line: the same facts, from the debug information instead of flash.
pub fn log_panic(_info: &core::panic::PanicInfo) {
    defmt::error!("panic (backtrace: probe-rs at the breakpoint)");
}

/// A fault path is logging (or has logged).
static FAULT_LOGGED: AtomicBool = AtomicBool::new(false);

/// Whether this is the first fault path to log: the fault handlers log only then and go
/// straight to [`halt`] otherwise. A fault inside a defmt frame (the logger
/// taken) makes the handler's own log panic with "defmt logger taken reentrantly"; that
/// nested panic, and any fault while logging, must reach `halt` (the reset), not recurse
/// into the logger until the core locks up.
pub fn first_fault() -> bool {
    !FAULT_LOGGED.swap(true, Ordering::Relaxed)
}
