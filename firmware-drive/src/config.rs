//! Build-time/board-time configuration of the drive core (not part of the user program).

use crate::comparators::{BoardProfile, SOURCE_SENSORS};

/// Why the MCU last started; the board reads it from the reset flags (RCC_CSR). A
/// watchdog reset is reported as fault `WDG` after boot. Shared with the PLC board:
/// `shared_protocol::supervision`.
pub use shared_protocol::supervision::ResetCause;

/// Board and safety parameters. `Default` is the B-G431B-ESC1 / NUCLEO-G431RB setup.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DriveConfig {
    /// TIM1 kernel clock (CK_INT), Hz.
    pub timer_clock_hz: u32,
    /// Requested dead time inserted at every transition of a leg, ns.
    pub dead_time_ns: u32,
    /// The dead time never goes below this, whatever `dead_time_ns` says (power-stage
    /// datasheet limit), ns.
    pub min_dead_time_ns: u32,
    /// Duties of 1..=this many counts become 0 and of N-this..N-1 become N (program.md 4.3).
    pub min_pulse_counts: u16,
    /// Min-max (third-harmonic equivalent) injection: raises the linear range of the
    /// modulation index from 1.0 to 1.1547. Off by default (the source did plain sine PWM,
    /// and the documented V/f ratio assumes it).
    pub min_max_injection: bool,
    /// Switching frequency before the program's `PWF` has run, Hz.
    pub default_pwm_hz: u16,
    /// The board: its comparators (which signal, direction, DAC), how its sensors scale
    /// (`measure::SensorScaling`) and its analog front end (`front_end`). `Default` keeps
    /// the source's sensors (the host simulator's reference rig); the image runs
    /// [`DriveConfig::image`], whose board is [`IMAGE_BOARD`] (`docs/drive-core.md`,
    /// "Board profiles").
    pub board: &'static BoardProfile,
    /// Hardware overcurrent threshold while the program sets no `I>>` (the source's
    /// trimmer as delivered), 0.01 A.
    pub oc_hw_default_centiamps: u16,
    /// Hardware overvoltage threshold while the program sets no `U>>`, V.
    pub ov_hw_default_volts: u16,
}

/// The board profile the firmware image is built for: the bare B-G431B-ESC1 (the board
/// users flash), or with the cargo feature `source-sensors` the source's ±10 A / 0-45 V
/// sensors on the ESC1's pins (a carrier board).
#[cfg(not(feature = "source-sensors"))]
pub const IMAGE_BOARD: &BoardProfile = &crate::comparators::B_G431B_ESC1;
/// The board profile the firmware image is built for (feature `source-sensors`).
#[cfg(feature = "source-sensors")]
pub const IMAGE_BOARD: &BoardProfile = &SOURCE_SENSORS;

impl DriveConfig {
    /// The configuration the firmware image runs: the defaults on [`IMAGE_BOARD`].
    pub fn image() -> Self {
        DriveConfig {
            board: IMAGE_BOARD,
            ..DriveConfig::default()
        }
    }
}

impl Default for DriveConfig {
    fn default() -> Self {
        DriveConfig {
            timer_clock_hz: 170_000_000,
            dead_time_ns: 1000,
            min_dead_time_ns: 500,
            min_pulse_counts: 4,
            min_max_injection: false,
            default_pwm_hz: 16_000,
            board: &SOURCE_SENSORS,
            oc_hw_default_centiamps: 300,
            ov_hw_default_volts: 40,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::comparators::B_G431B_ESC1;

    #[test]
    fn the_image_runs_the_board_of_its_build() {
        let expected = if cfg!(feature = "source-sensors") {
            &SOURCE_SENSORS
        } else {
            &B_G431B_ESC1
        };
        assert_eq!(DriveConfig::image().board, expected);
        // The host simulator's reference rig keeps the source's sensors.
        assert_eq!(DriveConfig::default().board, &SOURCE_SENSORS);
        assert_eq!(
            DriveConfig {
                board: &SOURCE_SENSORS,
                ..DriveConfig::image()
            },
            DriveConfig::default()
        );
    }
}
