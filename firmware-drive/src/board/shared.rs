//! The drive core, shared between the PWM interrupt and the tasks.
//!
//! Every access is one `critical_section` (interrupts masked): the PWM interrupt's section
//! is the core's per-period function plus a few register writes; the 1 ms task's is one
//! `tick_1ms`. A task holding the section delays the PWM interrupt at most by that long;
//! the compare registers are preloaded, so a late interrupt repeats the previous duties for
//! one period instead of glitching. `dwt-cycles` measures both.

use core::cell::RefCell;

use embassy_stm32::gpio::Output;
use embassy_sync::blocking_mutex::CriticalSectionMutex;
use firmware_drive::drive::DriveCore;
use firmware_drive::timing::PwmTiming;

/// What the interrupt and the tasks share.
pub struct Shared {
    /// The sans-IO drive core (issue 8: replaced by the `DriveApp` glue once it exists).
    pub core: DriveCore,
    /// Brake chopper gate, written by the PWM interrupt.
    pub brake: Output<'static>,
    /// TIM1 timing currently programmed.
    pub timing: PwmTiming,
    /// Fewest dead-time counts the power stage accepts.
    pub min_dead_counts: u32,
}

static SHARED: CriticalSectionMutex<RefCell<Option<Shared>>> =
    CriticalSectionMutex::new(RefCell::new(None));

/// Installs the shared state (once, before TIM1's interrupt is unmasked).
pub fn install(s: Shared) {
    SHARED.lock(|cell| *cell.borrow_mut() = Some(s));
}

/// Runs `f` on the shared state inside a critical section; `None` before [`install`].
#[inline(always)]
pub fn with<R>(f: impl FnOnce(&mut Shared) -> R) -> Option<R> {
    SHARED.lock(|cell| cell.borrow_mut().as_mut().map(f))
}
