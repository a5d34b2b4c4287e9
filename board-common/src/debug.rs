//! What stops while a debugger halts the core (DBGMCU, RM0440 §47.16).
//!
//! Review D15: the IWDG keeps counting while the core is halted, so about 100 ms after a
//! breakpoint (or the `bkpt` after a panic) the MCU resets, every breakpoint reboots the
//! board and probe-rs can lose the backtrace. In **debug builds** (`debug_assertions`) the
//! IWDG is frozen while halted; release builds keep it running, as a field unit must
//! (a release image with a probe attached still resets after a halt of 100 ms). The
//! drive's TIM1 freeze (D1) is the drive board's own (`power_stage`), in every build.

use embassy_stm32::pac;

/// Freezes the IWDG while the core is halted, in debug builds only. Call before the
/// watchdog starts.
pub fn freeze_watchdog_when_halted() {
    if cfg!(debug_assertions) {
        pac::DBGMCU.apb1lfzr().modify(|w| w.set_iwdg(true));
    }
}
