//! `hw_trip_off`: while a hardware trip condition holds (a comparator high: `OC_HW`,
//! `OV_HW`; `STO_IN` low) the legs are open, at once and without software (drive.md
//! "Trips": "or in hardware at once"; safety.md 6: `STO_IN` opens the outputs in
//! hardware; RM0440 29.3.18: MOE cannot be set while a break input is active).

use super::Invariant;
use crate::campaign::observe::Observation;

pub struct HwTripOff;

impl Invariant for HwTripOff {
    fn name(&self) -> &'static str {
        "hw_trip_off"
    }

    fn check(&mut self, o: &Observation) -> Option<String> {
        if !o.outputs_on {
            return None;
        }
        if o.sto_in_low {
            return Some("outputs on while STO_IN is low".into());
        }
        o.comparator_high
            .then(|| "outputs on while a protection comparator is high".into())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::campaign::invariants::first_firing;

    #[test]
    fn fires_on_outputs_under_an_active_break() {
        let on = Observation {
            outputs_on: true,
            legs_driven: [true; 3],
            ..Observation::default()
        };
        let sto = Observation {
            sto_in_low: true,
            ..on
        };
        let comp = Observation {
            comparator_high: true,
            ..on
        };
        let off = Observation {
            outputs_on: false,
            ..comp
        };
        let mut inv = HwTripOff;
        assert_eq!(first_firing(&mut inv, &[on, off]), None);
        assert!(first_firing(&mut inv, &[sto]).unwrap().1.contains("STO_IN"));
        assert!(first_firing(&mut inv, &[comp])
            .unwrap()
            .1
            .contains("comparator"));
    }
}
