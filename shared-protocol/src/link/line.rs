//! The UART line between the two link tasks: one [`Channel`] each way, and the rule by
//! which a link task passes (the boards' link task, `board_common::link::run`): when bytes
//! arrived, at its pump's deadline, when its busy transmitter becomes free with a frame
//! due, or when the application kicked it ([`crate::link::pump::is_due`]).
//!
//! The line does not own the tasks: [`super::pair::Pair`] owns two of them with the line,
//! and hil-sim keeps its boards where they are and lends each to [`Line::pass`]. Time is
//! in nanoseconds (hil-sim's clock); the pumps see whole microseconds.

use super::channel::{Channel, Impairments, IN_FLIGHT};
use super::frame::MAX_WIRE_FRAME;
use super::pump::{is_due, LinkEndpoint, Pass, Pump};
use crate::units::Micros;

/// One end of the line.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum End {
    /// Transmits on `to_drive`, receives from `to_plc`.
    Plc,
    /// Transmits on `to_plc`, receives from `to_drive`.
    Drive,
}

impl End {
    fn index(self) -> usize {
        match self {
            End::Plc => 0,
            End::Drive => 1,
        }
    }
}

/// What a link task does in one pass: the board's link task around its [`Pump`] (hil-sim's
/// boards: `link_pass`/`link_tx`/`link_timeout`), or a bare endpoint with its pump
/// ([`Pumped`]).
pub trait LinkTask {
    /// One pass: `rx` received since the last one, at most `room` bytes out.
    fn pass(&mut self, rx: &[u8], room: usize, now: Micros) -> Pass;
    /// The bytes the last pass handed out, for the UART.
    fn tx(&self) -> &[u8];
    /// The endpoint's next deadline (whether an application kick finds something due).
    fn timeout(&self) -> Option<Micros>;
}

/// An endpoint with the pump that serves it, as a board's link task holds them. Derefs to
/// the endpoint, so a test writes `pair.plc.run()`.
pub struct Pumped<E> {
    pub ep: E,
    pub pump: Pump,
}

impl<E> Pumped<E> {
    /// `max_idle_us`: the pump's idle bound ([`super::pump::MAX_IDLE_US`] on the boards).
    pub const fn new(ep: E, max_idle_us: u64) -> Self {
        Pumped {
            ep,
            pump: Pump::new(max_idle_us),
        }
    }
}

impl<E: LinkEndpoint> LinkTask for Pumped<E> {
    fn pass(&mut self, rx: &[u8], room: usize, now: Micros) -> Pass {
        self.pump.pass(&mut self.ep, rx, room, now)
    }
    fn tx(&self) -> &[u8] {
        self.pump.tx()
    }
    fn timeout(&self) -> Option<Micros> {
        self.ep.poll_timeout()
    }
}

impl<E> core::ops::Deref for Pumped<E> {
    type Target = E;
    fn deref(&self) -> &E {
        &self.ep
    }
}

impl<E> core::ops::DerefMut for Pumped<E> {
    fn deref_mut(&mut self) -> &mut E {
        &mut self.ep
    }
}

/// Both directions of the UART line and when each end's link task passes next.
pub struct Line {
    /// PLC TX -> drive RX.
    pub to_drive: Channel,
    /// Drive TX -> PLC RX.
    pub to_plc: Channel,
    /// Each task's next pass by its own deadline (or its line becoming free), ns.
    wake_ns: [Option<u64>; 2],
    /// Passes of each task woken by that deadline (not by bytes or a kick).
    timer_passes: [u32; 2],
}

impl Line {
    /// Both directions at `baud` with the same impairments; the drive-to-PLC direction's
    /// random stream is derived from `seed`.
    pub fn new(baud: u32, imp: Impairments, seed: u64) -> Self {
        Line::with_channels(
            Channel::new(baud, imp, seed),
            Channel::new(baud, imp, seed.wrapping_mul(31).wrapping_add(17)),
        )
    }

    /// Given wires (`to_drive` carries the PLC's transmissions, `to_plc` the drive's).
    pub fn with_channels(to_drive: Channel, to_plc: Channel) -> Self {
        Line {
            to_drive,
            to_plc,
            wake_ns: [None; 2],
            timer_passes: [0; 2],
        }
    }

    /// The wire `end` transmits on.
    pub fn outbox(&mut self, end: End) -> &mut Channel {
        match end {
            End::Plc => &mut self.to_drive,
            End::Drive => &mut self.to_plc,
        }
    }

    /// The wire `end` receives from.
    pub fn inbox(&mut self, end: End) -> &mut Channel {
        match end {
            End::Plc => &mut self.to_plc,
            End::Drive => &mut self.to_drive,
        }
    }

    /// Cuts (or restores) both directions.
    pub fn set_cut(&mut self, cut: bool) {
        self.to_drive.set_cut(cut);
        self.to_plc.set_cut(cut);
    }

    /// The same impairments both ways from now on.
    pub fn set_impairments(&mut self, imp: Impairments) {
        self.to_drive.set_impairments(imp);
        self.to_plc.set_impairments(imp);
    }

    /// Both tasks pass at `t_ns` (they start: the boards' link tasks pass at boot).
    pub fn start(&mut self, t_ns: u64) {
        self.wake_ns = [Some(t_ns); 2];
    }

    /// `end`'s MCU restarted and its link task passes at `t_ns` (its first pass at boot).
    pub fn restart(&mut self, end: End, t_ns: u64) {
        if let Some(w) = self.wake_ns.get_mut(end.index()) {
            *w = Some(t_ns);
        }
    }

    /// `end`'s MCU restarted: its link task has no deadline until it first passes.
    pub fn forget(&mut self, end: End) {
        if let Some(w) = self.wake_ns.get_mut(end.index()) {
            *w = None;
        }
    }

    /// Passes of `end`'s task woken by its own deadline so far.
    pub fn timer_passes(&self, end: End) -> u32 {
        self.timer_passes.get(end.index()).copied().unwrap_or(0)
    }

    /// The next time something on the line wakes a task: a byte arrives, a deadline.
    pub fn next_event_ns(&self) -> Option<u64> {
        let arrivals = [self.to_drive.next_arrival(), self.to_plc.next_arrival()]
            .into_iter()
            .flatten()
            .map(|a| a.0.saturating_mul(1000));
        arrivals.chain(self.wake_ns.into_iter().flatten()).min()
    }

    /// Whether `end`'s task passes at `t_ns`: bytes arrived for it, its deadline came, or
    /// `kicked` (the application task just ran) and its endpoint has something due.
    pub fn is_woken<T: LinkTask + ?Sized>(
        &self,
        end: End,
        task: &T,
        t_ns: u64,
        kicked: bool,
    ) -> bool {
        let inbox = match end {
            End::Plc => &self.to_plc,
            End::Drive => &self.to_drive,
        };
        let arrived = inbox
            .next_arrival()
            .is_some_and(|a| a.0.saturating_mul(1000) <= t_ns);
        arrived
            || self.timer_due(end, t_ns)
            || (kicked && is_due(task.timeout(), Micros(t_ns / 1000)))
    }

    fn timer_due(&self, end: End, t_ns: u64) -> bool {
        self.wake_ns
            .get(end.index())
            .copied()
            .flatten()
            .is_some_and(|w| w <= t_ns)
    }

    /// [`Self::pass`] if [`Self::is_woken`]; whether it passed.
    pub fn poll<T: LinkTask + ?Sized>(
        &mut self,
        end: End,
        task: &mut T,
        t_ns: u64,
        kicked: bool,
    ) -> bool {
        let woken = self.is_woken(end, task, t_ns, kicked);
        if woken {
            self.pass(end, task, t_ns);
        }
        woken
    }

    /// One pass of `end`'s task at `t_ns`, as the board's link task runs it: every byte
    /// received by then in, a frame out if the line is free (the boards' DMA transmitter
    /// takes a whole frame once the previous one is out), and the next wake-up: the
    /// pump's deadline, or the moment the line is free when something is due now but the
    /// line is busy.
    pub fn pass<T: LinkTask + ?Sized>(&mut self, end: End, task: &mut T, t_ns: u64) -> Pass {
        let now = Micros(t_ns / 1000);
        if self.timer_due(end, t_ns) {
            if let Some(n) = self.timer_passes.get_mut(end.index()) {
                *n += 1;
            }
        }
        let mut rx = [0u8; IN_FLIGHT];
        let n = self.inbox(end).receive(now, &mut rx);
        let out = self.outbox(end);
        let room = if out.is_idle(now) { MAX_WIRE_FRAME } else { 0 };
        let pass = task.pass(rx.get(..n).unwrap_or(&[]), room, now);
        let tx = task.tx();
        if !tx.is_empty() {
            out.send(tx, now);
        }
        let mut wake = pass.wake_at.0.saturating_mul(1000);
        if wake <= t_ns && !out.is_idle(now) {
            wake = out.free_at().0.saturating_mul(1000);
        }
        // Never the same instant again (a pump that asks for "now" and sends nothing
        // would otherwise stop virtual time).
        if let Some(w) = self.wake_ns.get_mut(end.index()) {
            *w = Some(wake.max(t_ns + 1));
        }
        pass
    }
}
