//! Where a board's measured signals enter the MCU: which ADC channel reads each sampled
//! phase current, and which on-chip amplifiers (OPAMP1-3 in PGA mode) sit in front of them.
//! One table per board profile ([`crate::comparators::BoardProfile::front_end`]); the board
//! layer applies it (`board/analog.rs`) and decides nothing, hil-sim's emulator board puts
//! the profile's voltages on the pins.
//!
//! RM0440 facts the tables are checked against (unit tests below):
//! * OPAMPx_CSR.VP_SEL (§25.5.1): OPAMP1 VINP0-2 = PA1, PA3, PA7; OPAMP2 = PA7, PB14, PB0;
//!   OPAMP3 = PB0, PB13, PA1 (11 = DAC3 for OPAMP1/3, not bonded for OPAMP2 on the G431).
//! * PGA_GAIN bits 2:0 (VM_SEL = 10): 000 = 2, 001 = 4, 010 = 8, 011 = 16, 100 = 32,
//!   101 = 64. Bits 4:3 place the foot of the gain network: 00 on VSSA (output
//!   G x VINP), 01 on the VINM0 pin ("input/bias connected to VINM0", stm32-metapac 21
//!   `PgaGain::GAIN16_INPUT_VINM0` = 0x0B, embassy-stm32 0.6 `pga_biased_int`): output
//!   G x VINP - (G - 1) x VINM0, which is what a board that brings a biased shunt to VINP
//!   and VINM0 needs.
//! * With OPAINTOEN = 1 the output reaches an ADC channel internally, not the VOUT pin
//!   (PA2, PA6, PB1): OPAMP1 = ADC1_IN13, OPAMP2 = ADC2_IN16, OPAMP3 = ADC2_IN18 (RM0440
//!   ADC1/ADC2 channel tables, "VOPAMP1", "VOPAMP2", "VOPAMP3"; the same numbers as ST's
//!   `LL_ADC_CHANNEL_VOPAMPx` and embassy-stm32 0.6 `opamp.rs`).

use crate::comparators::Signal;

/// One on-chip amplifier in PGA mode.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct OpampSpec {
    /// OPAMP instance, 1..=3.
    pub opamp: u8,
    /// The signal at its non-inverting input.
    pub signal: Signal,
    /// Its non-inverting input pin (documentation and the checks; [`OpampSpec::vp_sel`]
    /// is what the board writes).
    pub vinp: &'static str,
    /// Non-inverting gain: 2, 4, 8, 16, 32 or 64.
    pub gain: u8,
    /// The gain network's foot on the VINM0 pin (PGA_GAIN bits 4:3 = 01) rather than on
    /// VSSA: the amplifier outputs G x VINP - (G - 1) x VINM0.
    pub vinm0_bias: bool,
}

impl OpampSpec {
    /// OPAMPx_CSR.VP_SEL of [`OpampSpec::vinp`]; `None`: that pin is not an input of it.
    pub fn vp_sel(&self) -> Option<u8> {
        let pins: [&str; 3] = match self.opamp {
            1 => ["PA1", "PA3", "PA7"],
            2 => ["PA7", "PB14", "PB0"],
            3 => ["PB0", "PB13", "PA1"],
            _ => return None,
        };
        pins.iter().position(|p| *p == self.vinp).map(|k| k as u8)
    }

    /// OPAMPx_CSR.PGA_GAIN: the gain (bits 2:0) and the network's foot (bits 4:3: 00 =
    /// VSSA, 01 = VINM0, [`OpampSpec::vinm0_bias`]); `None` for a gain the PGA does not
    /// have.
    pub const fn pga_gain_bits(&self) -> Option<u8> {
        let gain = match self.gain {
            2 => 0b000,
            4 => 0b001,
            8 => 0b010,
            16 => 0b011,
            32 => 0b100,
            64 => 0b101,
            _ => return None,
        };
        Some(if self.vinm0_bias {
            0b01000 | gain
        } else {
            gain
        })
    }

    /// The ADC and channel its internal output (OPAINTOEN = 1) reaches: (1 = ADC1, channel).
    pub const fn adc_channel(&self) -> Option<(u8, u8)> {
        match self.opamp {
            1 => Some((1, 13)),
            2 => Some((2, 16)),
            3 => Some((2, 18)),
            _ => None,
        }
    }
}

/// What the ADC converts for a sampled phase current.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum AdcInput {
    /// The sensor's pin directly (ADC `adc`, channel `channel`).
    Pin {
        pin: &'static str,
        adc: u8,
        channel: u8,
    },
    /// The internal output of OPAMP `opamp` (one of [`FrontEndSpec::opamps`]).
    Opamp(u8),
}

/// A board's analog front end: the amplifiers it enables and what the ADC reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FrontEndSpec {
    /// Amplifiers to enable (PGA mode, output to the ADC internally), in any order.
    pub opamps: &'static [OpampSpec],
    /// Phase current a: ADC1, first injected rank.
    pub current_a: AdcInput,
    /// Phase current b: ADC2, first injected rank.
    pub current_b: AdcInput,
}

impl FrontEndSpec {
    /// The amplifier `opamp` of the table.
    pub fn opamp(&self, opamp: u8) -> Option<&OpampSpec> {
        self.opamps.iter().find(|o| o.opamp == opamp)
    }

    /// The gain between the signal's sensor pin and the ADC (1 without an amplifier).
    pub fn gain_of(&self, signal: Signal) -> u16 {
        self.opamps
            .iter()
            .find(|o| o.signal == signal)
            .map_or(1, |o| u16::from(o.gain))
    }

    /// The ADC and channel an input is converted on.
    pub fn adc_channel(&self, input: AdcInput) -> Option<(u8, u8)> {
        match input {
            AdcInput::Pin { adc, channel, .. } => Some((adc, channel)),
            AdcInput::Opamp(n) => self.opamp(n)?.adc_channel(),
        }
    }
}

/// No amplifiers: the sensors' outputs on PA1 (ADC1_IN2) and PA7 (ADC2_IN4).
pub const DIRECT_PINS: FrontEndSpec = FrontEndSpec {
    opamps: &[],
    current_a: AdcInput::Pin {
        pin: "PA1",
        adc: 1,
        channel: 2,
    },
    current_b: AdcInput::Pin {
        pin: "PA7",
        adc: 2,
        channel: 4,
    },
};

/// The B-G431B-ESC1's shunt amplifiers: OPAMP1/2/3 in PGA mode, gain 16, with the foot of
/// the gain network on VINM0, on the shunt networks of U (PA1/PA3), V (PA7/PA5) and W
/// (PB0/PB2) (NuttX `boards/arm/stm32/b-g431b-esc1/src/stm32_foc.c`: "Current U+
/// OPAMP1_VINP PA1", "Current U- PA3", PGA_GAIN `0b01011` "PGA mode, non-inverting
/// configuration with external bias on VINM0"; SimpleFOC `_configureOPAMP`:
/// `OPAMP_PGA_GAIN_16_OR_MINUS_15`, `OPAMP_PGA_CONNECT_INVERTINGINPUT_IO0_BIAS`; the
/// UM2516 pin table brings each shunt's minus side to VINM0). The board biases both pins of
/// a leg from 3V3; only this mode subtracts that bias (the grounded-input mode outputs
/// 16 x 1.4 V: the rail). ADC1 reads
/// OPAMP1 (IN13), ADC2 reads OPAMP2 (IN16); OPAMP3 (ADC2 IN18) is enabled for the bench
/// check and the W comparator's future use, the core does not sample it.
pub const ESC1_PGAS: FrontEndSpec = FrontEndSpec {
    opamps: &[
        OpampSpec {
            opamp: 1,
            signal: Signal::CurrentA,
            vinp: "PA1",
            gain: 16,
            vinm0_bias: true,
        },
        OpampSpec {
            opamp: 2,
            signal: Signal::CurrentB,
            vinp: "PA7",
            gain: 16,
            vinm0_bias: true,
        },
        OpampSpec {
            opamp: 3,
            signal: Signal::CurrentC,
            vinp: "PB0",
            gain: 16,
            vinm0_bias: true,
        },
    ],
    current_a: AdcInput::Opamp(1),
    current_b: AdcInput::Opamp(2),
};

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_esc1_table_is_what_rm0440_allows() {
        let fe = &ESC1_PGAS;
        for (k, o) in fe.opamps.iter().enumerate() {
            assert_eq!(o.vp_sel(), Some(0), "{o:?}: VINP0");
            assert_eq!(
                o.pga_gain_bits(),
                Some(0b01011),
                "{o:?}: gain 16, network foot on VINM0 (metapac GAIN16_INPUT_VINM0)"
            );
            assert!(fe.opamps[..k].iter().all(|p| p.opamp != o.opamp));
        }
        assert_eq!(fe.adc_channel(fe.current_a), Some((1, 13)));
        assert_eq!(fe.adc_channel(fe.current_b), Some((2, 16)));
        assert_eq!(fe.opamp(3).and_then(|o| o.adc_channel()), Some((2, 18)));
        assert_eq!(fe.gain_of(Signal::CurrentB), 16);
        assert_eq!(fe.gain_of(Signal::DcLink), 1);
    }

    #[test]
    fn direct_pins_read_the_sensor_pins() {
        let fe = &DIRECT_PINS;
        assert_eq!(fe.adc_channel(fe.current_a), Some((1, 2)));
        assert_eq!(fe.adc_channel(fe.current_b), Some((2, 4)));
        assert_eq!(fe.gain_of(Signal::CurrentA), 1);
    }

    #[test]
    fn inputs_and_gains_outside_rm0440_are_refused() {
        let o = OpampSpec {
            opamp: 1,
            signal: Signal::CurrentA,
            vinp: "PB0",
            gain: 3,
            vinm0_bias: false,
        };
        assert_eq!(o.vp_sel(), None);
        assert_eq!(o.pga_gain_bits(), None);
        let grounded = OpampSpec { gain: 16, ..o };
        assert_eq!(grounded.pga_gain_bits(), Some(0b00011));
        let o = OpampSpec { opamp: 4, ..o };
        assert_eq!(o.adc_channel(), None);
        assert_eq!(
            OpampSpec {
                opamp: 3,
                vinp: "PA1",
                ..o
            }
            .vp_sel(),
            Some(2)
        );
    }
}
