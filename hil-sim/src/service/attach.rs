//! The service line attached to a run (service.md 9): stepped after each PLC tick, its
//! host end on a pty or (tests, the flood) on nothing. On a pty (`run --service-pty`),
//! virtual time follows the wall clock from the first client's arrival to the end of the
//! linger, whether a client has the pty open or not: a user runs several `plcctl`
//! commands in a row, and each finds the PLC where the clock says it is. Clients come
//! and go; the pty takes one after another.

use std::time::{Duration, Instant};

use anyhow::Result;
use shared_protocol::units::Micros;

use super::line::{ServiceLine, STEP_NS};
use super::pty::Pty;
use crate::sim::{Sample, Simulation};

/// How `run --service-pty` serves its client.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PtyOptions {
    /// Wait at t = 0 until a client opens the pty.
    pub wait_for_client: bool,
    /// After the duration, keep serving (inputs held) this long, clients coming and going.
    pub linger: Duration,
    /// Follow the wall clock at this many virtual seconds per wall second (`run`: 1 unless
    /// `--service-speed` says otherwise); `None`: run free (the panel runs in real time by
    /// itself).
    pub pace_virtual_per_wall: Option<f64>,
}

/// A service line in a run, with its host end.
pub struct Attached {
    line: ServiceLine,
    pty: Option<(Pty, PtyOptions)>,
    /// (wall clock, virtual ns) at the first paced step: the pacing's reference.
    paced_since: Option<(Instant, u64)>,
    /// The simulation after the run's duration, for [`Attached::linger`]. Boxed: a
    /// `Simulation` is ~90 KiB, and the panel's backend holds an `Attached` inline.
    parked: Option<Box<Simulation>>,
}

impl Attached {
    /// The line without a host end (the flood test; a client of the library).
    pub fn detached(line: ServiceLine) -> Self {
        Attached {
            line,
            pty: None,
            paced_since: None,
            parked: None,
        }
    }

    pub fn on_pty(line: ServiceLine, pty: Pty, opts: PtyOptions) -> Self {
        Attached {
            line,
            pty: Some((pty, opts)),
            paced_since: None,
            parked: None,
        }
    }

    pub fn line(&mut self) -> &mut ServiceLine {
        &mut self.line
    }

    /// Blocks until a client opens the pty, if the options say so.
    pub fn wait_for_client(&self) {
        if let Some((pty, opts)) = &self.pty {
            while opts.wait_for_client && !pty.client() {
                std::thread::sleep(Duration::from_millis(5));
            }
        }
    }

    /// Runs `sim` until `end_ns`, stepping the service after each 1 ms tick.
    pub fn run_until(
        &mut self,
        sim: &mut Simulation,
        end_ns: u64,
        on_sample: &mut impl FnMut(&Sample),
    ) {
        while sim.now_ns() < end_ns {
            let next = ((sim.now_ns() / STEP_NS + 1) * STEP_NS).min(end_ns);
            sim.run_until(next, &mut *on_sample);
            if next.is_multiple_of(STEP_NS) {
                self.step(sim);
            }
        }
    }

    /// One service step at the simulation's time, with the pty's bytes and pacing.
    fn step(&mut self, sim: &mut Simulation) {
        let now_ns = sim.now_ns();
        if let Some((pty, _)) = &mut self.pty {
            let bytes = pty.read_available();
            self.line.host_write(&bytes);
        }
        let out = self.line.step(sim.plc_mut(), Micros(now_ns / 1000));
        if let Some((pty, _)) = &mut self.pty {
            pty.write(&out);
        }
        self.pace(now_ns);
    }

    /// Virtual time follows the wall clock, with or without a client (a run that raced
    /// ahead while nobody was attached left the next command without a device).
    fn pace(&mut self, now_ns: u64) {
        let Some(speed) = self.pty.as_ref().and_then(|(_, o)| o.pace_virtual_per_wall) else {
            return;
        };
        let (wall0, virt0) = *self
            .paced_since
            .get_or_insert_with(|| (Instant::now(), now_ns));
        let virt_s = now_ns.saturating_sub(virt0) as f64 * 1e-9;
        let due = wall0 + Duration::from_secs_f64(virt_s / speed);
        let wall = Instant::now();
        if due > wall {
            std::thread::sleep(due - wall);
        }
    }

    /// Keeps the simulation after the run's duration (`run::run_with`).
    pub fn park(&mut self, sim: Simulation) {
        self.parked = Some(Box::new(sim));
    }

    /// After the duration: keep serving, inputs held, until the linger time passes,
    /// clients coming and going (nothing is recorded).
    pub fn linger(&mut self) -> Result<()> {
        let Some(mut sim) = self.parked.take() else {
            return Ok(());
        };
        let sim: &mut Simulation = &mut sim;
        let Some((_, opts)) = &self.pty else {
            return Ok(());
        };
        // `--service-linger` is bounded (crate::args): the sum cannot overflow.
        let Some(until) = Instant::now().checked_add(opts.linger) else {
            anyhow::bail!("--service-linger too long");
        };
        sim.hold_inputs();
        while Instant::now() < until {
            let end = sim.now_ns() + 10 * STEP_NS;
            self.run_until(sim, end, &mut |_| {});
        }
        Ok(())
    }
}
