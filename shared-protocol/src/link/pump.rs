//! The link pump: the one loop that moves bytes between a UART and a link endpoint, used
//! the same way by both boards' link tasks and by hil-sim.
//!
//! Each [`Pump::pass`] takes what the UART has received since the last pass, feeds it to
//! the endpoint, hands out **at most one frame, and at most what the line can take now**,
//! and returns the next deadline ([`Pass::wake_at`], quinn-proto's `poll_timeout` style).
//! The caller then waits for received bytes *or* that deadline, whichever comes first,
//! writes [`Pump::tx`] to the UART, and passes again.
//!
//! Why one frame per pass: a go-back-N window of download frames is ~50 ms of line time at
//! 115200 baud, longer than the link timeout. A loop that sent the whole window before it
//! read RX again left the peer's acknowledgements unread until the link timed out, then
//! started over: the download never finished (the livelock the emulator found). Reading
//! between frames keeps acknowledgements flowing.
//!
//! Why deadlines: the endpoints know when their next timer fires (retransmission, status,
//! heartbeat, link loss); waking exactly then, instead of every millisecond, costs less
//! and is the same in the simulator and on the board. The caller also wakes the pump when
//! the application queued something to send ([`is_due`] says whether that is needed).

use super::frame::MAX_WIRE_FRAME;
use crate::rate_limit::RateLimit;
use crate::units::Micros;

/// What the pump moves bytes for: a link endpoint, or an application that wraps one
/// (`PlcApp`, `DriveApp`), which then sees its link's events at once.
pub trait LinkEndpoint {
    /// Bytes received from the UART, in order.
    fn on_rx(&mut self, bytes: &[u8], now: Micros);
    /// The next frame into `out` (its length; 0 = nothing now). An `out` shorter than
    /// [`MAX_WIRE_FRAME`] only runs the timers.
    fn poll_tx(&mut self, now: Micros, out: &mut [u8]) -> usize;
    /// When `poll_tx` must run next if nothing arrives meanwhile; a time not after the
    /// present means now; `None`: no timer is running.
    fn poll_timeout(&self) -> Option<Micros>;
    /// The UART reported a line error (framing, noise, overrun, parity).
    fn line_error(&mut self);
    /// The application's reaction to what the link delivered (events: a fault report
    /// to log, a download result to act on). The pump calls it after the pass's frame
    /// was handed out, and the boards after that frame was written: a slow reaction (the
    /// PLC's EEPROM fault log takes tens of ms) then never holds back the acknowledgement
    /// of the message that caused it. An endpoint whose reaction happens in `on_rx`
    /// delays the acknowledgement by the reaction's time; longer than the peer's link
    /// timeout, the peer drops the session and delivers its unacknowledged reports again
    /// in the next, which are reacted to again: the livelock the emulator showed after a
    /// drive watchdog reset. The default does nothing (the bare link endpoints).
    fn service(&mut self, now: Micros) {
        let _ = now;
    }
}

impl LinkEndpoint for super::plc::PlcLink {
    fn on_rx(&mut self, bytes: &[u8], now: Micros) {
        self.receive(bytes, now);
    }
    fn poll_tx(&mut self, now: Micros, out: &mut [u8]) -> usize {
        self.poll_transmit(now, out)
    }
    fn poll_timeout(&self) -> Option<Micros> {
        super::plc::PlcLink::poll_timeout(self)
    }
    fn line_error(&mut self) {
        super::plc::PlcLink::line_error(self);
    }
}

impl LinkEndpoint for super::drive::DriveLink {
    fn on_rx(&mut self, bytes: &[u8], now: Micros) {
        self.receive(bytes, now);
    }
    fn poll_tx(&mut self, now: Micros, out: &mut [u8]) -> usize {
        self.poll_transmit(now, out)
    }
    fn poll_timeout(&self) -> Option<Micros> {
        super::drive::DriveLink::poll_timeout(self)
    }
    fn line_error(&mut self) {
        super::drive::DriveLink::line_error(self);
    }
}

/// Whether an endpoint whose [`LinkEndpoint::poll_timeout`] is `deadline` wants a pass at
/// `now` (e.g. the application just queued a command): the caller then wakes its pump.
pub fn is_due(deadline: Option<Micros>, now: Micros) -> bool {
    deadline.is_some_and(|d| d <= now)
}

/// `rx` cut after each frame delimiter (0x00, `frame.rs`): a board that feeds each piece
/// to [`Pump::receive`] in a critical section of its own never decodes more than one frame
/// in one (64 bytes of download frames in one section held the drive's PWM
/// interrupt off for more than a period at 20 kHz).
pub fn frame_pieces(rx: &[u8]) -> impl Iterator<Item = &[u8]> {
    rx.split_inclusive(|&b| b == 0)
}

/// The longest a board's link task waits between passes with no deadline due: it
/// reports itself alive every pass, and the watchdog supervisor checks every 20 ms.
pub const MAX_IDLE_US: u64 = 10_000;

/// Line errors are logged at most this often (the count in between is carried).
pub const LINE_ERROR_LOG_US: u64 = 1_000_000;

/// The result of one pass.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Pass {
    /// How many bytes [`Pump::tx`] holds for the UART now (at most the room given).
    pub tx_len: usize,
    /// Pass again at this time at the latest (or earlier when bytes arrive). Not after
    /// `now + max_idle_us`. When [`Pump::holding`] is true, also pass as soon as the line
    /// can take more.
    pub wake_at: Micros,
}

/// The pump's state: the frame being handed out, the idle bound and the line-error log
/// limiter.
pub struct Pump {
    frame: [u8; MAX_WIRE_FRAME],
    len: usize,
    /// Bytes of `frame` already handed out, before the last pass's.
    start: usize,
    /// End of the bytes handed out by the last pass.
    end: usize,
    max_idle_us: u64,
    errors: RateLimit,
}

impl Pump {
    /// `max_idle_us`: the longest the caller may wait between passes even with no timer
    /// due (the board reports its task alive every pass, so this is below the watchdog
    /// supervision period).
    pub const fn new(max_idle_us: u64) -> Self {
        Pump {
            frame: [0; MAX_WIRE_FRAME],
            len: 0,
            start: 0,
            end: 0,
            max_idle_us,
            errors: RateLimit::new(LINE_ERROR_LOG_US),
        }
    }

    /// One pass: `rx` are the bytes received since the last pass; `tx_room` how many bytes
    /// the transmitter accepts now (0 while it is busy; a DMA transmitter that takes a
    /// whole frame when idle gives [`MAX_WIRE_FRAME`]).
    pub fn pass<E: LinkEndpoint + ?Sized>(
        &mut self,
        ep: &mut E,
        rx: &[u8],
        tx_room: usize,
        now: Micros,
    ) -> Pass {
        self.receive(ep, rx, now);
        let p = self.transmit(ep, tx_room, now);
        Pass {
            wake_at: self.service(ep, now),
            ..p
        }
    }

    /// The receiving half of [`Self::pass`], for a board that wants the two halves in
    /// separate critical sections.
    pub fn receive<E: LinkEndpoint + ?Sized>(&mut self, ep: &mut E, rx: &[u8], now: Micros) {
        if !rx.is_empty() {
            ep.on_rx(rx, now);
        }
    }

    /// The transmitting half of [`Self::pass`].
    pub fn transmit<E: LinkEndpoint + ?Sized>(
        &mut self,
        ep: &mut E,
        tx_room: usize,
        now: Micros,
    ) -> Pass {
        self.start = self.end;
        if self.start >= self.len && tx_room > 0 {
            // The previous frame is all out: the next one (at most one per pass).
            self.len = ep.poll_tx(now, &mut self.frame);
            self.start = 0;
            self.end = 0;
        } else {
            // Busy line or a frame still going out: the endpoint's timers only.
            ep.poll_tx(now, &mut []);
        }
        self.end = self.len.min(self.start.saturating_add(tx_room));
        Pass {
            tx_len: self.end - self.start,
            wake_at: self.wake_at(ep, now),
        }
    }

    /// The third part of [`Self::pass`], for a board that runs it after writing
    /// [`Self::tx`] to the UART: the application's reaction
    /// ([`LinkEndpoint::service`]). Returns the next deadline, which the reaction may
    /// have moved (e.g. a command it queued: at once).
    pub fn service<E: LinkEndpoint + ?Sized>(&mut self, ep: &mut E, now: Micros) -> Micros {
        ep.service(now);
        self.wake_at(ep, now)
    }

    /// The endpoint's deadline, not before `now` and not after the idle bound.
    fn wake_at<E: LinkEndpoint + ?Sized>(&self, ep: &E, now: Micros) -> Micros {
        let idle = Micros(now.0.saturating_add(self.max_idle_us));
        match ep.poll_timeout() {
            Some(d) => d.max(now).min(idle),
            None => idle,
        }
    }

    /// The bytes the last pass handed out, for the UART.
    pub fn tx(&self) -> &[u8] {
        self.frame.get(self.start..self.end).unwrap_or(&[])
    }

    /// Whether part of a frame is still waiting for room on the line.
    pub fn holding(&self) -> bool {
        self.end < self.len
    }

    /// The UART reported a line error: the endpoint drops the frame being received and
    /// counts the error. `Some(n)` when the board should log now (`n` errors since the
    /// last log); at most once per [`LINE_ERROR_LOG_US`].
    pub fn line_error<E: LinkEndpoint + ?Sized>(&mut self, ep: &mut E, now: Micros) -> Option<u32> {
        ep.line_error();
        self.errors.hit(now)
    }
}

#[cfg(test)]
mod tests;
