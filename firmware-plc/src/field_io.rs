//! Field I/O through ST's X-NUCLEO-PLC01A1 shield (issue 33): eight 24 V inputs read from
//! its CLT01-38SQ7 and eight 24 V high-side outputs written to its VNI8200XP, both over
//! one SPI bus. Every frame, check bit and fault bit is taken from `docs/field-io.md`,
//! which names the datasheet section or driver each comes from.
//!
//! * [`clt01`], [`vni8200`]: the chips' frames, encoded and decoded with their check bits.
//! * [`shield`]: the policy over a [`shield::SpiPort`] (the board's bytes and pins):
//!   retry a failed check once then trip, outputs off (OUT_EN low) first on a trip or when
//!   the image is all off, the trip latched until the next RUN.

pub mod clt01;
pub mod shield;
pub mod vni8200;

pub use shield::{Shield, SpiPort};

/// A trip of the field I/O, with its fault-log code (`docs/field-io.md`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FieldFault {
    /// An output channel in over-temperature, or the output chip's case warning.
    OutputOvertemp,
    /// The 24 V field supply lost or low (input under-voltage, output power good or
    /// DC-DC feedback).
    SupplyLost,
    /// The input chip in over-temperature.
    InputOvertemp,
    /// A frame failed its check twice in a row.
    FrameCheck,
}

impl FieldFault {
    /// Its fault-log code.
    pub const fn code(self) -> u8 {
        use shared_protocol::service as s;
        match self {
            FieldFault::OutputOvertemp => s::FIELD_FAULT_OVT,
            FieldFault::SupplyLost => s::FIELD_FAULT_24V,
            FieldFault::InputOvertemp => s::FIELD_FAULT_INT,
            FieldFault::FrameCheck => s::FIELD_FAULT_SPI,
        }
    }
}
