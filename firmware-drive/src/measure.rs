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
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
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

/// How a board's analog front end puts the phase currents and the DC link on the ADC.
/// The core works in the source's scale ("canonical counts": 2048 = 0 A,
/// +-10 A full scale, 0-45 V); [`FrontEnd::canonical`] maps each board's raw readings onto
/// it once per PWM period, so limits, `IMX`, `UDC` and the program's units are the same on
/// every board.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SensorScaling {
    /// Nominal reading at 0 A (the boot calibration measures the real one).
    pub current_zero_counts: u16,
    /// The boot self-test: the PWM-off readings must lie within this many counts of the
    /// nominal zero (a missing or shorted sensor reads near a rail).
    pub current_zero_tolerance_counts: u16,
    /// Counts per ampere x 1000; negative for an inverting amplifier.
    pub current_millicounts_per_amp: i32,
    /// DC-link voltage at 4095 counts, 0.1 V.
    pub udc_full_decivolts: u32,
}

/// The source's sensors: +-10 A on 0-3.3 V around 1.65 V, DC link 0-45 V (a carrier
/// board with the source's current sensors and divider on the ESC1's pins).
pub const SOURCE_SCALING: SensorScaling = SensorScaling {
    current_zero_counts: CURRENT_ZERO_COUNTS as u16,
    current_zero_tolerance_counts: 205,
    current_millicounts_per_amp: 204_800,
    udc_full_decivolts: UDC_FULL_DECIVOLTS,
};

/// The bare B-G431B-ESC1: 3 mOhm shunts whose two ends reach VINP and VINM0 through a
/// network biased from 3V3, and the OPAMP in the VINM0-biased PGA mode, gain 16
/// (`front_end::ESC1_PGAS`): out = 16 VINP - 15 VINM0 = the bias - 9.14 x the
/// shunt's volts (-64/7: NuttX "Current sense gain = -9.14", SimpleFOC `-64.0f/7.0f`),
/// i.e. -27.43 mV/A = -34.05 counts/A at the ADC. The bias is not in a document we
/// reached: 64/7 over the PGA's 16 leaves 4/7 of each shunt end on its pin, the rest of a
/// two-resistor divider to 3V3 is 3/7 x 3.3 V = 1.414 V = 1755 counts at 0 A (the same
/// derivation as g431-emu's board model, `docs/models.md`); the boot check accepts
/// +-410 counts (0.33 V: 1 % resistors move the bias ~20 mV, the OPAMP's +-4.5 mV offset
/// x 16 = 72 mV) and rejects an amplifier at a rail (the grounded-input mode on this
/// network, an amplifier not started). Range about -51 A..+69 A. DC link divided by
/// 0.0962 (NuttX "Vbus sense gain = 0.0962"): 34.3 V at full scale.
pub const ESC1_SCALING: SensorScaling = SensorScaling {
    current_zero_counts: 1755,
    current_zero_tolerance_counts: 410,
    current_millicounts_per_amp: -34_050,
    udc_full_decivolts: 343,
};

/// Canonical counts per ampere x 1000 (the source's scale).
const CANONICAL_MILLICOUNTS_PER_AMP: i64 = 204_800;

/// A board's front end with its zero-current readings as calibrated at boot.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FrontEnd {
    scaling: SensorScaling,
    /// Zero-current reading of channel a and b (raw counts).
    zero: [i32; 2],
    /// Raw current counts to canonical counts, Q16 (signed).
    current_q16: i64,
    /// Raw DC-link counts to canonical counts, Q16.
    udc_q16: i64,
}

impl FrontEnd {
    pub fn new(scaling: SensorScaling) -> Self {
        let m = i64::from(scaling.current_millicounts_per_amp);
        let m = if m == 0 { 1 } else { m };
        FrontEnd {
            scaling,
            zero: [i32::from(scaling.current_zero_counts); 2],
            current_q16: div_round(CANONICAL_MILLICOUNTS_PER_AMP << 16, m),
            udc_q16: div_round(
                i64::from(scaling.udc_full_decivolts) << 16,
                i64::from(UDC_FULL_DECIVOLTS),
            ),
        }
    }

    pub fn scaling(&self) -> &SensorScaling {
        &self.scaling
    }

    /// The calibrated zero-current readings (raw counts).
    pub fn zero_counts(&self) -> [i32; 2] {
        self.zero
    }

    /// Use these zero-current readings from now on.
    pub fn calibrate(&mut self, zero: [i32; 2]) {
        self.zero = zero;
    }

    /// The board's raw reading in canonical counts (clamped to 0..=4095).
    #[inline(always)]
    pub fn canonical(&self, raw: &AdcSample) -> AdcSample {
        let i = |c: u16, zero: i32| {
            let d = i64::from(i32::from(c) - zero) * self.current_q16;
            (i64::from(CURRENT_ZERO_COUNTS) + ((d + 0x8000) >> 16)).clamp(0, 4095) as u16
        };
        let [za, zb] = self.zero;
        AdcSample {
            i_a: i(raw.i_a, za),
            i_b: i(raw.i_b, zb),
            u_dc: ((i64::from(raw.u_dc) * self.udc_q16 + 0x8000) >> 16).clamp(0, 4095) as u16,
            aux: raw.aux,
        }
    }

    /// The raw reading (not clamped) of a phase current of `canonical` counts on channel
    /// a's calibration (comparator thresholds).
    pub fn raw_current_counts(&self, canonical: i32) -> i32 {
        let d = i64::from(canonical - CURRENT_ZERO_COUNTS)
            * i64::from(self.scaling.current_millicounts_per_amp);
        self.zero[0] + div_round(d, CANONICAL_MILLICOUNTS_PER_AMP) as i32
    }

    /// The raw DC-link reading of `canonical` counts.
    pub fn raw_udc_counts(&self, canonical: u32) -> u32 {
        let r = div_round(
            i64::from(canonical) * i64::from(UDC_FULL_DECIVOLTS),
            i64::from(self.scaling.udc_full_decivolts.max(1)),
        );
        r.clamp(0, i64::from(u32::MAX)) as u32
    }
}

/// `a / b` rounded to nearest (b != 0).
fn div_round(a: i64, b: i64) -> i64 {
    let q = a / b;
    let r = a % b;
    if 2 * r.abs() >= b.abs() {
        q + if (r < 0) == (b < 0) { 1 } else { -1 }
    } else {
        q
    }
}

/// The boot self-test and calibration of the zero-current readings: every PWM-off sample
/// of BOOT must lie within the tolerance of the nominal zero; their mean becomes the zero.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ZeroCalibration {
    sum: [u32; 2],
    samples: u32,
    out_of_tolerance: bool,
}

impl ZeroCalibration {
    /// One BOOT sample (raw counts).
    #[inline(always)]
    pub fn add(&mut self, raw: &AdcSample, scaling: &SensorScaling) {
        let nominal = i32::from(scaling.current_zero_counts);
        let tol = u32::from(scaling.current_zero_tolerance_counts);
        for (sum, c) in self.sum.iter_mut().zip([raw.i_a, raw.i_b]) {
            *sum = sum.saturating_add(u32::from(c));
            if (i32::from(c) - nominal).unsigned_abs() > tol {
                self.out_of_tolerance = true;
            }
        }
        self.samples = self.samples.saturating_add(1);
    }

    /// The measured zeros, or an error when a sample was out of tolerance; `Ok(None)`
    /// when no sample was taken (the nominal zero stays).
    pub fn result(&self) -> Result<Option<[i32; 2]>, ZeroOutOfTolerance> {
        if self.out_of_tolerance {
            return Err(ZeroOutOfTolerance);
        }
        if self.samples == 0 {
            return Ok(None);
        }
        let n = self.samples;
        let mean = |s: u32| (s.saturating_add(n / 2) / n) as i32;
        Ok(Some([mean(self.sum[0]), mean(self.sum[1])]))
    }
}

/// A current sensor's zero at boot was out of tolerance (the self-test fails: `BOOT`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ZeroOutOfTolerance;

impl core::fmt::Display for ZeroOutOfTolerance {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str("current-sensor zero out of tolerance")
    }
}

impl core::error::Error for ZeroOutOfTolerance {}

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

    fn raw(i_a: u16, i_b: u16, u_dc: u16) -> AdcSample {
        AdcSample {
            i_a,
            i_b,
            u_dc,
            aux: 7,
        }
    }

    #[test]
    fn the_source_scaling_is_the_identity() {
        let fe = FrontEnd::new(SOURCE_SCALING);
        for c in [0u16, 1, 1000, 2047, 2048, 2049, 3000, 4095] {
            assert_eq!(fe.canonical(&raw(c, c, c)), raw(c, c, c));
            assert_eq!(fe.raw_current_counts(i32::from(c)), i32::from(c));
            assert_eq!(fe.raw_udc_counts(u32::from(c)), u32::from(c));
        }
    }

    #[test]
    fn the_esc1_scaling_reads_amps_and_volts() {
        let fe = FrontEnd::new(ESC1_SCALING);
        // +2 A at the ESC1 (inverting, zero at the bias 1755): 1755 - 68 counts -> +2 A.
        let s = fe.canonical(&raw(1755 - 68, 1755 + 34, 0));
        assert_eq!(current_centiamps(s.i_a), CentiAmps(199));
        assert!((current_centiamps(s.i_b).0 + 100).abs() <= 1);
        // 24 V on the 0.0962 divider: 24 / 34.3 x 4095 = 2865 counts.
        let s = fe.canonical(&raw(1755, 1755, 2865));
        assert!((udc_decivolts(s.u_dc).0 - 240).abs() <= 1, "{s:?}");
        // Beyond +-10 A the canonical scale saturates (the program's limits stop at 9.99 A).
        let s = fe.canonical(&raw(0, 4095, 4095));
        assert_eq!((s.i_a, s.i_b), (4095, 0));
        // The inverse: +3 A is 102 counts below the zero; 40 V canonical is 34.3 V max.
        assert_eq!(fe.raw_current_counts(2048 + 614), 1755 - 102);
        assert_eq!(fe.raw_udc_counts(3000), 3936);
    }

    #[test]
    fn the_calibrated_zero_is_the_mean_of_the_boot_samples() {
        let mut cal = ZeroCalibration::default();
        assert_eq!(cal.result(), Ok(None));
        for k in 0..10u16 {
            cal.add(&raw(2100 + k % 2, 1990, 0), &ESC1_SCALING);
        }
        assert_eq!(cal.result(), Ok(Some([2101, 1990])));
        let mut fe = FrontEnd::new(ESC1_SCALING);
        fe.calibrate([2101, 1990]);
        let s = fe.canonical(&raw(2101, 1990, 0));
        assert_eq!((s.i_a, s.i_b), (2048, 2048));
        // A sensor reading near a rail fails the self-test.
        cal.add(&raw(2048, 2048 + 206, 0), &ESC1_SCALING);
        assert_eq!(cal.result(), Err(ZeroOutOfTolerance));
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
