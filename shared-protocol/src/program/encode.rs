//! The compact binary form of one program line, shared by the EEPROM image and the link
//! download so that both carry exactly the same bytes.
//!
//! # Layout ([`LINE_BYTES`] = 4)
//!
//! One line is a big-endian `u32` (byte 0 is the most significant):
//!
//! | bits  | field | values |
//! | ----- | ----- | ------ |
//! | 31-24 | mnemonic code | the `repr(u8)` discriminant of [`Mnemonic`]; 0 = empty line (only in [`encode_slot`]/[`decode_slot`]) |
//! | 23-21 | operand kind | 0 none, 1 `D`, 2 `O`, 3 `B`, 4 `A`, 5 `K`, 6 `Q`, 7 named |
//! | 20-14 | operand index | area index 0..=99; for kind 7 the named operand's code (see below); 0 for kind 0 |
//! | 13-0  | constant | 0..=9999; must be 0 unless the operand is `K` |
//!
//! Named operand codes (kind 7): 0 `COM`, 1 `VLT`, 2 `AMP`, 3 `PW1`, 4 `PW3`, 5 `PW5`,
//! 6 `FRQ`, 7 `UDC`, 8 `IMX`, 9 `FLT`, 10 `DIR`, 11 `RDY`, 12 `FLB`, 13 `IHW`, 14 `UHW`,
//! then the safety operands (safety.md, appended): 15 + n the safety function of bit n
//! (15 `STO` .. 26 `SLA`), 27 `SDC`, 28 `SFT`, 29 `SFP`.
//!
//! Example: `LD K00 0100` = `01 A0 00 64`; `150 LET B03` = `0B 60 C0 00`.
//!
//! Four bytes per line means 16 lines per 64-byte EEPROM page and a 4000-byte image for
//! the whole program. A line decodes only in its canonical form (no stray bits, no
//! constant without `K`), so equal instructions always have equal bytes and image CRCs.
//! Erased EEPROM (`FF FF FF FF`) is a decode error, not an empty line. Area ranges
//! (`D16`) and section rules are the verifier's job, not the decoder's: a decoded line can
//! still fail [`super::verify_line`].

use super::model::{Instruction, Mnemonic, Operand, CONSTANT_MAX};
use super::operand::OperandClass;
use crate::safety::SafetyFunction;

/// Bytes per encoded line.
pub const LINE_BYTES: usize = 4;

const KIND_NONE: u32 = 0;
const KIND_NAMED: u32 = 7;
const KIND_SHIFT: u32 = 21;
const INDEX_SHIFT: u32 = 14;
const INDEX_MASK: u32 = 0x7F;
const CONSTANT_MASK: u32 = 0x3FFF;
/// Largest area index the text format can express (two digits).
const INDEX_MAX: u32 = 99;

/// Named operands by their code (kind 7).
const NAMED: [Operand; 30] = [
    Operand::Com,
    Operand::Vlt,
    Operand::Amp,
    Operand::Pw1,
    Operand::Pw3,
    Operand::Pw5,
    Operand::Frq,
    Operand::Udc,
    Operand::Imx,
    Operand::Flt,
    Operand::Dir,
    Operand::Rdy,
    Operand::Flb,
    Operand::Ihw,
    Operand::Uhw,
    Operand::Sf(SafetyFunction::Sto),
    Operand::Sf(SafetyFunction::Ss1),
    Operand::Sf(SafetyFunction::Ss2),
    Operand::Sf(SafetyFunction::Sos),
    Operand::Sf(SafetyFunction::Sl1),
    Operand::Sf(SafetyFunction::Sl2),
    Operand::Sf(SafetyFunction::Sl3),
    Operand::Sf(SafetyFunction::Sl4),
    Operand::Sf(SafetyFunction::Sli),
    Operand::Sf(SafetyFunction::Sdp),
    Operand::Sf(SafetyFunction::Sdn),
    Operand::Sf(SafetyFunction::Sla),
    Operand::Sdc,
    Operand::Sft,
    Operand::Sfp,
];

/// Why bytes are not a line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DecodeError {
    /// Fewer or more than [`LINE_BYTES`] bytes.
    Length(usize),
    /// Mnemonic code 0: an empty line where an instruction was required.
    Empty,
    /// No mnemonic has this code (255: erased EEPROM).
    UnknownMnemonic(u8),
    /// Named-operand code without an operand.
    UnknownNamedOperand(u8),
    /// Area index above 99.
    Index(u8),
    /// Index bits set although the line has no operand.
    IndexWithoutOperand,
    /// Constant above 9999.
    Constant(u16),
    /// Non-zero constant with an operand other than `K`.
    ConstantWithoutK,
}

impl core::error::Error for DecodeError {}

impl core::fmt::Display for DecodeError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            DecodeError::Length(n) => write!(f, "{n} bytes, a line is {LINE_BYTES}"),
            DecodeError::Empty => f.write_str("empty line"),
            DecodeError::UnknownMnemonic(c) => write!(f, "unknown mnemonic code {c}"),
            DecodeError::UnknownNamedOperand(c) => write!(f, "unknown named operand code {c}"),
            DecodeError::Index(i) => write!(f, "operand index {i} above 99"),
            DecodeError::IndexWithoutOperand => f.write_str("operand index without an operand"),
            DecodeError::Constant(c) => write!(f, "constant {c} above 9999"),
            DecodeError::ConstantWithoutK => f.write_str("constant without a K operand"),
        }
    }
}

fn kind_of(op: Option<&Operand>) -> (u32, u32) {
    let Some(op) = op else {
        return (KIND_NONE, 0);
    };
    let class = op.class();
    if class.is_area() {
        // D=1 .. Q=6 follow the class order D, O, B, A, K, Q.
        (class as u32 + 1, u32::from(op.index()))
    } else {
        let code = NAMED.iter().position(|n| n == op).unwrap_or(0);
        (KIND_NAMED, code as u32)
    }
}

/// Encode one instruction.
///
/// Exact for every instruction the verifier accepts (`decode_line(&encode_line(i)) ==
/// Ok(i)`); fields beyond their bit width are masked, which the decoder then rejects or
/// reads differently.
pub fn encode_line(i: &Instruction) -> [u8; LINE_BYTES] {
    let (kind, index) = kind_of(i.operand.as_ref());
    let word = (u32::from(i.mnemonic.code()) << 24)
        | (kind << KIND_SHIFT)
        | ((index & INDEX_MASK) << INDEX_SHIFT)
        | (u32::from(i.constant) & CONSTANT_MASK);
    word.to_be_bytes()
}

/// Decode one line; any bytes give a value or an error, never a panic.
pub fn decode_line(b: &[u8]) -> Result<Instruction, DecodeError> {
    let bytes: [u8; LINE_BYTES] = b.try_into().map_err(|_| DecodeError::Length(b.len()))?;
    let word = u32::from_be_bytes(bytes);
    let [code, ..] = bytes;
    if code == 0 {
        return Err(DecodeError::Empty);
    }
    let mnemonic = Mnemonic::from_code(code).ok_or(DecodeError::UnknownMnemonic(code))?;
    let kind = (word >> KIND_SHIFT) & 0x7;
    let index = (word >> INDEX_SHIFT) & INDEX_MASK;
    let constant = (word & CONSTANT_MASK) as u16;
    let operand = match kind {
        KIND_NONE if index != 0 => return Err(DecodeError::IndexWithoutOperand),
        KIND_NONE => None,
        KIND_NAMED => Some(
            *NAMED
                .get(index as usize)
                .ok_or(DecodeError::UnknownNamedOperand(index as u8))?,
        ),
        _ if index > INDEX_MAX => return Err(DecodeError::Index(index as u8)),
        area => {
            let class = OperandClass::ALL
                .get(area as usize - 1)
                .copied()
                .unwrap_or(OperandClass::D);
            Some(class.operand_unchecked_range(index as u8))
        }
    };
    if constant > CONSTANT_MAX {
        return Err(DecodeError::Constant(constant));
    }
    if constant != 0 && !operand.is_some_and(|o| o.is_k()) {
        return Err(DecodeError::ConstantWithoutK);
    }
    Ok(Instruction {
        mnemonic,
        operand,
        constant,
    })
}

/// Encode a line that may be empty (all zero bytes), as stored in program images.
pub fn encode_slot(line: Option<&Instruction>) -> [u8; LINE_BYTES] {
    line.map_or([0; LINE_BYTES], encode_line)
}

/// Decode a line that may be empty: all-zero bytes are `None`; a zero mnemonic with other
/// bits set, or any other bad line, is an error.
pub fn decode_slot(b: &[u8]) -> Result<Option<Instruction>, DecodeError> {
    if b.len() == LINE_BYTES && b.iter().all(|&x| x == 0) {
        return Ok(None);
    }
    decode_line(b).map(Some)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ins(mnemonic: Mnemonic, operand: Option<Operand>, constant: u16) -> Instruction {
        Instruction {
            mnemonic,
            operand,
            constant,
        }
    }

    #[test]
    fn documented_examples() {
        assert_eq!(
            encode_line(&ins(Mnemonic::Ld, Some(Operand::K(0)), 100)),
            [0x01, 0xA0, 0x00, 0x64]
        );
        assert_eq!(
            encode_line(&ins(Mnemonic::Let, Some(Operand::B(3)), 0)),
            [0x0B, 0x60, 0xC0, 0x00]
        );
    }

    #[test]
    fn every_operand_kind_round_trips() {
        let ops = [
            Some(Operand::D(7)),
            Some(Operand::O(5)),
            Some(Operand::B(99)),
            Some(Operand::A(3)),
            Some(Operand::Q(63)),
            None,
        ];
        for op in ops {
            let i = ins(Mnemonic::Wr, op, 0);
            assert_eq!(decode_line(&encode_line(&i)), Ok(i));
        }
        for n in NAMED {
            let i = ins(Mnemonic::Ld, Some(n), 0);
            assert_eq!(decode_line(&encode_line(&i)), Ok(i));
        }
        let k = ins(Mnemonic::Pwf, Some(Operand::K(99)), 9999);
        assert_eq!(decode_line(&encode_line(&k)), Ok(k));
    }

    #[test]
    fn rejects_non_canonical_and_garbage() {
        assert_eq!(
            decode_line(&[0xFF; 4]),
            Err(DecodeError::UnknownMnemonic(255))
        );
        assert_eq!(decode_line(&[0; 4]), Err(DecodeError::Empty));
        assert_eq!(decode_line(&[1, 2, 3]), Err(DecodeError::Length(3)));
        assert_eq!(
            decode_line(&[0x01, 0x00, 0x40, 0x00]),
            Err(DecodeError::IndexWithoutOperand)
        );
        // D with index 100.
        assert_eq!(
            decode_line(&[0x01, 0x39, 0x00, 0x00]),
            Err(DecodeError::Index(100))
        );
        // Named code 13 is IHW; 29 is the first unused one (15-28: safety.md's operands).
        assert_eq!(
            decode_line(&[0x01, 0xE3, 0x40, 0x00]),
            Ok(Instruction {
                mnemonic: Mnemonic::Ld,
                operand: Some(Operand::Ihw),
                constant: 0
            })
        );
        assert_eq!(
            decode_line(&[0x01, 0xE3, 0xC0, 0x00]),
            Ok(Instruction {
                mnemonic: Mnemonic::Ld,
                operand: Some(Operand::Sf(SafetyFunction::Sto)),
                constant: 0
            })
        );
        assert_eq!(
            decode_line(&[0x01, 0xE7, 0x40, 0x00]),
            Ok(Instruction {
                mnemonic: Mnemonic::Ld,
                operand: Some(Operand::Sfp),
                constant: 0
            })
        );
        assert_eq!(
            decode_line(&[0x01, 0xE7, 0x80, 0x00]),
            Err(DecodeError::UnknownNamedOperand(30))
        );
        // K00 with constant 10000.
        assert_eq!(
            decode_line(&[0x01, 0xA0, 0x27, 0x10]),
            Err(DecodeError::Constant(10000))
        );
        // Q00 with constant 1.
        assert_eq!(
            decode_line(&[0x01, 0xC0, 0x00, 0x01]),
            Err(DecodeError::ConstantWithoutK)
        );
    }

    #[test]
    fn slots() {
        assert_eq!(encode_slot(None), [0; 4]);
        assert_eq!(decode_slot(&[0; 4]), Ok(None));
        assert_eq!(
            decode_slot(&[0, 0, 0, 1]),
            Err(DecodeError::Empty),
            "zero mnemonic with bits set is not an empty line"
        );
        let i = ins(Mnemonic::Lcd, None, 0);
        assert_eq!(decode_slot(&encode_slot(Some(&i))), Ok(Some(i)));
    }
}
