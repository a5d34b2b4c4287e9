//! The analog errors of the comparators, the DACs and the OPAMPs, in one place so that a host
//! (hil-sim's scenario) can set them together: the datasheet's typical part by default, an
//! ideal part, or a part at the datasheet's limits in either direction.
//!
//! Figures: STM32G431 datasheet DS12589, electrical characteristics, tables "COMP
//! characteristics", "DAC characteristics" and "OPAMP characteristics"; the programmed
//! hysteresis levels from RM0440 COMPx_CSR.HYST and ST's `stm32g4xx_hal_comp.h`
//! (`COMP_HYSTERESIS_10MV` .. `_70MV`). `g431-emu/docs/models.md` lists them with their
//! sources and what is still to be checked against the PDF.

use crate::time::{ns_to_cycles, Cycles};

/// COMP input offset, typical (DS12589 "COMP characteristics", Voffset, full common-mode
/// range).
pub const COMP_OFFSET_TYP_VOLTS: f64 = 0.002;
/// COMP input offset, datasheet limit (same row, maximum).
pub const COMP_OFFSET_MAX_VOLTS: f64 = 0.020;
/// COMP propagation delay, typical (DS12589 "COMP characteristics", tD, 200 mV step with
/// 100 mV overdrive). The G431's comparators have one speed (COMPx_CSR has no power-mode
/// field, unlike the L4/G0 comparators): this is the figure for the images' use.
pub const COMP_DELAY_TYP_NS: f64 = 16.7;
/// COMP propagation delay, datasheet limit (same row, maximum).
pub const COMP_DELAY_MAX_NS: f64 = 29.0;
/// DAC offset error, typical, in volts at the output (DS12589 "DAC characteristics", offset
/// error at code 0x800; 2 LSB at VREF+ = 3.3 V).
pub const DAC_OFFSET_TYP_VOLTS: f64 = 2.0 * 3.3 / 4096.0;
/// DAC offset error, datasheet limit (same row, maximum: 12 LSB at 3.3 V).
pub const DAC_OFFSET_MAX_VOLTS: f64 = 12.0 * 3.3 / 4096.0;
/// OPAMP input offset voltage, typical (DS12589 "OPAMP characteristics", VIOFFSET, 25 °C,
/// after the user trimming embassy's `calibrate` performs).
pub const OPAMP_OFFSET_TYP_VOLTS: f64 = 0.0015;
/// OPAMP input offset voltage, datasheet limit over the voltage and temperature range.
pub const OPAMP_OFFSET_MAX_VOLTS: f64 = 0.0045;

/// The analog errors the models apply. Offsets are signed: a positive comparator offset
/// raises the level INP must pass (INP > INM + offset), a positive DAC offset raises the
/// DAC's output, a positive OPAMP offset adds to its non-inverting input.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AnalogErrors {
    /// COMP1-4 input offset, volts.
    pub comp_offset_v: f64,
    /// COMP1-4 propagation delay, ns.
    pub comp_delay_ns: f64,
    /// DAC1/DAC3 output offset, volts.
    pub dac_offset_v: f64,
    /// OPAMP1-3 input offset, volts.
    pub opamp_offset_v: f64,
}

impl AnalogErrors {
    /// The datasheet's typical part (the default).
    pub const TYPICAL: AnalogErrors = AnalogErrors {
        comp_offset_v: COMP_OFFSET_TYP_VOLTS,
        comp_delay_ns: COMP_DELAY_TYP_NS,
        dac_offset_v: DAC_OFFSET_TYP_VOLTS,
        opamp_offset_v: OPAMP_OFFSET_TYP_VOLTS,
    };

    /// No offsets, no delay (for tests of the register logic alone).
    pub const IDEAL: AnalogErrors = AnalogErrors {
        comp_offset_v: 0.0,
        comp_delay_ns: 0.0,
        dac_offset_v: 0.0,
        opamp_offset_v: 0.0,
    };

    /// A part at the datasheet's limits, every offset in the direction `sign` (+1: every
    /// offset positive, -1: every offset negative), the slowest comparator.
    pub fn worst(sign: f64) -> AnalogErrors {
        let s = if sign < 0.0 { -1.0 } else { 1.0 };
        AnalogErrors {
            comp_offset_v: s * COMP_OFFSET_MAX_VOLTS,
            comp_delay_ns: COMP_DELAY_MAX_NS,
            dac_offset_v: s * DAC_OFFSET_MAX_VOLTS,
            opamp_offset_v: s * OPAMP_OFFSET_MAX_VOLTS,
        }
    }

    /// The comparator delay in CPU cycles (rounded up: never faster than the part).
    pub fn comp_delay_cycles(&self) -> Cycles {
        ns_to_cycles(self.comp_delay_ns.max(0.0).ceil() as u64)
    }
}

impl Default for AnalogErrors {
    fn default() -> Self {
        AnalogErrors::TYPICAL
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn typical_delay_is_three_cycles_at_170_mhz() {
        // 17 ns x 170 MHz = 2.89 cycles, rounded up.
        assert_eq!(AnalogErrors::TYPICAL.comp_delay_cycles(), 3);
        assert_eq!(AnalogErrors::IDEAL.comp_delay_cycles(), 0);
        let w = AnalogErrors::worst(-1.0);
        assert!(w.comp_offset_v < 0.0 && w.dac_offset_v < 0.0 && w.opamp_offset_v < 0.0);
        assert_eq!(w.comp_delay_cycles(), 5);
        assert_eq!(AnalogErrors::default(), AnalogErrors::TYPICAL);
    }
}
