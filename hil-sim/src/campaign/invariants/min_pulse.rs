//! `min_pulse`: no pulse shorter than the minimum pulse: a driven leg's compare is 0, N,
//! or at least 5 counts from both (program.md 4 "Dead-time-safe clamping": a duty in
//! 1..=4 counts becomes 0, one in N-4..N-1 becomes N; drive.md "Safety of the power
//! stage").

use super::Invariant;
use crate::campaign::observe::Observation;

/// The minimum pulse, timer counts (program.md 4: the source's 4-count rule).
pub const MIN_PULSE_COUNTS: u16 = 4;

pub struct MinPulse;

impl Invariant for MinPulse {
    fn name(&self) -> &'static str {
        "min_pulse"
    }

    fn check(&mut self, o: &Observation) -> Option<String> {
        let n = o.arr;
        for (leg, (&driven, &c)) in o.legs_driven.iter().zip(&o.compares).enumerate() {
            let short_high = (1..=MIN_PULSE_COUNTS).contains(&c);
            let short_low = c < n && n - c <= MIN_PULSE_COUNTS;
            if driven && (short_high || short_low) {
                return Some(format!(
                    "leg {}: compare {c} of {n} counts leaves a pulse of {} counts (minimum {})",
                    leg + 1,
                    if short_high { c } else { n - c },
                    MIN_PULSE_COUNTS + 1
                ));
            }
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::campaign::invariants::first_firing;

    fn with(c: [u16; 3]) -> Observation {
        Observation {
            outputs_on: true,
            legs_driven: [true; 3],
            dead_time_ns: 1000,
            compares: c,
            arr: 1000,
            ..Observation::default()
        }
    }

    #[test]
    fn fires_on_a_short_high_or_low_pulse_only() {
        let mut inv = MinPulse;
        let fine = [with([0, 1000, 500]), with([5, 995, 500])];
        assert_eq!(first_firing(&mut inv, &fine), None);
        assert!(first_firing(&mut inv, &[with([0, 4, 500])]).is_some());
        let (_, m) = first_firing(&mut inv, &[with([0, 996, 500])]).unwrap();
        assert!(m.contains("leg 2") && m.contains("4 counts"), "{m}");
        // A leg that is not driven has no pulse.
        let off = Observation {
            legs_driven: [false, true, true],
            ..with([3, 500, 500])
        };
        assert_eq!(first_firing(&mut inv, &[off]), None);
    }
}
