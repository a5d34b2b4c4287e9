//! The user program model (program.md sections 1-2, shared by both MCUs and the host).
//!
//! * mnemonic: the instruction table ([`Mnemonic`]: code, text, operands, constants).
//! * model: lines, instructions, operands ([`Program`], [`Instruction`], [`Operand`]).
//! * [`encode_line`]/[`decode_line`]: the 4-byte binary line (EEPROM image, link download).
//! * [`verify()`]: what may run, and the valid choices the keypad editor offers
//!   ([`mnemonics_for`], [`operands_for`], [`constant_range`]).
//! * [`assemble`]/[`disassemble`]: the `.plc` text format.
//! * [`payload`]: a whole program's stored form (EEPROM copies, the service port's
//!   program transfers).
//! * `testing` (feature `testing`): proptest strategies for valid programs.
//!
//! The format decisions are collected in `docs/program-format.md`.

mod asm;
mod disasm;
mod encode;
mod mnemonic;
mod model;
mod operand;
pub mod payload;
mod verify;

#[cfg(test)]
mod proptests;
#[cfg(any(test, feature = "testing"))]
pub mod testing;

pub use asm::*;
pub use disasm::*;
pub use encode::*;
pub use mnemonic::*;
pub use model::*;
pub use operand::*;
pub use verify::*;
