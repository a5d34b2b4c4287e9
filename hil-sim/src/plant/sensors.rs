//! Current and voltage sensors with the drive's 12-bit ADC, and the hardware comparators.
//!
//! The scaling is the source hardware's (drive.md, "Measurements"): phase currents ±10 A
//! full scale around mid-scale, DC link 0..45 V. The drive core converts counts back
//! with the same constants, so a quantisation step is 10 A / 2048 ≈ 4.9 mA and
//! 45 V / 4095 ≈ 11 mV.
//!
//! The comparators are the board's, from the drive core's own table
//! (`firmware_drive::comparators`: which signal, which direction, which DAC) with the DAC
//! values the drive core computes from the program's `I>>`/`U>>` (or the board defaults):
//! on the B-G431B-ESC1 the positive half-wave of each of the three phases and the DC link.
//! The simulator trips exactly where the board does, not on |i|.

use firmware_drive::comparators::{dac_values, BoardProfile, DacValues, HwThresholds, Signal};
use firmware_drive::power_port::ComparatorLevels;
use shared_protocol::program::{I_MAX_HW_LIMIT, U_MAX_HW_LIMIT};
use shared_protocol::units::{CentiAmps, Volts};

#[cfg(test)]
use firmware_drive::comparators::B_G431B_ESC1;

/// ADC resolution of the drive MCU.
pub const ADC_BITS: u32 = 12;
/// Largest ADC count.
pub const ADC_MAX: u16 = (1 << ADC_BITS) - 1;
/// Current that reads full scale (either sign).
pub const CURRENT_FULL_SCALE_A: f64 = 10.0;
/// DC-link voltage that reads full scale.
pub const UDC_FULL_SCALE_V: f64 = 45.0;

/// One conversion of the three channels the drive reads every PWM period.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct AdcSample {
    pub i_a_counts: u16,
    pub i_b_counts: u16,
    pub u_dc_counts: u16,
}

fn quantise(x: f64) -> u16 {
    // Rounds to the nearest count and saturates like a real ADC at its rails.
    let c = x.round().clamp(0.0, f64::from(ADC_MAX));
    c as u16
}

/// ADC counts of a phase current.
pub fn current_counts(i_a: f64) -> u16 {
    let mid = f64::from(1u16 << (ADC_BITS - 1));
    quantise(mid + i_a * mid / CURRENT_FULL_SCALE_A)
}

/// ADC counts of the DC-link voltage.
pub fn udc_counts(u_v: f64) -> u16 {
    quantise(u_v / UDC_FULL_SCALE_V * f64::from(ADC_MAX))
}

/// Current a count stands for (the inverse the drive applies).
pub fn counts_to_current(c: u16) -> f64 {
    let mid = f64::from(1u16 << (ADC_BITS - 1));
    (f64::from(c) - mid) * CURRENT_FULL_SCALE_A / mid
}

/// Voltage a count stands for.
pub fn counts_to_udc(c: u16) -> f64 {
    f64::from(c) * UDC_FULL_SCALE_V / f64::from(ADC_MAX)
}

/// The board's default hardware thresholds (the source's trimmers as delivered): the drive
/// uses them while the program sets no `I>>`/`U>>` (scenario `[plant] oc_hw_a`, `ov_hw_v`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HwDefaults {
    pub oc_hw_a: f64,
    pub ov_hw_v: f64,
}

impl HwDefaults {
    /// In the units of the drive's settings (0.01 A, V), rounded.
    pub fn thresholds(&self) -> HwThresholds {
        let clamp = |x: f64, max: u16| x.round().clamp(1.0, f64::from(max)) as i16;
        HwThresholds {
            oc_hw: CentiAmps(clamp(self.oc_hw_a * 100.0, I_MAX_HW_LIMIT)),
            ov_hw: Volts(clamp(self.ov_hw_v, U_MAX_HW_LIMIT)),
        }
    }
}

/// The board's comparators with their threshold DACs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Comparators {
    pub board: &'static BoardProfile,
    /// The DAC values in effect (12-bit, ADC counts of each comparator's signal).
    pub dacs: DacValues,
}

impl Comparators {
    /// The board's comparators at the thresholds `t`.
    pub fn new(board: &'static BoardProfile, t: HwThresholds) -> Self {
        Comparators {
            board,
            dacs: dac_values(board, t),
        }
    }

    /// Comparator outputs for phase currents `i_abc` (inverter legs 1-3) and the DC link,
    /// as COMPx_CSR.VALUE reads (index = COMPx - 1).
    pub fn levels(&self, i_abc: [f64; 3], u_dc: f64) -> ComparatorLevels {
        let mut out = ComparatorLevels::default();
        for spec in self.board.comparators {
            let Some(dac) = self.dacs.get(spec.dac) else {
                continue;
            };
            let counts = match spec.signal {
                Signal::CurrentA => current_signal_counts(i_abc[0]),
                Signal::CurrentB => current_signal_counts(i_abc[1]),
                Signal::CurrentC => current_signal_counts(i_abc[2]),
                Signal::DcLink => udc_signal_counts(u_dc),
            };
            if let Some(l) = out.0.get_mut(usize::from(spec.comp.saturating_sub(1))) {
                *l = spec.trips(counts, dac);
            }
        }
        out
    }
}

/// A phase current in ADC counts, not quantised (what the comparator sees).
pub fn current_signal_counts(i_a: f64) -> f64 {
    let mid = f64::from(1u16 << (ADC_BITS - 1));
    mid + i_a * mid / CURRENT_FULL_SCALE_A
}

/// The DC-link voltage in ADC counts, not quantised.
pub fn udc_signal_counts(u_v: f64) -> f64 {
    u_v / UDC_FULL_SCALE_V * f64::from(ADC_MAX)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn current_scaling_is_mid_scale_and_saturates() {
        assert_eq!(current_counts(0.0), 2048);
        assert_eq!(current_counts(10.0), 4095);
        assert_eq!(current_counts(-10.0), 0);
        assert_eq!(current_counts(50.0), 4095);
        assert!((counts_to_current(current_counts(1.234)) - 1.234).abs() < 0.003);
    }

    #[test]
    fn voltage_scaling_covers_0_to_45_v() {
        assert_eq!(udc_counts(0.0), 0);
        assert_eq!(udc_counts(45.0), 4095);
        assert!((counts_to_udc(udc_counts(30.0)) - 30.0).abs() < 0.006);
    }

    #[test]
    fn comparators_are_the_boards_positive_half_waves_and_the_dc_link() {
        let t = HwDefaults {
            oc_hw_a: 3.0,
            ov_hw_v: 40.0,
        }
        .thresholds();
        let c = Comparators::new(&B_G431B_ESC1, t);
        // Each phase's positive half-wave trips, on any of the three phases.
        assert_eq!(
            c.levels([3.05, -1.5, -1.55], 30.0).causes(c.board),
            [true, false]
        );
        assert_eq!(
            c.levels([-1.5, 3.05, -1.55], 30.0).causes(c.board),
            [true, false]
        );
        assert_eq!(
            c.levels([-1.5, -1.55, 3.05], 30.0).causes(c.board),
            [true, false]
        );
        // A negative half-wave alone does not (no window on the G431's four comparators):
        // -5 A on phase a with +2.5 A on b and c is the software check's (I>).
        assert_eq!(
            c.levels([-5.0, 2.5, 2.5], 30.0).causes(c.board),
            [false, false]
        );
        // Beyond -2 x the threshold another phase exceeds +threshold (sum zero).
        assert_eq!(
            c.levels([-6.2, 3.1, 3.1], 30.0).causes(c.board),
            [true, false]
        );
        assert_eq!(
            c.levels([0.0, 0.0, 0.0], 40.05).causes(c.board),
            [false, true]
        );
        assert_eq!(
            c.levels([2.9, 2.9, -5.8], 39.9).causes(c.board),
            [false, false]
        );
    }
}
