//! The boot trim of the overcurrent comparators that watch a small signal. On
//! the bare B-G431B-ESC1 the only pins of the three phases that reach a comparator input
//! are the PGA inputs PA1, PA7, PB0 (RM0440 COMP inputs: COMP1 PA1/PB1, COMP2 PA7/PA3,
//! COMP4 PB0/PE7; the amplifier outputs PA2/PA6 reach none, PB1 only COMP1), where 1 A is
//! 1.71 mV on a 1.41 V bias. The bias's resistor tolerance (~20 mV), the comparator's
//! offset (up to 20 mV) and the DAC's (up to 9.7 mV) are each worth several amperes there,
//! so a threshold computed from nominal values can sit below 0 A. Instead, at boot, with
//! the outputs off (0 A), each trimmed comparator's DAC is searched for the code at which
//! its output turns on: that code holds the bias and both offsets as that comparator sees
//! them, and the threshold is counted from it ([`trimmed_dac`]). The hysteresis is off on
//! these comparators (`board/hw_protection.rs`), so that the trip and the release lie at
//! the same level.
//!
//! Sans-IO: [`ComparatorTrim::probe`] gives the DAC values to write, the board waits
//! [`SETTLE_US`] and passes the comparator outputs to [`ComparatorTrim::observe`]; twelve
//! probes (a binary search over the 12-bit DAC) and [`ComparatorTrim::result`] has the
//! zero codes.

use crate::comparators::{BoardProfile, DacValues, Direction};
use crate::power_port::ComparatorLevels;

/// Time from a DAC write to reading the comparator outputs, us: the DAC's settling (a few
/// us to 1 LSB, DS12589) and the comparator's delay (tens of ns), with room.
pub const SETTLE_US: u64 = 50;

/// Largest 12-bit DAC code.
const DAC_MAX: u16 = 4095;

/// The search of one comparator: `lo` never tripped, `hi` tripped (in the direction of
/// [`Direction`]: a `Below` comparator trips for high DAC codes, an `Above` one for low).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
struct Search {
    comp: u8,
    below: bool,
    /// DAC codes where the comparator did not trip / tripped (ends excluded at start).
    quiet: u16,
    tripped: u16,
}

impl Search {
    fn mid(&self) -> u16 {
        ((u32::from(self.quiet) + u32::from(self.tripped)) / 2) as u16
    }

    fn done(&self) -> bool {
        self.quiet.abs_diff(self.tripped) <= 1
    }
}

/// The zero codes found: per comparator (index COMPx - 1) the DAC code at the trip edge at
/// 0 A (`Below`: the lowest code that trips; `Above`: the highest), `None` for a
/// comparator not trimmed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TrimmedZeros(pub [Option<u16>; 4]);

impl TrimmedZeros {
    pub fn get(&self, comp: u8) -> Option<u16> {
        self.0
            .get(usize::from(comp.wrapping_sub(1)))
            .copied()
            .flatten()
    }
}

/// Why a trim failed: the comparator never tripped, or tripped at every code (a signal at a
/// rail: a missing bias, a broken shunt network), or its zero is further than the
/// profile's tolerance from the nominal one.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TrimFailed {
    pub comp: u8,
    pub code: u16,
}

impl core::fmt::Display for TrimFailed {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(
            f,
            "comparator {} trim failed at DAC code {}",
            self.comp, self.code
        )
    }
}

impl core::error::Error for TrimFailed {}

/// The search of every comparator the profile trims.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ComparatorTrim {
    profile: &'static BoardProfile,
    searches: [Option<Search>; 4],
}

impl ComparatorTrim {
    pub fn new(profile: &'static BoardProfile) -> Self {
        let mut searches = [None; 4];
        for s in profile.comparators.iter().filter(|s| s.zero_trim) {
            let below = s.direction == Direction::Below;
            if let Some(slot) = searches.get_mut(usize::from(s.comp.wrapping_sub(1))) {
                *slot = Some(Search {
                    comp: s.comp,
                    below,
                    // A `Below` comparator trips at high codes: 0 is its quiet end.
                    quiet: if below { 0 } else { DAC_MAX },
                    tripped: if below { DAC_MAX } else { 0 },
                });
            }
        }
        ComparatorTrim { profile, searches }
    }

    /// The DAC values of the next probe; `None` when the search is over.
    pub fn probe(&self) -> Option<DacValues> {
        let mut v = DacValues::default();
        let mut any = false;
        for s in self.searches.iter().flatten().filter(|s| !s.done()) {
            if let Some(spec) = self.profile.comparators.iter().find(|c| c.comp == s.comp) {
                if let Some(slot) = v.0.get_mut(spec.dac.index()) {
                    *slot = Some(s.mid());
                    any = true;
                }
            }
        }
        any.then_some(v)
    }

    /// The comparator outputs (after polarity: high = trip) of the last probe.
    pub fn observe(&mut self, levels: ComparatorLevels) {
        for s in self.searches.iter_mut().flatten().filter(|s| !s.done()) {
            let mid = s.mid();
            let tripped = levels
                .0
                .get(usize::from(s.comp.wrapping_sub(1)))
                .copied()
                .unwrap_or(false);
            if tripped {
                s.tripped = mid;
            } else {
                s.quiet = mid;
            }
        }
    }

    /// The zero codes, once [`ComparatorTrim::probe`] returned `None`.
    pub fn result(&self) -> Result<TrimmedZeros, TrimFailed> {
        let mut z = TrimmedZeros::default();
        let nominal = self.profile.scaling.current_zero_counts;
        let tol = self.profile.scaling.current_zero_tolerance_counts;
        for (slot, s) in z.0.iter_mut().zip(self.searches.iter()) {
            let Some(s) = s else { continue };
            let at_rail = s.tripped == 0 || s.tripped == DAC_MAX;
            if !s.done() || at_rail || s.tripped.abs_diff(nominal) > tol {
                return Err(TrimFailed {
                    comp: s.comp,
                    code: s.tripped,
                });
            }
            *slot = Some(s.tripped);
        }
        Ok(z)
    }
}

/// The DAC code that trips a trimmed comparator at `steps_x1000` thousandths of a DAC step
/// from 0 A (`I>>` times the comparator input's counts per ampere), given its zero code.
///
/// With the hysteresis off, the zero code `c0` of a `Below` comparator says that the
/// signal at 0 A, less the offsets, lies in `[c0 - 1, c0)` counts; a threshold `n` codes
/// below `c0` then trips for a fall of `[n - 1, n)` counts. `n = floor(steps) + 1` puts
/// `I>>` inside that interval: the trip lies within one DAC step of the setting (0.47 A
/// on the ESC1), the step that contains it. `Above` mirrors it.
pub fn trimmed_dac(zero: u16, below: bool, steps_x1000: u32) -> u16 {
    let n = (steps_x1000 / 1000 + 1).min(u32::from(DAC_MAX)) as i32;
    let z = i32::from(zero);
    let code = if below { z - n } else { z + n };
    code.clamp(0, i32::from(DAC_MAX)) as u16
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::comparators::B_G431B_ESC1;

    /// A comparator whose signal (less offsets) sits at `x` counts.
    fn run(x: f64) -> Result<TrimmedZeros, TrimFailed> {
        let mut t = ComparatorTrim::new(&B_G431B_ESC1);
        let mut probes = 0;
        while let Some(v) = t.probe() {
            probes += 1;
            let mut l = ComparatorLevels::default();
            for spec in B_G431B_ESC1.comparators.iter().filter(|s| s.zero_trim) {
                let dac = v.get(spec.dac).map(f64::from);
                if let (Some(d), Some(o)) = (dac, l.0.get_mut(usize::from(spec.comp - 1))) {
                    // Below: trips when the signal is under the DAC.
                    *o = x < d;
                }
            }
            t.observe(l);
            assert!(probes <= 12, "a binary search over 12 bits");
        }
        t.result()
    }

    #[test]
    fn the_esc1_trims_its_three_phase_comparators_to_the_edge() {
        let z = run(1754.3).expect("trim");
        for comp in [1, 2, 4] {
            assert_eq!(z.get(comp), Some(1755), "COMP{comp}");
        }
        assert_eq!(z.get(3), None, "the DC link's is not trimmed");
    }

    #[test]
    fn a_signal_at_a_rail_or_far_from_the_bias_fails() {
        assert!(run(5000.0).is_err());
        assert!(run(-1.0).is_err());
        assert!(run(1000.0).is_err());
    }

    #[test]
    fn the_threshold_brackets_the_setting_within_one_step() {
        // 3 A on the ESC1's input: 2.128 counts/A -> 6.38 steps -> 7 codes below zero.
        assert_eq!(trimmed_dac(1755, true, 6_384), 1748);
        assert_eq!(trimmed_dac(1755, false, 6_384), 1762);
        // For any x in [c0-1, c0), the trip (fall of x - d counts) brackets the setting.
        for k in 0..100 {
            let x = 1754.0 + f64::from(k) / 100.0;
            let d = f64::from(trimmed_dac(1755, true, 6_384));
            let fall = x - d;
            assert!((6.384 - 1.0..=6.384 + 1.0).contains(&fall), "{fall}");
        }
        assert_eq!(trimmed_dac(3, true, 10_000), 0);
    }
}
