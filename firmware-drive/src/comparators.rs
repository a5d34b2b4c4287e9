//! The hardware trip comparators, described once. The board layer configures the G431's
//! comparators, their threshold DACs and TIM1's break input from this table
//! (`board/hw_protection.rs`), and hil-sim's comparator model evaluates the same table
//! against the simulated signals, so the simulator trips exactly where the board does.
//!
//! Why only one half-wave per phase (RM0440, STM32G431: COMP1-COMP4, no window mode):
//! each comparator's non-inverting input is one of two pins (COMP1 PA1/PB1, COMP2
//! PA7/PA3, COMP3 PA0/PC1, COMP4 PB0/PE7) and its inverting input a DAC channel, a VREFINT
//! fraction or one of two other pins (COMP1 PA4/PA0, COMP2 PA5/PA2, COMP3 PF1/PC0, COMP4
//! PE8/PB2). On the B-G431B-ESC1 the phase currents are on PA1 (U), PA7 (V) and PB0 (W)
//! and the DC link on PA0: each phase signal reaches exactly one comparator input, so one
//! threshold per phase, and a window (both half-waves, the source's two trimmers per
//! phase) would need the signal on two comparators. What the board can do, and does:
//! the positive half-wave of all three phases (COMP1, COMP2, COMP4) and the DC link
//! (COMP3). `docs/drive-core.md` "Hardware comparators" lists the faults only the software
//! `I>` check catches.
//!
//! Thresholds are in the ADC counts of the signal (the comparator sees the same pin as
//! the ADC, and DAC and ADC share VREF+), from the program's `I>>` (0.01 A) and `U>>` (V)
//! or the board's defaults ([`crate::DriveConfig`]). A second board profile (e.g. the
//! OPAMPs in PGA mode feeding the comparators) is a second [`BoardProfile`] constant.

use shared_protocol::units::{CentiAmps, Volts};

use crate::comparator_trim::{trimmed_dac, TrimmedZeros};
use crate::front_end::{FrontEndSpec, DIRECT_PINS, ESC1_PGAS};
use crate::measure::{udc_counts_at_volts, ADC_FULL_COUNTS, CURRENT_FULL_CENTIAMPS};
use crate::measure::{FrontEnd, SensorScaling, CURRENT_ZERO_COUNTS, ESC1_SCALING, SOURCE_SCALING};
use crate::protection::HwBreak;

/// The analog signal at a comparator's non-inverting input.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Signal {
    /// Phase current of inverter leg 1 (a), 2 (b), 3 (c), in the ADC scale of
    /// `measure` (2048 = 0 A, +-10 A full scale).
    CurrentA,
    CurrentB,
    CurrentC,
    /// DC-link voltage (0..45 V full scale).
    DcLink,
}

/// When the comparator output is high (trip).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Direction {
    /// Signal above the threshold (output polarity not inverted).
    Above,
    /// Signal below the threshold (output polarity inverted).
    Below,
}

/// Which setting sets the threshold.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Threshold {
    /// `I>>`: +threshold for [`Direction::Above`], -threshold for [`Direction::Below`].
    OcHw,
    /// `U>>`.
    OvHw,
}

/// A DAC output the comparators can take as their inverting input.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DacChannel {
    Dac1Ch1,
    Dac1Ch2,
    Dac3Ch1,
    Dac3Ch2,
}

impl DacChannel {
    pub const ALL: [DacChannel; 4] = [
        DacChannel::Dac1Ch1,
        DacChannel::Dac1Ch2,
        DacChannel::Dac3Ch1,
        DacChannel::Dac3Ch2,
    ];

    pub const fn index(self) -> usize {
        self as usize
    }
}

/// One comparator of the board.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ComparatorSpec {
    /// COMP instance, 1..=4.
    pub comp: u8,
    /// Its non-inverting input pin (documentation; the board's `pins.rs` binds it).
    pub inp: &'static str,
    pub signal: Signal,
    pub direction: Direction,
    pub threshold: Threshold,
    /// Its inverting input.
    pub dac: DacChannel,
    /// A change of the signal at the comparator is the ADC's divided by this: 1 when it
    /// watches the ADC's own pin, 16 when it watches the input of a PGA of gain 16 (whose
    /// output the ADC reads).
    pub input_divider: u16,
    /// Its DAC counts from the zero code found at boot with 0 A (`crate::comparator_trim`)
    /// rather than from the ADC's calibrated zero: a comparator on a signal
    /// whose 0 A level is not known to a few counts (the ESC1's biased PGA inputs).
    pub zero_trim: bool,
    /// COMPx_CSR.HYST, mV (0, 10 .. 70). The hysteresis lies below the inverting input on
    /// the way down of the raw comparison (RM0440 "Comparator hysteresis" figure, ST's HAL
    /// "hysteresis of the input minus"): for a `Below` comparator on the trip edge.
    pub hysteresis_mv: u8,
    /// Blanked by TIM1's OC5 around the switching edges (`crate::blanking`):
    /// the phase-current comparators, whose shunts ring at every turn-on.
    pub blanked: bool,
}

impl ComparatorSpec {
    /// The fault its break raises.
    pub const fn cause(&self) -> HwBreak {
        match self.threshold {
            Threshold::OcHw => HwBreak::Overcurrent,
            Threshold::OvHw => HwBreak::Overvoltage,
        }
    }

    /// COMPx_CSR.INMSEL for its DAC (RM0440 "COMP inverting input" table): 0b100 is
    /// DAC3 CH1 for COMP1/COMP3 and DAC3 CH2 for COMP2/COMP4; 0b101 is DAC1 CH1 for
    /// COMP1/COMP3/COMP4 and DAC1 CH2 for COMP2. `None`: that DAC cannot reach it.
    pub const fn inmsel(&self) -> Option<u8> {
        use DacChannel as D;
        match (self.comp, self.dac) {
            (1 | 3, D::Dac3Ch1) | (2 | 4, D::Dac3Ch2) => Some(0b100),
            (1 | 3 | 4, D::Dac1Ch1) | (2, D::Dac1Ch2) => Some(0b101),
            _ => None,
        }
    }

    /// COMPx_CSR.BLANKSEL: TIM1_OC5 if [`ComparatorSpec::blanked`] (RM0440 "COMP blanking
    /// sources": 001 for COMP1-COMP3, 100 for COMP4; ST's `COMP_BLANKINGSRC_TIM1_OC5_COMP4`
    /// = BLANKSEL_2), else 000. `None`: TIM1_OC5 cannot blank this comparator.
    pub const fn blanksel(&self) -> Option<u8> {
        if !self.blanked {
            return Some(0);
        }
        match self.comp {
            1..=3 => Some(0b001),
            4 => Some(0b100),
            _ => None,
        }
    }

    /// Output polarity inverted (COMPx_CSR.POLARITY): a trip below the threshold.
    pub const fn inverted(&self) -> bool {
        matches!(self.direction, Direction::Below)
    }

    /// The DAC value (12-bit counts at the comparator's input) for these thresholds on a
    /// front end with its calibration and the boot trim's zero codes. An overcurrent
    /// comparator watches the positive half-wave: above +`I>>` on a non-inverting front
    /// end, below it on an inverting one; `direction` says which way the signal at the pin
    /// goes.
    pub fn dac_counts(&self, t: HwThresholds, fe: &FrontEnd, trim: &TrimmedZeros) -> u16 {
        let raw = match self.threshold {
            Threshold::OcHw if self.zero_trim => {
                // Until the trim has run: the nominal zero (both PGA pins at the bias).
                let zero = trim
                    .get(self.comp)
                    .unwrap_or(fe.scaling().current_zero_counts);
                let per_amp = fe.scaling().current_millicounts_per_amp.unsigned_abs()
                    / u32::from(self.input_divider.max(1));
                let steps_x1000 = u32::from(t.oc_hw.0.max(0) as u16) * per_amp / 100;
                let below = matches!(self.direction, Direction::Below);
                return trimmed_dac(zero, below, steps_x1000);
            }
            Threshold::OcHw => {
                let d = (i32::from(t.oc_hw.0) * CURRENT_ZERO_COUNTS + CURRENT_FULL_CENTIAMPS / 2)
                    / CURRENT_FULL_CENTIAMPS;
                let rising = fe.scaling().current_millicounts_per_amp > 0;
                let positive = matches!(self.direction, Direction::Above) == rising;
                let canonical = if positive {
                    CURRENT_ZERO_COUNTS + d
                } else {
                    CURRENT_ZERO_COUNTS - d
                };
                fe.raw_current_counts(canonical)
            }
            Threshold::OvHw => {
                let c = udc_counts_at_volts(u32::from(t.ov_hw.0.max(0) as u16));
                fe.raw_udc_counts(c).min(ADC_FULL_COUNTS + 1) as i32
            }
        };
        // At the comparator's input a count can stand for several of the ADC's (the PGA
        // input: 16): round to the safe side, so that the trip is at or below the setting.
        let div = i32::from(self.input_divider.max(1));
        let q = match self.direction {
            Direction::Above => raw.div_euclid(div),
            Direction::Below => (raw + div - 1).div_euclid(div),
        };
        q.clamp(0, ADC_FULL_COUNTS as i32) as u16
    }

    /// The comparator output for a signal of `signal_counts` (ADC counts, not quantised)
    /// against `dac` counts (ideal comparator: no offset; a hysteresis only delays the
    /// release of a latched break).
    pub fn trips(&self, signal_counts: f64, dac: u16) -> bool {
        match self.direction {
            Direction::Above => signal_counts > f64::from(dac),
            Direction::Below => signal_counts < f64::from(dac),
        }
    }
}

/// A drive board's comparators.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BoardProfile {
    pub name: &'static str,
    /// Short name: hil-sim's `[plant] board` value, and the image's `DRIVE_BOARD_PROFILE`
    /// marker (the emulator puts this profile's voltages on the pins).
    pub key: &'static str,
    pub comparators: &'static [ComparatorSpec],
    /// How the currents and the DC link reach the ADC.
    pub scaling: SensorScaling,
    /// The amplifiers the board enables and the ADC channels it reads.
    pub front_end: FrontEndSpec,
    /// The board has a brake chopper (`U>` switches it); without one `U>` caps the
    /// overvoltage controller's level (`crate::overvoltage`).
    pub brake_chopper: bool,
    /// `U>>` while the program sets none, V (at most `DriveConfig::ov_hw_default_volts`).
    pub ov_hw_default_volts: u16,
}

impl BoardProfile {
    /// [`BoardProfile::key`] as the fixed-size, zero-padded marker the image carries
    /// (truncated to 8 bytes).
    // Both indices are below the bounds the loop checks (`get` is not const); the image
    // evaluates it at compile time.
    #[allow(clippy::indexing_slicing)]
    pub const fn key_bytes(&self) -> [u8; 8] {
        let k = self.key.as_bytes();
        let mut out = [0u8; 8];
        let mut i = 0;
        while i < k.len() && i < 8 {
            out[i] = k[i];
            i += 1;
        }
        out
    }
}

/// The source's sensors (+-10 A around 1.65 V, 0-45 V) on the ESC1's pins (a carrier board
/// with the ESC1's shunt network removed from PA1, PA7, PB0): the positive half-wave of
/// each phase, and the DC link. Cargo feature `source-sensors` of the image.
pub const SOURCE_SENSORS: BoardProfile = BoardProfile {
    name: "source sensors on B-G431B-ESC1 pins",
    key: "source",
    scaling: SOURCE_SCALING,
    front_end: DIRECT_PINS,
    brake_chopper: true,
    ov_hw_default_volts: 40,
    comparators: &[
        ComparatorSpec {
            comp: 1,
            inp: "PA1",
            signal: Signal::CurrentA,
            direction: Direction::Above,
            threshold: Threshold::OcHw,
            dac: DacChannel::Dac3Ch1,
            input_divider: 1,
            zero_trim: false,
            hysteresis_mv: 20,
            blanked: true,
        },
        ComparatorSpec {
            comp: 2,
            inp: "PA7",
            signal: Signal::CurrentB,
            direction: Direction::Above,
            threshold: Threshold::OcHw,
            dac: DacChannel::Dac3Ch2,
            input_divider: 1,
            zero_trim: false,
            hysteresis_mv: 20,
            blanked: true,
        },
        ComparatorSpec {
            comp: 3,
            inp: "PA0",
            signal: Signal::DcLink,
            direction: Direction::Above,
            threshold: Threshold::OvHw,
            dac: DacChannel::Dac1Ch1,
            input_divider: 1,
            zero_trim: false,
            hysteresis_mv: 20,
            blanked: false,
        },
        // DAC3 CH2 is shared with COMP2: the same I>> threshold.
        ComparatorSpec {
            comp: 4,
            inp: "PB0",
            signal: Signal::CurrentC,
            direction: Direction::Above,
            threshold: Threshold::OcHw,
            dac: DacChannel::Dac3Ch2,
            input_divider: 1,
            zero_trim: false,
            hysteresis_mv: 20,
            blanked: true,
        },
    ],
};

/// The bare B-G431B-ESC1. The ADC reads the OPAMPs' outputs (PGA x16
/// with the network's foot on VINM0, [`ESC1_SCALING`]); the comparators watch the OPAMPs'
/// inputs PA1, PA7, PB0, the only pins of the three phases that reach COMP1/2/4 (OPAMP1/2
/// outputs PA2/PA6 reach no comparator input; OPAMP3's PB1 reaches COMP1 only). The
/// signal there falls 1.71 mV/A from the bias (~1.41 V): 2.13 DAC counts per ampere, too
/// small against the bias's tolerance and the comparator's and DAC's offsets to count
/// from a nominal zero: each comparator's zero is trimmed at boot
/// (`crate::comparator_trim`), each with a DAC channel of its own (COMP2 on DAC1 CH2,
/// whose pin PA5 stays off: internal mode), no hysteresis; `I>>` then trips within one
/// DAC step (0.47 A) of the setting, on the positive half-wave (signal below the
/// threshold). DC link on PA0 through the 0.0962 divider (full scale 34.3 V), 20 mV
/// hysteresis (0.21 V of DC link).
pub const B_G431B_ESC1: BoardProfile = BoardProfile {
    name: "B-G431B-ESC1",
    key: "esc1",
    scaling: ESC1_SCALING,
    front_end: ESC1_PGAS,
    // No chopper: PB5 is `GPIO_BEMF` (UM2516 pin table, stm32duino's ESC1 variant).
    brake_chopper: false,
    // UM2516: "up to 6S LiPo" (25.2 V full); the measuring range ends at 34.3 V; the
    // MOSFETs are 60 V parts, the capacitors' rating is in the schematic we could not
    // read. 32 V: 2.3 V inside the range (the comparator's and the divider's tolerances
    // stay measurable), room above a 6S pack for the overvoltage controller (cap 30 V),
    // and above the 30 V of the project's rig (docs/drive-core.md "Overvoltage without a
    // chopper").
    ov_hw_default_volts: 32,
    comparators: &[
        ComparatorSpec {
            comp: 1,
            inp: "PA1",
            signal: Signal::CurrentA,
            direction: Direction::Below,
            threshold: Threshold::OcHw,
            dac: DacChannel::Dac3Ch1,
            input_divider: 16,
            zero_trim: true,
            hysteresis_mv: 0,
            blanked: true,
        },
        ComparatorSpec {
            comp: 2,
            inp: "PA7",
            signal: Signal::CurrentB,
            direction: Direction::Below,
            threshold: Threshold::OcHw,
            dac: DacChannel::Dac1Ch2,
            input_divider: 16,
            zero_trim: true,
            hysteresis_mv: 0,
            blanked: true,
        },
        ComparatorSpec {
            comp: 3,
            inp: "PA0",
            signal: Signal::DcLink,
            direction: Direction::Above,
            threshold: Threshold::OvHw,
            dac: DacChannel::Dac1Ch1,
            input_divider: 1,
            zero_trim: false,
            hysteresis_mv: 20,
            blanked: false,
        },
        ComparatorSpec {
            comp: 4,
            inp: "PB0",
            signal: Signal::CurrentC,
            direction: Direction::Below,
            threshold: Threshold::OcHw,
            dac: DacChannel::Dac3Ch2,
            input_divider: 16,
            zero_trim: true,
            hysteresis_mv: 0,
            blanked: true,
        },
    ],
};

/// The hardware thresholds in effect.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct HwThresholds {
    /// `I>>`, 0.01 A.
    pub oc_hw: CentiAmps,
    /// `U>>`, V.
    pub ov_hw: Volts,
}

/// The value of each DAC channel ([`DacChannel::index`]); `None` for a channel no
/// comparator uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DacValues(pub [Option<u16>; 4]);

impl DacValues {
    pub fn get(&self, ch: DacChannel) -> Option<u16> {
        self.0.get(ch.index()).copied().flatten()
    }
}

/// The DAC values a profile needs for these thresholds (with the boot trim's zero codes,
/// `TrimmedZeros::default()` before it). Comparators sharing a channel must agree on its
/// value (unit-tested for every profile); the first one sets it.
pub fn dac_values(
    profile: &BoardProfile,
    t: HwThresholds,
    fe: &FrontEnd,
    trim: &TrimmedZeros,
) -> DacValues {
    let mut v = [None; 4];
    for spec in profile.comparators {
        if let Some(slot) = v.get_mut(spec.dac.index()) {
            if slot.is_none() {
                *slot = Some(spec.dac_counts(t, fe, trim));
            }
        }
    }
    DacValues(v)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::measure::current_centiamps;

    fn t(oc: i16, ov: i16) -> HwThresholds {
        HwThresholds {
            oc_hw: CentiAmps(oc),
            ov_hw: Volts(ov),
        }
    }

    #[test]
    fn the_tables_are_what_rm0440_allows() {
        for p in [&SOURCE_SENSORS, &B_G431B_ESC1] {
            table_is_what_rm0440_allows(p);
        }
    }

    fn table_is_what_rm0440_allows(p: &BoardProfile) {
        let fe = FrontEnd::new(p.scaling);
        for (k, spec) in p.comparators.iter().enumerate() {
            assert!((1..=4).contains(&spec.comp), "G431: COMP1-COMP4");
            assert!(spec.inmsel().is_some(), "{spec:?}: DAC not reachable");
            assert!(
                spec.blanksel().is_some(),
                "{spec:?}: TIM1_OC5 cannot blank it"
            );
            // The phase-current comparators are blanked, the DC link's is not.
            assert_eq!(
                spec.blanked,
                spec.cause() == HwBreak::Overcurrent,
                "{spec:?}"
            );
            // COMPx_INP0 pins of the G431 (RM0440; INP1 is PB1/PA3/PC1/PE7).
            let inp0 = ["PA1", "PA7", "PA0", "PB0"][usize::from(spec.comp - 1)];
            assert_eq!(spec.inp, inp0);
            // One spec per comparator.
            assert!(p.comparators[..k].iter().all(|o| o.comp != spec.comp));
            // A comparator on an amplifier's input sees the ADC's signal divided by the
            // amplifier's gain: the divider is that gain.
            assert_eq!(
                spec.input_divider,
                p.front_end.gain_of(spec.signal),
                "{spec:?}"
            );
        }
        // Comparators sharing a DAC channel need the same value for any thresholds.
        let z = TrimmedZeros::default();
        for oc in [1, 150, 300, 999] {
            for ov in [1, 40, 45] {
                let th = t(oc, ov);
                for a in p.comparators {
                    for b in p.comparators {
                        if a.dac == b.dac {
                            assert_eq!(
                                a.dac_counts(th, &fe, &z),
                                b.dac_counts(th, &fe, &z),
                                "{a:?} {b:?}"
                            );
                        }
                    }
                }
            }
        }
        // Both causes are watched; each phase's positive half-wave (the signal rises with
        // the current on a non-inverting front end, falls on an inverting one).
        assert!(p
            .comparators
            .iter()
            .any(|s| s.cause() == HwBreak::Overvoltage));
        let rising = p.scaling.current_millicounts_per_amp > 0;
        let positive = if rising {
            Direction::Above
        } else {
            Direction::Below
        };
        for sig in [Signal::CurrentA, Signal::CurrentB, Signal::CurrentC] {
            assert!(p
                .comparators
                .iter()
                .any(|s| s.signal == sig && s.direction == positive));
        }
    }

    #[test]
    fn blanksel_is_tim1_oc5_per_rm0440() {
        let codes: Vec<(u8, Option<u8>)> = B_G431B_ESC1
            .comparators
            .iter()
            .map(|s| (s.comp, s.blanksel()))
            .collect();
        assert_eq!(
            codes,
            vec![(1, Some(1)), (2, Some(1)), (3, Some(0)), (4, Some(0b100))]
        );
        let c5 = ComparatorSpec {
            comp: 5,
            ..B_G431B_ESC1.comparators[0]
        };
        assert_eq!(c5.blanksel(), None);
    }

    #[test]
    fn the_key_marker_is_zero_padded() {
        assert_eq!(&B_G431B_ESC1.key_bytes(), b"esc1\0\0\0\0");
        assert_eq!(&SOURCE_SENSORS.key_bytes(), b"source\0\0");
    }

    #[test]
    fn thresholds_in_adc_counts() {
        let p = &SOURCE_SENSORS;
        let fe = FrontEnd::new(p.scaling);
        let z = TrimmedZeros::default();
        let v = dac_values(p, t(300, 40), &fe, &z);
        // 3.00 A = 614.4 counts above 2048; 40 V = 91 * 40 counts.
        assert_eq!(v.get(DacChannel::Dac3Ch1), Some(2662));
        assert_eq!(v.get(DacChannel::Dac3Ch2), Some(2662));
        assert_eq!(v.get(DacChannel::Dac1Ch1), Some(3640));
        assert_eq!(v.get(DacChannel::Dac1Ch2), None);
        assert!(current_centiamps(2662).0 >= 299);
        // Full scale: clamped to the DAC's range.
        let v = dac_values(p, t(999, 45), &fe, &z);
        assert_eq!(v.get(DacChannel::Dac3Ch1), Some(4094));
        assert_eq!(v.get(DacChannel::Dac1Ch1), Some(4095));
        // A "below" comparator (another profile) mirrors the threshold around 0 A.
        let below = ComparatorSpec {
            direction: Direction::Below,
            ..p.comparators[0]
        };
        assert_eq!(below.dac_counts(t(300, 40), &fe, &z), 2048 - 614);
        assert!(below.inverted());
        assert!(below.trips(1400.0, 1434) && !below.trips(1500.0, 1434));
        assert!(p.comparators[0].trips(2663.0, 2662) && !p.comparators[0].trips(2662.0, 2662));
    }

    #[test]
    fn esc1_thresholds_count_from_the_trimmed_zero_at_the_pga_input() {
        let p = &B_G431B_ESC1;
        let fe = FrontEnd::new(p.scaling);
        // Before the trim: the nominal zero (the bias, 1755 counts); 3 A = 6.38 steps of
        // 2.128 counts/A -> 7 codes below it.
        let v = dac_values(p, t(300, 28), &fe, &TrimmedZeros::default());
        assert_eq!(v.get(DacChannel::Dac3Ch1), Some(1748));
        assert_eq!(v.get(DacChannel::Dac1Ch2), Some(1748));
        assert_eq!(v.get(DacChannel::Dac3Ch2), Some(1748));
        // 28 V on the 34.3 V range.
        assert_eq!(v.get(DacChannel::Dac1Ch1), Some(3343));
        // Each comparator from its own trimmed zero.
        let z = TrimmedZeros([Some(1760), Some(1740), None, Some(1790)]);
        let v = dac_values(p, t(300, 28), &fe, &z);
        assert_eq!(v.get(DacChannel::Dac3Ch1), Some(1753));
        assert_eq!(v.get(DacChannel::Dac1Ch2), Some(1733));
        assert_eq!(v.get(DacChannel::Dac3Ch2), Some(1783));
        // The ADC's calibrated zero does not move a trimmed comparator.
        let mut fe2 = fe;
        fe2.calibrate([2080, 2080]);
        assert_eq!(dac_values(p, t(300, 28), &fe2, &z), v);
    }

    #[test]
    fn the_esc1_trims_its_phase_comparators_without_hysteresis() {
        for s in B_G431B_ESC1.comparators {
            let oc = s.cause() == HwBreak::Overcurrent;
            assert_eq!(s.zero_trim, oc, "{s:?}");
            assert_eq!(s.hysteresis_mv, if oc { 0 } else { 20 }, "{s:?}");
        }
        // One DAC channel per comparator: each trim needs its own.
        let chans: Vec<_> = B_G431B_ESC1.comparators.iter().map(|s| s.dac).collect();
        for (k, c) in chans.iter().enumerate() {
            assert!(!chans[..k].contains(c), "{chans:?}");
        }
        const { assert!(!B_G431B_ESC1.brake_chopper && SOURCE_SENSORS.brake_chopper) };
    }
}
