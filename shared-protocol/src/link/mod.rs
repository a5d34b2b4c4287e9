//! The PLC-drive UART link (link.md): wire format and both endpoints, sans-IO.
//!
//! * [`frame`]: COBS framing with a 0x00 delimiter, CRC-32C, frame header (seq, ack).
//! * [`message`]: every message of both directions (postcard + serde).
//! * [`plc_decode`]: the drive's decoder of the PLC's frames, written out (postcard's
//!   format, checked against postcard's decoder). It stays next to [`wire`]: the drive
//!   decoding with `wire`'s serde decoder instead was 892 B larger (53 788 -> 54 680 B of
//!   flash, `CI_STEPS="build_firmware sizes" bash .ci/run`).
//! * [`wire`]: postcard's format written by a serializer that is small in flash.
//! * [`rx_ring`]: the reader's side of a DMA-filled receive ring (the boards' receiver).
//! * [`reliable`]: sequencing, acknowledgement, go-back-N retransmission.
//! * [`pump`]: the loop between a UART and an endpoint (boards and hil-sim), with deadlines.
//! * [`session`]: what both endpoints share (frame reader, transmit window, sequencing,
//!   stall and loss timers, counters, encoding of what goes out).
//! * [`plc::PlcLink`] and [`drive::DriveLink`]: the two endpoint state machines; the
//!   firmware crates re-export them as `firmware_plc::link` and `firmware_drive::link`.
//! * `channel`, `line` and `pair` (feature `sim`): a byte-timed, impaired in-memory UART,
//!   the line of two such wires with the link tasks' wake-up rule, and the co-simulation
//!   rig that steps two link tasks (endpoints or applications, each with its pump) over
//!   it; for tests, benchmarks and hil-sim, never in the images (`docs/cosim.md`).
//!
//! The full description (frame layout, messages, timing, decisions) is `docs/link.md`
//! in this crate.

#[cfg(any(test, feature = "sim"))]
pub mod channel;
pub mod config;
pub mod drive;
pub mod frame;
#[cfg(any(test, feature = "sim"))]
pub mod line;
pub mod message;
#[cfg(any(test, feature = "sim"))]
pub mod pair;
pub mod plc;
pub mod plc_decode;
pub mod pump;
pub mod reliable;
pub mod rx_ring;
pub mod session;
pub mod wire;

pub use config::LinkConfig;
pub use drive::{DriveEvent, DriveLink, DriveLinkState};
pub use frame::{FrameError, FrameReader, MAX_WIRE_FRAME};
pub use message::{
    fault_name, fault_text, AckRefusal, DownloadResult, DriveMsg, DriveState, DriveStatus,
    DriveWarning, FaultCode, PlcMsg, QValue, RejectReason, PROTOCOL_VERSION,
};
pub use plc::{CommandError, PlcEvent, PlcLink, PlcLinkState};

pub use crate::program::Q_COUNT;

/// Counters of one endpoint, for diagnostics and tests.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LinkStats {
    /// Frames that passed CRC and parsing.
    pub frames_ok: u32,
    /// Delimited byte runs that were not a valid frame (corruption, cuts, garbage).
    pub frames_bad: u32,
    /// Reliable messages received again (or out of order) and not applied.
    pub duplicates: u32,
    /// Reliable messages sent again after a timeout.
    pub retransmits: u32,
    pub frames_sent: u32,
    pub bytes_sent: u64,
    pub link_losses: u32,
    /// Line errors the UART reported (framing, noise, overrun, parity): each one drops
    /// the frame being received.
    pub line_errors: u32,
}
