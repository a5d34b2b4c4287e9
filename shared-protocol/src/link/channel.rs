//! One direction of an emulated UART wire, timed to the byte, with impairments: bit
//! errors, lost and duplicated bytes, lost and duplicated frames, extra delays, and a cut.
//!
//! Used by the link tests, the link benchmark and hil-sim. Deterministic for a seed.
//! Bytes keep their order (a UART wire cannot reorder); a delay holds the line.

use crate::units::Micros;

/// Bytes that can be on the wire at once (a few frames).
pub(crate) const IN_FLIGHT: usize = 1024;

/// Probabilities of each impairment (0.0 = never).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Impairments {
    /// Each bit flips with this probability.
    pub bit_error_rate: f64,
    /// Each byte is lost with this probability.
    pub byte_drop: f64,
    /// Each byte arrives twice with this probability.
    pub byte_dup: f64,
    /// Each frame (one `send`) is lost whole.
    pub frame_drop: f64,
    /// Each frame is sent twice.
    pub frame_dup: f64,
    /// Each frame is held back by a random delay up to this (the line stays busy).
    pub max_delay_us: u64,
}

/// What the channel did, for tests.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ChannelStats {
    pub frames: u64,
    pub bytes: u64,
    pub bits_flipped: u64,
    pub corrupted_frames: u64,
    /// Wire time spent sending, ns (for bandwidth use).
    pub busy_ns: u64,
}

/// The line's random draws (xorshift64*): one stream for every impairment of a wire, here
/// and in hil-sim's character-timed wires between the emulated USARTs.
#[derive(Debug, Clone)]
pub struct Noise(u64);

impl Noise {
    /// A stream from its raw state (not 0).
    pub const fn from_state(state: u64) -> Self {
        Noise(state)
    }

    pub fn next_u64(&mut self) -> u64 {
        let mut x = self.0;
        x ^= x >> 12;
        x ^= x << 25;
        x ^= x >> 27;
        self.0 = x;
        x.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }

    /// True with probability `p` (never for `p` <= 0, without a draw).
    pub fn chance(&mut self, p: f64) -> bool {
        p > 0.0 && ((self.next_u64() >> 11) as f64) < p * (1u64 << 53) as f64
    }
}

/// One direction of the wire.
pub struct Channel {
    byte_time_ns: u64,
    imp: Impairments,
    rng: Noise,
    queue: heapless::Deque<(u64, u8), IN_FLIGHT>,
    line_free_ns: u64,
    cut: bool,
    /// Bytes still to be hit by a noise burst ([`Channel::burst`]).
    burst: u32,
    stats: ChannelStats,
}

impl Channel {
    pub fn new(baud: u32, imp: Impairments, seed: u64) -> Self {
        Channel {
            byte_time_ns: 10_000_000_000 / u64::from(baud.max(1)),
            imp,
            rng: Noise::from_state(seed ^ 0x9E37_79B9_7F4A_7C15),
            queue: heapless::Deque::new(),
            line_free_ns: 0,
            cut: false,
            burst: 0,
            stats: ChannelStats::default(),
        }
    }

    pub fn stats(&self) -> ChannelStats {
        self.stats
    }

    pub fn set_impairments(&mut self, imp: Impairments) {
        self.imp = imp;
    }

    /// Cut (or reconnect) the wire. While cut nothing arrives.
    pub fn set_cut(&mut self, cut: bool) {
        self.cut = cut;
        if cut {
            self.queue.clear();
        }
    }

    /// A noise burst: the next `bytes` bytes sent each get at least one bit flipped (a
    /// motor's switching transient on the cable, longer than a CRC's burst guarantee).
    pub fn burst(&mut self, bytes: u32) {
        self.burst = self.burst.saturating_add(bytes);
    }

    /// Nanoseconds per byte.
    pub fn byte_time_ns(&self) -> u64 {
        self.byte_time_ns
    }

    /// Whether the transmitter has finished the last frame (the UART can take another).
    pub fn is_idle(&self, now: Micros) -> bool {
        self.line_free_ns <= now.0.saturating_mul(1000)
    }

    /// Time at which the line becomes free.
    pub fn free_at(&self) -> Micros {
        Micros(self.line_free_ns.div_ceil(1000))
    }

    /// Arrival time of the next byte on the wire.
    pub fn next_arrival(&self) -> Option<Micros> {
        self.queue.front().map(|(t, _)| Micros(t.div_ceil(1000)))
    }

    fn rand(&mut self) -> u64 {
        self.rng.next_u64()
    }

    fn chance(&mut self, p: f64) -> bool {
        self.rng.chance(p)
    }

    /// A frame handed to the UART at `now`: it goes out after what is already on the line.
    pub fn send(&mut self, bytes: &[u8], now: Micros) {
        self.stats.frames += 1;
        let copies = if self.chance(self.imp.frame_dup) {
            2
        } else {
            1
        };
        let delay_ns = if self.imp.max_delay_us > 0 {
            (self.rand() % (self.imp.max_delay_us + 1)) * 1000
        } else {
            0
        };
        let mut t = self.line_free_ns.max(now.0.saturating_mul(1000)) + delay_ns;
        let lost = self.chance(self.imp.frame_drop);
        for _ in 0..copies {
            let mut corrupted = false;
            for &b in bytes {
                t += self.byte_time_ns;
                self.stats.bytes += 1;
                self.stats.busy_ns += self.byte_time_ns;
                let mut v = b;
                for bit in 0..8 {
                    if self.chance(self.imp.bit_error_rate) {
                        v ^= 1 << bit;
                        self.stats.bits_flipped += 1;
                        corrupted = true;
                    }
                }
                if self.burst > 0 {
                    self.burst -= 1;
                    let hit = (self.rand() as u8) | 1;
                    v ^= hit;
                    self.stats.bits_flipped += u64::from(hit.count_ones());
                    corrupted = true;
                }
                if lost || self.cut || self.chance(self.imp.byte_drop) {
                    corrupted = true;
                    continue;
                }
                let _ = self.queue.push_back((t, v));
                if self.chance(self.imp.byte_dup) {
                    corrupted = true;
                    let _ = self.queue.push_back((t, v));
                }
            }
            if corrupted {
                self.stats.corrupted_frames += 1;
            }
        }
        self.line_free_ns = t;
    }

    /// Bytes that have arrived by `now`, into `out`; returns how many.
    pub fn receive(&mut self, now: Micros, out: &mut [u8]) -> usize {
        let now_ns = now.0.saturating_mul(1000);
        let mut n = 0;
        while let Some(&(t, b)) = self.queue.front() {
            if t > now_ns || n >= out.len() {
                break;
            }
            if let Some(slot) = out.get_mut(n) {
                *slot = b;
            }
            n += 1;
            self.queue.pop_front();
        }
        n
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bytes_arrive_at_the_baud_rate_in_order() {
        let mut c = Channel::new(115_200, Impairments::default(), 1);
        c.send(&[1, 2, 3], Micros(0));
        assert!(!c.is_idle(Micros(200)));
        let mut out = [0u8; 8];
        assert_eq!(c.receive(Micros(86), &mut out), 0);
        assert_eq!(c.receive(Micros(87), &mut out), 1);
        assert_eq!(c.receive(Micros(261), &mut out), 2);
        assert_eq!(&out[..2], &[2, 3]);
        assert!(c.is_idle(Micros(261)));
    }

    #[test]
    fn bit_error_rate_is_about_right() {
        let imp = Impairments {
            bit_error_rate: 1e-3,
            ..Default::default()
        };
        let mut c = Channel::new(1_000_000, imp, 7);
        let mut out = [0u8; 64];
        let mut flipped = 0u32;
        for i in 0..2000u64 {
            c.send(&[0u8; 50], Micros(i * 1000));
            let n = c.receive(Micros(i * 1000 + 999), &mut out);
            flipped += out[..n].iter().map(|b| b.count_ones()).sum::<u32>();
        }
        // 800 000 bits at 1e-3: 800 expected.
        assert!((650..950).contains(&flipped), "{flipped}");
    }
}
