//! What stops while a debugger halts the core (DBGMCU, RM0440 §47.16), and [`halt`], the
//! end of both images' panic and fault handlers.
//!
//! Review D15: the IWDG keeps counting while the core is halted, so about 100 ms after a
//! breakpoint (or the `bkpt` after a panic) the MCU resets, every breakpoint reboots the
//! board and probe-rs can lose the backtrace. So the IWDG is frozen while halted whenever a
//! debugger is attached (DHCSR.C_DEBUGEN, which only a probe sets), in every build: a
//! release image under a probe stops like a debug build. Without a probe the core can never
//! halt, so the freeze changes nothing on a field unit, whose watchdog runs as before.
//! [`freeze_watchdog_when_halted`] runs when the watchdog starts and at every supervision
//! check, so a probe attached later (probe-rs `attach`) is seen within 20 ms. While the PLC
//! is halted its outputs keep their levels (bench rule: `firmware-plc/docs/board.md`); the
//! drive's TIM1 freeze (D1) is the drive board's own (`power_stage`), in every build.

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
