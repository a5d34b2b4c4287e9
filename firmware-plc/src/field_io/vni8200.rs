//! The VNI8200XP's 16-bit SPI frames (the shield's eight 24 V high-side outputs), as
//! `docs/field-io.md` "VNI8200XP" gives them. Command: `IN7..IN0 0000 P2 P1 P0 nP0`;
//! answer: `F7..F0 FB_OK TWARN PC PG P2 P1 P0 nP0`; both MSB first.

/// The answer's status, from one good frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Status {
    /// Bit n: channel n in over-temperature (latched until this exchange).
    pub channel_overtemp: u8,
    /// The DC-DC's feedback is above 90 % of nominal (low at its turn-on).
    pub fb_ok: bool,
    /// The case over-temperature warning.
    pub temp_warning: bool,
    /// The previous command failed the chip's parity check and was not applied.
    pub parity_failed: bool,
    /// The supply is not good (PG set, `docs/field-io.md` on its polarity).
    pub power_fault: bool,
}

/// A frame whose check bits do not match: never used.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CheckFailed(pub u16);

const FB_OK: u16 = 1 << 7;
const TWARN: u16 = 1 << 6;
const PC: u16 = 1 << 5;
const PG: u16 = 1 << 4;
/// P2 P1 P0 nP0 in bits 3..0.
const CHECK_MASK: u16 = 0x000F;

const fn odd(x: u16) -> bool {
    x.count_ones() % 2 == 1
}

/// `P2 P1 P0 nP0` (bits 3..0) from the parities of the three groups.
const fn nibble(p0: bool, p1: bool, p2: bool) -> u16 {
    (p2 as u16) << 3 | (p1 as u16) << 2 | (p0 as u16) << 1 | !p0 as u16
}

/// The command for the output image `outputs` (bit n = channel n on): P0 over all eight,
/// P1 over IN1, IN3, IN5, IN7, P2 over IN0, IN2, IN4, IN6, nP0 = NOT P0.
pub const fn command(outputs: u8) -> u16 {
    let w = (outputs as u16) << 8;
    w | nibble(odd(w & 0xFF00), odd(w & 0xAA00), odd(w & 0x5500))
}

/// The output image a command carries, if its parity is right (the chip's own check; the
/// emulator's model uses it).
pub const fn decode_command(word: u16) -> Option<u8> {
    if word == command((word >> 8) as u8) {
        Some((word >> 8) as u8)
    } else {
        None
    }
}

/// The check bits of an answer whose bits 15..4 are `w`: P0 over F7..F0, P1 over the odd
/// bits 15..5, P2 over the even bits 14..4, nP0 = NOT P0 (ST's driver's definition,
/// `docs/field-io.md`).
const fn answer_check(w: u16) -> u16 {
    nibble(odd(w & 0xFF00), odd(w & 0xAAA0), odd(w & 0x5550))
}

/// The answer the chip shifts out for `status` (the emulator's model and the tests).
pub const fn encode_answer(status: Status) -> u16 {
    let mut w = (status.channel_overtemp as u16) << 8;
    if status.fb_ok {
        w |= FB_OK;
    }
    if status.temp_warning {
        w |= TWARN;
    }
    if status.parity_failed {
        w |= PC;
    }
    if status.power_fault {
        w |= PG;
    }
    w | answer_check(w)
}

/// The status of `word`, if its check bits are right.
pub const fn decode_answer(word: u16) -> Result<Status, CheckFailed> {
    if word & CHECK_MASK != answer_check(word & !CHECK_MASK) {
        return Err(CheckFailed(word));
    }
    Ok(Status {
        channel_overtemp: (word >> 8) as u8,
        fb_ok: word & FB_OK != 0,
        temp_warning: word & TWARN != 0,
        parity_failed: word & PC != 0,
        power_fault: word & PG != 0,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn commands_follow_the_datasheet_formulas() {
        // All off: every parity even, nP0 = 1.
        assert_eq!(command(0x00), 0x0001);
        // IN0 alone: P0 = 1, P2 = 1 (even channels), P1 = 0, nP0 = 0.
        assert_eq!(command(0x01), 0x0100 | 0b1010);
        // IN1 alone: P0 = 1, P1 = 1.
        assert_eq!(command(0x02), 0x0200 | 0b0110);
        // All on: eight ones, all parities even.
        assert_eq!(command(0xFF), 0xFF01);
    }

    #[test]
    fn a_healthy_answer_decodes() {
        let s = Status {
            fb_ok: true,
            ..Default::default()
        };
        let w = encode_answer(s);
        // F = 0, FB_OK = 1: P0 (F only) = 0, P1 (odd bits, FB_OK is bit 7) = 1, nP0 = 1.
        assert_eq!(w, 0x0080 | 0b0101);
        assert_eq!(decode_answer(w), Ok(s));
    }

    #[test]
    fn a_stuck_miso_line_never_decodes() {
        assert!(decode_answer(0x0000).is_err());
        assert!(decode_answer(0xFFFF).is_err());
    }

    proptest! {
        #[test]
        fn commands_round_trip(outputs: u8) {
            prop_assert_eq!(decode_command(command(outputs)), Some(outputs));
        }

        #[test]
        fn a_command_with_one_bit_flipped_is_refused(outputs: u8, bit in 0u32..16) {
            // Bits 7..4 are not covered by the check but must be 0.
            prop_assert_eq!(decode_command(command(outputs) ^ (1 << bit)), None);
        }

        #[test]
        fn answers_round_trip(f: u8, fb_ok: bool, tw: bool, pc: bool, pg: bool) {
            let s = Status { channel_overtemp: f, fb_ok, temp_warning: tw, parity_failed: pc, power_fault: pg };
            prop_assert_eq!(decode_answer(encode_answer(s)), Ok(s));
        }

        #[test]
        fn an_answer_with_one_bit_flipped_fails_its_check(
            f: u8, fb_ok: bool, tw: bool, pc: bool, pg: bool, bit in 0u32..16,
        ) {
            let s = Status { channel_overtemp: f, fb_ok, temp_warning: tw, parity_failed: pc, power_fault: pg };
            prop_assert!(decode_answer(encode_answer(s) ^ (1 << bit)).is_err());
        }
    }
}
