//! Direction changes (program.md 4.2 `frv`): a request from the PLC stays pending until
//! the frequency is below `frv` and not falling, so the phases are never swapped while the
//! motor is being braked down ("reversal happens only when the frequency starts rising
//! again").
//!
//! "Not falling" is kept as a trend, not a one-cycle comparison: f changes by less than
//! one 0.1 Hz step per millisecond on a slow ramp (the motor example's 2.333 s lag), so
//! comparing with the previous cycle alone would see "equal" in the middle of a ramp-down
//! and reverse there. The trend is "falling" from the first cycle in which f decreases
//! until the first cycle in which it increases; cycles with equal f keep it. This is
//! stricter than the letter of program.md and never weaker: a cycle with f lower than
//! the previous one always counts as falling.
//!
//! **Standstill** (program.md 4.2, lift.md 2.2): a cycle that starts with the previous
//! cycle's f at 0 applies a pending request at once, before the drive section computes
//! the new f ([`Reversal::start_cycle`]), and clears the trend. Without this the trend
//! stays "falling" at f = 0 after a stop, the first rising cycle has f >= 0.1 Hz (not
//! below the default frv), and the motor would restart in the old direction.

#[derive(Debug, Clone, Default)]
pub struct Reversal {
    requested: bool,
    applied: bool,
    f_prev: i16,
    falling: bool,
}

impl Reversal {
    /// Direction wanted by the PLC (false forward, true reverse).
    pub fn request(&mut self, reverse: bool) {
        self.requested = reverse;
    }

    /// Direction in effect (true = phases 1 and 2 swapped).
    pub fn applied(&self) -> bool {
        self.applied
    }

    pub fn pending(&self) -> bool {
        self.requested != self.applied
    }

    /// A RUN starts from standstill: no trend yet.
    pub fn restart(&mut self, f: i16) {
        self.f_prev = f;
        self.falling = false;
    }

    /// The start of a 1 ms cycle, before the drive section runs: at standstill (the
    /// previous cycle's f was 0) the trend restarts and a pending request is applied now,
    /// so the first PWM period of the next start already runs in the requested direction.
    /// Returns the new direction when it was applied.
    pub fn start_cycle(&mut self) -> Option<bool> {
        if self.f_prev != 0 {
            return None;
        }
        self.falling = false;
        if self.pending() {
            self.applied = self.requested;
            Some(self.applied)
        } else {
            None
        }
    }

    /// The end of a 1 ms cycle with commanded frequency `f`; returns the new direction when
    /// the pending request is applied in this cycle (f below frv and not falling).
    pub fn cycle(&mut self, f: i16, frv: i16) -> Option<bool> {
        if f < self.f_prev {
            self.falling = true;
        } else if f > self.f_prev {
            self.falling = false;
        }
        self.f_prev = f;
        if self.pending() && f < frv && !self.falling {
            self.applied = self.requested;
            Some(self.applied)
        } else {
            None
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn waits_for_the_turning_point_below_frv() {
        let mut r = Reversal::default();
        r.cycle(400, 200);
        r.request(true);
        // Ramp down 40 Hz -> 2 Hz with plateaus: never applies.
        let mut f = 400;
        while f > 20 {
            for _ in 0..5 {
                assert_eq!(r.cycle(f, 200), None, "f = {f}");
            }
            f -= 1;
        }
        assert!(r.pending());
        // Turning point: rising again below frv.
        assert_eq!(r.cycle(21, 200), None);
        assert_eq!(r.cycle(22, 200), Some(true));
        assert!(r.applied() && !r.pending());
    }

    #[test]
    fn never_at_or_above_frv() {
        let mut r = Reversal::default();
        r.request(true);
        for f in 200..300 {
            assert_eq!(r.cycle(f, 200), None);
        }
    }

    #[test]
    fn a_stop_after_a_ramp_down_reverses_before_the_restart() {
        // Forward at 10 Hz, stopped (f = 0: the trend is "falling"), reverse requested,
        // started again at 10 Hz in one step: the request applies at the start of that
        // cycle, before the new f exists (the default frv is 0.1 Hz).
        let mut r = Reversal::default();
        for f in [100, 100, 0, 0] {
            r.start_cycle();
            r.cycle(f, 1);
        }
        r.request(true);
        assert_eq!(r.start_cycle(), Some(true));
        assert_eq!(r.cycle(100, 1), None);
        assert!(r.applied());
        // Not at standstill: the request waits for the frv rule.
        r.request(false);
        assert_eq!(r.start_cycle(), None);
        assert_eq!(r.cycle(100, 1), None);
        assert!(r.pending());
    }

    #[test]
    fn at_standstill_it_applies_at_once() {
        let mut r = Reversal::default();
        r.request(true);
        assert_eq!(r.cycle(0, 1), Some(true));
        r.request(false);
        assert_eq!(r.cycle(0, 1), Some(false));
    }
}
