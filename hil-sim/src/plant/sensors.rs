//! Current and voltage sensors with the drive's 12-bit ADC, and the hardware comparators.
//!
//! The scaling is the source hardware's (drive.md, "Measurements"): phase currents ±10 A
//! full scale around mid-scale, DC link 0..45 V. The drive core converts counts back
//! with the same constants, so a quantisation step is 10 A / 2048 ≈ 4.9 mA and
//! 45 V / 4095 ≈ 11 mV.

/// ADC resolution of the drive MCU.
pub const ADC_BITS: u32 = 12;
/// Largest ADC count.
pub const ADC_MAX: u16 = (1 << ADC_BITS) - 1;
/// Current that reads full scale (either sign).
pub const CURRENT_FULL_SCALE_A: f64 = 10.0;
/// DC-link voltage that reads full scale.
pub const UDC_FULL_SCALE_V: f64 = 45.0;

/// One conversion of the three channels the drive reads every PWM period.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct AdcSample {
    pub i_a_counts: u16,
    pub i_b_counts: u16,
    pub u_dc_counts: u16,
}

fn quantise(x: f64) -> u16 {
    // Rounds to the nearest count and saturates like a real ADC at its rails.
    let c = x.round().clamp(0.0, f64::from(ADC_MAX));
    c as u16
}

/// ADC counts of a phase current.
pub fn current_counts(i_a: f64) -> u16 {
    let mid = f64::from(1u16 << (ADC_BITS - 1));
    quantise(mid + i_a * mid / CURRENT_FULL_SCALE_A)
}

/// ADC counts of the DC-link voltage.
pub fn udc_counts(u_v: f64) -> u16 {
    quantise(u_v / UDC_FULL_SCALE_V * f64::from(ADC_MAX))
}

/// Current a count stands for (the inverse the drive applies).
pub fn counts_to_current(c: u16) -> f64 {
    let mid = f64::from(1u16 << (ADC_BITS - 1));
    (f64::from(c) - mid) * CURRENT_FULL_SCALE_A / mid
}

/// Voltage a count stands for.
pub fn counts_to_udc(c: u16) -> f64 {
    f64::from(c) * UDC_FULL_SCALE_V / f64::from(ADC_MAX)
}

/// Why the hardware break input fired.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BreakCause {
    /// A phase current beyond the comparator threshold (drive fault OC_HW).
    Overcurrent,
    /// DC link beyond the comparator threshold (drive fault OV_HW).
    Overvoltage,
}

/// The source's trimmer-set window comparators on phases a and b and on the DC link.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Comparators {
    pub oc_hw_a: f64,
    pub ov_hw_v: f64,
}

impl Comparators {
    /// Comparator outputs: [overcurrent, overvoltage].
    pub fn levels(&self, i_a: f64, i_b: f64, u_dc: f64) -> [bool; 2] {
        [
            i_a.abs() > self.oc_hw_a || i_b.abs() > self.oc_hw_a,
            u_dc > self.ov_hw_v,
        ]
    }
}

impl BreakCause {
    pub const ALL: [BreakCause; 2] = [BreakCause::Overcurrent, BreakCause::Overvoltage];
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn current_scaling_is_mid_scale_and_saturates() {
        assert_eq!(current_counts(0.0), 2048);
        assert_eq!(current_counts(10.0), 4095);
        assert_eq!(current_counts(-10.0), 0);
        assert_eq!(current_counts(50.0), 4095);
        assert!((counts_to_current(current_counts(1.234)) - 1.234).abs() < 0.003);
    }

    #[test]
    fn voltage_scaling_covers_0_to_45_v() {
        assert_eq!(udc_counts(0.0), 0);
        assert_eq!(udc_counts(45.0), 4095);
        assert!((counts_to_udc(udc_counts(30.0)) - 30.0).abs() < 0.006);
    }

    #[test]
    fn comparators_report_the_cause() {
        let c = Comparators {
            oc_hw_a: 3.0,
            ov_hw_v: 40.0,
        };
        assert_eq!(c.levels(0.0, -3.1, 30.0), [true, false]);
        assert_eq!(c.levels(0.0, 0.0, 40.5), [false, true]);
        assert_eq!(c.levels(2.9, 2.9, 39.9), [false, false]);
    }
}
