//! When the board's periodic tasks run next: a pass schedule that never
//! replays missed periods, and a retry timer for a device that stopped answering.
//!
//! embassy's `Ticker` returns at once for every period that has passed, so a pass that
//! took 3 s (a blocking save, once) was followed by 3000 passes back to back without a
//! yield: no other task ran and the watchdog reset the MCU. [`Pacer`] instead drops the
//! backlog as soon as it exceeds [`MAX_BACKLOG_PERIODS`]: a late application simply
//! samples, scans and debounces less often for a moment (debouncing is counted in
//! samples, so it gets longer, never shorter). The board also yields once per pass.

use shared_protocol::units::Micros;

/// Late by more than this many periods: the schedule restarts from now.
pub const MAX_BACKLOG_PERIODS: u64 = 2;

/// A periodic schedule without catch-up bursts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Pacer {
    period_us: u64,
    next_us: Option<u64>,
    skipped: u32,
}

impl Pacer {
    /// A schedule with period `period_us` (at least 1 µs); the first pass is due at once.
    pub const fn new(period_us: u64) -> Self {
        Pacer {
            period_us: if period_us == 0 { 1 } else { period_us },
            next_us: None,
            skipped: 0,
        }
    }

    /// The time the next pass is due, called once per pass before waiting for it; `now` is
    /// the time of the call. The deadline is the previous one plus one period, unless that
    /// lies more than [`MAX_BACKLOG_PERIODS`] periods in the past: then the missed periods
    /// are dropped (counted in [`Pacer::skipped`]) and the pass is due now.
    pub fn next(&mut self, now: Micros) -> Micros {
        let due = match self.next_us {
            None => now.0,
            Some(d) => {
                let limit = self.period_us.saturating_mul(MAX_BACKLOG_PERIODS);
                let late = now.0.saturating_sub(d);
                if late > limit {
                    let missed = late / self.period_us;
                    self.skipped = self
                        .skipped
                        .saturating_add(u32::try_from(missed).unwrap_or(u32::MAX));
                    now.0
                } else {
                    d
                }
            }
        };
        self.next_us = Some(due.saturating_add(self.period_us));
        Micros(due)
    }

    /// Periods dropped since creation (for the board's statistics).
    pub fn skipped(&self) -> u32 {
        self.skipped
    }
}

/// Retries a device that stopped answering (the LCD after an I2C error)
/// every [`RetryTimer::interval_us`] instead of giving up until the next reset.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RetryTimer {
    interval_us: u64,
    failed_at: Option<u64>,
}

impl RetryTimer {
    pub const fn new(interval_us: u64) -> Self {
        RetryTimer {
            interval_us,
            failed_at: None,
        }
    }

    /// The device failed at `now`.
    pub fn failed(&mut self, now: Micros) {
        self.failed_at = Some(now.0);
    }

    /// The device works (again).
    pub fn ok(&mut self) {
        self.failed_at = None;
    }

    /// Whether the device is in use (no failure pending).
    pub fn working(&self) -> bool {
        self.failed_at.is_none()
    }

    /// Whether a failed device should be tried again at `now`.
    pub fn retry_due(&self, now: Micros) -> bool {
        self.failed_at
            .is_some_and(|t| now.0.saturating_sub(t) >= self.interval_us)
    }

    pub fn interval_us(&self) -> u64 {
        self.interval_us
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn on_time_passes_keep_the_period() {
        let mut p = Pacer::new(1000);
        assert_eq!(p.next(Micros(5)), Micros(5));
        assert_eq!(p.next(Micros(900)), Micros(1005));
        // Slightly late (within the backlog): the schedule holds, one pass catches up.
        assert_eq!(p.next(Micros(3500)), Micros(2005));
        assert_eq!(p.next(Micros(3600)), Micros(3005));
        assert_eq!(p.skipped(), 0);
    }

    #[test]
    fn a_long_pass_drops_the_backlog_instead_of_replaying_it() {
        let mut p = Pacer::new(1000);
        let _ = p.next(Micros(0));
        // One pass took 3 s: the next pass is due now, then one period later, not 3000
        // passes back to back.
        assert_eq!(p.next(Micros(3_000_000)), Micros(3_000_000));
        assert_eq!(p.next(Micros(3_000_100)), Micros(3_001_000));
        assert!(p.skipped() >= 2990, "{}", p.skipped());
    }

    #[test]
    fn after_any_delay_at_most_the_backlog_limit_of_passes_are_due_at_once() {
        // However late a pass ends, instantaneous passes after it find at most
        // MAX_BACKLOG_PERIODS + 1 deadlines already passed (no replay burst).
        for late_us in (0..20_000u64).step_by(137).chain([3_000_000]) {
            let mut p = Pacer::new(1000);
            let _ = p.next(Micros(0));
            let now = Micros(late_us);
            let mut due_at_once = 0;
            while p.next(now) <= now {
                due_at_once += 1;
                assert!(due_at_once <= MAX_BACKLOG_PERIODS + 1, "late {late_us}");
            }
        }
    }

    #[test]
    fn retry_timer_waits_its_interval() {
        let mut r = RetryTimer::new(2_000_000);
        assert!(r.working());
        r.failed(Micros(10));
        assert!(!r.working());
        assert!(!r.retry_due(Micros(1_000_000)));
        assert!(r.retry_due(Micros(2_000_010)));
        r.ok();
        assert!(r.working() && !r.retry_due(Micros(9_000_000)));
    }
}
