//! `lift_doors`: the lift's door is never open while the car moves (lift.md 3.2 and 4:
//! O00 opens the door, the car stops at a floor first; issue 32's invariant; seed 000 and
//! EN 81-20's door interlock).

use super::Invariant;
use crate::campaign::observe::Observation;
use crate::plant::lift::DOOR_CLOSED_P;

/// A car slower than this is at rest (mm/s): the brake's creep and the levelling
/// stop's last millimetres.
pub const MOVING_MMS: f64 = 10.0;

pub struct LiftDoors;

impl Invariant for LiftDoors {
    fn name(&self) -> &'static str {
        "lift_doors"
    }

    fn check(&mut self, o: &Observation) -> Option<String> {
        let l = o.lift?;
        (l.door > DOOR_CLOSED_P && l.car_mms.abs() > MOVING_MMS).then(|| {
            format!(
                "door {:.0} % open while the car moves at {:.0} mm/s (at {:.0} mm)",
                l.door * 100.0,
                l.car_mms,
                l.car_mm
            )
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::campaign::invariants::first_firing;
    use crate::campaign::observe::LiftView;

    fn lift(door: f64, car_mms: f64) -> Observation {
        Observation {
            lift: Some(LiftView {
                car_mm: 100.0,
                car_mms,
                door,
                limit_low_mm: -40.0,
                limit_high_mm: 3040.0,
            }),
            ..Observation::default()
        }
    }

    #[test]
    fn fires_on_an_open_door_in_travel() {
        let mut inv = LiftDoors;
        assert_eq!(
            first_firing(&mut inv, &[lift(1.0, 0.0), lift(0.0, 500.0)]),
            None
        );
        let (_, m) = first_firing(&mut inv, &[lift(0.5, -300.0)]).unwrap();
        assert!(m.contains("50 % open"), "{m}");
    }
}
