//! The CLT01-38SQ7's 16-bit SPI frame (the shield's eight 24 V inputs), as
//! `docs/field-io.md` "CLT01-38SQ7" gives it: `IN8..IN1 /UVA /OTA PC1 PC2 PC3 PC4 0 1`,
//! MSB first.

/// What one good frame says.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct InputFrame {
    /// Bit n = input n + 1 (D0n), 1 = on.
    pub inputs: u8,
    /// The field supply's under-voltage alarm (/UVA low).
    pub under_voltage: bool,
    /// The chip's over-temperature alarm (/OTA low).
    pub over_temperature: bool,
}

/// A frame whose check bits do not match: never used.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CheckFailed(pub u16);

const NOT_UVA: u16 = 1 << 7;
const NOT_OTA: u16 = 1 << 6;
/// PC1..PC4 in bits 5..2.
const CHECK_MASK: u16 = 0b0011_1100;
/// The last two bits: `0 1`.
const STOP_MASK: u16 = 0b11;
const STOP_BITS: u16 = 0b01;

/// PC1..PC4 of `inputs`, in their frame positions (bits 5..2): each the inverted parity
/// of its inputs (PC1 all eight, PC2 IN5-IN8, PC3 IN1-IN4, PC4 IN3-IN6).
pub const fn check_bits(inputs: u8) -> u16 {
    inverted_parity(inputs, 5)
        | inverted_parity(inputs & 0xF0, 4)
        | inverted_parity(inputs & 0x0F, 3)
        | inverted_parity(inputs & 0x3C, 2)
}

/// `1 << bit` when `x` has an even number of ones.
const fn inverted_parity(x: u8, bit: u16) -> u16 {
    if x.count_ones() % 2 == 1 {
        0
    } else {
        1 << bit
    }
}

/// The frame the chip shifts out for `frame` (the emulator's model and the tests use
/// it; the firmware only decodes).
pub const fn encode(frame: InputFrame) -> u16 {
    let mut w = (frame.inputs as u16) << 8;
    if !frame.under_voltage {
        w |= NOT_UVA;
    }
    if !frame.over_temperature {
        w |= NOT_OTA;
    }
    w | check_bits(frame.inputs) | STOP_BITS
}

/// The inputs and alarms of `word`, if its check bits and stop bits are right.
pub const fn decode(word: u16) -> Result<InputFrame, CheckFailed> {
    let inputs = (word >> 8) as u8;
    if word & CHECK_MASK != check_bits(inputs) || word & STOP_MASK != STOP_BITS {
        return Err(CheckFailed(word));
    }
    Ok(InputFrame {
        inputs,
        under_voltage: word & NOT_UVA == 0,
        over_temperature: word & NOT_OTA == 0,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn all_inputs_off_healthy_is_the_documented_word() {
        // IN = 0: every parity even, so PC1..PC4 = 1; /UVA = /OTA = 1; stop bits 01.
        assert_eq!(encode(InputFrame::default()), 0b0000_0000_1111_1101);
    }

    #[test]
    fn in1_alone_flips_pc1_and_pc3_only() {
        let w = encode(InputFrame {
            inputs: 0x01,
            ..Default::default()
        });
        assert_eq!(w, 0x0100 | 0b1100_0000 | 0b0001_0100 | 0b01);
    }

    #[test]
    fn alarms_are_active_low() {
        let f = decode(0b0000_0000_0011_1101).unwrap();
        assert!(f.under_voltage && f.over_temperature);
        let f = decode(0b0000_0000_1011_1101).unwrap();
        assert!(!f.under_voltage && f.over_temperature);
    }

    #[test]
    fn a_stuck_miso_line_never_decodes() {
        assert_eq!(decode(0x0000), Err(CheckFailed(0x0000)));
        assert_eq!(decode(0xFFFF), Err(CheckFailed(0xFFFF)));
    }

    proptest! {
        #[test]
        fn encode_then_decode_round_trips(inputs: u8, uv: bool, ot: bool) {
            let f = InputFrame { inputs, under_voltage: uv, over_temperature: ot };
            prop_assert_eq!(decode(encode(f)), Ok(f));
        }

        #[test]
        fn every_single_bit_error_in_the_inputs_or_check_bits_is_caught(
            inputs: u8, uv: bool, ot: bool, bit in prop::sample::select(vec![15u32, 14, 13, 12, 11, 10, 9, 8, 5, 4, 3, 2, 1, 0]),
        ) {
            let w = encode(InputFrame { inputs, under_voltage: uv, over_temperature: ot });
            prop_assert!(decode(w ^ (1 << bit)).is_err());
        }

        #[test]
        fn decode_accepts_only_what_encode_makes(word: u16) {
            if let Ok(f) = decode(word) {
                prop_assert_eq!(encode(f), word);
            }
        }
    }
}
