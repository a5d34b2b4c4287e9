//! `dwt-cycles`: DWT cycle counts of the PWM interrupt and of the 1 ms task's critical
//! section (which delays the interrupt), logged once a second (bring-up figures, 170
//! cycles = 1 us).

use core::sync::atomic::{AtomicU32, Ordering};

static PWM_MAX: AtomicU32 = AtomicU32::new(0);
static PWM_LAST: AtomicU32 = AtomicU32::new(0);
static TICK_MAX: AtomicU32 = AtomicU32::new(0);
static TICKS: AtomicU32 = AtomicU32::new(0);

/// Starts the cycle counter.
pub fn enable() {
    // SAFETY: only DCB/DWT are touched, and nothing else in the firmware uses them.
    let mut cp = unsafe { cortex_m::Peripherals::steal() };
    cp.DCB.enable_trace();
    cp.DWT.enable_cycle_counter();
}

/// Current cycle count.
#[inline(always)]
pub fn now() -> u32 {
    cortex_m::peripheral::DWT::cycle_count()
}

/// Records one PWM interrupt that started at `start`.
#[inline(always)]
pub fn record_pwm(start: u32) {
    let c = now().wrapping_sub(start);
    PWM_LAST.store(c, Ordering::Relaxed);
    PWM_MAX.fetch_max(c, Ordering::Relaxed);
}

/// Records one 1 ms tick (critical section) that started at `start`.
#[inline(always)]
pub fn record_tick(start: u32) {
    TICK_MAX.fetch_max(now().wrapping_sub(start), Ordering::Relaxed);
}

/// Called every millisecond; logs and resets the maximum once a second.
pub fn report_every_second() {
    if TICKS.fetch_add(1, Ordering::Relaxed) % 1000 == 999 {
        defmt::info!(
            "dwt: PWM isr last {} max {} cycles, 1 ms tick max {} cycles",
            PWM_LAST.load(Ordering::Relaxed),
            PWM_MAX.swap(0, Ordering::Relaxed),
            TICK_MAX.swap(0, Ordering::Relaxed)
        );
    }
}
