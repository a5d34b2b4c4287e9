//! The 24 settings in the monitor's units, converted once per download so that a tick
//! only adds and compares: T(s) = 100·s ticks for 0.1 s, n turns = n·10⁴ units of x.
//! Absent settings are 0 (safety.md 4: 0 is every optional setting's default, and the
//! strictest value of a needed one that the verifier should have refused).

use shared_protocol::safety::{SafetySetting as S, SafetySettings};

/// Ticks of a setting in 0.1 s.
const fn ticks(ds: u16) -> u32 {
    ds as u32 * 100
}

/// 10⁻⁴ turn of a setting in turns.
const fn turns_e4(t: u16) -> i64 {
    t as i64 * 10_000
}

/// The settings as the monitor uses them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Limits {
    /// `fss`, 0.1 Hz.
    pub fss: i32,
    /// `pss`, 10⁻⁴ turn.
    pub pss: i64,
    /// `trd`, ticks.
    pub trd: u32,
    /// `ard`, 0.1 Hz/s (0 = off).
    pub ard: u16,
    /// `tel`, ticks (0 = off).
    pub tel: u32,
    /// `ts1`, `ts2`, ticks.
    pub ts: [u32; 2],
    /// `fl1`..`fl4`, 0.1 Hz.
    pub fl: [i32; 4],
    /// `tl1`..`tl4`, ticks.
    pub tl: [u32; 4],
    /// `pli`, 10⁻⁴ turn.
    pub pli: i64,
    /// `tli`, `tdi`, `tla`, ticks.
    pub tli: u32,
    pub tdi: u32,
    pub tla: u32,
    /// `aap` `adp` `aan` `adn`, 0.1 Hz/s.
    pub aap: i32,
    pub adp: i32,
    pub aan: i32,
    pub adn: i32,
    /// `asr`, 0.1 Hz/s (0 = off).
    pub asr: u16,
}

impl Limits {
    pub fn from_settings(s: &SafetySettings) -> Self {
        let g = |k| s.or_zero(k);
        let gi = |k| i32::from(s.or_zero(k));
        Limits {
            fss: gi(S::Fss),
            pss: turns_e4(g(S::Pss)),
            trd: ticks(g(S::Trd)),
            ard: g(S::Ard),
            tel: ticks(g(S::Tel)),
            ts: [ticks(g(S::Ts1)), ticks(g(S::Ts2))],
            fl: [gi(S::Fl1), gi(S::Fl2), gi(S::Fl3), gi(S::Fl4)],
            tl: [
                ticks(g(S::Tl1)),
                ticks(g(S::Tl2)),
                ticks(g(S::Tl3)),
                ticks(g(S::Tl4)),
            ],
            pli: turns_e4(g(S::Pli)),
            tli: ticks(g(S::Tli)),
            tdi: ticks(g(S::Tdi)),
            tla: ticks(g(S::Tla)),
            aap: gi(S::Aap),
            adp: gi(S::Adp),
            aan: gi(S::Aan),
            adn: gi(S::Adn),
            asr: g(S::Asr),
        }
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
            (l.fss, l.pss, l.trd, l.ts[0]),
            (40, 2_000_000, 5000, 10_000)
        );
        assert_eq!((l.fl[1], l.pli), (100, 99_990_000));
        // Absent = 0.
        assert_eq!((l.tel, l.ard, l.asr, l.ts[1], l.fl[0]), (0, 0, 0, 0, 0));
    }
}
