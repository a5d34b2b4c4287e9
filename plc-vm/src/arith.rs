//! P arithmetic: everything saturates at the i16 range and nothing can panic
//! (program.md 3.1: "never wraps, never panics").

/// Widened result back to i16, saturating.
fn sat(v: i32) -> i16 {
    v.clamp(i32::from(i16::MIN), i32::from(i16::MAX)) as i16
}

pub fn add(p: i16, v: i16) -> i16 {
    p.saturating_add(v)
}

pub fn sub(p: i16, v: i16) -> i16 {
    p.saturating_sub(v)
}

pub fn mul(p: i16, v: i16) -> i16 {
    p.saturating_mul(v)
}

/// Truncating division; `None` on division by zero (the caller sets P = 0 and warns).
/// `-32768 / -1` saturates to 32767.
pub fn div(p: i16, v: i16) -> Option<i16> {
    if v == 0 {
        None
    } else {
        Some(p.checked_div(v).unwrap_or(i16::MAX))
    }
}

/// `LD VLT`: DC-link ADC counts to 0.1 V (0..1023 -> 0..450), truncating toward zero.
pub fn vlt(p: i16) -> i16 {
    sat(i32::from(p) * 450 / 1023)
}

/// `LD AMP`: current-sensor ADC counts to 0.1 A (0..1023 -> -100..99), truncating
/// toward zero.
pub fn amp(p: i16) -> i16 {
    sat((i32::from(p) - 512) * 100 / 512)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn saturates_instead_of_wrapping() {
        assert_eq!(add(32000, 1000), i16::MAX);
        assert_eq!(sub(-32000, 1000), i16::MIN);
        assert_eq!(mul(300, 300), i16::MAX);
        assert_eq!(mul(-300, 300), i16::MIN);
        assert_eq!(add(5, -7), -2);
        assert_eq!(mul(-12, 11), -132);
    }

    #[test]
    fn div_truncates_toward_zero_and_flags_zero() {
        assert_eq!(div(7, 2), Some(3));
        assert_eq!(div(-7, 2), Some(-3));
        assert_eq!(div(7, -2), Some(-3));
        assert_eq!(div(i16::MIN, -1), Some(i16::MAX));
        assert_eq!(div(5, 0), None);
    }

    #[test]
    fn vlt_scales_full_range_to_45_volts() {
        assert_eq!(vlt(0), 0);
        assert_eq!(vlt(1023), 450);
        assert_eq!(vlt(512), 225); // 512*450/1023 = 225.2
        assert_eq!(vlt(i16::MAX), 14413);
        assert_eq!(vlt(-1023), -450);
    }

    #[test]
    fn amp_maps_mid_scale_to_zero() {
        assert_eq!(amp(0), -100);
        assert_eq!(amp(512), 0);
        assert_eq!(amp(1023), 99); // 99.8 truncated
        assert_eq!(amp(256), -50);
        assert_eq!(amp(i16::MIN), -6500);
        assert_eq!(amp(i16::MAX), 6299);
    }
}
