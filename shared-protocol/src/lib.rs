//! Shared between the PLC image, the drive image and hil-sim.
//!
//! * [`program`]: the user program model (both sections), its compact binary line encoding,
//!   the verifier and the `.plc` text assembler/disassembler.
//! * [`link`]: the PLC-drive UART wire format (framing, CRC, messages).
//!
//! `no_std`, no allocation, never panics on any input.
#![cfg_attr(not(test), no_std)]
// The cores touch no registers: `unsafe` belongs to the board binaries only.
#![forbid(unsafe_code)]
#![cfg_attr(
    not(test),
    deny(
        clippy::unwrap_used,
        clippy::expect_used,
        clippy::indexing_slicing,
        clippy::panic
    )
)]

pub mod link;
pub mod program;
pub mod units;
