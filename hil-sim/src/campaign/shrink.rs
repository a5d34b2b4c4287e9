//! Shrinking a failing fault list: drop faults one at a time while the same invariant
//! still breaks, until no single fault can go (a 1-minimal list, the last stage of
//! Zeller's delta debugging; the lists are short, so the quadratic cost is a few runs).

use super::faults::Fault;
use super::runner::{run, Outcome};
use super::world::World;

/// The shortest list found that still breaks `invariant`, and its outcome.
pub fn shrink(
    world: &World,
    faults: &[Fault],
    invariant: &str,
    first: Outcome,
) -> (Vec<Fault>, Outcome) {
    shrink_with(faults, first, |f| {
        let o = run(world, f);
        let same = o
            .violation
            .as_ref()
            .is_some_and(|v| v.invariant == invariant);
        same.then_some(o)
    })
}

/// Drop-one shrinking with `fails` deciding (`Some`: still fails, with what it gave).
/// Faults after the violation never started: they go first, without a run.
pub fn shrink_with<O: Clone>(
    faults: &[Fault],
    first: O,
    mut fails: impl FnMut(&[Fault]) -> Option<O>,
) -> (Vec<Fault>, O) {
    let mut cur = faults.to_vec();
    let mut best = first;
    loop {
        let mut shorter = None;
        for i in 0..cur.len() {
            let mut c = cur.clone();
            c.remove(i);
            if let Some(o) = fails(&c) {
                shorter = Some((c, o));
                break;
            }
        }
        match shorter {
            Some((c, o)) => {
                cur = c;
                best = o;
            }
            None => return (cur, best),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::campaign::faults::FaultKind;

    fn f(at_ns: u64) -> Fault {
        Fault {
            at_ns,
            kind: FaultKind::DrivePowerCut,
        }
    }

    #[test]
    fn keeps_exactly_the_faults_that_make_it_fail() {
        // Fails when both the faults at 3 and 7 are there.
        let all: Vec<Fault> = (1..=9).map(f).collect();
        let fails = |l: &[Fault]| {
            let has = |t| l.iter().any(|x| x.at_ns == t);
            (has(3) && has(7)).then_some(l.len())
        };
        let (min, n) = shrink_with(&all, 9, fails);
        assert_eq!(min.iter().map(|x| x.at_ns).collect::<Vec<_>>(), [3, 7]);
        assert_eq!(n, 2);
    }

    #[test]
    fn a_list_that_fails_without_faults_shrinks_to_nothing() {
        let (min, _) = shrink_with(&[f(1), f(2)], (), |_| Some(()));
        assert!(min.is_empty());
    }
}
