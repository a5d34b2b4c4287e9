//! The PWM-rate part of the drive: phase accumulator, sine lookup, V/f amplitude, duty
//! in timer counts, and the dead-time-safe clamp. Called once per PWM period from the
//! interrupt, so it is integer-only and branch-light; everything that needs a division
//! (modulation index, phase step) is computed by the 1 ms tick and handed over in
//! [`ModulatorParams`].
//!
//! duty_k = N/2 + N/2 * m * sin(theta + phi_k), theta += step every period. theta is a
//! 64-bit accumulator (2^64 = one turn) so that the frequency is exact to 1e-12 at any f;
//! its upper 32 bits are the angle.
//! With min-max injection, the common-mode offset -(max v + min v)/2 is added to all three
//! legs (equivalent to third-harmonic injection, line-to-line voltages unchanged), which
//! keeps duties inside 0..N up to m = 2/sqrt(3) = 1.1547.
//!
//! Above the linear range (m > 1.0, or 1.1547 with injection) the drive overmodulates as
//! the source did: each sample's duty is clipped at the carrier limits 0 and N (then the
//! dead-time-safe clamp), so the fundamental keeps rising with m toward the six-step
//! limit (4/pi of the linear m = 1.0 value). m itself is limited only to [`M_LIMIT_Q16`]
//! so that the fixed-point products cannot overflow; at that m the legs are within 1 % of
//! six-step.

use crate::sine::sin_q15;

/// Modulation index 1.0 in Q16.
pub const M_ONE_Q16: u32 = 1 << 16;
/// 2/sqrt(3) in Q16: the linear limit with min-max injection.
pub const M_MAX_MIN_MAX_Q16: u32 = 75_674;
/// Largest modulation index the modulator takes (8.0, Q16): far into overmodulation
/// (fundamental within 1 % of six-step), and small enough that N/2 * m * sin stays far
/// inside i64 for any 16-bit N.
pub const M_LIMIT_Q16: u32 = 8 << 16;

/// What one leg (phase pair PW0/PW1, PW2/PW3, PW4/PW5) outputs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum LegMode {
    /// Not set by the program: duty 0 (low switch on), as the source's reset PDC value.
    #[default]
    Unused,
    /// `WR PWx`: fixed duty, 0.1 % of the period (0..=1000).
    Direct { permille: u16 },
    /// `SNx`: sine with the common amplitude and frequency.
    Sine,
}

/// Set by the 1 ms tick; read by every PWM period.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ModulatorParams {
    /// Phase advance per PWM period (2^64 = one turn).
    pub step: u64,
    /// Requested modulation index, Q16 (at most [`M_LIMIT_Q16`]; above the linear range
    /// the duties clip).
    pub m_q16: u32,
    /// Phase offsets of the three sine phases (2^32 = one turn).
    pub phi: [u32; 3],
    pub legs: [LegMode; 3],
    /// Reverse direction: legs 1 and 2 exchange their outputs.
    pub swap_1_2: bool,
}

#[derive(Debug, Clone)]
pub struct Modulator {
    theta: u64,
    p: ModulatorParams,
    min_pulse_counts: u16,
    min_max_injection: bool,
}

impl Modulator {
    pub fn new(min_pulse_counts: u16, min_max_injection: bool) -> Self {
        Modulator {
            theta: 0,
            p: ModulatorParams::default(),
            min_pulse_counts,
            min_max_injection,
        }
    }

    /// End of the linear range of this configuration (1.0, or 1.1547 with min-max
    /// injection); above it the duties clip (overmodulation).
    pub fn linear_limit_q16(&self) -> u32 {
        if self.min_max_injection {
            M_MAX_MIN_MAX_Q16
        } else {
            M_ONE_Q16
        }
    }

    pub fn set_params(&mut self, p: ModulatorParams) {
        self.p = p;
    }

    pub fn params(&self) -> &ModulatorParams {
        &self.p
    }

    /// Angle of the accumulator (phase 1 without its offset), 2^32 = one turn.
    pub fn theta(&self) -> u32 {
        (self.theta >> 32) as u32
    }

    /// Restart the sine at angle 0 (outputs were off).
    pub fn reset_phase(&mut self) {
        self.theta = 0;
    }

    /// Duties in counts (0..=n) for this PWM period, then advance the angle by one period.
    #[inline(always)]
    pub fn step(&mut self, n: u16) -> [u16; 3] {
        let p = &self.p;
        let nn = i64::from(n);
        // Half the period times m, Q16 counts: the sine's amplitude in counts.
        let half_amp_q16 = (u64::from(n) * u64::from(p.m_q16.min(M_LIMIT_Q16))) >> 1;
        let angle = (self.theta >> 32) as u32;
        let phase =
            |phi: u32| (half_amp_q16 as i64 * i64::from(sin_q15(angle.wrapping_add(phi)))) >> 15;
        // The three phases written out, not `map`, iterators or loops: at opt-level "s"
        // `array::map` stays a call (89 instructions of the 457 per period), a loop zeroes
        // its array first, and iterators are not unrolled (`docs/size.md`).
        let [phi0, phi1, phi2] = p.phi;
        let [mut v0, mut v1, mut v2] = [phase(phi0), phase(phi1), phase(phi2)];
        let [l0, l1, l2] = p.legs;
        let all_sine = l0 == LegMode::Sine && l1 == LegMode::Sine && l2 == LegMode::Sine;
        if self.min_max_injection && all_sine {
            let offset = -((v0.max(v1).max(v2) + v0.min(v1).min(v2)) >> 1);
            v0 += offset;
            v1 += offset;
            v2 += offset;
        }
        let min_pulse = self.min_pulse_counts;
        let duty_of = |leg: LegMode, vk: i64| {
            let counts = match leg {
                LegMode::Unused => 0,
                LegMode::Direct { permille } => (nn * i64::from(permille.min(1000)) + 500) / 1000,
                LegMode::Sine => ((nn << 15) + vk + 0x8000) >> 16,
            };
            dead_time_safe(counts.clamp(0, nn) as u16, n, min_pulse)
        };
        let mut duty = [duty_of(l0, v0), duty_of(l1, v1), duty_of(l2, v2)];
        if p.swap_1_2 {
            duty.swap(0, 1);
        }
        self.theta = self.theta.wrapping_add(p.step);
        duty
    }
}

/// No pulse of `min` counts or less: a duty of 1..=min becomes 0 (no high pulse) and
/// N-min..N-1 becomes N (no low pulse). The source's silicon-errata rule, generalised.
/// Duties above `n` are clamped to `n`.
#[inline(always)]
pub fn dead_time_safe(d: u16, n: u16, min: u16) -> u16 {
    let d = d.min(n);
    if d <= min {
        0
    } else if d >= n.saturating_sub(min) {
        n
    } else {
        d
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sine::phase_of_decidegrees;

    fn three_phase(m_q16: u32, step: u64) -> ModulatorParams {
        ModulatorParams {
            step,
            m_q16,
            phi: [0, phase_of_decidegrees(1200), phase_of_decidegrees(2400)],
            legs: [LegMode::Sine; 3],
            swap_1_2: false,
        }
    }

    #[test]
    fn clamp_follows_the_four_count_rule() {
        let n = 1000;
        assert_eq!(dead_time_safe(0, n, 4), 0);
        assert_eq!(dead_time_safe(1, n, 4), 0);
        assert_eq!(dead_time_safe(4, n, 4), 0);
        assert_eq!(dead_time_safe(5, n, 4), 5);
        assert_eq!(dead_time_safe(995, n, 4), 995);
        assert_eq!(dead_time_safe(996, n, 4), 1000);
        assert_eq!(dead_time_safe(999, n, 4), 1000);
        assert_eq!(dead_time_safe(1000, n, 4), 1000);
        assert_eq!(dead_time_safe(4000, n, 4), 1000);
    }

    #[test]
    fn sine_duty_spans_the_period_at_m_one() {
        let mut m = Modulator::new(4, false);
        // 1/400 of a turn per period.
        m.set_params(three_phase(M_ONE_Q16, u64::MAX / 400 + 1));
        let (mut lo, mut hi) = (u16::MAX, 0);
        let mut sum = 0u64;
        for _ in 0..400 {
            let d = m.step(4250);
            lo = lo.min(d[0]);
            hi = hi.max(d[0]);
            sum += u64::from(d[0]);
        }
        assert_eq!((lo, hi), (0, 4250));
        let mean = sum as f64 / 400.0;
        assert!((mean - 2125.0).abs() < 2.0, "{mean}");
    }

    #[test]
    fn phases_are_120_degrees_apart_and_reverse_swaps_1_2() {
        let mut m = Modulator::new(0, false);
        let mut p = three_phase(M_ONE_Q16 / 2, 0);
        m.set_params(p);
        // theta = 0: sin 0, sin 120, sin 240.
        let d = m.step(10_000);
        assert_eq!(d[0], 5000);
        assert_eq!(d[1], 5000 + 2165);
        assert_eq!(d[2], 5000 - 2165);
        p.swap_1_2 = true;
        m.set_params(p);
        let r = m.step(10_000);
        assert_eq!(r, [d[1], d[0], d[2]]);
    }

    #[test]
    fn direct_duty_is_in_tenths_of_percent() {
        let mut m = Modulator::new(4, false);
        m.set_params(ModulatorParams {
            legs: [
                LegMode::Direct { permille: 500 },
                LegMode::Direct { permille: 1000 },
                LegMode::Unused,
            ],
            ..Default::default()
        });
        assert_eq!(m.step(4250), [2125, 4250, 0]);
    }

    #[test]
    fn min_max_injection_keeps_duties_in_range_up_to_1_1547() {
        let mut m = Modulator::new(0, true);
        m.set_params(three_phase(M_MAX_MIN_MAX_Q16, u64::MAX / 997 + 1));
        let n = 5000u16;
        let mut worst_line = 0f64;
        for _ in 0..997 {
            let d = m.step(n);
            for x in d {
                assert!(x <= n);
            }
            let l = (f64::from(d[0]) - f64::from(d[1])) / f64::from(n);
            worst_line = worst_line.max(l.abs());
        }
        // Line-to-line amplitude m*sqrt(3)/2 = 1.0 of the DC link at m = 1.1547.
        assert!((worst_line - 1.0).abs() < 0.002, "{worst_line}");
    }

    /// Fundamental of the line voltage (duty_1 - duty_2, in units of U_dc) over one
    /// 1000-period turn, by correlation.
    fn line_fundamental(m_q16: u32, injection: bool) -> f64 {
        let mut m = Modulator::new(4, injection);
        let periods = 1000u32;
        m.set_params(three_phase(m_q16, u64::MAX / u64::from(periods) + 1));
        let n = 10_000u16;
        let (mut re, mut im) = (0.0, 0.0);
        for k in 0..periods {
            let d = m.step(n);
            for x in d {
                assert!(x <= n);
            }
            let v = (f64::from(d[0]) - f64::from(d[1])) / f64::from(n);
            let a = std::f64::consts::TAU * f64::from(k) / f64::from(periods);
            re += v * a.cos();
            im += v * a.sin();
        }
        2.0 * re.hypot(im) / f64::from(periods)
    }

    #[test]
    fn overmodulation_keeps_the_fundamental_rising_to_six_step() {
        let q16 = |m: f64| (m * 65536.0).round() as u32;
        let lin = 3f64.sqrt() / 2.0;
        // Linear range: sqrt(3)/2 * m.
        assert!((line_fundamental(q16(0.5), false) - lin * 0.5).abs() < 1e-3);
        assert!((line_fundamental(q16(1.0), false) - lin).abs() < 2e-3);
        // Clipped sine: (2/pi)(asin(1/m) + sqrt(1 - 1/m^2)/m) * m of the linear value.
        for m in [1.1, 1.2, 1.3, 1.465, 2.0] {
            let r = 1.0 / m;
            let expect =
                lin * m * 2.0 / std::f64::consts::PI * (r.asin() + r * (1.0 - r * r).sqrt());
            let got = line_fundamental(q16(m), false);
            assert!((got - expect).abs() < 3e-3, "m {m}: {got} vs {expect}");
        }
        // Monotonic up to the six-step limit 2 sqrt(3)/pi = 1.1027 of U_dc.
        let six_step = 2.0 * 3f64.sqrt() / std::f64::consts::PI;
        let mut last = 0.0;
        for k in 1..=16 {
            let v = line_fundamental(q16(0.5 * f64::from(k)), false);
            assert!(v > last, "m = {}", 0.5 * f64::from(k));
            assert!(v <= six_step + 1e-9);
            last = v;
        }
        assert!(last > 0.99 * six_step, "{last}");
        // With min-max injection: linear to 1.1547, then clipping too.
        let at_lin = line_fundamental(M_MAX_MIN_MAX_Q16, true);
        assert!((at_lin - 1.0).abs() < 3e-3, "{at_lin}");
        assert!(line_fundamental(q16(1.5), true) > at_lin);
    }

    #[test]
    fn accumulator_advances_by_step_and_wraps() {
        let mut m = Modulator::new(4, false);
        m.set_params(ModulatorParams {
            step: 1 << 63,
            ..three_phase(0, 0)
        });
        m.step(100);
        assert_eq!(m.theta(), 0x8000_0000);
        m.step(100);
        assert_eq!(m.theta(), 0);
    }
}
