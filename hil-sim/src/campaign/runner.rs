//! Runs one world with a fault list, checking every invariant after every scheduler
//! event, and catching a panic of the cores as the `no_panic` violation.

use std::panic::{catch_unwind, AssertUnwindSafe};

use firmware_plc::storage::Job;

use super::faults::{
    aim, apply, arm_cut, edges, outlasts_the_period, plc_cut_happened, sustain, Fault, FaultKind,
    AIM_WINDOW_NS,
};
use super::invariants::storage_decodes::{self, StorageTrack};
use super::invariants::{self, check_all, Violation, NO_PANIC};
use super::observe::Observation;
use super::world::World;
use crate::sim::{RunOptions, Simulation};

/// The name of the violation a diverging plant gives (a model error, not the firmware's:
/// docs/campaign.md).
pub const PLANT_DIVERGED: &str = "plant_diverged";

/// What one run gave.
#[derive(Debug, Clone, PartialEq)]
pub struct Outcome {
    /// The first invariant broken, if any.
    pub violation: Option<Violation>,
    /// The faults that had started when the run ended.
    pub injected: usize,
    /// Simulated time, ns.
    pub sim_ns: u64,
    /// Simulated time with the outputs on, ns (at the resolution of the events).
    pub outputs_on_ns: u64,
    /// The drive's faults in the order they latched (codes).
    pub trips: Vec<u8>,
    /// Armed cuts that stopped an EEPROM write, by the storage job in flight (`None`: a
    /// write outside the job queue, the counters record).
    pub write_cuts: Vec<Option<Job>>,
}

/// Runs `world` with `faults` (the world's own or a shrunk list) to its end or to the
/// first violation.
pub fn run(world: &World, faults: &[Fault]) -> Outcome {
    let mut p = Progress::default();
    let r = catch_unwind(AssertUnwindSafe(|| run_inner(world, faults, &mut p)));
    let violation = match r {
        Ok(v) => v,
        Err(payload) => {
            let msg = payload
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "a panic".into());
            Some(Violation {
                invariant: NO_PANIC,
                t_ns: p.sim_ns,
                message: format!("panicked: {msg}"),
            })
        }
    };
    Outcome {
        violation,
        injected: p.injected,
        sim_ns: p.sim_ns,
        outputs_on_ns: p.outputs_on_ns,
        trips: p.trips,
        write_cuts: p.write_cuts,
    }
}

/// How far a run got (kept outside the unwinding closure).
#[derive(Default)]
struct Progress {
    injected: usize,
    sim_ns: u64,
    outputs_on_ns: u64,
    trips: Vec<u8>,
    write_cuts: Vec<Option<Job>>,
}

/// The PLC's storage between events: a cut that stopped a write restarts the PLC and is
/// checked (`storage_decodes`); a job that ends refreshes the track's snapshot; a save
/// that starts tells it which program it writes.
struct StorageWatch {
    track: StorageTrack,
    job: Option<Job>,
    /// A cut waiting for its job ([`aim`]) until a time.
    aimed: Option<(fn(&Job) -> bool, u32, u64)>,
}

impl StorageWatch {
    fn after_event(&mut self, sim: &mut Simulation, p: &mut Progress) -> Option<Violation> {
        if plc_cut_happened(sim) {
            p.write_cuts.push(self.job);
            sim.restart_plc();
            return self.after_cut(sim);
        }
        if let Some((wanted, at_byte, until)) = self.aimed {
            let first = sim.plc_mut().app_mut().storage().jobs().next();
            if first.as_ref().is_some_and(wanted) {
                arm_cut(sim, at_byte);
                self.aimed = None;
            } else if sim.now_ns() > until {
                self.aimed = None;
            }
        }
        let job = sim.plc_mut().app_mut().storage().active_job();
        if job != self.job {
            if self.job.is_some() {
                self.track
                    .snapshot(sim.plc_mut().app_mut().storage().eeprom());
            }
            if let Some(Job::Save { slot }) = job {
                self.track.save_started(slot, sim.plc().program());
            }
            self.job = job;
        }
        None
    }

    /// The PLC has just powered up again after a cut.
    fn after_cut(&mut self, sim: &mut Simulation) -> Option<Violation> {
        self.job = None;
        let m = self
            .track
            .after_cut(sim.plc_mut().app_mut().storage().eeprom())?;
        Some(Violation {
            invariant: storage_decodes::NAME,
            t_ns: sim.now_ns(),
            message: m,
        })
    }
}

fn run_inner(world: &World, faults: &[Fault], p: &mut Progress) -> Option<Violation> {
    let opts = RunOptions {
        seed: world.seed,
        // One sample at the end: the campaign observes every event instead.
        sample_ns: world.duration_ns,
    };
    let mut sim = match Simulation::new(&world.program, world.scenario.clone(), opts) {
        Ok(s) => s,
        Err(e) => {
            return Some(Violation {
                invariant: NO_PANIC,
                t_ns: 0,
                message: format!("the world does not build: {e:#}"),
            })
        }
    };
    let mut invs = invariants::all();
    let track = match StorageTrack::new(sim.plc_mut().app_mut().storage().eeprom()) {
        Ok(t) => t,
        Err(m) => {
            return Some(Violation {
                invariant: storage_decodes::NAME,
                t_ns: 0,
                message: format!("at power-up: {m}"),
            })
        }
    };
    let mut storage = StorageWatch {
        track,
        job: None,
        aimed: None,
    };
    let edges = edges(faults);
    let mut k = 0;
    let end = world.duration_ns;
    // Spikes wider than a PWM period, until their end: re-armed for every period.
    let mut sustained: Vec<(u64, FaultKind)> = Vec::new();
    let mut last: Option<Observation> = None;
    let mut observe = |sim: &Simulation, p: &mut Progress| -> Option<Violation> {
        p.sim_ns = sim.now_ns();
        p.trips = sim.faults().iter().map(|f| f.code).collect();
        if let Some(t) = sim.unstable_at_ns() {
            return Some(Violation {
                invariant: PLANT_DIVERGED,
                t_ns: t,
                message: "the plant model left physics".into(),
            });
        }
        let o = Observation::of(sim);
        if let Some(l) = last.replace(o) {
            if l.outputs_on {
                p.outputs_on_ns += o.t_ns - l.t_ns;
            }
        }
        check_all(&mut invs, &o)
    };
    loop {
        let next = sim.next_event_at_ns().min(end);
        while let Some(e) = edges.get(k).filter(|e| e.at_ns <= next) {
            sim.run_until(e.at_ns, |_| {});
            if let Some(v) = observe(&sim, p) {
                return Some(v);
            }
            if let Some(v) = storage.after_event(&mut sim, p) {
                return Some(v);
            }
            apply(&mut sim, e, &world.baseline);
            if let (Some((wanted, at_byte)), false) = (aim(&e.kind), e.end) {
                storage.aimed = Some((wanted, at_byte, e.at_ns + AIM_WINDOW_NS));
            }
            if matches!((e.kind, e.end), (FaultKind::PlcPowerCut, false)) {
                if let Some(v) = storage.after_cut(&mut sim) {
                    return Some(v);
                }
            }
            if !e.end {
                p.injected += 1;
                if outlasts_the_period(&e.kind, sim.plant().period_ns()) {
                    sustained.push((e.at_ns + e.kind.duration_ns(), e.kind));
                }
            }
            k += 1;
        }
        let now = sim.now_ns();
        sustained.retain(|(until, _)| *until > now);
        for (_, kind) in &sustained {
            sustain(&mut sim, kind);
        }
        sim.run_until(next, |_| {});
        if let Some(v) = observe(&sim, p) {
            return Some(v);
        }
        if let Some(v) = storage.after_event(&mut sim, p) {
            return Some(v);
        }
        if next >= end {
            return None;
        }
    }
}
