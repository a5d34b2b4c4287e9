//! Direction changes (program.md 4.2 `frv`): "if the frequency falls below frv and the PLC
//! sends a reversal request, the reversal happens only when the frequency starts rising
//! again; the PLC must provide the decrease and increase". A request stays pending until
//! the turning point of the commanded frequency below `frv`: the first cycle in which it
//! rises after it has been falling. So the phases are never swapped while the motor turns
//! at a steady speed it was run up to, nor while it is being braked: a request at a steady
//! 8 Hz waits for the program to lower the frequency and raise it again (or to stop),
//! instead of plugging the motor at speed.
//!
//! "Falling" is a trend, not a one-cycle comparison: f changes by less than one 0.1 Hz
//! step per millisecond on a slow ramp (the motor example's 2.333 s lag), so cycles with
//! an equal f keep the trend; it is set by a cycle with a lower f and cleared by a cycle
//! with a higher one. The turning point is a cycle with a higher f than the previous one
//! while the trend was falling. A request that reaches the drive within
//! [`TURN_GRACE_MS`] of the turning point applies at the next rise: a program that writes
//! its setpoint before its `REV` in the same scan sends the two in different link frames,
//! and the rise may reach the drive a few milliseconds before the request.
//!
//! **Standstill** (program.md 4.2, lift.md 2.2): a cycle that starts with the previous
//! cycle's f at 0 applies a pending request at once, before the drive section computes
//! the new f ([`Reversal::start_cycle`]), so that the first PWM period of a restart already
//! runs in the requested direction; a cycle whose command is 0 applies it too, and so does
//! a cycle below `fmn` in which f is not falling (the outputs are off below `fmn`: nothing
//! is plugged; a command that dithers between 0 and 0.1 Hz after a stop is such a case).

/// How long after the turning point a request still applies at a rise: the link's skew
/// between two writes of one PLC scan (about 1.2 ms worst case, `docs/link.md`) with room.
pub const TURN_GRACE_MS: u8 = 10;

/// [`Reversal::trend`] while the command falls.
const FALLING: u8 = u8::MAX;

/// One byte of trend keeps the rule small in flash (the drive image's budget).
#[derive(Debug, Clone, Default)]
pub struct Reversal {
    requested: bool,
    applied: bool,
    f_prev: i16,
    /// [`FALLING`], or the milliseconds of the grace after the last turning point still
    /// left (`TURN_GRACE_MS + 1` in the cycle of the turn, down to 0: no turn to apply at).
    trend: u8,
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
        self.trend = 0;
    }

    /// The pending request takes effect if `now`; returns the new direction then.
    fn apply_if(&mut self, now: bool) -> Option<bool> {
        if now && self.pending() {
            self.applied = self.requested;
            Some(self.applied)
        } else {
            None
        }
    }

    /// The start of a 1 ms cycle, before the drive section runs: at standstill (the
    /// previous cycle's f was 0) the trend restarts and a pending request is applied now,
    /// so the first PWM period of the next start already runs in the requested direction.
    /// Returns the new direction when it was applied.
    pub fn start_cycle(&mut self) -> Option<bool> {
        if self.f_prev != 0 {
            return None;
        }
        self.trend = 0;
        self.apply_if(true)
    }

    /// The end of a 1 ms cycle with commanded frequency `f`; returns the new direction when
    /// the pending request is applied in this cycle: at standstill, at the turning point
    /// below `frv` (f rises after a falling trend, or within the grace after it), or below
    /// `fmn` while f is not falling (the outputs are off there: no motor is plugged; while
    /// f falls below fmn the request waits for the turning point, as the source's figure
    /// shows).
    pub fn cycle(&mut self, f: i16, frv: i16, fmn: i16) -> Option<bool> {
        let rising = f > self.f_prev;
        self.trend = if f < self.f_prev {
            FALLING
        } else if self.trend == FALLING {
            if rising {
                TURN_GRACE_MS + 1
            } else {
                FALLING
            }
        } else {
            self.trend.saturating_sub(1)
        };
        self.f_prev = f;
        let not_falling = self.trend != FALLING;
        // `rising` implies `not_falling`: a grace left (trend > 0) is a recent turn.
        self.apply_if(
            f == 0 || (not_falling && (f < fmn || (rising && f < frv && self.trend != 0))),
        )
    }
}

#[cfg(test)]
#[path = "../tests/support/ramp_profile.rs"]
mod ramp_profile;

#[cfg(test)]
mod tests {
    use super::ramp_profile::{ramp_profile, ramp_segments};
    use super::*;

    #[test]
    fn waits_for_the_turning_point_below_frv() {
        let mut r = Reversal::default();
        r.cycle(400, 200, 0);
        r.request(true);
        // Ramp down 40 Hz -> 2 Hz with plateaus: never applies.
        let mut f = 400;
        while f > 20 {
            for _ in 0..5 {
                assert_eq!(r.cycle(f, 200, 0), None, "f = {f}");
            }
            f -= 1;
        }
        assert!(r.pending());
        // Turning point: rising again below frv.
        assert_eq!(r.cycle(21, 200, 0), None);
        assert_eq!(r.cycle(22, 200, 0), Some(true));
        assert!(r.applied() && !r.pending());
    }

    #[test]
    fn never_at_or_above_frv() {
        let mut r = Reversal::default();
        r.request(true);
        for f in 200..300 {
            assert_eq!(r.cycle(f, 200, 0), None);
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
            r.cycle(f, 1, 0);
        }
        r.request(true);
        assert_eq!(r.start_cycle(), Some(true));
        assert_eq!(r.cycle(100, 1, 0), None);
        assert!(r.applied());
        // Not at standstill: the request waits for the frv rule.
        r.request(false);
        assert_eq!(r.start_cycle(), None);
        assert_eq!(r.cycle(100, 1, 0), None);
        assert!(r.pending());
    }

    #[test]
    fn at_standstill_it_applies_at_once() {
        let mut r = Reversal::default();
        r.request(true);
        assert_eq!(r.cycle(0, 1, 0), Some(true));
        r.request(false);
        assert_eq!(r.cycle(0, 1, 0), Some(false));
    }

    #[test]
    fn a_request_at_a_steady_speed_below_frv_waits_for_the_decrease_and_increase() {
        // The source's motor.plc at a steady 8 Hz with frv = 20 Hz: the request alone
        // never swaps the phases at speed.
        let mut r = Reversal::default();
        for _ in 0..10 {
            r.cycle(80, 200, 0);
        }
        r.request(true);
        for _ in 0..100 {
            assert_eq!(r.cycle(80, 200, 0), None);
        }
        // A rise without a fall first is no turning point either.
        assert_eq!(r.cycle(81, 200, 0), None);
        // The PLC lowers the command and raises it again: the turning point applies it.
        assert_eq!(r.cycle(70, 200, 0), None);
        assert_eq!(r.cycle(70, 200, 0), None);
        assert_eq!(r.cycle(71, 200, 0), Some(true));
    }

    #[test]
    fn a_request_during_the_ramp_down_applies_at_the_turning_point_or_at_standstill() {
        let mut r = Reversal::default();
        r.cycle(300, 200, 0);
        r.cycle(250, 200, 0);
        r.request(true);
        for f in (0..250).rev() {
            let got = r.cycle(f, 200, 0);
            if f == 0 {
                assert_eq!(got, Some(true));
            } else {
                assert_eq!(got, None, "f = {f}");
            }
        }
    }

    #[test]
    fn below_fmn_a_steady_command_applies_at_once_a_falling_one_waits() {
        let mut r = Reversal::default();
        for f in [0, 1] {
            r.start_cycle();
            r.cycle(f, 200, 50);
        }
        r.request(true);
        assert_eq!(r.cycle(1, 200, 50), Some(true), "outputs off, steady");
        let mut r = Reversal::default();
        r.cycle(300, 200, 50);
        r.request(true);
        for f in (10..300).rev() {
            assert_eq!(r.cycle(f, 200, 50), None, "falling at {f}");
        }
        assert_eq!(r.cycle(11, 200, 50), Some(true), "the turning point");
    }

    #[test]
    fn a_request_just_after_the_turning_point_applies_at_the_next_rise() {
        let mut r = Reversal::default();
        for f in [80, 60, 40, 40, 41, 41] {
            r.cycle(f, 200, 0);
        }
        r.request(true);
        assert_eq!(r.cycle(41, 200, 0), None, "not rising");
        assert_eq!(r.cycle(42, 200, 0), Some(true));
        // Long after the turn, a request waits for the next decrease and increase.
        let mut r = Reversal::default();
        for f in [80, 60, 40, 41] {
            r.cycle(f, 200, 0);
        }
        for _ in 0..=TURN_GRACE_MS {
            r.cycle(41, 200, 0);
        }
        r.request(true);
        assert_eq!(r.cycle(42, 200, 0), None);
    }

    proptest::proptest! {
        /// 002 4.2 over random ramps and request times (before a ramp-down, during it, at
        /// a steady speed, at standstill): the phase order changes only at standstill
        /// (this cycle's or the previous cycle's command 0), below fmn (outputs off) or
        /// when the command rises below frv; never above fmn while it is not rising. And
        /// the rule does not just refuse: a request pending while the command falls
        /// applies at the first rise below frv, and one pending at a command of 0 applies.
        #[test]
        fn swaps_only_when_rising_below_frv_or_at_standstill(
            segs in ramp_segments(10),
            requests in proptest::collection::vec(0u16..1000, 0..8),
            frv in 1i16..300,
            fmn in 0i16..100,
        ) {
            let fs = ramp_profile(&segs);
            let n = fs.len();
            // Request times as fractions of the profile (toggling the direction).
            let at: std::vec::Vec<usize> =
                requests.iter().map(|r| usize::from(*r) * n / 1000).collect();
            let mut r = Reversal::default();
            let (mut prev, mut want) = (0i16, false);
            // A request was pending in a cycle in which the command fell.
            let mut armed = false;
            for (k, &f) in fs.iter().enumerate() {
                if r.start_cycle().is_some() {
                    proptest::prop_assert_eq!(prev, 0);
                }
                for _ in at.iter().filter(|&&t| t == k) {
                    want = !want;
                    r.request(want);
                }
                if r.cycle(f, frv, fmn).is_some() {
                    proptest::prop_assert!(
                        f == 0 || f < fmn || (f > prev && f < frv),
                        "swapped at f = {} after {}",
                        f,
                        prev
                    );
                }
                if f == 0 {
                    proptest::prop_assert!(!r.pending(), "pending at standstill");
                }
                if f > prev {
                    proptest::prop_assert!(
                        !(armed && f < frv && r.pending()),
                        "still pending at the turning point {} -> {} (frv {})",
                        prev,
                        f,
                        frv
                    );
                    armed = false;
                }
                if f < prev {
                    armed = r.pending();
                }
                armed &= r.pending();
                prev = f;
            }
        }
    }
}
