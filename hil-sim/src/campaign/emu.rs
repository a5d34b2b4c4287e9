//! `hil-sim campaign --emu`: each seed's world on the exact release images in the
//! emulator (`hil-sim emu`, [`crate::emu`]), with the same faults at the same times and
//! the same invariants where the emulated boards expose what they need
//! ([`super::emu_observe`], docs/campaign.md "On the real images").
//!
//! The world is the one the seed gives on the cores ([`World::generate`]); what the
//! emulator cannot take is left out, never drawn differently: a world on the lift
//! template is skipped (the `[lift]` plant runs on the cores only), and a fault of a class
//! the emulator cannot inject ([`supported`]) is dropped from the list.

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::PathBuf;

use anyhow::Result;
use g431_emu::boards::ExternalWire;

use super::emu_observe::{Change, DriveLogReader, EmuView, PlcLogReader};
use super::faults::{edges, Fault, FaultEdge, FaultKind, CLASSES};
use super::invariants::{self, check_all, Invariant, Violation, NO_PANIC};
use super::runner::{Outcome, PLANT_DIVERGED};
use super::world::{World, WorldOptions};
use super::{Failure, SeedResult};
use crate::emu::boards::{SenseSpikeAt, UdcSpikeAt};
use crate::emu::sim::{EmuSim, QUANTUM_NS};
use crate::sim::RunOptions;

/// The release images the worlds run on.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct EmuImages {
    pub drive: PathBuf,
    pub plc: PathBuf,
}

/// The invariants checked on the images (by name): the others need what the emulated
/// boards do not expose (docs/campaign.md "On the real images").
pub const EMU_INVARIANTS: &[&str] = &[
    "leg_interlock",
    "min_pulse",
    "hw_trip_off",
    "sw_trip_off",
    "run_gate",
    "trip_latched",
];

/// An image reset, HardFault, lockup or watchdog reset that no fault caused (the images'
/// own `no_panic`: a panic ends in a HardFault).
pub const IMAGE_TROUBLE: &str = "image_trouble";

/// The fault classes the emulator injects (every class of the cores' first slice);
/// a class added later is not drawn under `--emu` until it is listed here with its
/// injection in `apply`.
pub fn supported(kind: &FaultKind) -> bool {
    matches!(
        kind,
        FaultKind::LinkBitErrors { .. }
            | FaultKind::LinkBurst { .. }
            | FaultKind::LinkCut { .. }
            | FaultKind::CurrentSpike { .. }
            | FaultKind::UdcSpike { .. }
            | FaultKind::StoPulse { .. }
            | FaultKind::Supply { .. }
            | FaultKind::LoadStep { .. }
            | FaultKind::LockedRotor { .. }
            | FaultKind::DrivePowerCut
            | FaultKind::PlcPowerCut
    )
}

/// The world's faults the emulator can inject, in order.
pub fn emu_faults(world: &World) -> Vec<Fault> {
    world
        .faults
        .iter()
        .filter(|f| supported(&f.kind))
        .copied()
        .collect()
}

/// The world runs in the emulator (the lift's plant does not).
pub fn runs_on_images(world: &World) -> bool {
    world.scenario.lift.is_none()
}

/// The invariants of [`EMU_INVARIANTS`], fresh.
fn emu_invariants() -> Vec<Box<dyn Invariant>> {
    invariants::all()
        .into_iter()
        .filter(|i| EMU_INVARIANTS.contains(&i.name()))
        .collect()
}

/// Applies one fault edge to the images' rig now.
fn apply(sim: &mut EmuSim, e: &FaultEdge, world: &World) {
    let now = sim.now_ns();
    let base = &world.baseline;
    match (e.kind, e.end) {
        (FaultKind::LinkBitErrors { rate, .. }, false) => sim.set_link_bit_error_rate(rate),
        (FaultKind::LinkBitErrors { .. }, true) => sim.set_link_bit_error_rate(base.bit_error_rate),
        (FaultKind::LinkBurst { to_drive, bytes }, false) => sim.link_burst(to_drive, bytes),
        (FaultKind::LinkCut { .. }, end) => sim.set_cut(!end),
        // A spike is placed `from_ns` after the fault's time (the cores place it in the
        // next PWM period): the emulator's sense pins take any width at any time.
        (
            FaultKind::CurrentSpike {
                phase,
                amps,
                from_ns,
                width_ns,
            },
            false,
        ) => sim.rig_mut().sense_spikes.push(SenseSpikeAt {
            phase,
            amps,
            from_ns: now + from_ns,
            to_ns: now + from_ns + width_ns,
        }),
        (
            FaultKind::UdcSpike {
                volts,
                from_ns,
                width_ns,
            },
            false,
        ) => sim.rig_mut().udc_spikes.push(UdcSpikeAt {
            volts,
            from_ns: now + from_ns,
            to_ns: now + from_ns + width_ns,
        }),
        (FaultKind::StoPulse { .. }, end) => sim.set_sto_wire(if end {
            ExternalWire::DrivenHigh
        } else {
            ExternalWire::DrivenLow
        }),
        (FaultKind::Supply { delta_v, .. }, false) => {
            sim.rig_mut().plant.params_mut().supply_v = (base.supply_v + delta_v).max(0.0)
        }
        (FaultKind::Supply { .. }, true) => {
            sim.rig_mut().plant.params_mut().supply_v = base.supply_v
        }
        (FaultKind::LoadStep { nm }, false) => {
            sim.rig_mut().plant.params_mut().motor.load_torque_nm = nm
        }
        (FaultKind::LockedRotor { .. }, end) => {
            sim.rig_mut().plant.params_mut().motor.locked_rotor = !end
        }
        (FaultKind::DrivePowerCut, false) => sim.power_cycle_drive(),
        (FaultKind::PlcPowerCut, false) => sim.power_cycle_plc(),
        _ => {}
    }
}

/// Runs `world` with `faults` on the images to its end or to the first violation.
pub fn run(world: &World, faults: &[Fault], images: &EmuImages) -> Outcome {
    let mut p = Progress::default();
    let r = catch_unwind(AssertUnwindSafe(|| {
        run_inner(world, faults, images, &mut p)
    }));
    let violation = match r {
        Ok(v) => v,
        Err(payload) => {
            let msg = super::runner::panic_message(payload.as_ref());
            Some(Violation {
                invariant: NO_PANIC,
                t_ns: p.sim_ns,
                message: format!("the co-simulation panicked: {msg}"),
            })
        }
    };
    Outcome {
        violation,
        injected: p.injected,
        sim_ns: p.sim_ns,
        outputs_on_ns: p.outputs_on_ns,
        trips: p.trips,
        // The classes that cut writes and the cores' storage checks do not run on the
        // images (`supported`).
        write_cuts: Vec::new(),
        checks: Default::default(),
    }
}

#[derive(Default)]
struct Progress {
    injected: usize,
    sim_ns: u64,
    outputs_on_ns: u64,
    trips: Vec<u8>,
}

/// The observer: the view, the invariants and the time with the outputs on.
///
/// The invariants see a slice one slice late: a log line read at the end of a slice may
/// tell a change of the slice before (an image turns its outputs on in an interrupt and
/// logs the state change from a task a few microseconds later, often after the slice's
/// end), so an entry into RUN is credited from the start of the slice before the one
/// it was read in, and each slice is checked only when the next one has run
/// (`emu_observe`'s docs).
struct Checker {
    view: EmuView,
    log: DriveLogReader,
    plc_log: PlcLogReader,
    /// The start and end of the last slice run.
    slice: (u64, u64),
    /// Changes of the last slice run, not yet checked.
    pending: Vec<(u64, Change)>,
    invariants: Vec<Box<dyn Invariant>>,
    last: Option<(u64, bool)>,
    cpu_events: usize,
}

impl Checker {
    /// A change made between two slices (a fault applied) at `t`.
    fn note(&mut self, t: u64, c: Change) {
        self.pending.push((t, c));
    }

    /// Reads what changed in the slice just run, then checks the slice before it, change
    /// by change in time order, and at its end. `flush`: the run ends, check this slice
    /// too.
    fn after_slice(
        &mut self,
        sim: &mut EmuSim,
        p: &mut Progress,
        flush: bool,
    ) -> Option<Violation> {
        let now = sim.now_ns();
        let (prev_start, prev_end) = self.slice;
        self.slice = (prev_end, now);
        let mut changes: Vec<(u64, Change)> = sim
            .rig_mut()
            .tim_trace
            .as_mut()
            .map(|t| {
                t.drain(..)
                    .map(|e| (EmuSim::ns(tim_event_at(&e)), Change::Tim(e)))
                    .collect()
            })
            .unwrap_or_default();
        let logged = changes.len();
        self.log.read(sim.drive(), &mut changes);
        self.plc_log.read(sim.plc(), &mut changes);
        for (t, c) in changes.iter_mut().skip(logged) {
            if c.enters_run() {
                *t = prev_start.min(*t);
            }
        }
        if !sim
            .drive()
            .soc()
            .tim1()
            .is_some_and(|t| t.breaks_active().iter().any(|b| *b))
        {
            changes.push((now, Change::BreaksInactive));
        }
        self.pending.extend(changes);
        self.pending.sort_by_key(|(t, _)| *t);
        let upto = if flush { now } else { prev_end };
        let split = self.pending.partition_point(|(t, _)| *t <= upto);
        let due: Vec<(u64, Change)> = self.pending.drain(..split).collect();
        // Everything at one instant first, then one look (a break's flag and the outputs
        // it opens are two events of the same cycle).
        for (k, (t, c)) in due.iter().enumerate() {
            self.view.apply(c);
            let last_at_t = due.get(k + 1).is_none_or(|(t2, _)| t2 != t);
            if last_at_t {
                if let Some(v) = self.observe(*t, p) {
                    return Some(v);
                }
            }
        }
        if let Some(v) = self.observe(upto, p) {
            return Some(v);
        }
        p.sim_ns = now;
        p.trips = sim.faults().iter().map(|f| f.code).collect();
        if sim.rig().plant.diverged() {
            return Some(Violation {
                invariant: PLANT_DIVERGED,
                t_ns: now,
                message: "the plant model left physics".into(),
            });
        }
        let n = sim.drive().events().len() + sim.plc().events().len();
        if n != self.cpu_events {
            self.cpu_events = n;
            if let Some(t) = sim.unexpected_troubles().first() {
                return Some(Violation {
                    invariant: IMAGE_TROUBLE,
                    t_ns: now,
                    message: t.clone(),
                });
            }
        }
        None
    }

    fn observe(&mut self, t: u64, p: &mut Progress) -> Option<Violation> {
        let o = self.view.observation(t);
        if let Some((t0, on)) = self.last.replace((t, o.outputs_on)) {
            if on {
                p.outputs_on_ns += t.saturating_sub(t0);
            }
        }
        check_all(&mut self.invariants, &o)
    }
}

fn tim_event_at(e: &g431_emu::periph::tim_adv::TimEvent) -> u64 {
    use g431_emu::periph::tim_adv::TimEvent as E;
    match *e {
        E::Update { at, .. }
        | E::GateChanged { at, .. }
        | E::OutputsOff { at, .. }
        | E::OutputsOn { at }
        | E::Trgo { at, .. }
        | E::Trgo2 { at, .. }
        | E::Blanking { at, .. }
        | E::Break { at, .. } => at,
    }
}

fn run_inner(
    world: &World,
    faults: &[Fault],
    images: &EmuImages,
    p: &mut Progress,
) -> Option<Violation> {
    let opts = RunOptions {
        seed: world.seed,
        sample_ns: world.duration_ns,
    };
    let mut sim = match EmuSim::new(
        &images.drive,
        &images.plc,
        &world.program,
        world.scenario.clone(),
        opts,
    ) {
        Ok(s) => s,
        Err(e) => {
            return Some(Violation {
                invariant: NO_PANIC,
                t_ns: 0,
                message: format!("the world does not load on the images: {e:#}"),
            })
        }
    };
    sim.rig_mut().tim_trace = Some(Vec::new());
    let mut checker = Checker {
        view: EmuView::default(),
        log: DriveLogReader::default(),
        plc_log: PlcLogReader::default(),
        slice: (0, 0),
        pending: Vec::new(),
        invariants: emu_invariants(),
        last: None,
        cpu_events: 0,
    };
    let edges = edges(faults);
    let mut k = 0;
    let end = world.duration_ns;
    loop {
        let mut next = (sim.now_ns() + QUANTUM_NS).min(end);
        if let Some(e) = edges.get(k) {
            next = next.min(e.at_ns.max(sim.now_ns()));
        }
        if next > sim.now_ns() {
            sim.run_until(next, |_| {});
            if let Some(v) = checker.after_slice(&mut sim, p, next >= end) {
                return Some(v);
            }
        }
        while let Some(e) = edges.get(k).filter(|e| e.at_ns <= sim.now_ns()) {
            apply(&mut sim, e, world);
            if !e.end {
                p.injected += 1;
            }
            k += 1;
        }
        let now = sim.now_ns();
        let sto_in_low = sim.rig().plant.sto_in_low();
        // At the instant TIM1's BKIN took it (the cycle of `now`, as its events are
        // stamped), so that the wire and the break it opens are seen together.
        let at = now.max(EmuSim::ns(g431_emu::time::ns_to_cycles(now)));
        checker.note(at, Change::Sto(sto_in_low));
        sim.rig_mut().sense_spikes.retain(|s| s.to_ns >= now);
        sim.rig_mut().udc_spikes.retain(|s| s.to_ns >= now);
        if sim.now_ns() >= end {
            return None;
        }
    }
}

/// Runs one seed on the images (and shrinks it if it fails and `shrink`); `None` when
/// the seed's world cannot run there (the lift).
pub fn run_seed(
    seed: u64,
    opts: &WorldOptions,
    shrink: bool,
    images: &EmuImages,
) -> Result<Option<SeedResult>> {
    let world = World::generate(seed, opts)?;
    if !runs_on_images(&world) {
        return Ok(None);
    }
    let faults = emu_faults(&world);
    let out = run(&world, &faults, images);
    let mut by_class = [0u64; CLASSES.len()];
    for f in faults.iter().take(out.injected) {
        if let Some(i) = CLASSES.iter().position(|c| *c == f.kind.class()) {
            by_class[i] += 1;
        }
    }
    let failure = out.violation.clone().map(|v| {
        let so_far: Vec<Fault> = faults.iter().take(out.injected).copied().collect();
        let shrunk = shrink.then(|| {
            let (l, o) = super::shrink::shrink_with(&so_far, out.clone(), |f| {
                let o = run(&world, f, images);
                let same = o
                    .violation
                    .as_ref()
                    .is_some_and(|x| x.invariant == v.invariant);
                same.then_some(o)
            });
            (l, o.violation.unwrap_or_else(|| v.clone()))
        });
        Failure {
            violation: v,
            world: world.summary.clone(),
            faults_so_far: so_far,
            shrunk,
        }
    });
    Ok(Some(SeedResult {
        seed,
        injected_by_class: by_class,
        sim_ns: out.sim_ns,
        outputs_on_ns: out.outputs_on_ns,
        trips: out.trips,
        write_cuts: [0; super::WRITES.len()],
        checks: out.checks,
        failure,
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_class_of_the_first_slice_is_injected_on_the_images() {
        let kinds = [
            FaultKind::LinkBitErrors {
                rate: 1e-3,
                for_ns: 1,
            },
            FaultKind::LinkBurst {
                to_drive: true,
                bytes: 1,
            },
            FaultKind::LinkCut { for_ns: 1 },
            FaultKind::CurrentSpike {
                phase: 0,
                amps: 1.0,
                from_ns: 0,
                width_ns: 1,
            },
            FaultKind::UdcSpike {
                volts: 1.0,
                from_ns: 0,
                width_ns: 1,
            },
            FaultKind::StoPulse { width_ns: 1 },
            FaultKind::Supply {
                delta_v: -1.0,
                for_ns: 1,
            },
            FaultKind::Supply {
                delta_v: 1.0,
                for_ns: 1,
            },
            FaultKind::LoadStep { nm: 0.1 },
            FaultKind::LockedRotor { for_ns: 1 },
            FaultKind::DrivePowerCut,
            FaultKind::PlcPowerCut,
        ];
        assert!(kinds.iter().all(supported));
        assert!(kinds.iter().all(|k| CLASSES.contains(&k.class())));
    }

    #[test]
    fn the_emu_invariants_exist_and_the_lift_worlds_are_skipped() {
        let names: Vec<&str> = emu_invariants().iter().map(|i| i.name()).collect();
        assert_eq!(names.len(), EMU_INVARIANTS.len(), "{names:?}");
        let opts = WorldOptions::default();
        let lift = (1..200)
            .map(|s| World::generate(s, &opts).unwrap())
            .find(|w| w.template.name == "lift")
            .expect("a lift world in 200 seeds");
        assert!(!runs_on_images(&lift));
    }
}
