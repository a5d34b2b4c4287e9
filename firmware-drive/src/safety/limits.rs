//! The 24 settings as the monitor reads them: one table of the written values (absent =
//! 0), with accessors that convert on use: T(s) = 100·s ticks for 0.1 s, n turns = n·10⁴
//! units of x. A multiply per use is cheaper in flash than a converted copy of every
//! setting (the drive image has a 64 KiB budget). Absent settings are 0 (safety.md 4: 0 is
//! every optional setting's default, and the strictest value of a needed one that the
//! verifier should have refused).

use shared_protocol::safety::{SafetySetting as S, SafetySettings, SETTINGS};

/// The settings as the monitor uses them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Limits {
    raw: [u16; SETTINGS],
}

impl Limits {
    pub fn from_settings(s: &SafetySettings) -> Self {
        let mut l = Limits::default();
        l.load(s);
        l
    }

    /// Take new settings, in place.
    pub fn load(&mut self, s: &SafetySettings) {
        for (dst, k) in self.raw.iter_mut().zip(S::ALL) {
            *dst = s.or_zero(k);
        }
    }

    /// The value as written (0 when absent).
    #[inline(always)]
    pub fn get(&self, s: S) -> u16 {
        self.raw.get(s.index()).copied().unwrap_or(0)
    }

    /// A setting in 0.1 s, as ticks.
    #[inline(always)]
    pub fn ticks(&self, s: S) -> u32 {
        u32::from(self.get(s)) * 100
    }

    /// A speed or rate setting (0.1 Hz, 0.1 Hz/s) as a signed value.
    #[inline(always)]
    pub fn speed(&self, s: S) -> i32 {
        i32::from(self.get(s))
    }

    /// A setting in turns, as 10⁻⁴ turn.
    #[inline(always)]
    pub fn turns_e4(&self, s: S) -> i64 {
        i64::from(self.get(s)) * 10_000
    }

    /// `fss`, 0.1 Hz.
    #[inline(always)]
    pub fn fss(&self) -> i32 {
        self.speed(S::Fss)
    }

    /// `pss`, 10⁻⁴ turn.
    #[inline(always)]
    pub fn pss(&self) -> i64 {
        self.turns_e4(S::Pss)
    }
}

/// ⌊rate·n/1000⌋ in 0.1 Hz for a rate in 0.1 Hz/s over n ticks, saturating, in 32-bit
/// arithmetic (no 64-bit division on the M4): rate·n = rate·1000·⌊n/1000⌋ + rate·(n mod
/// 1000), and the second part is below 10⁷.
pub fn ramp_drop(rate: u16, n: u32) -> u32 {
    let r = u32::from(rate);
    r.saturating_mul(n / 1000)
        .saturating_add(r * (n % 1000) / 1000)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ramp_drop_is_the_exact_floor() {
        for (rate, n) in [
            (20u16, 49u32),
            (20, 50),
            (50, 1199),
            (50, 1200),
            (9999, 999_900),
        ] {
            assert_eq!(
                u64::from(ramp_drop(rate, n)),
                u64::from(rate) * u64::from(n) / 1000,
                "{rate} {n}"
            );
        }
        assert_eq!(ramp_drop(9999, u32::MAX), u32::MAX);
        assert_eq!(ramp_drop(0, u32::MAX), 0);
    }

    #[test]
    fn settings_convert_to_ticks_and_turns() {
        let mut s = SafetySettings::default();
        s.set(S::Fss, Some(40));
        s.set(S::Pss, Some(200));
        s.set(S::Trd, Some(50));
        s.set(S::Ts1, Some(100));
        s.set(S::Fl2, Some(100));
        s.set(S::Pli, Some(9999));
        let l = Limits::from_settings(&s);
        assert_eq!(
            (l.fss(), l.pss(), l.ticks(S::Trd), l.ticks(S::Ts1)),
            (40, 2_000_000, 5000, 10_000)
        );
        assert_eq!((l.speed(S::Fl2), l.turns_e4(S::Pli)), (100, 99_990_000));
        // Absent = 0.
        assert_eq!(
            (
                l.ticks(S::Tel),
                l.get(S::Ard),
                l.get(S::Asr),
                l.ticks(S::Ts2)
            ),
            (0, 0, 0, 0)
        );
    }
}
