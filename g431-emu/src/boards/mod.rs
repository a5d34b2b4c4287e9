//! The boards around the emulated MCUs, built from the boards' documents.
//!
//! A board model turns physical quantities that the host gives it (phase currents in A,
//! DC-link volts, the state of an external wire, a potentiometer's position) into what the
//! MCU's pins see (volts, driven levels), and says what the MCU's outputs drive on the
//! board. Every constant comes from a board document and is cited next to it and in
//! `docs/models.md` ("Boards"): the board's user manual and schematic, public ports of the
//! same board, the datasheets of the parts on it. Where no document we could reach gives a
//! value, the constant says so and takes the conservative value (the one that hides
//! nothing from the firmware). **No board model takes a constant from the firmware**: the
//! emulator is a second opinion on the firmware's assumptions, not a copy of them (CI step
//! `board_models` greps these files).
//!
//! * [`b_g431b_esc1`]: the bare B-G431B-ESC1 (the drive board).
//! * [`source_sensors`]: the source's sensors on a carrier around the ESC1's pins (the
//!   drive image's `source-sensors` build).
//! * [`nucleo_g431rb`]: the NUCLEO-G431RB (the PLC board).

pub mod b_g431b_esc1;
pub mod nucleo_g431rb;
pub mod source_sensors;

/// Both boards' MCU supply and ADC/DAC reference, V: VDD = VDDA = VREF+ = 3V3 (UM2516 pin
/// table: VREF+, VDDA, VDDx on 3V3; UM2505: the NUCLEO's MCU runs from its 3V3 regulator).
pub const VDDA_VOLTS: f64 = 3.3;

/// The drive boards an image can be built for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DriveBoardId {
    /// The bare B-G431B-ESC1.
    Esc1,
    /// The source's sensors on a carrier around the ESC1's pins.
    SourceSensors,
}

impl DriveBoardId {
    pub const ALL: [DriveBoardId; 2] = [DriveBoardId::Esc1, DriveBoardId::SourceSensors];

    /// The id a drive image names its board with: its `DRIVE_BOARD_PROFILE` symbol holds
    /// it as 8 zero-padded ASCII bytes (the image's marker format, `docs/emulator.md`). The
    /// ids are the emulator's own: an image whose marker is none of them is refused.
    pub const fn id(self) -> &'static str {
        match self {
            DriveBoardId::Esc1 => "esc1",
            DriveBoardId::SourceSensors => "source",
        }
    }

    /// What a user calls it (summaries, CSV headers).
    pub const fn name(self) -> &'static str {
        match self {
            DriveBoardId::Esc1 => "B-G431B-ESC1",
            DriveBoardId::SourceSensors => "source sensors on B-G431B-ESC1 pins",
        }
    }

    /// The board whose id the marker bytes hold (zero-padded, at most 8 bytes).
    pub fn from_marker(marker: &[u8]) -> Option<Self> {
        let end = marker.iter().position(|&b| b == 0).unwrap_or(marker.len());
        let text = marker.get(..end)?;
        Self::ALL
            .into_iter()
            .find(|b| b.id().as_bytes() == text && text.len() <= 8)
    }

    /// The board with this id (`"esc1"`, `"source"`).
    pub fn from_id(id: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|b| b.id() == id)
    }
}

/// The physical quantities of the power stage that a drive board senses.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PowerStageQuantities {
    /// Current of each inverter leg into the motor, A (legs U, V, W).
    pub phase_currents_a: [f64; 3],
    /// DC-link voltage, V.
    pub dc_link_v: f64,
}

/// An external wire brought to a pin (e.g. the rig's STO signal): what the far end does.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ExternalWire {
    /// The far end drives the wire high (through a low impedance).
    DrivenHigh,
    /// The far end pulls the wire to 0 V hard (a contact to ground, a saturated
    /// transistor): it wins against a logic output on the same net.
    DrivenLow,
    /// Nothing drives it: the wire is broken or the far end's contact is open.
    Open,
}

/// A net's level and whether two drivers fight on it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NetLevel {
    pub level: crate::periph::gpio::External,
    /// Two sources drive the net to different levels (an electrical fault the silicon
    /// survives only by current limiting; reported by the host).
    pub contention: bool,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn markers_name_the_boards() {
        assert_eq!(
            DriveBoardId::from_marker(b"esc1\0\0\0\0"),
            Some(DriveBoardId::Esc1)
        );
        assert_eq!(
            DriveBoardId::from_marker(b"source\0\0"),
            Some(DriveBoardId::SourceSensors)
        );
        assert_eq!(DriveBoardId::from_marker(b"esc2\0\0\0\0"), None);
        assert_eq!(DriveBoardId::from_marker(b""), None);
        assert_eq!(DriveBoardId::from_id("esc1"), Some(DriveBoardId::Esc1));
    }
}
