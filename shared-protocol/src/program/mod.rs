//! The user program model (program.md sections 1-2, shared by both MCUs and the host).
//!
//! * [`model`](self): lines, instructions, operands ([`Program`], [`Instruction`]).
//! * [`encode_line`]/[`decode_line`]: the 4-byte binary line (EEPROM image, link download).
//! * [`verify`]: what may run, and the valid choices the keypad editor offers.

mod encode;
mod model;
mod operand;
mod verify;

pub use encode::*;
pub use model::*;
pub use operand::*;
pub use verify::*;
