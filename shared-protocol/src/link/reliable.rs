//! Sequencing, acknowledgement and retransmission (go-back-N), shared by both endpoints.
//!
//! Every reliable message gets the next 8-bit sequence number. The receiver applies a
//! message only when its number is exactly the one it expects (so each is applied once
//! and in order) and acknowledges cumulatively in the `ack` field of every frame it sends.
//! The sender keeps at most `W` unacknowledged messages and, when the oldest has waited
//! for one retransmission timeout, sends all of them again from the oldest.

use super::session::AT_ONCE;
use crate::units::Micros;

struct Entry<M> {
    seq: u8,
    msg: M,
    sent_at: Option<Micros>,
}

/// The sending side's window of unacknowledged reliable messages.
pub struct TxWindow<M, const W: usize> {
    entries: heapless::Deque<Entry<M>, W>,
    next_seq: u8,
    /// Index into `entries` of the next one to put on the wire.
    cursor: usize,
    retransmits: u32,
}

impl<M, const W: usize> Default for TxWindow<M, W> {
    fn default() -> Self {
        Self::new()
    }
}

impl<M, const W: usize> TxWindow<M, W> {
    pub const fn new() -> Self {
        TxWindow {
            entries: heapless::Deque::new(),
            next_seq: 0,
            cursor: 0,
            retransmits: 0,
        }
    }

    /// Start a new session: numbering from 0, nothing in flight. Returns what was in flight.
    pub fn reset(&mut self) -> impl Iterator<Item = M> + '_ {
        self.next_seq = 0;
        self.cursor = 0;
        core::iter::from_fn(move || self.entries.pop_front().map(|e| e.msg))
    }

    pub fn is_full(&self) -> bool {
        self.entries.is_full()
    }

    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// Whether a pushed message was never sent (they go out in order, so if any was not,
    /// the newest was not).
    pub fn has_unsent(&self) -> bool {
        self.entries.back().is_some_and(|e| e.sent_at.is_none())
    }

    /// Total number of frames sent again after a timeout.
    pub fn retransmits(&self) -> u32 {
        self.retransmits
    }

    /// Number the message and keep it until acknowledged. Gives it back when full.
    pub fn push(&mut self, msg: M) -> Result<u8, M> {
        let seq = self.next_seq;
        self.entries
            .push_back(Entry {
                seq,
                msg,
                sent_at: None,
            })
            .map_err(|e| e.msg)?;
        self.next_seq = seq.wrapping_add(1);
        Ok(seq)
    }

    /// The peer expects `ack` next: drop everything before it. An `ack` outside the
    /// window (stale or bogus) is ignored. Returns how many messages were acknowledged.
    pub fn on_ack(&mut self, ack: u8) -> usize {
        let Some(front) = self.entries.front() else {
            return 0;
        };
        let count = usize::from(ack.wrapping_sub(front.seq));
        if count > self.entries.len() {
            return 0;
        }
        for _ in 0..count {
            self.entries.pop_front();
        }
        self.cursor = self.cursor.saturating_sub(count);
        count
    }

    /// The next message to put on the wire now, with its sequence number: a new one, or,
    /// once the oldest has waited `rto_us`, the whole window again.
    pub fn next_to_send(&mut self, now: Micros, rto_us: u64) -> Option<(u8, &M)> {
        if let Some(Entry {
            sent_at: Some(t), ..
        }) = self.entries.front()
        {
            if now.0.saturating_sub(t.0) >= rto_us && self.cursor > 0 {
                self.cursor = 0;
            }
        }
        let cursor = self.cursor;
        let e = self.entries.get_mut(cursor)?;
        if e.sent_at.is_some() {
            self.retransmits = self.retransmits.saturating_add(1);
        }
        e.sent_at = Some(now);
        self.cursor = cursor + 1;
        Some((e.seq, &e.msg))
    }

    /// When [`Self::next_to_send`] next returns something: [`AT_ONCE`] while a message
    /// was never sent, the oldest one's retransmission time otherwise; `None` when empty.
    pub fn next_deadline(&self, rto_us: u64) -> Option<Micros> {
        if self.cursor < self.entries.len() {
            return Some(AT_ONCE);
        }
        match self.entries.front() {
            Some(Entry {
                sent_at: Some(t), ..
            }) => Some(Micros(t.0.saturating_add(rto_us))),
            _ => None,
        }
    }

    /// Whether [`Self::next_to_send`] would return something now.
    pub fn has_to_send(&self, now: Micros, rto_us: u64) -> bool {
        if self.cursor < self.entries.len() {
            return true;
        }
        matches!(self.entries.front(), Some(Entry { sent_at: Some(t), .. }) if now.0.saturating_sub(t.0) >= rto_us)
    }
}

/// What the receiver does with a reliable message.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Arrival {
    /// The expected one: apply it, then call [`RxSeq::advance`].
    New,
    /// Already applied, or a later one after a loss: do not apply, acknowledge again.
    Ignore,
}

/// The receiving side's expected sequence number.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RxSeq {
    expected: u8,
}

impl RxSeq {
    pub fn reset(&mut self) {
        self.expected = 0;
    }

    pub fn classify(&self, seq: u8) -> Arrival {
        if seq == self.expected {
            Arrival::New
        } else {
            Arrival::Ignore
        }
    }

    pub fn advance(&mut self) {
        self.expected = self.expected.wrapping_add(1);
    }

    /// The value for the `ack` field of outgoing frames.
    pub fn ack(&self) -> u8 {
        self.expected
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn window_acks_and_goes_back_n() {
        let mut w: TxWindow<u32, 4> = TxWindow::new();
        for i in 0..4 {
            assert_eq!(w.push(i), Ok(i as u8));
        }
        assert_eq!(w.push(9), Err(9));
        let t = Micros(0);
        for i in 0..4 {
            assert_eq!(
                w.next_to_send(t, 100).map(|(s, m)| (s, *m)),
                Some((i, i as u32))
            );
        }
        assert!(w.next_to_send(Micros(50), 100).is_none());
        assert_eq!(w.on_ack(2), 2);
        assert_eq!(w.on_ack(200), 0, "ack outside the window is ignored");
        // Oldest (seq 2) times out: 2 and 3 are sent again.
        assert_eq!(w.next_to_send(Micros(100), 100).map(|(s, _)| s), Some(2));
        assert_eq!(w.next_to_send(Micros(100), 100).map(|(s, _)| s), Some(3));
        assert_eq!(w.retransmits(), 2);
        assert_eq!(w.on_ack(4), 2);
        assert!(w.is_empty());
    }

    #[test]
    fn sequence_wraps() {
        let mut w: TxWindow<u8, 2> = TxWindow::new();
        let mut rx = RxSeq::default();
        for n in 0..600u32 {
            let seq = w.push(n as u8).unwrap();
            let (s, _) = w.next_to_send(Micros(u64::from(n)), 10).unwrap();
            assert_eq!(s, seq);
            assert_eq!(rx.classify(s), Arrival::New);
            rx.advance();
            assert_eq!(rx.classify(s), Arrival::Ignore);
            assert_eq!(w.on_ack(rx.ack()), 1);
        }
    }
}

/// A stall must last this many link timeouts to count: on a very noisy wire, legit
/// retransmission rounds can fail several times in a row; a real desync goes on forever.
pub const STALL_TIMEOUTS: u64 = 4;

/// Detects a receiver that keeps getting reliable messages it cannot apply: the two ends
/// disagree on the numbering (e.g. the PLC restarted and reused a session number). Legit
/// duplicates (a lost acknowledgement) stop after one retransmission round; a desync goes
/// on forever, once per retransmission timeout.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct StallDetector {
    since: Option<Micros>,
    last: Micros,
}

impl StallDetector {
    /// A message was applied: the numbering agrees.
    pub fn progress(&mut self) {
        self.since = None;
    }

    /// A message was ignored. Returns true when ignored messages have kept coming, each
    /// within `gap_us` of the previous one, for longer than `limit_us`.
    pub fn ignored(&mut self, now: Micros, gap_us: u64, limit_us: u64) -> bool {
        let start = match self.since {
            Some(s) if now.0.saturating_sub(self.last.0) <= gap_us => s,
            _ => now,
        };
        self.since = Some(start);
        self.last = now;
        now.0.saturating_sub(start.0) > limit_us
    }
}

#[cfg(test)]
mod stall_tests {
    use super::*;

    #[test]
    fn only_a_persistent_stream_of_ignored_messages_is_a_stall() {
        let mut s = StallDetector::default();
        // Legit: a round of duplicates, then quiet, then another round much later.
        for t in [0, 100, 200, 1_000_000, 1_000_100] {
            assert!(!s.ignored(Micros(t), 30_000, 50_000));
        }
        // Desync: one every 14 ms for longer than 50 ms.
        let mut hit = false;
        for k in 0..6u64 {
            hit = s.ignored(Micros(2_000_000 + k * 14_000), 30_000, 50_000);
        }
        assert!(hit);
        s.progress();
        assert!(!s.ignored(Micros(2_100_000), 30_000, 50_000));
    }
}
