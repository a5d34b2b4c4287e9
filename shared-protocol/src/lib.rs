//! Shared between the PLC image, the drive image and hil-sim.
//!
//! * [`program`]: the user program model (both sections), its compact binary line encoding,
//!   the verifier and the `.plc` text assembler/disassembler.
//! * [`link`]: the PLC-drive UART wire format (framing, CRC, messages).
//! * [`fault`] and [`drive_state`]: the drive's vocabulary (fault codes with their names
//!   and texts, hardware-break causes, operating states), one copy for both images and
//!   hil-sim. The Q count is [`program::Q_COUNT`].
//! * [`service`]: the PLC's service port to a PC (messages on the link's frame codec).
//! * [`safety`]: the safety functions (NOT RATED), their settings and the parameter
//!   signature (safety.md).
//!
//! `no_std`, no allocation, never panics on any input.
#![cfg_attr(not(test), no_std)]
// The cores touch no registers: `unsafe` belongs to the image crates only.
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

pub mod crc16;
pub mod crc32;
pub mod drive_state;
pub mod fault;
pub mod link;
pub mod program;
pub mod rate_limit;
pub mod safety;
pub mod service;
pub mod shift;
pub mod supervision;
pub mod units;
