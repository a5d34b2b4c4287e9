//! The host's record of when each power-up of a PLC began (service.md 6): the PLC has no
//! clock, its log entries carry (power-up, seconds since it). At every connection the
//! wall-clock start of the current power-up is recorded, per MCU unique ID, so that
//! entries of older power-ups get a date too.
//!
//! One file per PLC, `$XDG_CACHE_HOME/plcctl/<uid hex>.txt` (else
//! `~/.cache/plcctl/`), a line `power_up start_unix_ms` per power-up. Best effort: a
//! cache that cannot be read or written only costs the dates of older power-ups.

use std::collections::BTreeMap;
use std::path::PathBuf;

/// When the current power-up began (Unix ms): `at_ms`, the host's clock when the PLC
/// said it had been up `uptime_ms`, minus that uptime; `None` when the PLC's number is
/// beyond what a clock can hold (device data is never trusted to be sane).
pub fn power_up_start_ms(at_ms: i64, uptime_ms: u64) -> Option<i64> {
    at_ms.checked_sub(i64::try_from(uptime_ms).ok()?)
}

/// The last millisecond of the year 9999: dates beyond it (or before 1970) come from a
/// PLC or a cache that is wrong, and are not shown as dates.
const LAST_DATE_MS: i64 = 253_402_300_799_999;

/// The wall-clock time `uptime_s` into a power-up that began at `start_ms`; `None`
/// outside 1970-9999.
pub fn date_of(start_ms: i64, uptime_s: u32) -> Option<chrono::DateTime<chrono::Utc>> {
    let ms = start_ms.checked_add(i64::from(uptime_s).checked_mul(1000)?)?;
    if !(0..=LAST_DATE_MS).contains(&ms) {
        return None;
    }
    chrono::DateTime::from_timestamp_millis(ms)
}

/// Power-up starts of one PLC.
#[derive(Debug, Default)]
pub struct PowerUps {
    path: Option<PathBuf>,
    starts: BTreeMap<u16, i64>,
}

fn cache_dir() -> Option<PathBuf> {
    if let Some(d) = std::env::var_os("XDG_CACHE_HOME").filter(|d| !d.is_empty()) {
        return Some(PathBuf::from(d).join("plcctl"));
    }
    std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache").join("plcctl"))
}

/// Parses the file's lines; bad lines are skipped.
pub fn parse(text: &str) -> BTreeMap<u16, i64> {
    text.lines()
        .filter_map(|l| {
            let mut f = l.split_whitespace();
            Some((f.next()?.parse().ok()?, f.next()?.parse().ok()?))
        })
        .collect()
}

impl PowerUps {
    /// The record of the PLC with `uid`.
    pub fn load(uid: &[u8; 12]) -> Self {
        let name: String = uid.iter().map(|b| format!("{b:02x}")).collect();
        let path = cache_dir().map(|d| d.join(format!("{name}.txt")));
        let starts = path
            .as_ref()
            .and_then(|p| std::fs::read_to_string(p).ok())
            .map(|t| parse(&t))
            .unwrap_or_default();
        PowerUps { path, starts }
    }

    /// Power-up `n` began at `start_ms` (Unix ms); written back when it is new or moved
    /// by more than a second (the host's and the PLC's clocks drift apart).
    pub fn record(&mut self, n: u16, start_ms: i64) {
        let known = self.starts.get(&n).copied();
        if known.is_some_and(|k| k.abs_diff(start_ms) <= 1000) {
            return;
        }
        self.starts.insert(n, start_ms);
        let Some(p) = &self.path else { return };
        let text: String = self
            .starts
            .iter()
            .map(|(n, t)| format!("{n} {t}\n"))
            .collect();
        if let Some(d) = p.parent() {
            let _ = std::fs::create_dir_all(d);
        }
        let _ = std::fs::write(p, text);
    }

    /// When power-up `n` began, if recorded.
    pub fn start_of(&self, n: u16) -> Option<i64> {
        self.starts.get(&n).copied()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn absurd_uptimes_give_no_date_and_no_panic() {
        let now = 1_800_000_000_000;
        assert_eq!(power_up_start_ms(now, 5_000), Some(now - 5_000));
        for up in [u64::MAX, i64::MAX as u64, 1 << 62] {
            if let Some(start) = power_up_start_ms(now, up) {
                for s in [0, 1, u32::MAX] {
                    let _ = date_of(start, s);
                }
            }
        }
        assert_eq!(power_up_start_ms(i64::MIN, 1), None);
        assert_eq!(date_of(i64::MAX, 1), None);
        assert_eq!(date_of(i64::MIN + 1, 0), None);
        let d = date_of(now - 5_000, 2).unwrap();
        assert_eq!(d.timestamp_millis(), now - 3_000);
        let mut p = PowerUps::default();
        p.record(1, i64::MIN);
        p.record(1, i64::MAX);
        assert_eq!(p.start_of(1), Some(i64::MAX));
    }

    #[test]
    fn lines_parse_and_bad_ones_are_skipped() {
        let m = parse("3 1700000000000\nx y\n4\n5 -12\n");
        assert_eq!(m.get(&3), Some(&1_700_000_000_000));
        assert_eq!(m.get(&5), Some(&-12));
        assert_eq!(m.len(), 2);
    }
}
