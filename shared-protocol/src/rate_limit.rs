//! A log rate limiter: the boards log a repeated warning (a UART line-error storm with the
//! peer unplugged, a silent task) at most once per interval, with how many occurrences
//! the interval folded together. The decision lives here, where host tests reach it; the
//! board only calls `defmt::warn!` when [`RateLimit::hit`] says so.
//!
//! Why: every defmt log takes a critical section for the whole frame (interrupts masked),
//! so a storm of logs delays the drive's PWM interrupt.

use crate::units::Micros;

/// At most one report per `interval_us`; the occurrences in between are counted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RateLimit {
    interval_us: u64,
    last: Option<Micros>,
    /// Occurrences since the last report, including those not reported.
    count: u32,
}

impl RateLimit {
    pub const fn new(interval_us: u64) -> Self {
        RateLimit {
            interval_us,
            last: None,
            count: 0,
        }
    }

    /// One occurrence at `now`. `Some(n)` when it should be reported now: `n` occurrences
    /// (this one and the ones held back since the last report); `None` when it is held
    /// back.
    pub fn hit(&mut self, now: Micros) -> Option<u32> {
        self.count = self.count.saturating_add(1);
        let due = self
            .last
            .is_none_or(|t| now.0.saturating_sub(t.0) >= self.interval_us);
        if !due {
            return None;
        }
        self.last = Some(now);
        let n = self.count;
        self.count = 0;
        Some(n)
    }

    /// Occurrences held back since the last report.
    pub fn held_back(&self) -> u32 {
        self.count
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_storm_is_reported_once_per_interval_with_its_count() {
        let mut r = RateLimit::new(1_000_000);
        assert_eq!(r.hit(Micros(5)), Some(1), "the first one at once");
        // A storm: one error every 100 us for 2.5 s.
        let mut reports = Vec::new();
        for k in 1..25_000u64 {
            if let Some(n) = r.hit(Micros(5 + k * 100)) {
                reports.push((k, n));
            }
        }
        assert_eq!(reports, vec![(10_000, 10_000), (20_000, 10_000)]);
        assert_eq!(r.held_back(), 4_999);
        // After a quiet spell the next one is reported at once, with the held-back ones.
        assert_eq!(r.hit(Micros(10_000_000)), Some(5_000));
        assert_eq!(r.held_back(), 0);
    }
}
