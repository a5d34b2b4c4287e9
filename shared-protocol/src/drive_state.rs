//! The drive's operating states (drive.md "States"): the drive core's state machine and
//! the state its status frame reports are the same type.

use serde::{Deserialize, Serialize};

/// BOOT -> IDLE <-> RUN; any state -> FAULT on a trip; FAULT -> IDLE on an accepted ACK.
///
/// On the wire (the status's `state`) the variant order is the byte: never reorder.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DriveState {
    /// After reset, until the first 1 ms tick has run the self-test. Also what the PLC
    /// assumes before the first status.
    #[default]
    Boot,
    /// Ready; PWM off; the drive section does not run.
    Idle,
    /// The drive section runs every 1 ms; PWM on while f >= fmn.
    Run,
    /// A fault is latched; PWM off until ACK (then IDLE, then a new RUN).
    Fault,
}

impl DriveState {
    /// Upper-case name, for the LCD and logs.
    pub const fn name(self) -> &'static str {
        match self {
            DriveState::Boot => "BOOT",
            DriveState::Idle => "IDLE",
            DriveState::Run => "RUN",
            DriveState::Fault => "FAULT",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_wire_byte_is_the_variant_order() {
        let mut buf = [0u8; 2];
        for (i, s) in [
            DriveState::Boot,
            DriveState::Idle,
            DriveState::Run,
            DriveState::Fault,
        ]
        .into_iter()
        .enumerate()
        {
            assert_eq!(postcard::to_slice(&s, &mut buf).unwrap(), [i as u8]);
        }
        assert_eq!(DriveState::default().name(), "BOOT");
    }
}
