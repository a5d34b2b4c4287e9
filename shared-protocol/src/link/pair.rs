//! The co-simulation rig (quinn-proto's test `Pair`): both link tasks and the [`Line`]
//! between them, stepped in virtual time. Each side is any [`LinkTask`]: a bare endpoint
//! or a whole application (`PlcApp`, `DriveApp`) with its [`super::pump::Pump`]
//! ([`Pumped`]), so the link tests, the firmware crates' tests and hil-sim move bytes by
//! the same rule as the boards. `docs/cosim.md` in this crate says what it models and how
//! a test uses it.

use super::channel::Impairments;
use super::config::LinkConfig;
use super::drive::DriveLink;
use super::line::{End, Line, LinkTask, Pumped};
use super::plc::PlcLink;
use super::pump::{LinkEndpoint, MAX_IDLE_US};
use crate::units::Micros;

/// The PLC's task, the drive's task, the line, and the clock.
pub struct Pair<P, D> {
    pub plc: P,
    pub drive: D,
    pub line: Line,
    /// Virtual time: the last instant stepped to.
    pub now: Micros,
}

/// The two bare link endpoints, each with its pump.
pub type LinkPair = Pair<Pumped<PlcLink>, Pumped<DriveLink>>;

impl LinkPair {
    /// Both endpoints at `cfg`, both directions with the same impairments (independent
    /// random streams from `seed`).
    pub fn new(cfg: LinkConfig, imp: Impairments, seed: u64) -> Self {
        Pair::pumped(
            PlcLink::new(cfg),
            DriveLink::new(cfg),
            Line::new(cfg.baud, imp, seed),
        )
    }
}

impl<P: LinkEndpoint, D: LinkEndpoint> Pair<Pumped<P>, Pumped<D>> {
    /// Two endpoints (or applications), each served by a pump with the boards' idle bound.
    pub fn pumped(plc: P, drive: D, line: Line) -> Self {
        Pair::with_line(
            Pumped::new(plc, MAX_IDLE_US),
            Pumped::new(drive, MAX_IDLE_US),
            line,
        )
    }
}

impl<P: LinkTask, D: LinkTask> Pair<P, D> {
    /// Both tasks start at time 0 and pass at once (as the boards' link tasks at boot).
    pub fn with_line(plc: P, drive: D, mut line: Line) -> Self {
        line.start(0);
        Pair {
            plc,
            drive,
            line,
            now: Micros(0),
        }
    }

    /// Pass each task that is woken at `now`; `kicked`: the applications just ran, so a
    /// task whose endpoint has something due passes too (the boards' `pump::is_due`).
    fn poll(&mut self, kicked: bool) {
        let t_ns = self.now.0.saturating_mul(1000);
        self.line.poll(End::Plc, &mut self.plc, t_ns, kicked);
        self.line.poll(End::Drive, &mut self.drive, t_ns, kicked);
    }

    /// The applications (or the test) changed something: each task with something due
    /// passes now, as a board's application task wakes its link task.
    pub fn kick(&mut self) {
        self.poll(true);
    }

    /// The next moment something happens on the line (a byte arrives, a task's deadline),
    /// in whole microseconds, if before `until`.
    pub fn next_event(&self, until: Micros) -> Micros {
        let next = self
            .line
            .next_event_ns()
            .map_or(until, |t| Micros(t.div_ceil(1000)));
        next.min(until).max(self.now)
    }

    /// Advance to the next moment something happens, but not beyond `until`, and pass the
    /// tasks it wakes. The test is the applications: what it changed since the last step
    /// (a command queued, a status set) is kicked first, at the present, as a board's
    /// application task wakes its link task when it leaves something due.
    pub fn step(&mut self, until: Micros) {
        self.kick();
        self.now = self.next_event(until);
        self.kick();
    }

    /// Step until `until` (inclusive), calling `each` after every step.
    pub fn run_until(&mut self, until: Micros, mut each: impl FnMut(&mut Self)) {
        while self.now < until {
            self.step(until);
            each(self);
        }
    }

    /// Step for `us` microseconds.
    pub fn run_for(&mut self, us: u64) {
        let until = Micros(self.now.0.saturating_add(us));
        self.run_until(until, |_| {});
    }

    /// The PLC's MCU restarts now with `plc` as its task (a new endpoint and pump).
    pub fn restart_plc(&mut self, plc: P) {
        self.plc = plc;
        self.line.restart(End::Plc, self.now.0.saturating_mul(1000));
    }

    /// The drive's MCU restarts now with `drive` as its task.
    pub fn restart_drive(&mut self, drive: D) {
        self.drive = drive;
        self.line
            .restart(End::Drive, self.now.0.saturating_mul(1000));
    }

    /// Cuts (or restores) the line, both directions.
    pub fn cut(&mut self, cut: bool) {
        self.line.set_cut(cut);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::drive::DriveEvent;

    /// The example of `docs/cosim.md`.
    #[test]
    fn the_documented_example() {
        let mut p = LinkPair::new(LinkConfig::default(), Impairments::default(), 1);
        p.run_until(Micros(20_000), |_| {});
        assert!(p.plc.is_up() && p.drive.is_up());
        p.plc.write_q(0, 100).unwrap();
        p.run_for(5_000);
        assert_eq!(
            std::iter::from_fn(|| p.drive.poll_event()).last(),
            Some(DriveEvent::QWrite {
                addr: 0,
                value: 100
            })
        );
        let cut = p.now;
        p.cut(true);
        p.run_until(Micros(cut.0 + 60_000), |_| {});
        assert!(!p.drive.is_up(), "the drive's link timeout (50 ms) expired");
    }

    /// A noise burst spoils the frame it hits: the receiver counts it bad, and the link
    /// stays up (the next frames are clean).
    #[test]
    fn a_burst_is_one_bad_frame_and_the_link_stays_up() {
        let mut p = LinkPair::new(LinkConfig::default(), Impairments::default(), 1);
        p.run_until(Micros(20_000), |_| {});
        let bad = p.drive.stats().frames_bad;
        p.line.to_drive.burst(4);
        p.run_for(30_000);
        assert_eq!(p.drive.stats().frames_bad, bad + 1);
        assert!(p.plc.is_up() && p.drive.is_up());
        assert!(p.line.to_drive.stats().corrupted_frames >= 1);
    }

    /// A restarted side passes at once: the new PLC's Hello goes out at the restart.
    #[test]
    fn a_restarted_side_passes_at_once() {
        let cfg = LinkConfig::default();
        let mut p = LinkPair::new(cfg, Impairments::default(), 1);
        p.run_until(Micros(20_000), |_| {});
        let frames = p.line.to_drive.stats().frames;
        p.restart_plc(Pumped::new(PlcLink::new(cfg), MAX_IDLE_US));
        p.step(p.now);
        assert_eq!(p.line.to_drive.stats().frames, frames + 1, "Hello at once");
    }
}
