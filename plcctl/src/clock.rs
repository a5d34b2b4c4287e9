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
        if known.is_some_and(|k| (k - start_ms).abs() <= 1000) {
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
    fn lines_parse_and_bad_ones_are_skipped() {
        let m = parse("3 1700000000000\nx y\n4\n5 -12\n");
        assert_eq!(m.get(&3), Some(&1_700_000_000_000));
        assert_eq!(m.get(&5), Some(&-12));
        assert_eq!(m.len(), 2);
    }
}
