//! Current and voltage sensors with the drive's 12-bit ADC, and the hardware comparators.
//!
//! The scaling is the drive board profile's (`firmware_drive::measure::SensorScaling`):
//! by default the source hardware's (drive.md, "Measurements": phase currents ±10 A full
//! scale around mid-scale, DC link 0..45 V; a step is 10 A / 2048 ≈ 4.9 mA and
//! 45 V / 4095 ≈ 11 mV), with `[plant] board = "esc1"` the bare B-G431B-ESC1's (shunt,
//! PGA gain 16, inverting: -34.03 counts/A, 29 mA per step; DC link 0..34.3 V).
//!
//! The comparators are the board's, from the drive core's own table
//! (`firmware_drive::comparators`: which signal, which direction, which DAC) with the DAC
//! values the drive core computes from the program's `I>>`/`U>>` (or the board defaults):
//! the positive half-wave of each of the three phases and the DC link (on the ESC1 at the
//! PGA inputs, before the gain).
//! The simulator trips exactly where the board does, not on |i|.

use firmware_drive::comparator_trim::TrimmedZeros;
use firmware_drive::comparators::{
    dac_values, BoardProfile, DacValues, Direction, HwThresholds, Signal,
};
use firmware_drive::power_port::ComparatorLevels;
use shared_protocol::program::{I_MAX_HW_LIMIT, U_MAX_HW_LIMIT};
use shared_protocol::units::{CentiAmps, Volts};

use firmware_drive::measure::{FrontEnd, SensorScaling};

/// ADC resolution of the drive MCU.
pub const ADC_BITS: u32 = 12;
/// Largest ADC count.
pub const ADC_MAX: u16 = (1 << ADC_BITS) - 1;

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

/// The ADC reading of a phase current on a board with sensors `sc`, not quantised.
pub fn current_signal_counts(sc: &SensorScaling, i_a: f64) -> f64 {
    f64::from(sc.current_zero_counts) + i_a * f64::from(sc.current_millicounts_per_amp) / 1000.0
}

/// The ADC reading of the DC-link voltage, not quantised.
pub fn udc_signal_counts(sc: &SensorScaling, u_v: f64) -> f64 {
    u_v * 10.0 / f64::from(sc.udc_full_decivolts.max(1)) * f64::from(ADC_MAX)
}

/// ADC counts of a phase current.
pub fn current_counts(sc: &SensorScaling, i_a: f64) -> u16 {
    quantise(current_signal_counts(sc, i_a))
}

/// ADC counts of the DC-link voltage.
pub fn udc_counts(sc: &SensorScaling, u_v: f64) -> u16 {
    quantise(udc_signal_counts(sc, u_v))
}

/// Current a count stands for (the inverse the drive applies, at the nominal zero).
pub fn counts_to_current(sc: &SensorScaling, c: u16) -> f64 {
    counts_to_current_f(sc, f64::from(c))
}

/// Current an ADC reading (not quantised) stands for, at the nominal zero.
pub fn counts_to_current_f(sc: &SensorScaling, counts: f64) -> f64 {
    (counts - f64::from(sc.current_zero_counts)) * 1000.0
        / f64::from(sc.current_millicounts_per_amp)
}

/// Voltage a count stands for.
pub fn counts_to_udc(sc: &SensorScaling, c: u16) -> f64 {
    f64::from(c) * f64::from(sc.udc_full_decivolts) / 10.0 / f64::from(ADC_MAX)
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
            // Ideal sensors: the nominal zero is the trimmed one.
            dacs: dac_values(
                board,
                t,
                &FrontEnd::new(board.scaling),
                &TrimmedZeros::default(),
            ),
        }
    }

    /// The board's comparators with no threshold set: they never trip. The emulator's
    /// plant uses this: there the comparators are the emulated COMP/DAC registers.
    pub fn off(board: &'static BoardProfile) -> Self {
        Comparators {
            board,
            dacs: DacValues::default(),
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
            let sc = &self.board.scaling;
            let adc_counts = match spec.signal {
                Signal::CurrentA => current_signal_counts(sc, i_abc[0]),
                Signal::CurrentB => current_signal_counts(sc, i_abc[1]),
                Signal::CurrentC => current_signal_counts(sc, i_abc[2]),
                Signal::DcLink => udc_signal_counts(sc, u_dc),
            };
            // A comparator on a PGA's input sees the signal's change before the gain,
            // around the same zero (the ESC1's PGA subtracts the bias its VINM0 carries).
            let div = f64::from(spec.input_divider.max(1));
            let zero = f64::from(sc.current_zero_counts);
            let counts = zero + (adc_counts - zero) / div;
            if let Some(l) = out.0.get_mut(usize::from(spec.comp.saturating_sub(1))) {
                *l = spec.trips(counts, dac);
            }
        }
        out
    }
}

/// One comparator of [`ComparatorTable`]: its input as `offset + gain * signal` (counts;
/// the signal in A or V).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Linear {
    /// Index into [`ComparatorLevels`].
    level: usize,
    signal: Signal,
    offset_counts: f64,
    gain_counts: f64,
    dac: f64,
    above: bool,
}

/// [`Comparators::levels`] with each comparator's scaling folded into one gain and one
/// offset (the plant evaluates the comparators after every integration step; the
/// parameters hold for one [`super::Plant::advance`]). The same straight lines: the
/// input differs from `levels`' by rounding only (~1e-13 counts), so a decision can
/// differ only for a signal within that of a threshold.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ComparatorTable {
    rows: [Option<Linear>; 7],
}

impl ComparatorTable {
    pub fn new(c: &Comparators) -> Self {
        let mut rows = [None; 7];
        let sc = &c.board.scaling;
        let zero = f64::from(sc.current_zero_counts);
        let mut n = 0;
        for spec in c.board.comparators {
            let Some(dac) = c.dacs.get(spec.dac) else {
                continue;
            };
            let level = usize::from(spec.comp.saturating_sub(1));
            if level >= 7 || n >= rows.len() {
                continue;
            }
            let div = f64::from(spec.input_divider.max(1));
            // counts = zero + (adc - zero) / div, adc = adc0 + k * signal.
            let (adc0, k) = match spec.signal {
                Signal::DcLink => (
                    0.0,
                    10.0 / f64::from(sc.udc_full_decivolts.max(1)) * f64::from(ADC_MAX),
                ),
                _ => (zero, f64::from(sc.current_millicounts_per_amp) / 1000.0),
            };
            rows[n] = Some(Linear {
                level,
                signal: spec.signal,
                offset_counts: zero + (adc0 - zero) / div,
                gain_counts: k / div,
                dac: f64::from(dac),
                above: matches!(spec.direction, Direction::Above),
            });
            n += 1;
        }
        ComparatorTable { rows }
    }

    /// As [`Comparators::levels`].
    pub fn levels(&self, i_abc: [f64; 3], u_dc: f64) -> ComparatorLevels {
        let mut out = ComparatorLevels::default();
        for r in self.rows.iter().flatten() {
            let x = match r.signal {
                Signal::CurrentA => i_abc[0],
                Signal::CurrentB => i_abc[1],
                Signal::CurrentC => i_abc[2],
                Signal::DcLink => u_dc,
            };
            let counts = r.offset_counts + r.gain_counts * x;
            if let Some(l) = out.0.get_mut(r.level) {
                *l = if r.above {
                    counts > r.dac
                } else {
                    counts < r.dac
                };
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    use firmware_drive::comparators::{B_G431B_ESC1, SOURCE_SENSORS};
    use firmware_drive::measure::{ESC1_SCALING, SOURCE_SCALING};
    use firmware_drive::power_port::Causes;
    use firmware_drive::HwBreak;

    #[test]
    fn current_scaling_is_mid_scale_and_saturates() {
        let sc = &SOURCE_SCALING;
        assert_eq!(current_counts(sc, 0.0), 2048);
        assert_eq!(current_counts(sc, 10.0), 4095);
        assert_eq!(current_counts(sc, -10.0), 0);
        assert_eq!(current_counts(sc, 50.0), 4095);
        assert!((counts_to_current(sc, current_counts(sc, 1.234)) - 1.234).abs() < 0.003);
    }

    #[test]
    fn voltage_scaling_covers_0_to_45_v() {
        let sc = &SOURCE_SCALING;
        assert_eq!(udc_counts(sc, 0.0), 0);
        assert_eq!(udc_counts(sc, 45.0), 4095);
        assert!((counts_to_udc(sc, udc_counts(sc, 30.0)) - 30.0).abs() < 0.006);
    }

    #[test]
    fn the_esc1_front_end_inverts_and_spans_about_50_amps_and_34_volts() {
        let sc = &ESC1_SCALING;
        // The bias of the VINM0-biased PGA: 1755 counts at 0 A.
        assert_eq!(current_counts(sc, 0.0), 1755);
        // -34.05 counts per ampere: +2 A reads 68 counts below the zero.
        assert_eq!(current_counts(sc, 2.0), 1755 - 68);
        assert_eq!(current_counts(sc, 51.6), 0);
        assert_eq!(current_counts(sc, -68.8), 4095);
        assert_eq!(udc_counts(sc, 34.3), 4095);
        assert!((counts_to_udc(sc, udc_counts(sc, 24.0)) - 24.0).abs() < 0.005);
        assert!((counts_to_current(sc, current_counts(sc, 5.0)) - 5.0).abs() < 0.02);
    }

    #[test]
    fn the_esc1_comparators_watch_the_pga_inputs_in_steps_of_half_an_amp() {
        let t = HwDefaults {
            oc_hw_a: 3.0,
            ov_hw_v: 30.0,
        }
        .thresholds();
        let c = Comparators::new(&B_G431B_ESC1, t);
        // The PGA input: the bias (1755 counts) at 0 A, -2.13 counts per ampere; 3 A is
        // 6.4 counts below: the DAC holds 7 below the zero, the step that brackets 3 A.
        assert_eq!(
            c.dacs.get(firmware_drive::comparators::DacChannel::Dac3Ch1),
            Some(1748)
        );
        for phase in 0..3 {
            let mut i = [-1.0; 3];
            i[phase] = 3.3;
            assert_eq!(
                c.levels(i, 24.0).causes(c.board),
                Causes::only(HwBreak::Overcurrent),
                "{phase}"
            );
            i[phase] = 2.8;
            assert_eq!(c.levels(i, 24.0).causes(c.board), Causes::NONE, "{phase}");
        }
        // Negative currents raise the signal: no trip.
        assert_eq!(
            c.levels([-8.0, 4.0, 4.0], 24.0).causes(c.board),
            Causes::only(HwBreak::Overcurrent),
            "phase b and c at +4 A"
        );
        assert_eq!(
            c.levels([-2.5, 1.25, 1.25], 24.0).causes(c.board),
            Causes::NONE
        );
        // The DC link at 30 V of the 34.3 V range.
        assert_eq!(
            c.levels([0.0; 3], 30.2).causes(c.board),
            Causes::only(HwBreak::Overvoltage)
        );
        assert_eq!(c.levels([0.0; 3], 29.8).causes(c.board), Causes::NONE);
    }

    #[test]
    fn comparators_are_the_boards_positive_half_waves_and_the_dc_link() {
        let t = HwDefaults {
            oc_hw_a: 3.0,
            ov_hw_v: 40.0,
        }
        .thresholds();
        let c = Comparators::new(&SOURCE_SENSORS, t);
        // Each phase's positive half-wave trips, on any of the three phases.
        assert_eq!(
            c.levels([3.05, -1.5, -1.55], 30.0).causes(c.board),
            Causes::only(HwBreak::Overcurrent)
        );
        assert_eq!(
            c.levels([-1.5, 3.05, -1.55], 30.0).causes(c.board),
            Causes::only(HwBreak::Overcurrent)
        );
        assert_eq!(
            c.levels([-1.5, -1.55, 3.05], 30.0).causes(c.board),
            Causes::only(HwBreak::Overcurrent)
        );
        // A negative half-wave alone does not (no window on the G431's four comparators):
        // -5 A on phase a with +2.5 A on b and c is the software check's (I>).
        assert_eq!(
            c.levels([-5.0, 2.5, 2.5], 30.0).causes(c.board),
            Causes::NONE
        );
        // Beyond -2 x the threshold another phase exceeds +threshold (sum zero).
        assert_eq!(
            c.levels([-6.2, 3.1, 3.1], 30.0).causes(c.board),
            Causes::only(HwBreak::Overcurrent)
        );
        assert_eq!(
            c.levels([0.0, 0.0, 0.0], 40.05).causes(c.board),
            Causes::only(HwBreak::Overvoltage)
        );
        assert_eq!(
            c.levels([2.9, 2.9, -5.8], 39.9).causes(c.board),
            Causes::NONE
        );
    }

    #[test]
    fn the_table_decides_as_the_comparators_do() {
        for board in [&B_G431B_ESC1, &SOURCE_SENSORS] {
            let t = HwDefaults {
                oc_hw_a: 3.0,
                ov_hw_v: 30.0,
            };
            let c = Comparators::new(board, t.thresholds());
            let table = ComparatorTable::new(&c);
            let mut trips = 0;
            for k in -4000..4000 {
                let i = f64::from(k) * 0.0013;
                let u = 20.0 + f64::from(k) * 0.0031;
                let abc = [i, -0.7 * i, 1.3 * i];
                let want = c.levels(abc, u);
                assert_eq!(table.levels(abc, u), want, "{} {i} A {u} V", board.name);
                trips += want.0.iter().filter(|l| **l).count();
            }
            assert!(trips > 1000, "{}: {trips}", board.name);
        }
    }
}
