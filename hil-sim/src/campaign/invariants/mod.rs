//! The invariants checked at every simulation step, one module each. Each has a name
//! (what a failing seed prints) and says in its message what it saw; each cites the
//! document its rule comes from (docs/campaign.md "Invariants").

use super::observe::Observation;

pub mod command_fresh;
pub mod hw_trip_off;
pub mod leg_interlock;
pub mod lift_doors;
pub mod lift_limits;
pub mod min_pulse;
pub mod run_gate;
pub mod storage_decodes;
pub mod sw_trip_off;
pub mod trip_latched;
pub mod trip_logged_once;

/// One rule over the trace of observations; it may keep state between steps.
pub trait Invariant {
    fn name(&self) -> &'static str;
    /// `Some(message)` when `o`, after the steps already seen, breaks the rule.
    fn check(&mut self, o: &Observation) -> Option<String>;
}

/// The name of the invariant a panic breaks (the runner catches it).
pub const NO_PANIC: &str = "no_panic";

/// A broken invariant.
#[derive(Debug, Clone, PartialEq)]
pub struct Violation {
    pub invariant: &'static str,
    pub t_ns: u64,
    pub message: String,
}

/// Every invariant, fresh.
pub fn all() -> Vec<Box<dyn Invariant>> {
    vec![
        Box::new(leg_interlock::LegInterlock),
        Box::new(min_pulse::MinPulse),
        Box::new(hw_trip_off::HwTripOff),
        Box::new(sw_trip_off::SwTripOff::default()),
        Box::new(run_gate::RunGate::default()),
        Box::new(trip_latched::TripLatched::default()),
        Box::new(lift_doors::LiftDoors),
        Box::new(lift_limits::LiftLimits),
    ]
}

/// Checks `o` against every invariant: the first broken one.
pub fn check_all(invariants: &mut [Box<dyn Invariant>], o: &Observation) -> Option<Violation> {
    for inv in invariants.iter_mut() {
        if let Some(message) = inv.check(o) {
            return Some(Violation {
                invariant: inv.name(),
                t_ns: o.t_ns,
                message,
            });
        }
    }
    None
}

/// Test helper: the first step of `trace` at which `inv` fires.
#[cfg(test)]
pub(crate) fn first_firing(
    inv: &mut dyn Invariant,
    trace: &[Observation],
) -> Option<(u64, String)> {
    trace.iter().find_map(|o| inv.check(o).map(|m| (o.t_ns, m)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_unique() {
        let mut names: Vec<&str> = all().iter().map(|i| i.name()).collect();
        names.push(NO_PANIC);
        names.push(storage_decodes::NAME);
        names.push(command_fresh::NAME);
        names.push(crate::campaign::runner::EEPROM_POLLED);
        names.push(trip_logged_once::NAME);
        let n = names.len();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), n);
    }

    #[test]
    fn a_quiet_rig_breaks_nothing() {
        let mut inv = all();
        for k in 0..100 {
            let o = Observation {
                t_ns: k * 50_000,
                ..Observation::default()
            };
            assert_eq!(check_all(&mut inv, &o), None);
        }
    }
}
