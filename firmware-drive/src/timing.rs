//! TIM1 settings for a switching frequency: prescaler, auto-reload, dead time, and the
//! phase-accumulator step per 0.1 Hz that makes the output frequency exact for the
//! period the timer really has (ARR is an integer, so f_pwm is rarely the requested one).
//!
//! Centre-aligned counting: f_pwm = f_tim / (2 * ARR * (PSC + 1)).

/// Largest value of the 16-bit PSC register.
const PSC_MAX: u64 = 65_535;
/// Largest ARR used: one below the register's maximum so that a 100 % duty can be written
/// as CCR = ARR + 1 (see `PwmCommand::ccr`).
const ARR_MAX: u64 = 65_534;

/// What the board programs into TIM1 (and the core uses for the phase step).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PwmTiming {
    /// TIM1_PSC (the counter runs at f_tim / (psc + 1)).
    pub psc: u16,
    /// TIM1_ARR: the period in counts, the full-scale duty `N`.
    pub arr: u16,
    /// Dead time in CK_INT (= f_tim) periods, as realised by [`PwmTiming::dtg`] (never
    /// below the requested or minimum dead time).
    pub dead_time_counts: u16,
    /// TIM1_BDTR.DTG encoding of `dead_time_counts` (CKD = 0, tDTS = 1/f_tim).
    pub dtg: u8,
    /// The switching frequency the timer really produces, mHz.
    pub pwm_millihertz: u32,
    /// Comparator blanking past the last switching edge, counter counts: the dead time
    /// plus [`crate::blanking::RINGING_NS`], rounded up (`blanking::ccr5`).
    pub blank_counts: u16,
    /// Live comparator time kept either side of the peak, counter counts
    /// ([`crate::blanking::MIN_LIVE_NS`]).
    pub live_counts: u16,
    /// Phase-accumulator step per PWM period for 0.1 Hz output (2^64 = one turn).
    pub(crate) phase_step_per_decihertz: u128,
}

impl PwmTiming {
    /// Timer setup for `pwf_hz / prescaler` switching frequency.
    ///
    /// `pwf_hz` is clamped to 1.. and `prescaler` to 1..; the ARR is rounded to the
    /// nearest count, the PSC is the smallest that makes ARR fit in 16 bits (best duty
    /// resolution).
    pub fn compute(
        timer_clock_hz: u32,
        pwf_hz: u32,
        prescaler: u32,
        dead_time_ns: u32,
        min_dead_time_ns: u32,
    ) -> PwmTiming {
        let f_tim = u64::from(timer_clock_hz.max(1));
        let pwf = u64::from(pwf_hz.max(1));
        let pre = u64::from(prescaler.max(1));
        // ARR * (PSC + 1), rounded.
        let total = ((f_tim * pre + pwf) / (2 * pwf)).max(1);
        let psc1 = total.div_ceil(ARR_MAX).clamp(1, PSC_MAX + 1);
        let arr = ((total + psc1 / 2) / psc1).clamp(1, ARR_MAX);
        let ticks_per_period = 2 * arr * psc1;
        let pwm_millihertz = ((f_tim * 1000 + ticks_per_period / 2) / ticks_per_period) as u32;
        // step(0.1 Hz) = 0.1 * T_pwm * 2^64 = ticks * 2^64 / (10 * f_tim).
        let phase_step_per_decihertz = shl64_div(ticks_per_period, 10 * f_tim);
        let dead_ns = u64::from(dead_time_ns.max(min_dead_time_ns));
        let dead_counts = (dead_ns * f_tim).div_ceil(1_000_000_000);
        let (dtg, realised) = encode_dtg(dead_counts);
        let psc = (psc1 - 1) as u16;
        let ringing =
            crate::blanking::counts_of_ns(crate::blanking::RINGING_NS, timer_clock_hz, psc);
        let dead = u32::from(realised).div_ceil(u32::from(psc) + 1);
        let live = crate::blanking::counts_of_ns(crate::blanking::MIN_LIVE_NS, timer_clock_hz, psc);
        PwmTiming {
            psc,
            arr: arr as u16,
            dead_time_counts: realised,
            dtg,
            pwm_millihertz,
            blank_counts: (dead + ringing).min(u32::from(u16::MAX)) as u16,
            live_counts: live.min(u32::from(u16::MAX)) as u16,
            phase_step_per_decihertz,
        }
    }

    /// Phase-accumulator step per PWM period (2^64 = one turn) for an output frequency in
    /// 0.1 Hz (negative is treated as 0). Capped just below half a turn per period
    /// (Nyquist): above it the output would alias to a lower frequency.
    pub fn phase_step(&self, f_decihertz: i16) -> u64 {
        let f = u128::from(f_decihertz.max(0) as u16);
        let step = f.saturating_mul(self.phase_step_per_decihertz);
        step.min(u128::from(u64::MAX >> 1)) as u64
    }
}

/// Fewest CK_INT periods of dead time the power stage accepts: `min_dead_time_ns` rounded up.
pub fn min_dead_time_counts(timer_clock_hz: u32, min_dead_time_ns: u32) -> u32 {
    let counts = (u64::from(min_dead_time_ns) * u64::from(timer_clock_hz)).div_ceil(1_000_000_000);
    u32::try_from(counts).unwrap_or(u32::MAX)
}

impl PwmTiming {
    /// The dead time the DTG code really gives is the one the timing claims and at least
    /// `min_counts` ([`min_dead_time_counts`]): false when the minimum is beyond what DTG
    /// can encode (1008 counts). The dead time counts in CK_INT periods, so every timing of
    /// one configuration has the same DTG whatever its PSC and ARR.
    pub fn dead_time_meets(&self, min_counts: u32) -> bool {
        let realised = decode_dtg(self.dtg);
        realised == self.dead_time_counts && u32::from(realised) >= min_counts
    }
}

/// `(n << 64) / d` for `d` in 1..2^36 (the callers' `10 * f_tim` with a 32-bit `f_tim`),
/// exact, in 64-bit divisions: long division by 28-bit digits (every remainder is below
/// d < 2^36, so shifting it by 28 bits stays within 64). A 128-bit division is a software
/// loop of thousands of Cortex-M4 instructions and, expanded inline, 666 B of flash; this
/// runs in the 1 ms tick whenever `PWF` changes, inside the critical section the PWM
/// interrupt waits for.
fn shl64_div(n: u64, d: u64) -> u128 {
    let d = d.clamp(1, SHL64_DIV_MAX);
    let (q, r) = (n / d, n % d);
    let (q1, r) = ((r << 28) / d, (r << 28) % d);
    let (q2, r) = ((r << 28) / d, (r << 28) % d);
    let q3 = (r << 8) / d;
    (u128::from(q) << 64) | (u128::from(q1) << 36) | (u128::from(q2) << 8) | u128::from(q3)
}

/// Largest divisor of [`shl64_div`]: 2^36 - 1 (10 times any 32-bit timer clock is below).
const SHL64_DIV_MAX: u64 = (1 << 36) - 1;

/// The smallest BDTR.DTG code whose dead time is at least `counts` CK_INT periods
/// (RM0440 BDTR: four ranges with steps of 1, 2, 8 and 16 counts). Saturates at the
/// longest encodable dead time (1008 counts, 5.9 us at 170 MHz).
pub fn encode_dtg(counts: u64) -> (u8, u16) {
    if counts <= 127 {
        (counts as u8, counts as u16)
    } else if counts <= 254 {
        let k = (counts.div_ceil(2) - 64) as u8;
        (0x80 | k, (64 + u16::from(k)) * 2)
    } else if counts <= 504 {
        let k = (counts.div_ceil(8) - 32) as u8;
        (0xC0 | k, (32 + u16::from(k)) * 8)
    } else {
        let k = (counts.div_ceil(16).min(63) - 32) as u8;
        (0xE0 | k, (32 + u16::from(k)) * 16)
    }
}

/// Dead time in CK_INT periods for a BDTR.DTG code (the inverse of [`encode_dtg`]).
pub fn decode_dtg(dtg: u8) -> u16 {
    let d = u16::from(dtg);
    match dtg >> 5 {
        0..=3 => d & 0x7F,
        4 | 5 => (64 + (d & 0x3F)) * 2,
        6 => (32 + (d & 0x1F)) * 8,
        _ => (32 + (d & 0x1F)) * 16,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shl64_div_is_the_exact_128_bit_quotient() {
        let ds = [
            1u64,
            7,
            10,
            1_700_000_000,
            1_699_999_999,
            u64::from(u32::MAX),
            1 << 32,
            10 * u64::from(u32::MAX),
            SHL64_DIV_MAX,
        ];
        let ns = [
            0u64,
            1,
            2,
            4250,
            8_589_672_450,
            1 << 33,
            u64::MAX - 1,
            u64::MAX,
        ];
        for d in ds {
            for n in ns {
                assert_eq!(
                    shl64_div(n, d),
                    (u128::from(n) << 64) / u128::from(d),
                    "{n} / {d}"
                );
            }
        }
        let mut x = 0x9E37_79B9_7F4A_7C15u64;
        for _ in 0..100_000 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            let n = x >> (x % 40);
            let d = (x.rotate_left(17) >> (28 + x % 36)).max(1);
            assert_eq!(
                shl64_div(n, d),
                (u128::from(n) << 64) / u128::from(d),
                "{n} / {d}"
            );
        }
    }

    /// Every divisor `compute` passes (10 * f_tim for a 32-bit f_tim) is in range.
    #[test]
    fn the_phase_step_divisor_fits_shl64_div() {
        assert!(10 * u64::from(u32::MAX) <= SHL64_DIV_MAX);
    }

    #[test]
    fn twenty_khz_at_170_mhz_is_arr_4250() {
        let t = PwmTiming::compute(170_000_000, 20_000, 1, 1000, 500);
        assert_eq!((t.psc, t.arr), (0, 4250));
        assert_eq!(t.pwm_millihertz, 20_000_000);
        // 1 us = 170 counts, encoded in the 2-count range exactly.
        assert_eq!(t.dead_time_counts, 170);
        assert_eq!(decode_dtg(t.dtg), 170);
    }

    #[test]
    fn low_frequencies_use_the_prescaler() {
        // PWF 500 Hz with PR2 (/64): 7.8125 Hz.
        let t = PwmTiming::compute(170_000_000, 500, 64, 1000, 500);
        assert!(t.psc > 0);
        let f = 170e6 / (2.0 * t.arr as f64 * (t.psc as f64 + 1.0));
        assert!((f - 7.8125).abs() / 7.8125 < 1e-4, "{f}");
        assert!(t.arr > 30_000, "resolution kept: {}", t.arr);
    }

    #[test]
    fn dead_time_never_below_request_or_minimum() {
        for ns in [0u32, 10, 100, 747, 748, 1000, 1500, 2999, 3000, 5000] {
            let t = PwmTiming::compute(170_000_000, 16_000, 1, ns, 500);
            let want = (u64::from(ns.max(500)) * 170).div_ceil(1000);
            assert!(u64::from(t.dead_time_counts) >= want, "{ns} ns");
            assert_eq!(decode_dtg(t.dtg), t.dead_time_counts);
        }
    }

    #[test]
    fn the_dead_time_floor_holds_at_every_prescaler_and_fails_beyond_dtg() {
        let min = min_dead_time_counts(170_000_000, 500);
        assert_eq!(min, 85);
        let t = PwmTiming::compute(170_000_000, 16_000, 1, 1000, 500);
        for (pwf, pre) in [(1_000, 1), (16_000, 1), (16_000, 16), (50, 100)] {
            let u = PwmTiming::compute(170_000_000, pwf, pre, 1000, 500);
            assert!(u.dead_time_meets(min));
            assert_eq!(u.dtg, t.dtg, "{pwf} Hz / {pre}");
        }
        // 10 us is 1700 counts, beyond DTG's 1008.
        let min = min_dead_time_counts(170_000_000, 10_000);
        let t = PwmTiming::compute(170_000_000, 16_000, 1, 1000, 10_000);
        assert!(!t.dead_time_meets(min));
    }

    #[test]
    fn dtg_round_trips_every_code_boundary() {
        for counts in 0..=1008u64 {
            let (dtg, realised) = encode_dtg(counts);
            assert_eq!(decode_dtg(dtg), realised);
            assert!(u64::from(realised) >= counts);
            assert!(u64::from(realised) - counts < 16, "{counts}");
        }
    }

    #[test]
    fn phase_step_makes_the_real_period_give_the_exact_frequency() {
        let t = PwmTiming::compute(170_000_000, 16_000, 1, 1000, 500);
        let f_pwm = 170e6 / (2.0 * t.arr as f64);
        let step = t.phase_step(500) as f64;
        let f_out = step / 2f64.powi(64) * f_pwm;
        assert!((f_out - 50.0).abs() < 50.0 * 1e-12, "{f_out}");
    }
}
