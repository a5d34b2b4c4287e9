//! The physical ranges of scenario values (hil-sim/docs/cli.md "Scenario value ranges"): a rig of
//! this class (a small induction motor on a low-voltage inverter, a small lift). Outside
//! them a value is a typo or a plant the explicit integrator cannot follow
//! (`friction_nms = 100` on the default inertia diverged and printed `speed = NaN`), and
//! the scenario is refused naming the key and its range.

use anyhow::{bail, Result};

/// `(key, lowest, highest, unit)`; `[plant]` keys and `[[event]]` plant changes.
pub const PLANT_RANGES: &[(&str, f64, f64, &str)] = &[
    ("dc_link_v", 0.0, 1000.0, "V"),
    ("load_torque_nm", 0.0, 100.0, "N m"),
    ("inertia_kgm2", 1e-6, 10.0, "kg m2"),
    ("oc_hw_a", 0.01, 1000.0, "A"),
    ("ov_hw_v", 1.0, 2000.0, "V"),
    ("dc_capacitor_uf", 1.0, 1e6, "uF"),
    ("brake_resistor_ohm", 0.1, 1e9, "ohm"),
    ("supply_r_ohm", 1e-4, 1000.0, "ohm"),
    ("friction_nms", 0.0, 0.1, "N m s"),
    ("rs_ohm", 1e-3, 1000.0, "ohm"),
    ("rr_ohm", 1e-3, 1000.0, "ohm"),
    ("lls_h", 1e-6, 10.0, "H"),
    ("llr_h", 1e-6, 10.0, "H"),
    ("lm_h", 1e-5, 100.0, "H"),
    ("load_r_ohm", 1e-3, 1e6, "ohm"),
    ("load_l_h", 1e-6, 10.0, "H"),
];

/// `[lift]` keys.
pub const LIFT_RANGES: &[(&str, f64, f64, &str)] = &[
    ("unbalance_kg", -1000.0, 1000.0, "kg"),
    ("load_kg", 0.0, 5000.0, "kg"),
    ("moving_mass_kg", 0.0, 10_000.0, "kg"),
    ("start_mm", -100_000.0, 100_000.0, "mm"),
    ("limit_low_mm", -100_000.0, 100_000.0, "mm"),
    ("limit_high_mm", -100_000.0, 100_000.0, "mm"),
    ("floor_pitch_mm", 1.0, 100_000.0, "mm"),
];

/// Refuses `value` of `section.key` outside its range in `ranges` (keys not listed
/// pass).
pub fn check(
    ranges: &[(&str, f64, f64, &str)],
    section: &str,
    key: &str,
    value: Option<f64>,
) -> Result<()> {
    let Some(v) = value else { return Ok(()) };
    let Some((_, lo, hi, unit)) = ranges.iter().find(|(k, ..)| *k == key) else {
        return Ok(());
    };
    if !(v.is_finite() && v >= *lo && v <= *hi) {
        bail!("{section}.{key} = {v}: outside the physical range {lo} to {hi} {unit} (hil-sim/docs/cli.md \"Scenario value ranges\")");
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_outside_physics_are_refused_naming_the_key() {
        let e = check(PLANT_RANGES, "plant", "friction_nms", Some(100.0)).unwrap_err();
        assert!(e.to_string().contains("plant.friction_nms = 100"), "{e}");
        assert!(check(PLANT_RANGES, "plant", "dc_link_v", Some(1e8)).is_err());
        assert!(check(PLANT_RANGES, "plant", "dc_link_v", Some(f64::NAN)).is_err());
        assert!(check(LIFT_RANGES, "lift", "limit_high_mm", Some(f64::INFINITY)).is_err());
        assert!(check(LIFT_RANGES, "lift", "unbalance_kg", Some(1e30)).is_err());
        assert!(check(PLANT_RANGES, "plant", "dc_link_v", Some(24.0)).is_ok());
        assert!(check(PLANT_RANGES, "plant", "dc_link_v", None).is_ok());
    }
}
