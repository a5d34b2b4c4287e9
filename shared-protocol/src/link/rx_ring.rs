//! The reader's side of a receive ring that a DMA channel fills in circular mode (review
//! N13: the boards' own ring receiver, `board_common::link::ring`): where the new bytes
//! are, and whether the writer lapped the reader.
//!
//! The board gives what the hardware says: the channel's remaining count (CNDTR, which
//! counts down from the ring's length and reloads at the end) and how many half-ring
//! events (half transfer and transfer complete) its interrupt has counted. The position
//! alone cannot tell a lap; the event count can, and a half event still pending (the
//! interrupt not yet run) is seen from the position being in the other half.

use core::ops::Range;

/// What a [`RingReader::poll`] found.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum RingRead {
    /// The new bytes, oldest first: `first`, then `second` (empty unless they wrap).
    Bytes {
        first: Range<usize>,
        second: Range<usize>,
    },
    /// The writer came round to the reader: bytes were overwritten before they were read.
    /// The reader skipped to the writer; the caller treats it as a line error (the frame
    /// being received is dropped).
    Overrun,
}

/// The reader of a ring of `len` bytes (even, at least 2).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RingReader {
    len: u32,
    /// Bytes read since the start (wrapping).
    read: u32,
}

impl RingReader {
    /// A reader at the start of a ring of `len` bytes that the writer has just started
    /// filling (`len` even: the half events split it in two).
    pub const fn new(len: u16) -> Self {
        RingReader {
            len: len as u32,
            read: 0,
        }
    }

    /// The bytes written since the last poll (at most `max`: the rest stays for the next
    /// poll), with the channel's `remaining` count (CNDTR) and the number of half events
    /// (`halves`, wrapping) the interrupt counted.
    pub fn poll(&mut self, remaining: u16, halves: u32, max: usize) -> RingRead {
        let written = self.written(remaining, halves);
        let new = written.wrapping_sub(self.read);
        // A full lap is an overrun too: the writer may be storing into the oldest byte.
        if new >= self.len {
            self.read = written;
            return RingRead::Overrun;
        }
        let new = new.min(u32::try_from(max).unwrap_or(u32::MAX));
        let from = (self.read % self.len) as usize;
        let to = from + new as usize;
        self.read = self.read.wrapping_add(new);
        let len = self.len as usize;
        if to <= len {
            RingRead::Bytes {
                first: from..to,
                second: 0..0,
            }
        } else {
            RingRead::Bytes {
                first: from..len,
                second: 0..to - len,
            }
        }
    }

    /// Bytes written since the start (wrapping), from the position and the half events.
    fn written(&self, remaining: u16, halves: u32) -> u32 {
        let half = (self.len / 2).max(1);
        // CNDTR is `len` right after a reload (and never 0 in circular mode, but take it as
        // the reload).
        let pos = self.len.saturating_sub(u32::from(remaining)) % self.len.max(1);
        let in_second_half = pos >= half;
        // The half the writer is in by the events counted; if the position says the other
        // one, an event is pending (its interrupt has not run yet).
        let halves = if in_second_half != (halves % 2 == 1) {
            halves.wrapping_add(1)
        } else {
            halves
        };
        halves
            .wrapping_mul(half)
            .wrapping_add(pos - if in_second_half { half } else { 0 })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const LEN: u16 = 16;

    fn bytes(first: Range<usize>, second: Range<usize>) -> RingRead {
        RingRead::Bytes { first, second }
    }

    #[test]
    fn new_bytes_are_read_once() {
        let mut r = RingReader::new(LEN);
        assert_eq!(r.poll(16, 0, 64), bytes(0..0, 0..0));
        assert_eq!(r.poll(11, 0, 64), bytes(0..5, 0..0));
        assert_eq!(r.poll(11, 0, 64), bytes(5..5, 0..0));
        // The half event came with the 8th byte.
        assert_eq!(r.poll(6, 1, 64), bytes(5..10, 0..0));
    }

    #[test]
    fn bytes_across_the_end_come_in_two_pieces() {
        let mut r = RingReader::new(LEN);
        assert_eq!(r.poll(4, 1, 64), bytes(0..12, 0..0));
        // 12 -> 16 (transfer complete, reload) -> 3.
        assert_eq!(r.poll(13, 2, 64), bytes(12..16, 0..3));
    }

    #[test]
    fn an_event_not_yet_counted_is_seen_from_the_position() {
        let mut r = RingReader::new(LEN);
        assert_eq!(r.poll(10, 0, 64), bytes(0..6, 0..0));
        // The writer passed the middle, its interrupt has not run: still 4 new bytes.
        assert_eq!(r.poll(6, 0, 64), bytes(6..10, 0..0));
        // Past the end, the transfer-complete event pending.
        assert_eq!(r.poll(15, 1, 64), bytes(10..16, 0..1));
        // Now both counted.
        assert_eq!(r.poll(14, 2, 64), bytes(1..2, 0..0));
    }

    #[test]
    fn a_lap_is_an_overrun_and_the_reader_goes_on_from_the_writer() {
        let mut r = RingReader::new(LEN);
        assert_eq!(r.poll(13, 0, 64), bytes(0..3, 0..0));
        // The same position one lap later: 16 bytes written, the oldest overwritten.
        assert_eq!(r.poll(13, 2, 64), RingRead::Overrun);
        assert_eq!(r.poll(11, 2, 64), bytes(3..5, 0..0));
        // More than a lap.
        assert_eq!(r.poll(3, 5, 64), RingRead::Overrun);
        assert_eq!(r.poll(2, 5, 64), bytes(13..14, 0..0));
    }

    #[test]
    fn at_most_max_bytes_are_taken_and_the_rest_comes_next() {
        let mut r = RingReader::new(LEN);
        assert_eq!(r.poll(4, 1, 5), bytes(0..5, 0..0));
        assert_eq!(r.poll(4, 1, 5), bytes(5..10, 0..0));
        assert_eq!(r.poll(13, 2, 64), bytes(10..16, 0..3));
        assert_eq!(r.poll(13, 2, 0), bytes(3..3, 0..0));
    }

    #[test]
    fn the_count_wraps() {
        let mut r = RingReader::new(LEN);
        // 2^32 - 2 half events: the written count wraps past u32::MAX.
        let h = u32::MAX - 1;
        r.read = h.wrapping_mul(8).wrapping_add(6);
        assert_eq!(r.poll(10, h, 64), bytes(6..6, 0..0));
        assert_eq!(r.poll(12, h.wrapping_add(2), 64), bytes(6..16, 0..4));
    }
}
