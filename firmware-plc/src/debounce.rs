//! Debouncing of the digital inputs and of the keypad matrix.
//!
//! The board samples the raw pins at a fixed rate and feeds the bit masks here; a bit takes
//! a new level only after it has read that level on `samples` consecutive samples, so
//! contact bounce and short spikes shorter than `samples` sample periods never reach the
//! scan or the editor. Sans-IO: no clock, the caller's sampling rate is the time base.

use crate::editor::Key;

/// Debouncer of up to 32 parallel bits (bit n = input n).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Debouncer<const N: usize> {
    state: u32,
    counts: [u8; N],
    samples: u8,
}

impl<const N: usize> Debouncer<N> {
    /// All bits start low; a change needs `samples` equal samples (at least 1). `N` above
    /// 32 is treated as 32.
    pub const fn new(samples: u8) -> Self {
        Debouncer {
            state: 0,
            counts: [0; N],
            samples: if samples == 0 { 1 } else { samples },
        }
    }

    fn mask() -> u32 {
        if N >= 32 {
            u32::MAX
        } else {
            (1u32 << N) - 1
        }
    }

    /// Takes one sample of the raw bits and returns the debounced state.
    pub fn update(&mut self, raw: u32) -> u32 {
        let differs = (raw ^ self.state) & Self::mask();
        for (bit, count) in self.counts.iter_mut().enumerate().take(32) {
            let m = 1u32 << bit;
            if differs & m == 0 {
                *count = 0;
                continue;
            }
            *count = count.saturating_add(1);
            if *count >= self.samples {
                self.state ^= m;
                *count = 0;
            }
        }
        self.state
    }

    /// The debounced state (bit n = input n).
    pub fn state(&self) -> u32 {
        self.state
    }
}

/// The 4x4 keypad: debounced key matrix in, key-down/key-up events out.
///
/// Bit `4 * row + column` of a sample is the key at that position pressed; rows `123A`,
/// `456B`, `789C`, `*0#D` as in [`Key::ALL`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct KeyMatrix {
    debouncer: Debouncer<16>,
    reported: u16,
}

/// A debounced key transition.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct KeyEvent {
    pub key: Key,
    /// `true` = pressed, `false` = released.
    pub down: bool,
}

impl KeyMatrix {
    /// A key counts as pressed or released after `samples` equal full-matrix samples.
    pub const fn new(samples: u8) -> Self {
        KeyMatrix {
            debouncer: Debouncer::new(samples),
            reported: 0,
        }
    }

    /// Takes one full-matrix sample; `events` receives the transitions, in matrix order.
    pub fn update(&mut self, pressed: u16, events: &mut impl FnMut(KeyEvent)) {
        let state = self.debouncer.update(u32::from(pressed)) as u16;
        let changed = state ^ self.reported;
        self.reported = state;
        for (i, key) in Key::ALL.iter().enumerate() {
            let m = 1u16 << i;
            if changed & m != 0 {
                events(KeyEvent {
                    key: *key,
                    down: state & m != 0,
                });
            }
        }
    }

    /// Keys held down now (bit `4 * row + column`).
    pub fn pressed(&self) -> u16 {
        self.reported
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn a_level_needs_n_equal_samples() {
        let mut d = Debouncer::<8>::new(3);
        assert_eq!(d.update(0b1), 0);
        assert_eq!(d.update(0b1), 0);
        assert_eq!(d.update(0b1), 0b1);
        // Release also needs three samples.
        assert_eq!(d.update(0), 0b1);
        assert_eq!(d.update(0), 0b1);
        assert_eq!(d.update(0), 0);
    }

    #[test]
    fn bounce_restarts_the_count() {
        let mut d = Debouncer::<8>::new(3);
        for raw in [1, 1, 0, 1, 1, 0, 1, 1] {
            assert_eq!(d.update(raw), 0, "bouncing input must not switch");
        }
        assert_eq!(d.update(1), 1);
    }

    #[test]
    fn bits_beyond_n_are_ignored() {
        let mut d = Debouncer::<4>::new(1);
        assert_eq!(d.update(0xFF), 0x0F);
    }

    #[test]
    fn keypad_reports_down_and_up_once() {
        let mut m = KeyMatrix::new(2);
        let mut ev = Vec::new();
        // Row 1, column 1 = key 5.
        let five = 1u16 << 5;
        for _ in 0..4 {
            m.update(five, &mut |e| ev.push(e));
        }
        assert_eq!(
            ev,
            vec![KeyEvent {
                key: Key::Digit(5),
                down: true
            }]
        );
        ev.clear();
        for _ in 0..4 {
            m.update(0, &mut |e| ev.push(e));
        }
        assert_eq!(
            ev,
            vec![KeyEvent {
                key: Key::Digit(5),
                down: false
            }]
        );
    }

    #[test]
    fn keypad_corners_map_to_the_printed_keys() {
        let mut m = KeyMatrix::new(1);
        let mut ev = Vec::new();
        m.update(1 | 1 << 3 | 1 << 12 | 1 << 15, &mut |e| ev.push(e.key));
        assert_eq!(ev, vec![Key::Digit(1), Key::A, Key::Star, Key::D]);
    }

    proptest! {
        /// A bit never changes unless the last `samples` raw samples all showed the new
        /// level.
        #[test]
        fn never_switches_without_a_stable_run(raws in proptest::collection::vec(0u32..256, 1..200), n in 1u8..6) {
            let mut d = Debouncer::<8>::new(n);
            let mut history: Vec<u32> = Vec::new();
            let mut prev = 0u32;
            for raw in raws {
                history.push(raw);
                let now = d.update(raw);
                for bit in 0..8 {
                    let m = 1u32 << bit;
                    if (now ^ prev) & m != 0 {
                        let tail = &history[history.len().saturating_sub(usize::from(n))..];
                        prop_assert_eq!(tail.len(), usize::from(n));
                        prop_assert!(tail.iter().all(|r| r & m == now & m));
                    }
                }
                prev = now;
            }
        }
    }
}
