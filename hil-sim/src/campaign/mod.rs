//! `hil-sim campaign`: a seeded fault campaign on the firmware cores (docs/campaign.md).
//!
//! Each seed generates a world ([`world`]): a shipped program on its scenario, a plant
//! within physical ranges, user actions and faults ([`faults`]) at random times. The
//! world runs in the co-simulation for a bounded time, and after every scheduler event
//! every invariant ([`invariants`]) is checked on what the rig shows ([`observe`]). A
//! failing seed prints its one-line reproduction, the invariant, the time and the faults
//! injected so far, and its fault list shrunk ([`shrink`]) to the fewest that still fail.

#[cfg(feature = "emu")]
pub mod emu;
#[cfg(feature = "emu")]
pub mod emu_observe;
pub mod faults;
pub mod invariants;
pub mod observe;
pub mod rng;
pub mod runner;
pub mod shrink;
pub mod world;

use std::fmt::Write as _;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;

use anyhow::Result;

use faults::{Fault, CLASSES};
use invariants::Violation;
use world::{World, WorldOptions};

/// What to run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CampaignOptions {
    pub first: u64,
    pub seeds: u64,
    pub jobs: usize,
    pub world: WorldOptions,
    /// Shrink failing seeds' fault lists.
    pub shrink: bool,
}

/// One seed's result.
#[derive(Debug, Clone)]
pub struct SeedResult {
    pub seed: u64,
    /// The faults that started, by class (as [`CLASSES`]).
    pub injected_by_class: [u64; CLASSES.len()],
    pub sim_ns: u64,
    /// Simulated time with the outputs on, ns.
    pub outputs_on_ns: u64,
    /// The drive's trips (fault codes, in order).
    pub trips: Vec<u8>,
    /// Armed cuts that stopped an EEPROM write, by what was written (as [`WRITES`]).
    pub write_cuts: [u64; WRITES.len()],
    pub checks: runner::Checks,
    pub failure: Option<Failure>,
}

/// What an armed cut stopped: the storage job in flight, or a write outside the queue
/// (the counters record).
pub const WRITES: [&str; 5] = ["save", "fault log", "boot record", "counters", "other"];

/// The index in [`WRITES`] of a cut with `job` in flight.
fn write_index(job: &Option<firmware_plc::storage::Job>) -> usize {
    use firmware_plc::storage::Job;
    match job {
        Some(Job::Save { .. } | Job::Commit { .. }) => 0,
        Some(Job::LogFault(_)) => 1,
        Some(Job::Boot(_)) => 2,
        None => 3,
        Some(_) => 4,
    }
}

/// A failing seed.
#[derive(Debug, Clone)]
pub struct Failure {
    pub violation: Violation,
    pub world: String,
    /// The faults injected up to the violation.
    pub faults_so_far: Vec<Fault>,
    /// The shrunk list and the violation it gives.
    pub shrunk: Option<(Vec<Fault>, Violation)>,
}

/// The campaign's figures.
#[derive(Debug, Clone, Default)]
pub struct Summary {
    pub runs: u64,
    pub faults: u64,
    pub violations: u64,
    pub by_class: [u64; CLASSES.len()],
    pub sim_ns: u64,
    /// Simulated time with the outputs on, ns.
    pub outputs_on_ns: u64,
    /// The drive's trips, all worlds.
    pub trips: u64,
    /// Armed cuts that stopped an EEPROM write, by [`WRITES`].
    pub write_cuts: [u64; WRITES.len()],
    pub checks: runner::Checks,
    /// By invariant name.
    pub by_invariant: Vec<(&'static str, u64)>,
    /// Seeds whose world cannot run where the campaign runs (the lift under `--emu`).
    pub skipped: u64,
}

impl Summary {
    /// `N runs, F faults injected, V violations`, then the per-class counts.
    pub fn render(&self) -> String {
        let mut s = format!(
            "{} runs, {} faults injected, {} violations\n",
            self.runs, self.faults, self.violations
        );
        let classes: Vec<String> = CLASSES
            .iter()
            .zip(self.by_class)
            .map(|(c, n)| format!("{c} {n}"))
            .collect();
        let _ = writeln!(s, "faults by class: {}", classes.join(", "));
        if !self.by_invariant.is_empty() {
            let inv: Vec<String> = self
                .by_invariant
                .iter()
                .map(|(c, n)| format!("{c} {n}"))
                .collect();
            let _ = writeln!(s, "violations by invariant: {}", inv.join(", "));
        }
        let cuts: Vec<String> = WRITES
            .iter()
            .zip(self.write_cuts)
            .map(|(c, n)| format!("{c} {n}"))
            .collect();
        let _ = writeln!(
            s,
            "PLC power cuts inside EEPROM writes: {} ({})",
            self.write_cuts.iter().sum::<u64>(),
            cuts.join(", ")
        );
        let c = &self.checks;
        let _ = writeln!(
            s,
            "storage checked after {} PLC power cuts, fault log counted {} times, {} drive trips learned and logged; {} Q values applied in order, {} settled Q steps compared",
            c.storage_after_cut, c.log_counted, c.trips_learned, c.q_applied, c.q_settled
        );
        let _ = write!(
            s,
            "simulated {:.1} s ({:.3} h), outputs on {:.1} s, {} drive trips",
            self.sim_ns as f64 / 1e9,
            self.sim_ns as f64 / 3.6e12,
            self.outputs_on_ns as f64 / 1e9,
            self.trips
        );
        if self.skipped > 0 {
            let _ = write!(
                s,
                "\n{} seed(s) skipped: the lift's plant runs on the cores only",
                self.skipped
            );
        }
        s
    }
}

/// Runs one seed (and shrinks it if it fails and `shrink`).
pub fn run_seed(seed: u64, opts: &WorldOptions, shrink: bool) -> Result<SeedResult> {
    let world = World::generate(seed, opts)?;
    let out = runner::run(&world, &world.faults);
    let mut by_class = [0u64; CLASSES.len()];
    for f in world.faults.iter().take(out.injected) {
        if let Some(i) = CLASSES.iter().position(|c| *c == f.kind.class()) {
            by_class[i] += 1;
        }
    }
    let mut write_cuts = [0u64; WRITES.len()];
    for j in &out.write_cuts {
        if let Some(n) = write_cuts.get_mut(write_index(j)) {
            *n += 1;
        }
    }
    let failure = out.violation.clone().map(|v| {
        let so_far: Vec<Fault> = world.faults.iter().take(out.injected).copied().collect();
        let shrunk = shrink.then(|| {
            let (l, o) = shrink::shrink(&world, &so_far, v.invariant, out.clone());
            let v2 = o.violation.unwrap_or_else(|| v.clone());
            (l, v2)
        });
        Failure {
            violation: v,
            world: world.summary.clone(),
            faults_so_far: so_far,
            shrunk,
        }
    });
    Ok(SeedResult {
        seed,
        injected_by_class: by_class,
        sim_ns: out.sim_ns,
        outputs_on_ns: out.outputs_on_ns,
        trips: out.trips.clone(),
        write_cuts,
        checks: out.checks,
        failure,
    })
}

/// The report of a failing seed: the reproduction line first.
pub fn render_failure(seed: u64, f: &Failure, opts: &WorldOptions) -> String {
    render_failure_with(seed, f, opts, "")
}

/// [`render_failure`] with `flags` (such as ` --emu`) in the reproduction.
pub fn render_failure_with(seed: u64, f: &Failure, opts: &WorldOptions, flags: &str) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "FAIL seed {seed}: reproduce with `hil-sim campaign --seeds 1 --first {seed} --duration {} --max-faults {}{flags}`",
        opts.duration_ns as f64 / 1e9,
        opts.max_faults
    );
    let v = &f.violation;
    let _ = writeln!(
        s,
        "  {} at {:.6} s: {}",
        v.invariant,
        v.t_ns as f64 / 1e9,
        v.message
    );
    let _ = writeln!(s, "  world: {}", f.world);
    let _ = writeln!(s, "  faults injected so far ({}):", f.faults_so_far.len());
    for x in &f.faults_so_far {
        let _ = writeln!(s, "    {x}");
    }
    if let Some((l, v)) = &f.shrunk {
        let _ = writeln!(
            s,
            "  shrunk to {} fault(s), {} at {:.6} s: {}",
            l.len(),
            v.invariant,
            v.t_ns as f64 / 1e9,
            v.message
        );
        for x in l {
            let _ = writeln!(s, "    {x}");
        }
    }
    s
}

/// Runs the campaign on `jobs` threads; `on_result` sees each seed's result as it ends
/// (in any order); the summary counts them all.
pub fn run_campaign(
    opts: &CampaignOptions,
    on_result: impl Fn(&SeedResult) + Sync,
) -> Result<(Summary, Vec<SeedResult>)> {
    run_campaign_with(
        opts,
        |seed| run_seed(seed, &opts.world, opts.shrink).map(Some),
        on_result,
    )
}

/// [`run_campaign`] with `run_one` running a seed (`None`: the seed's world cannot run
/// there and is skipped), on the cores or the images (`emu::run_seed`).
pub fn run_campaign_with(
    opts: &CampaignOptions,
    run_one: impl Fn(u64) -> Result<Option<SeedResult>> + Sync,
    on_result: impl Fn(&SeedResult) + Sync,
) -> Result<(Summary, Vec<SeedResult>)> {
    let skipped = AtomicU64::new(0);
    let next = AtomicU64::new(0);
    let results = Mutex::new(Vec::new());
    let error = Mutex::new(None);
    std::thread::scope(|s| {
        for _ in 0..opts.jobs.max(1) {
            s.spawn(|| loop {
                let i = next.fetch_add(1, Ordering::Relaxed);
                if i >= opts.seeds {
                    return;
                }
                let seed = opts.first.wrapping_add(i);
                match run_one(seed) {
                    Ok(None) => {
                        skipped.fetch_add(1, Ordering::Relaxed);
                    }
                    Ok(Some(r)) => {
                        on_result(&r);
                        if let Ok(mut v) = results.lock() {
                            v.push(r);
                        }
                    }
                    Err(e) => {
                        if let Ok(mut x) = error.lock() {
                            x.get_or_insert(e);
                        }
                        return;
                    }
                }
            });
        }
    });
    if let Some(e) = error.into_inner().ok().flatten() {
        return Err(e);
    }
    let mut results = results.into_inner().unwrap_or_default();
    results.sort_by_key(|r| r.seed);
    let mut sum = Summary {
        skipped: skipped.into_inner(),
        ..Summary::default()
    };
    for r in &results {
        sum.runs += 1;
        sum.sim_ns += r.sim_ns;
        sum.outputs_on_ns += r.outputs_on_ns;
        sum.trips += r.trips.len() as u64;
        for (a, b) in sum.write_cuts.iter_mut().zip(r.write_cuts) {
            *a += b;
        }
        sum.checks.storage_after_cut += r.checks.storage_after_cut;
        sum.checks.log_counted += r.checks.log_counted;
        sum.checks.trips_learned += r.checks.trips_learned;
        sum.checks.q_applied += r.checks.q_applied;
        sum.checks.q_settled += r.checks.q_settled;
        for (a, b) in sum.by_class.iter_mut().zip(r.injected_by_class) {
            *a += b;
        }
        if let Some(f) = &r.failure {
            sum.violations += 1;
            let name = f.violation.invariant;
            match sum.by_invariant.iter_mut().find(|(n, _)| *n == name) {
                Some((_, n)) => *n += 1,
                None => sum.by_invariant.push((name, 1)),
            }
        }
    }
    sum.faults = sum.by_class.iter().sum();
    Ok((sum, results))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_summary_line_names_runs_faults_and_violations() {
        let mut s = Summary {
            runs: 3,
            faults: 5,
            violations: 1,
            sim_ns: 6_000_000_000,
            ..Summary::default()
        };
        s.by_class[0] = 5;
        let r = s.render();
        assert!(
            r.starts_with("3 runs, 5 faults injected, 1 violations\n"),
            "{r}"
        );
        assert!(r.contains("link_bit_errors 5"), "{r}");
    }
}
