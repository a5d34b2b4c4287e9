//! `lift_limits`: the car stays between the final limits (lift.md 4.1 `limit_low_mm` /
//! `limit_high_mm`: 000 §6.3, the final limit switch opens the safety chain; reaching it
//! means the control let the car run past the end floors).

use super::Invariant;
use crate::campaign::observe::Observation;

pub struct LiftLimits;

impl Invariant for LiftLimits {
    fn name(&self) -> &'static str {
        "lift_limits"
    }

    fn check(&mut self, o: &Observation) -> Option<String> {
        let l = o.lift?;
        (l.car_mm < l.limit_low_mm || l.car_mm > l.limit_high_mm).then(|| {
            format!(
                "car at {:.0} mm, outside the final limits {:.0} to {:.0} mm",
                l.car_mm, l.limit_low_mm, l.limit_high_mm
            )
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::campaign::invariants::first_firing;
    use crate::campaign::observe::LiftView;

    fn car(mm: f64) -> Observation {
        Observation {
            lift: Some(LiftView {
                car_mm: mm,
                car_mms: 0.0,
                door: 0.0,
                limit_low_mm: -40.0,
                limit_high_mm: 3040.0,
            }),
            ..Observation::default()
        }
    }

    #[test]
    fn fires_beyond_either_limit() {
        let mut inv = LiftLimits;
        assert_eq!(first_firing(&mut inv, &[car(-39.0), car(3039.0)]), None);
        assert!(first_firing(&mut inv, &[car(-41.0)]).is_some());
        assert!(first_firing(&mut inv, &[car(3041.0)])
            .unwrap()
            .1
            .contains("3041"));
    }
}
