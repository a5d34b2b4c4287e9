//! `dwt-cycles`: DWT cycle counts of one pass of the application task (I/O sampling, PLC
//! scan, outputs, LCD), logged once a second (bring-up figures, 170 cycles = 1 us).

use core::sync::atomic::{AtomicU32, Ordering};

static SCAN_MAX: AtomicU32 = AtomicU32::new(0);
static SCAN_LAST: AtomicU32 = AtomicU32::new(0);
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

/// Records one scan that started at `start`.
#[inline(always)]
pub fn record_scan(start: u32) {
    let c = now().wrapping_sub(start);
    SCAN_LAST.store(c, Ordering::Relaxed);
    SCAN_MAX.fetch_max(c, Ordering::Relaxed);
}

/// Called every millisecond; logs and resets the maximum once a second.
pub fn report_every_second() {
    if TICKS.fetch_add(1, Ordering::Relaxed) % 1000 == 999 {
        defmt::info!(
            "dwt: scan last {} max {} cycles",
            SCAN_LAST.load(Ordering::Relaxed),
            SCAN_MAX.swap(0, Ordering::Relaxed)
        );
    }
}
