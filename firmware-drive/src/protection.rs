//! The per-PWM-period checks (drive.md "Trips"). Limits from the program (V, 0.01 A) are
//! converted to ADC counts once, when the program sets them, so that the interrupt only
//! compares integers.

use crate::measure::{udc_counts_at_volts, AdcSample};
use shared_protocol::units::Volts;

/// The fault vocabulary is shared with the PLC and hil-sim (one copy, in
/// `shared-protocol`); re-exported here for the drive's modules.
pub use shared_protocol::fault::{FaultCode, HwBreak};

/// The program's protection settings, in ADC counts. `None` = not set (no check).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Limits {
    /// `I>` * 2048 (0.01 A): trip when |counts from zero| * 1000 exceeds it.
    oc_x2048: Option<u32>,
    /// Trip when the DC-link reading is below this (counts of `U<` V).
    uv_counts: Option<u32>,
    /// Brake on above this reading (counts of `U>` V) ...
    brake_on_above: Option<u32>,
    /// ... and off again below this one (`U>` - 1 V).
    brake_off_below: u32,
    /// Trip `OV_HW` above this reading (counts of `U>>` V).
    ov_above: Option<u32>,
}

impl Limits {
    /// No program limits yet, the overvoltage check at `U>>`.
    pub fn with_ov_hw(ov_hw: Volts) -> Self {
        let mut l = Limits::default();
        l.set_ov_hw(ov_hw);
        l
    }

    /// `U>>` in V: the software overvoltage check trips above it (0 or less: none).
    pub fn set_ov_hw(&mut self, ov_hw: Volts) {
        let v = ov_hw.0.max(0) as u32;
        self.ov_above = (v > 0).then_some(udc_counts_at_volts(v));
    }

    /// DC link above `U>>`?
    #[inline(always)]
    pub fn overvoltage(&self, s: &AdcSample) -> bool {
        match self.ov_above {
            Some(lim) => u32::from(s.u_dc) > lim,
            None => false,
        }
    }

    /// `I>` in 0.01 A (0 = no software overcurrent trip).
    pub fn set_i_max(&mut self, centiamps: u16) {
        self.oc_x2048 = (centiamps > 0).then_some(u32::from(centiamps) * 2048);
    }

    /// `U<` in V (0 = no undervoltage trip).
    pub fn set_u_min(&mut self, volts: u16) {
        self.uv_counts = (volts > 0).then_some(udc_counts_at_volts(u32::from(volts)));
    }

    /// DC link at or above `U<` + 1 V, the hysteresis of an automatic restart after `UV`
    /// (91 counts are exactly 1 V)? `U<` not set: always.
    pub fn back_above_u_min(&self, s: &AdcSample) -> bool {
        match self.uv_counts {
            Some(lim) => u32::from(s.u_dc) >= lim + 91,
            None => true,
        }
    }

    /// `U>` in V (0 = no brake chopper).
    pub fn set_u_max(&mut self, volts: u16) {
        let v = u32::from(volts);
        // counts_at(V) is exact (4095/45 = 91 counts per volt): "above V" is "> counts".
        self.brake_on_above = (volts > 0).then_some(udc_counts_at_volts(v));
        self.brake_off_below = udc_counts_at_volts(v.saturating_sub(1));
    }

    /// DC link above `U>` (the `OV` trip of a board without a chopper,
    /// `shared-protocol/docs/fault-codes.md`)? `U>` not set: never.
    #[inline(always)]
    pub fn above_u_max(&self, s: &AdcSample) -> bool {
        match self.brake_on_above {
            Some(lim) => u32::from(s.u_dc) > lim,
            None => false,
        }
    }

    /// Software overcurrent on this sample?
    #[inline(always)]
    pub fn overcurrent(&self, abs_current_counts: u32) -> bool {
        match self.oc_x2048 {
            Some(lim) => abs_current_counts * 1000 > lim,
            None => false,
        }
    }

    /// DC link below `U<`?
    #[inline(always)]
    pub fn undervoltage(&self, s: &AdcSample) -> bool {
        match self.uv_counts {
            Some(lim) => u32::from(s.u_dc) < lim,
            None => false,
        }
    }

    /// Brake-chopper state after this sample, with 1 V hysteresis.
    #[inline(always)]
    pub fn brake(&self, was_on: bool, s: &AdcSample) -> bool {
        let u = u32::from(s.u_dc);
        match self.brake_on_above {
            None => false,
            Some(on) if u > on => true,
            Some(_) => was_on && u >= self.brake_off_below,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn udc(counts: u16) -> AdcSample {
        AdcSample {
            u_dc: counts,
            ..Default::default()
        }
    }

    #[test]
    fn overcurrent_is_strictly_above_the_limit() {
        let mut l = Limits::default();
        assert!(!l.overcurrent(2048));
        l.set_i_max(200); // 2.00 A = 409.6 counts
        assert!(!l.overcurrent(409));
        assert!(l.overcurrent(410));
    }

    #[test]
    fn undervoltage_below_u_min() {
        let mut l = Limits::default();
        assert!(!l.undervoltage(&udc(0)));
        l.set_u_min(25);
        let edge = udc_counts_at_volts(25) as u16;
        assert!(l.undervoltage(&udc(edge - 1)));
        assert!(!l.undervoltage(&udc(edge)));
        assert!(f64::from(edge - 1) * 45.0 / 4095.0 < 25.0);
        assert!(f64::from(edge) * 45.0 / 4095.0 >= 25.0);
    }

    #[test]
    fn overvoltage_strictly_above_u_max_hw() {
        let mut l = Limits::default();
        assert!(!l.overvoltage(&udc(4095)));
        l.set_ov_hw(Volts(28));
        let edge = udc_counts_at_volts(28) as u16;
        assert!(!l.overvoltage(&udc(edge)));
        assert!(l.overvoltage(&udc(edge + 1)));
        assert_eq!(Limits::with_ov_hw(Volts(28)), l);
    }

    #[test]
    fn above_u_max_strictly_above_and_never_without_u_max() {
        let mut l = Limits::default();
        assert!(!l.above_u_max(&udc(4095)));
        l.set_u_max(28);
        let edge = udc_counts_at_volts(28) as u16;
        assert!(!l.above_u_max(&udc(edge)));
        assert!(l.above_u_max(&udc(edge + 1)));
        l.set_u_max(0);
        assert!(!l.above_u_max(&udc(4095)));
    }

    #[test]
    fn brake_has_one_volt_hysteresis() {
        let mut l = Limits::default();
        l.set_u_max(35);
        let on = udc_counts_at_volts(35) as u16;
        let off = udc_counts_at_volts(34) as u16;
        assert!(!l.brake(false, &udc(on)));
        assert!(l.brake(false, &udc(on + 1)));
        assert!(l.brake(true, &udc(off + 10)));
        assert!(l.brake(true, &udc(off)));
        assert!(!l.brake(true, &udc(off - 1)));
        assert!(!l.brake(false, &udc(off + 10)));
    }
}
