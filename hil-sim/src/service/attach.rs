//! The service line attached to a run (service.md 9): stepped after each PLC tick, its
//! host end on a pty or (tests, the flood) on nothing; virtual time follows the wall
//! clock while a client has the pty open, and runs at full speed otherwise.

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
    /// After the duration, keep serving (inputs held) this long while the client stays.
    pub linger: Duration,
    /// Follow the wall clock while a client is connected (`run`; the panel runs in real
    /// time by itself).
    pub pace: bool,
}

/// A service line in a run, with its host end.
pub struct Attached {
    line: ServiceLine,
    pty: Option<(Pty, PtyOptions)>,
    /// (wall clock, virtual ns) when the client was last seen arriving: the pacing's
    /// reference.
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
        let client = match &mut self.pty {
            Some((pty, _)) => {
                let c = pty.client();
                let bytes = pty.read_available();
                self.line.host_write(&bytes);
                c
            }
            None => false,
        };
        let out = self.line.step(sim.plc_mut(), Micros(now_ns / 1000));
        if let Some((pty, _)) = &mut self.pty {
            pty.write(&out);
        }
        self.pace(client, now_ns);
    }

    /// While a client is connected, virtual time follows the wall clock.
    fn pace(&mut self, client: bool, now_ns: u64) {
        if !client || !self.pty.as_ref().is_some_and(|(_, o)| o.pace) {
            self.paced_since = None;
            return;
        }
        let (wall0, virt0) = *self
            .paced_since
            .get_or_insert_with(|| (Instant::now(), now_ns));
        let due = wall0 + Duration::from_nanos(now_ns.saturating_sub(virt0));
        let wall = Instant::now();
        if due > wall {
            std::thread::sleep(due - wall);
        }
    }

    /// Keeps the simulation after the run's duration (`run::run_with`).
    pub fn park(&mut self, sim: Simulation) {
        self.parked = Some(Box::new(sim));
    }

    /// After the duration: keep serving, inputs held, until the client closes or the
    /// linger time passes (nothing is recorded).
    pub fn linger(&mut self) -> Result<()> {
        let Some(mut sim) = self.parked.take() else {
            return Ok(());
        };
        let sim: &mut Simulation = &mut sim;
        let Some((pty, opts)) = &self.pty else {
            return Ok(());
        };
        let until = Instant::now() + opts.linger;
        if !pty.client() {
            return Ok(());
        }
        sim.hold_inputs();
        loop {
            let end = sim.now_ns() + 10 * STEP_NS;
            self.run_until(sim, end, &mut |_| {});
            let gone = self.pty.as_ref().is_none_or(|(p, _)| !p.client());
            if gone || Instant::now() >= until {
                return Ok(());
            }
        }
    }
}
