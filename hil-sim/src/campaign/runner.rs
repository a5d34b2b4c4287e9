//! Runs one world with a fault list, checking every invariant after every scheduler
//! event, and catching a panic of the cores as the `no_panic` violation.

use std::panic::{catch_unwind, AssertUnwindSafe};

use firmware_plc::storage::{fault_log, FaultEntry, Job, FAULT_LOG_ENTRIES};

use super::faults::{
    aim, apply, arm_cut, edges, outlasts_the_period, plc_cut_happened, sustain, Fault, FaultKind,
    JobFilter, AIM_WINDOW_NS,
};
use super::invariants::command_fresh::{self, QTrack, QView};
use super::invariants::storage_decodes::{self, StorageTrack};
use super::invariants::trip_logged_once::{self, TripLog};
use super::invariants::{self, check_all, Violation, NO_PANIC};
use super::observe::Observation;
use super::world::{World, BOOT_RECORD_BYTES};
use crate::sim::{RunOptions, Simulation};
use firmware_plc::app::{drive_written_q, RunState};
use shared_protocol::link::Q_COUNT;
use shared_protocol::program::{Mnemonic, Operand, Program, Section};

/// The name of the violation a diverging plant gives (a model error, not the firmware's:
/// docs/campaign.md).
pub const PLANT_DIVERGED: &str = "plant_diverged";

/// The name of the violation an access to the EEPROM in its write cycle gives
/// (`firmware-plc/src/storage/job.rs`: "no access ever meets a busy chip").
pub const EEPROM_POLLED: &str = "eeprom_polled";

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
    /// How often the storage invariants looked (they are not vacuous).
    pub checks: Checks,
}

/// What `storage_decodes` and `trip_logged_once` checked in a run.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Checks {
    /// PLC power cuts after which the EEPROM was decoded and compared.
    pub storage_after_cut: u64,
    /// Times the fault log was read and counted against the entries queued.
    pub log_counted: u64,
    /// Drive trips the PLC had to learn of and did (an entry with the code queued).
    pub trips_learned: u64,
    /// Q values the drive applied, each found in the PLC's order.
    pub q_applied: u64,
    /// Steps at which a settled Q was compared (drive's copy = PLC's last write).
    pub q_settled: u64,
}

/// The text of a caught panic (`&str` or `String` payloads, as `panic!` makes them).
pub(crate) fn panic_message(payload: &(dyn std::any::Any + Send)) -> String {
    payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "a panic".into())
}

/// Runs `world` with `faults` (the world's own or a shrunk list) to its end or to the
/// first violation.
pub fn run(world: &World, faults: &[Fault]) -> Outcome {
    let mut p = Progress::default();
    let r = catch_unwind(AssertUnwindSafe(|| run_inner(world, faults, &mut p)));
    let violation = match r {
        Ok(v) => v,
        Err(payload) => {
            let msg = panic_message(payload.as_ref());
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
        checks: p.checks,
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
    checks: Checks,
}

/// The Qs `command_fresh` follows: written by the PLC section, not by the drive section.
fn followed_qs(program: &Program) -> Vec<u8> {
    let plc = program
        .section(Section::Plc)
        .filter(|(_, i)| i.mnemonic == Mnemonic::Wr)
        .filter_map(|(_, i)| match i.operand {
            Some(Operand::Q(n)) if usize::from(n) < Q_COUNT => Some(n),
            _ => None,
        });
    let drive = drive_written_q(program);
    let mut v: Vec<u8> = plc.filter(|n| drive & (1u64 << n) == 0).collect();
    v.sort_unstable();
    v.dedup();
    v
}

/// `command_fresh` on every followed Q.
struct Commands {
    qs: Vec<(u8, QTrack)>,
}

impl Commands {
    fn check(&mut self, sim: &Simulation) -> Option<Violation> {
        let live = sim.plc().run_state() == RunState::Running
            && sim.plc().app().link().is_up()
            && sim.drive().app().link().is_up();
        let t_ns = sim.now_ns();
        for (n, q) in &mut self.qs {
            let v = QView {
                t_ns,
                plc: sim.plc().app().q(*n),
                drive: sim.drive().core().vm().q(*n),
                live,
            };
            if let Some(m) = q.check(*n, &v) {
                return Some(Violation {
                    invariant: command_fresh::NAME,
                    t_ns,
                    message: m,
                });
            }
        }
        None
    }

    fn disturbed(&mut self, until_ns: u64) {
        self.qs.iter_mut().for_each(|(_, q)| q.disturbed(until_ns));
    }
}

/// A fault after which a drive trip may legitimately never reach the PLC's log: of the
/// link, of either MCU's supply, or a cut inside an EEPROM write.
fn disturbs_the_link(kind: &FaultKind) -> bool {
    matches!(
        kind,
        FaultKind::LinkBitErrors { .. }
            | FaultKind::LinkBurst { .. }
            | FaultKind::LinkCut { .. }
            | FaultKind::DrivePowerCut
            | FaultKind::DriveWatchdog
            | FaultKind::PlcPowerCut
            | FaultKind::CutInSave { .. }
            | FaultKind::CutInLog { .. }
            | FaultKind::CutInCounters { .. }
    )
}

/// The PLC's storage between events: a cut that stopped a write restarts the PLC and is
/// checked (`storage_decodes`); a job that ends refreshes the track's snapshot; a save
/// that starts tells it which program it writes.
struct StorageWatch {
    track: StorageTrack,
    job: Option<Job>,
    /// The EEPROM's bytes written when `job` became the active one.
    job_bytes: u32,
    /// A cut waiting for its job ([`aim`]) until a time.
    aimed: Option<(JobFilter, u32, u64)>,
    trips: TripLog,
    /// Drive trips already given to `trips`.
    trips_seen: usize,
}

impl StorageWatch {
    fn after_event(&mut self, sim: &mut Simulation, p: &mut Progress) -> Option<Violation> {
        if plc_cut_happened(sim) {
            // A boot-record job settles (waits for its write cycle) in the pass that
            // then writes the counters record: past its bytes, the cut is in that.
            let written = sim.plc_mut().app_mut().storage().eeprom().bytes_written();
            let settled = matches!(self.job, Some(Job::Boot(_)))
                && written.saturating_sub(self.job_bytes) >= BOOT_RECORD_BYTES as u32;
            p.write_cuts.push(if settled { None } else { self.job });
            sim.restart_plc();
            p.checks.storage_after_cut += 1;
            return self.after_cut(sim);
        }
        if let Some(v) = self.trip_log(sim, p) {
            return Some(v);
        }
        let busy = sim.plc_mut().app_mut().storage().eeprom().busy_violations();
        if busy > 0 {
            return Some(Violation {
                invariant: EEPROM_POLLED,
                t_ns: sim.now_ns(),
                message: format!(
                    "{busy} EEPROM access(es) met the chip in its write cycle (it NACKs): the storage must poll it ready first"
                ),
            });
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
            self.job_bytes = sim.plc_mut().app_mut().storage().eeprom().bytes_written();
        }
        None
    }

    /// `trip_logged_once`: the drive's new trips, the log entries queued, the log when
    /// they have all been written.
    fn trip_log(&mut self, sim: &mut Simulation, p: &mut Progress) -> Option<Violation> {
        let link_up = sim.plc().app().link().is_up() && sim.drive().app().link().is_up();
        for f in sim.faults().iter().skip(self.trips_seen) {
            self.trips.drive_trip(f.t_ns, f.code, link_up);
        }
        self.trips_seen = sim.faults().len();
        let storage = sim.plc_mut().app_mut().storage();
        let queue: Vec<FaultEntry> = storage
            .jobs()
            .filter_map(|j| match j {
                Job::LogFault(e) => Some(e),
                _ => None,
            })
            .collect();
        let now = sim.now_ns();
        let violation = |m| {
            Some(Violation {
                invariant: trip_logged_once::NAME,
                t_ns: now,
                message: m,
            })
        };
        let r = self.trips.step(now, &queue);
        p.checks.trips_learned = self.trips.learned;
        match r {
            Err(m) => violation(m),
            Ok(false) => None,
            Ok(true) => {
                p.checks.log_counted += 1;
                let mut e = sim.plc_mut().app_mut().storage().eeprom().clone();
                let mut log = heapless::Vec::<FaultEntry, FAULT_LOG_ENTRIES>::new();
                match fault_log::read_all(&mut e, &mut log) {
                    Err(x) => violation(format!("the fault log does not read: {x}")),
                    Ok(()) => self.trips.check_log(&log).and_then(violation),
                }
            }
        }
    }

    /// The PLC has just powered up again after a cut.
    fn after_cut(&mut self, sim: &mut Simulation) -> Option<Violation> {
        self.job = None;
        self.trips.cut();
        self.trips.disturbed(sim.now_ns());
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
    let mut commands = Commands {
        qs: followed_qs(&world.program)
            .into_iter()
            .map(|n| (n, QTrack::default()))
            .collect(),
    };
    let mut storage = StorageWatch {
        track,
        job: None,
        job_bytes: 0,
        aimed: None,
        trips: TripLog::default(),
        trips_seen: 0,
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
            if let Some(v) = commands.check(&sim) {
                return Some(v);
            }
            if let Some(v) = storage.after_event(&mut sim, p) {
                return Some(v);
            }
            apply(&mut sim, e, &world.baseline);
            if disturbs_the_link(&e.kind) {
                let until = e.at_ns + if e.end { 0 } else { e.kind.duration_ns() };
                storage.trips.disturbed(until);
                commands.disturbed(until);
            }
            if let (Some((wanted, at_byte)), false) = (aim(&e.kind), e.end) {
                storage.aimed = Some((wanted, at_byte, e.at_ns + AIM_WINDOW_NS));
            }
            if matches!((e.kind, e.end), (FaultKind::PlcPowerCut, false)) {
                p.checks.storage_after_cut += 1;
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
        // Before a cut in a write can restart the PLC: a value it wrote in this event
        // (and may have sent) is part of its history.
        let v = commands.check(&sim);
        p.checks.q_applied = commands.qs.iter().map(|(_, q)| q.applied).sum();
        p.checks.q_settled = commands.qs.iter().map(|(_, q)| q.settled).sum();
        if v.is_some() {
            return v;
        }
        if let Some(v) = storage.after_event(&mut sim, p) {
            return Some(v);
        }
        if next >= end {
            return None;
        }
    }
}
