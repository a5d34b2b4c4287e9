//! `trip_latched`: a hardware break that opens driven outputs latches a fault (drive.md
//! "Trips": `OC_HW`, `OV_HW` latch; safety.md 6: a `STO_IN` low pulse of **any width**
//! latches code 9, "a pulse shorter than the 1 ms read must not let the outputs come
//! back on by themselves"). The break interrupt records it at the next PWM period, the
//! 1 ms tick at the latest: the fault must be latched one PWM period plus 1 ms after the
//! break.

use super::Invariant;
use crate::campaign::observe::Observation;

/// Beyond the running PWM period: the 1 ms tick.
pub const LATCH_MARGIN_NS: u64 = 1_000_000;

#[derive(Default)]
pub struct TripLatched {
    prev: Option<Observation>,
    /// A break opened driven outputs at this time; the deadline of its fault.
    pending: Option<(u64, u64)>,
}

impl Invariant for TripLatched {
    fn name(&self) -> &'static str {
        "trip_latched"
    }

    fn check(&mut self, o: &Observation) -> Option<String> {
        let prev = self.prev.replace(*o);
        if o.drive_fault != 0 {
            self.pending = None;
            return None;
        }
        if let Some(p) = prev {
            let opened = o.hw_break && !p.hw_break && p.outputs_on;
            // A drive that restarts drops its latch with its RAM: what it reports after
            // a power cut is its own (BOOT), not this break's.
            let restarted = o.drive_state == shared_protocol::drive_state::DriveState::Boot;
            if restarted {
                self.pending = None;
            } else if opened && self.pending.is_none() {
                self.pending = Some((o.t_ns, o.t_ns + p.pwm_period_ns + LATCH_MARGIN_NS));
            }
        }
        let (t0, deadline) = self.pending?;
        (o.t_ns > deadline).then(|| {
            self.pending = None;
            format!(
                "a break opened the outputs at {:.6} s and no fault latched within {:.3} ms",
                t0 as f64 / 1e9,
                (deadline - t0) as f64 / 1e6
            )
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::campaign::invariants::first_firing;

    fn at(t_ns: u64, on: bool, hw_break: bool, fault: u8) -> Observation {
        Observation {
            t_ns,
            outputs_on: on,
            legs_driven: [true; 3],
            hw_break,
            drive_fault: fault,
            drive_state: shared_protocol::drive_state::DriveState::Run,
            pwm_period_ns: 100_000,
            ..Observation::default()
        }
    }

    #[test]
    fn fires_when_a_break_leaves_no_fault() {
        let mut inv = TripLatched::default();
        let latched = [
            at(0, true, false, 0),
            at(10, false, true, 0),
            at(500_000, false, false, 9),
        ];
        assert_eq!(first_firing(&mut inv, &latched), None);
        let mut inv = TripLatched::default();
        let lost = [
            at(0, true, false, 0),
            at(10, false, true, 0),
            at(310_000, true, false, 0),
            at(1_200_000, true, false, 0),
        ];
        let (t, m) = first_firing(&mut inv, &lost).unwrap();
        assert_eq!(t, 1_200_000);
        assert!(m.contains("no fault latched"), "{m}");
    }
}
