//! The source's sensors on a carrier around the B-G431B-ESC1's pins: the drive image's
//! `source-sensors` build.
//!
//! Its document is the project's contract: \[drive.md\] `shared/spec/drive.md`
//! "Measurements" ("Phase currents a and b: sensors with +-10 A full scale ... DC-link
//! voltage: 0..45 V full scale", the source hardware's scaling) and "brake chopper"
//! (`U>`), \[hardware.md\] ("the source's sensor scaling stays available as a second board
//! profile"), and the README's drive pin map (which ESC1 pins the carrier uses). The
//! ESC1's own parts the carrier does not replace (the CAN transceiver on PA11, the LED)
//! are those of [`super::b_g431b_esc1`].

use super::{PowerStageQuantities, VDDA_VOLTS};

/// Full scale of a phase-current sensor, A: +-10 A \[drive.md\] on 0..VDDA, 0 A at mid-scale
/// (a bipolar sensor on a unipolar ADC input).
pub const CURRENT_FULL_SCALE_A: f64 = 10.0;

/// Full scale of the DC-link sensor, V: 45 V \[drive.md\] on 0..VDDA.
pub const DC_LINK_FULL_SCALE_V: f64 = 45.0;

/// The sensor outputs on the ESC1's amplifier input pins (legs U, V, W), the DC link on
/// PA0 (README pin map). The carrier leaves the VINM0 pins (PA3, PA5, PB2) unconnected.
pub const CURRENT_PINS: [&str; 3] = ["PA1", "PA7", "PB0"];
pub const DC_LINK_PIN: &str = "PA0";
/// The source's auxiliary input (`COM`) on the ESC1's potentiometer pin.
pub const AUX_PIN: &str = "PB12";

/// The brake chopper's gate, PB5, active high (README pin map; the source's chopper,
/// \[drive.md\] "the brake chopper (`U>`)"): on this carrier PB5 drives a chopper, not the
/// ESC1's BEMF dividers.
pub const BRAKE_GATE: (u8, u8) = (1, 5);

/// Volts of a current sensor's output for `i_a`.
pub fn current_volts(i_a: f64) -> f64 {
    (VDDA_VOLTS / 2.0 * (1.0 + i_a / CURRENT_FULL_SCALE_A)).clamp(0.0, VDDA_VOLTS)
}

/// Volts of the DC-link sensor's output for `u` V.
pub fn dc_link_volts(u: f64) -> f64 {
    (u / DC_LINK_FULL_SCALE_V * VDDA_VOLTS).clamp(0.0, VDDA_VOLTS)
}

/// Volts on analog pin `pin`, or `None` for a pin the carrier does not drive. `aux` is the
/// auxiliary input's position, 0..=1.
pub fn pin_volts(pin: &str, q: &PowerStageQuantities, aux: f64) -> Option<f64> {
    if let Some(k) = CURRENT_PINS.iter().position(|p| *p == pin) {
        return q.phase_currents_a.get(k).map(|&i| current_volts(i));
    }
    match pin {
        DC_LINK_PIN => Some(dc_link_volts(q.dc_link_v)),
        AUX_PIN => Some(aux.clamp(0.0, 1.0) * VDDA_VOLTS),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn full_scales() {
        assert_eq!(current_volts(0.0), 1.65);
        assert_eq!(current_volts(10.0), 3.3);
        assert_eq!(current_volts(-20.0), 0.0);
        assert!((dc_link_volts(22.5) - 1.65).abs() < 1e-12);
        let q = PowerStageQuantities {
            phase_currents_a: [0.0, 5.0, -5.0],
            dc_link_v: 45.0,
        };
        assert!((pin_volts("PA7", &q, 0.0).unwrap() - 2.475).abs() < 1e-12);
        assert_eq!(pin_volts("PA0", &q, 0.0), Some(3.3));
        assert_eq!(pin_volts("PA3", &q, 0.0), None);
    }
}
