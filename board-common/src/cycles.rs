//! `dwt-cycles`: DWT cycle counters for bring-up figures (170 cycles = 1 µs). Each board
//! keeps its own [`CycleStat`]s and reports them; the link task's critical sections are
//! measured here ([`LINK_RX`], [`LINK_TX`]), and the PLC's service task's ([`SERVICE_RX`],
//! [`SERVICE_TX`]).

use core::sync::atomic::{AtomicU32, Ordering};

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

/// The last and the largest duration of one measured section.
pub struct CycleStat {
    last: AtomicU32,
    max: AtomicU32,
}

impl CycleStat {
    pub const fn new() -> Self {
        CycleStat {
            last: AtomicU32::new(0),
            max: AtomicU32::new(0),
        }
    }

    /// Records one section that started at `start` (a [`now`] reading).
    #[inline(always)]
    pub fn record(&self, start: u32) {
        let c = now().wrapping_sub(start);
        self.last.store(c, Ordering::Relaxed);
        self.max.fetch_max(c, Ordering::Relaxed);
    }

    pub fn last(&self) -> u32 {
        self.last.load(Ordering::Relaxed)
    }

    /// The largest since the last call.
    pub fn take_max(&self) -> u32 {
        self.max.swap(0, Ordering::Relaxed)
    }
}

impl Default for CycleStat {
    fn default() -> Self {
        Self::new()
    }
}

/// The link task's receive section (the endpoint's `on_rx`: on the drive, a download's
/// end verifies the whole section in it).
pub static LINK_RX: CycleStat = CycleStat::new();
/// The link task's transmit section (`poll_tx`: one frame encoded).
pub static LINK_TX: CycleStat = CycleStat::new();
/// The PLC's service task's receive section (the frame reader over the bytes of a pass).
pub static SERVICE_RX: CycleStat = CycleStat::new();
/// The PLC's service task's transmit section (one request executed and its answer
/// encoded, or one sample).
pub static SERVICE_TX: CycleStat = CycleStat::new();

/// Calls `report` once a second when called every millisecond.
pub struct EverySecond(AtomicU32);

impl EverySecond {
    pub const fn new() -> Self {
        EverySecond(AtomicU32::new(0))
    }

    pub fn tick(&self, report: impl FnOnce()) {
        if self.0.fetch_add(1, Ordering::Relaxed) % 1000 == 999 {
            report();
        }
    }
}

impl Default for EverySecond {
    fn default() -> Self {
        Self::new()
    }
}
