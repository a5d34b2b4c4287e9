//! Raw ADC counts in, engineering units out. The board layer and hil-sim's sensor model
//! deliver 12-bit counts exactly as the converter produces them; all scaling lives here,
//! with the source hardware's full scales so that the source's programs keep working.
//!
//! | channel | counts | value |
//! | --- | --- | --- |
//! | phase current a, b | 0..4095, 2048 = 0 A | (c - 2048) * 10 A / 2048 (+-10 A full scale) |
//! | DC link | 0..4095 | c * 45 V / 4095 |
//! | aux | 0..4095 | `COM` = c >> 2 (10-bit, as the source's ADC) |

use shared_protocol::units::{CentiAmps, Decivolts};

/// Zero-current reading of a phase-current channel.
pub const CURRENT_ZERO_COUNTS: i32 = 2048;
/// Full-scale ADC reading.
pub const ADC_FULL_COUNTS: u32 = 4095;
/// DC-link full scale, 0.1 V.
pub const UDC_FULL_DECIVOLTS: u32 = 450;
/// Current full scale (2048 counts from zero), 0.01 A.
pub const CURRENT_FULL_CENTIAMPS: i32 = 1000;

/// One conversion of every channel, taken in the PWM period's sampling window.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct AdcSample {
    pub i_a: u16,
    pub i_b: u16,
    pub u_dc: u16,
    pub aux: u16,
}

impl Default for AdcSample {
    /// Zero current, zero voltage.
    fn default() -> Self {
        AdcSample {
            i_a: CURRENT_ZERO_COUNTS as u16,
            i_b: CURRENT_ZERO_COUNTS as u16,
            u_dc: 0,
            aux: 0,
        }
    }
}

impl AdcSample {
    /// Largest |i_a|, |i_b| in counts from zero current (0..=2048).
    #[inline(always)]
    pub fn abs_current_counts(&self) -> u32 {
        let a = (i32::from(self.i_a.min(4095)) - CURRENT_ZERO_COUNTS).unsigned_abs();
        let b = (i32::from(self.i_b.min(4095)) - CURRENT_ZERO_COUNTS).unsigned_abs();
        a.max(b)
    }
}

/// Phase current of a reading, 0.01 A (truncated toward zero).
pub fn current_centiamps(counts: u16) -> CentiAmps {
    let d = i32::from(counts.min(4095)) - CURRENT_ZERO_COUNTS;
    CentiAmps((d * CURRENT_FULL_CENTIAMPS / CURRENT_ZERO_COUNTS) as i16)
}

/// Magnitude in counts from zero current to 0.01 A.
pub fn abs_counts_to_centiamps(abs_counts: u32) -> CentiAmps {
    let c = abs_counts.min(2048) * CURRENT_FULL_CENTIAMPS as u32 / CURRENT_ZERO_COUNTS as u32;
    CentiAmps(c as i16)
}

/// DC-link voltage of a reading, 0.1 V (rounded).
pub fn udc_decivolts(counts: u16) -> Decivolts {
    let c = u32::from(counts.min(4095));
    Decivolts(((c * UDC_FULL_DECIVOLTS + ADC_FULL_COUNTS / 2) / ADC_FULL_COUNTS) as i16)
}

/// The smallest DC-link reading (counts) that is at or above `volts` V.
pub fn udc_counts_at_volts(volts: u32) -> u32 {
    // counts = V * 10 * 4095 / 450, rounded up.
    (volts.saturating_mul(10 * ADC_FULL_COUNTS)).div_ceil(UDC_FULL_DECIVOLTS)
}

/// `COM`: the aux channel as the source's 10-bit value.
pub fn com_of(counts: u16) -> u16 {
    counts.min(4095) >> 2
}

/// Milliseconds of the `IMX` window.
pub const PEAK_WINDOW_MS: usize = 10;

/// `IMX`: largest |phase current| over the last 10 ms. The PWM interrupt raises the
/// current millisecond's slot (one compare), the 1 ms tick moves to the next slot.
#[derive(Debug, Clone, Default)]
pub struct PeakTracker {
    slots: [u16; PEAK_WINDOW_MS],
    now: usize,
}

impl PeakTracker {
    #[inline(always)]
    pub fn record(&mut self, abs_counts: u32) {
        if let Some(s) = self.slots.get_mut(self.now) {
            let c = abs_counts.min(u32::from(u16::MAX)) as u16;
            if c > *s {
                *s = c;
            }
        }
    }

    /// Start a new millisecond (drops the oldest one).
    pub fn next_ms(&mut self) {
        self.now = (self.now + 1) % PEAK_WINDOW_MS;
        if let Some(s) = self.slots.get_mut(self.now) {
            *s = 0;
        }
    }

    /// Largest |i| in counts over the window.
    pub fn peak_counts(&self) -> u32 {
        u32::from(self.slots.iter().copied().max().unwrap_or(0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn current_scaling_is_plus_minus_ten_amps() {
        assert_eq!(current_centiamps(2048), CentiAmps(0));
        assert_eq!(current_centiamps(0), CentiAmps(-1000));
        assert_eq!(current_centiamps(4095), CentiAmps(999));
        assert_eq!(current_centiamps(2048 + 410), CentiAmps(200));
        assert_eq!(abs_counts_to_centiamps(2048), CentiAmps(1000));
    }

    #[test]
    fn udc_scaling_is_45_volts_full_scale() {
        assert_eq!(udc_decivolts(0), Decivolts(0));
        assert_eq!(udc_decivolts(4095), Decivolts(450));
        assert_eq!(udc_decivolts(2730), Decivolts(300));
        let c = udc_counts_at_volts(35);
        assert!(udc_decivolts(c as u16).0 >= 350);
        assert!(udc_decivolts(c as u16 - 1).0 <= 350);
    }

    #[test]
    fn com_is_ten_bit() {
        assert_eq!(com_of(4095), 1023);
        assert_eq!(com_of(0), 0);
        assert_eq!(com_of(2048), 512);
    }

    #[test]
    fn peak_forgets_after_ten_ms() {
        let mut p = PeakTracker::default();
        p.record(500);
        p.next_ms();
        p.record(100);
        for _ in 0..8 {
            p.next_ms();
        }
        assert_eq!(p.peak_counts(), 500);
        p.next_ms();
        assert_eq!(p.peak_counts(), 100);
        p.next_ms();
        assert_eq!(p.peak_counts(), 0);
    }
}
