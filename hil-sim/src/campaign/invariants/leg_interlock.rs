//! `leg_interlock`: the two switches of a leg are never on together: every driven leg
//! switches with dead time inserted (drive.md "Safety of the power stage": "dead time is
//! inserted at every transition"; program.md 4 "Dead-time-safe clamping").

use super::Invariant;
use crate::campaign::observe::Observation;

pub struct LegInterlock;

impl Invariant for LegInterlock {
    fn name(&self) -> &'static str {
        "leg_interlock"
    }

    fn check(&mut self, o: &Observation) -> Option<String> {
        let leg = o.legs_driven.iter().position(|d| *d)?;
        (o.dead_time_ns == 0).then(|| {
            format!(
                "leg {} driven with no dead time: both switches of the leg on together at each edge",
                leg + 1
            )
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::campaign::invariants::first_firing;

    #[test]
    fn fires_on_a_driven_leg_without_dead_time() {
        let ok = Observation {
            outputs_on: true,
            legs_driven: [true; 3],
            dead_time_ns: 1000,
            ..Observation::default()
        };
        let bad = Observation {
            t_ns: 7,
            dead_time_ns: 0,
            ..ok
        };
        let mut inv = LegInterlock;
        assert_eq!(first_firing(&mut inv, &[ok]), None);
        let (t, m) = first_firing(&mut inv, &[ok, bad]).unwrap();
        assert_eq!(t, 7);
        assert!(m.contains("leg 1"), "{m}");
    }
}
