//! The half of a link endpoint that is the same at both ends: the frame reader, the
//! transmit window, the receive sequence, stall detection, the link-loss timer, the
//! acknowledgement owed, the counters and the encoding of what goes out.
//!
//! [`super::plc::PlcLink`] and [`super::drive::DriveLink`] are thin role-specific layers
//! over one [`Session`] each: they decide *what* to send and what a message means; the
//! session does the bookkeeping every frame needs. `M` is the message type this end
//! sends, `W` its window of unacknowledged reliable messages.

use serde::de::DeserializeOwned;
use serde::Serialize;

use super::config::LinkConfig;
use super::frame::{decode_body, encode_frame, Frame, FrameReader};
use super::reliable::{Arrival, RxSeq, StallDetector, TxWindow, STALL_TIMEOUTS};
use super::LinkStats;
use crate::units::Micros;

/// A deadline that has always passed: the endpoint wants to be polled now.
pub const AT_ONCE: Micros = Micros(0);

/// What the endpoint does with a reliable message it received.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Reliable {
    /// The expected one, now counted as received: apply it.
    Apply,
    /// A duplicate, a later one after a loss, or no room to apply it: drop it (the peer
    /// sends it again).
    Drop,
    /// Ignored messages have kept coming for [`STALL_TIMEOUTS`] link timeouts: the two
    /// ends disagree on the numbering; the endpoint must declare the link lost.
    Stalled,
}

/// The common state of one endpoint's session.
pub struct Session<M, const W: usize> {
    cfg: LinkConfig,
    reader: FrameReader,
    tx: TxWindow<M, W>,
    rx: RxSeq,
    stall: StallDetector,
    last_rx: Micros,
    last_tx: Micros,
    ack_owed: bool,
    stats: LinkStats,
}

impl<M: Serialize, const W: usize> Session<M, W> {
    pub fn new(cfg: LinkConfig) -> Self {
        Session {
            cfg,
            reader: FrameReader::new(),
            tx: TxWindow::new(),
            rx: RxSeq::default(),
            stall: StallDetector::default(),
            last_rx: Micros(0),
            last_tx: Micros(0),
            ack_owed: false,
            stats: LinkStats::default(),
        }
    }

    pub fn config(&self) -> &LinkConfig {
        &self.cfg
    }

    /// The counters, with the window's retransmissions.
    pub fn stats(&self) -> LinkStats {
        LinkStats {
            retransmits: self.tx.retransmits(),
            ..self.stats
        }
    }

    /// One received byte; at the end of a frame, the frame if it is valid (both outcomes
    /// are counted).
    pub fn read_byte<R: DeserializeOwned>(&mut self, byte: u8) -> Option<Frame<R>> {
        self.read_byte_with(byte, decode_body::<R>)
    }

    /// [`Session::read_byte`] with the body decoder `body` ([`FrameReader::push_with`]).
    pub fn read_byte_with<R>(
        &mut self,
        byte: u8,
        body: impl FnOnce(&[u8]) -> Option<Frame<R>>,
    ) -> Option<Frame<R>> {
        match self.reader.push_with(byte, body)? {
            Err(_) => {
                self.stats.frames_bad = self.stats.frames_bad.saturating_add(1);
                None
            }
            Ok(frame) => {
                self.stats.frames_ok = self.stats.frames_ok.saturating_add(1);
                Some(frame)
            }
        }
    }

    /// The UART reported a line error (framing, noise, overrun, parity): the frame being
    /// received is broken, so the reader starts over at the next delimiter.
    pub fn line_error(&mut self) {
        self.reader.reset();
        self.stats.line_errors = self.stats.line_errors.saturating_add(1);
    }

    /// A frame of the running session arrived: the peer is alive and acknowledges `ack`.
    pub fn peer_frame(&mut self, ack: u8, now: Micros) {
        self.last_rx = now;
        self.tx.on_ack(ack);
    }

    /// A reliable message with `seq` arrived in the running session; `room` says whether
    /// the endpoint could apply it now. `timeout_us` is this end's link timeout (the
    /// stall limit is [`STALL_TIMEOUTS`] of them).
    pub fn reliable(&mut self, seq: u8, room: bool, now: Micros, timeout_us: u64) -> Reliable {
        self.ack_owed = true;
        if self.rx.classify(seq) != Arrival::New {
            self.stats.duplicates = self.stats.duplicates.saturating_add(1);
            let rto = self.cfg.rto_us();
            if self
                .stall
                .ignored(now, 2 * rto, STALL_TIMEOUTS * timeout_us)
            {
                return Reliable::Stalled;
            }
            return Reliable::Drop;
        }
        if !room {
            return Reliable::Drop;
        }
        self.stall.progress();
        self.rx.advance();
        Reliable::Apply
    }

    /// A new session starts (handshake done): numbering from 0 both ways, the link-loss
    /// timer from `now`. Returns the messages that were in flight (oldest first).
    pub fn start(&mut self, now: Micros) -> impl Iterator<Item = M> + '_ {
        self.last_rx = now;
        self.rx.reset();
        self.stall.progress();
        self.ack_owed = false;
        self.tx.reset()
    }

    /// The messages in flight, taken out (oldest first), e.g. when the link is lost.
    pub fn take_in_flight(&mut self) -> impl Iterator<Item = M> + '_ {
        self.tx.reset()
    }

    /// A link loss, for the counters.
    pub fn count_loss(&mut self) {
        self.stats.link_losses = self.stats.link_losses.saturating_add(1);
    }

    /// Whether nothing valid has arrived for longer than `timeout_us`.
    pub fn timed_out(&self, now: Micros, timeout_us: u64) -> bool {
        now.0.saturating_sub(self.last_rx.0) > timeout_us
    }

    /// When [`Self::timed_out`] becomes true if nothing arrives meanwhile.
    pub fn loss_deadline(&self, timeout_us: u64) -> Micros {
        Micros(self.last_rx.0.saturating_add(timeout_us).saturating_add(1))
    }

    pub fn window_full(&self) -> bool {
        self.tx.is_full()
    }

    /// Reliable messages sent and not acknowledged yet.
    pub fn in_flight(&self) -> usize {
        self.tx.len()
    }

    /// Whether the window holds a message that was never sent.
    pub fn has_unsent(&self) -> bool {
        self.tx.has_unsent()
    }

    /// Number `msg` and keep it until acknowledged; gives it back when the window is full.
    pub fn push(&mut self, msg: M) -> Result<u8, M> {
        self.tx.push(msg)
    }

    /// Whether an acknowledgement is owed (a reliable message arrived since the last
    /// frame this end sent).
    pub fn ack_owed(&self) -> bool {
        self.ack_owed
    }

    /// When this end last sent a frame.
    pub fn last_tx(&self) -> Micros {
        self.last_tx
    }

    /// The window's next frame (new, or the whole window again after the retransmission
    /// timeout), encoded into `out`; 0 when the window has nothing to send now.
    pub fn send_reliable(&mut self, now: Micros, out: &mut [u8]) -> usize {
        let ack = self.rx.ack();
        let rto = self.cfg.rto_us();
        let Some((seq, msg)) = self.tx.next_to_send(now, rto) else {
            return 0;
        };
        match encode_frame(&Frame { seq, ack, msg }, false, out) {
            Ok(n) => self.sent(n, now),
            Err(_) => 0,
        }
    }

    /// An unreliable message (handshake frames with the leading delimiter, `lead`),
    /// encoded into `out`; 0 if it does not fit.
    pub fn send(&mut self, msg: M, lead: bool, now: Micros, out: &mut [u8]) -> usize {
        let frame = Frame {
            seq: 0,
            ack: self.rx.ack(),
            msg,
        };
        match encode_frame(&frame, lead, out) {
            Ok(n) => self.sent(n, now),
            Err(_) => 0,
        }
    }

    fn sent(&mut self, n: usize, now: Micros) -> usize {
        self.ack_owed = false;
        self.last_tx = now;
        self.stats.frames_sent = self.stats.frames_sent.saturating_add(1);
        self.stats.bytes_sent = self.stats.bytes_sent.saturating_add(n as u64);
        n
    }

    /// When the window next has a frame to send: [`AT_ONCE`] for one never sent, the
    /// retransmission deadline of the oldest otherwise; `None` when empty.
    pub fn window_deadline(&self) -> Option<Micros> {
        self.tx.next_deadline(self.cfg.rto_us())
    }
}

/// The earliest of two optional deadlines.
pub fn earliest(a: Option<Micros>, b: Option<Micros>) -> Option<Micros> {
    match (a, b) {
        (Some(x), Some(y)) => Some(x.min(y)),
        (x, None) => x,
        (None, y) => y,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::frame::MAX_WIRE_FRAME;
    use crate::link::message::PlcMsg;

    fn session() -> Session<PlcMsg, 2> {
        Session::new(LinkConfig::default())
    }

    #[test]
    fn reliable_is_applied_once_and_owes_an_ack() {
        let mut s = session();
        let now = Micros(1_000);
        assert_eq!(s.reliable(0, true, now, 50_000), Reliable::Apply);
        assert!(s.ack_owed());
        assert_eq!(s.reliable(0, true, now, 50_000), Reliable::Drop);
        assert_eq!(s.stats().duplicates, 1);
        // No room: not counted as received, so the retransmission is applied.
        assert_eq!(s.reliable(1, false, now, 50_000), Reliable::Drop);
        assert_eq!(s.reliable(1, true, now, 50_000), Reliable::Apply);
        let mut out = [0u8; MAX_WIRE_FRAME];
        assert!(s.send(PlcMsg::Heartbeat, false, now, &mut out) > 0);
        assert!(!s.ack_owed());
        assert_eq!(s.last_tx(), now);
    }

    #[test]
    fn endless_duplicates_are_a_stall() {
        let mut s = session();
        let rto = s.config().rto_us();
        let mut verdict = Reliable::Drop;
        for k in 0..100u64 {
            verdict = s.reliable(5, true, Micros(k * rto), 10_000);
            if verdict == Reliable::Stalled {
                break;
            }
        }
        assert_eq!(verdict, Reliable::Stalled);
    }

    #[test]
    fn window_deadlines_follow_the_retransmission_timeout() {
        let mut s = session();
        let mut out = [0u8; MAX_WIRE_FRAME];
        assert_eq!(s.window_deadline(), None);
        s.push(PlcMsg::Run).unwrap();
        assert_eq!(s.window_deadline(), Some(AT_ONCE), "unsent: now");
        assert!(s.send_reliable(Micros(10), &mut out) > 0);
        let rto = s.config().rto_us();
        assert_eq!(s.window_deadline(), Some(Micros(10 + rto)));
        assert_eq!(s.send_reliable(Micros(11), &mut out), 0);
        assert!(s.send_reliable(Micros(10 + rto), &mut out) > 0);
        assert_eq!(s.stats().retransmits, 1);
        s.peer_frame(1, Micros(20 + rto));
        assert_eq!(s.window_deadline(), None);
    }

    #[test]
    fn loss_timer_and_line_errors() {
        let mut s = session();
        s.peer_frame(0, Micros(100));
        assert_eq!(s.loss_deadline(50), Micros(151));
        assert!(!s.timed_out(Micros(150), 50));
        assert!(s.timed_out(Micros(151), 50));
        // A half-received frame is dropped at a line error: the rest of it is not glued
        // to the next frame.
        let mut out = [0u8; MAX_WIRE_FRAME];
        let mut other: Session<PlcMsg, 2> = session();
        let n = other.send(PlcMsg::Heartbeat, false, Micros(0), &mut out);
        for &b in &out[..n / 2] {
            assert!(s.read_byte::<PlcMsg>(b).is_none());
        }
        s.line_error();
        let mut got = 0;
        for &b in &out[..n] {
            got += usize::from(s.read_byte::<PlcMsg>(b).is_some());
        }
        assert_eq!(got, 1);
        let st = s.stats();
        assert_eq!((st.line_errors, st.frames_ok, st.frames_bad), (1, 1, 0));
    }

    #[test]
    fn earliest_of_optional_deadlines() {
        assert_eq!(earliest(None, None), None);
        assert_eq!(earliest(Some(Micros(3)), None), Some(Micros(3)));
        assert_eq!(earliest(None, Some(Micros(4))), Some(Micros(4)));
        assert_eq!(earliest(Some(Micros(5)), Some(Micros(4))), Some(Micros(4)));
    }
}
