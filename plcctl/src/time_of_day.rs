//! The PLC's clock from the PC: `plcctl clock` (show it and its offset to the PC),
//! `plcctl clock set [--time T]` and `serve`'s set on connect.
//!
//! Time zone rule: the PLC keeps UTC (seconds since 2000-01-01 00:00:00 UTC); the PC
//! shows UTC and its own local time. `--time` takes RFC 3339 with its offset
//! (`2026-11-29T11:00:00+01:00`) or a plain `YYYY-MM-DD HH:MM:SS`, which is UTC.

use std::time::Duration;

use chrono::{DateTime, Local, NaiveDateTime, Utc};
use shared_protocol::service::{Answer, Request, WALL_EPOCH_UNIX_S, WALL_MAX_S};

use crate::client::{unexpected, Client};
use crate::fail::{Fail, Result};

/// `serve` sets the clock when it is unset or off by more than this (seconds).
pub const SERVE_TOLERANCE_S: f64 = 2.0;

/// The PLC's seconds as a UTC time.
pub fn utc(seconds: u32) -> Option<DateTime<Utc>> {
    DateTime::from_timestamp(WALL_EPOCH_UNIX_S + i64::from(seconds), 0)
}

/// A UTC time as the PLC's seconds; `None` outside 2000-2099.
pub fn plc_seconds(t: DateTime<Utc>) -> Option<u32> {
    let s = u32::try_from(t.timestamp() - WALL_EPOCH_UNIX_S).ok()?;
    (s <= WALL_MAX_S).then_some(s)
}

/// `--time`: RFC 3339, or `YYYY-MM-DD HH:MM:SS` (also with `T`) in UTC.
pub fn parse_time(s: &str) -> std::result::Result<DateTime<Utc>, String> {
    let s = s.trim();
    if let Ok(t) = DateTime::parse_from_rfc3339(s) {
        return Ok(t.with_timezone(&Utc));
    }
    for f in ["%Y-%m-%d %H:%M:%S", "%Y-%m-%dT%H:%M:%S"] {
        if let Ok(t) = NaiveDateTime::parse_from_str(s, f) {
            return Ok(t.and_utc());
        }
    }
    Err(format!(
        "{s:?}: give RFC 3339 (2026-11-29T11:00:00+01:00) or YYYY-MM-DD HH:MM:SS (UTC)"
    ))
}

/// The PLC's clock, and the PC's time half-way through the request.
fn get(c: &mut Client) -> Result<(Option<u32>, DateTime<Utc>)> {
    let before = Utc::now();
    let a = c.ask(Request::GetClock)?;
    let after = Utc::now();
    let pc = before + (after - before) / 2;
    match a {
        Answer::Clock { seconds } => Ok((seconds, pc)),
        other => Err(unexpected("GetClock", &other)),
    }
}

/// The PLC's clock minus the PC's, in seconds (the PLC counts whole seconds: an exact
/// clock reads up to 1 s behind).
fn offset_s(plc: u32, pc: DateTime<Utc>) -> Option<f64> {
    let plc = utc(plc)?;
    Some((plc - pc).num_milliseconds() as f64 / 1000.0)
}

/// Sets the PLC's clock to `time`, or to the PC's UTC now sent at a whole second.
fn set(c: &mut Client, time: Option<DateTime<Utc>>) -> Result<u32> {
    let target = match time {
        Some(t) => t,
        None => {
            // Wait for the next whole second so the PLC starts it on time.
            let now = Utc::now();
            let frac = u64::from(now.timestamp_subsec_nanos());
            std::thread::sleep(Duration::from_nanos(1_000_000_000 - frac));
            Utc::now()
        }
    };
    let seconds = plc_seconds(target).ok_or_else(|| {
        Fail::Usage(anyhow::anyhow!(
            "{target}: the PLC's clock holds 2000-01-01 to 2099-12-31 (UTC)"
        ))
    })?;
    match c.ask(Request::SetClock { seconds })? {
        Answer::Clock { seconds: Some(s) } => Ok(s),
        other => Err(unexpected("SetClock", &other)),
    }
}

fn show(seconds: u32) -> String {
    match utc(seconds) {
        Some(t) => format!(
            "{} UTC ({} local)",
            t.format("%Y-%m-%d %H:%M:%S"),
            t.with_timezone(&Local).format("%Y-%m-%d %H:%M:%S %:z")
        ),
        None => format!("{seconds} s since 2000"),
    }
}

/// `plcctl clock`.
pub fn clock(c: &mut Client) -> Result<()> {
    match get(c)? {
        (Some(s), pc) => {
            println!("PLC clock {}", show(s));
            if let Some(o) = offset_s(s, pc) {
                println!("offset to this PC {o:+.1} s");
            }
        }
        (None, _) => println!("PLC clock unset (set it: plcctl clock set)"),
    }
    Ok(())
}

/// `plcctl clock set [--time T]`.
pub fn clock_set(c: &mut Client, time: Option<DateTime<Utc>>) -> Result<()> {
    let s = set(c, time)?;
    println!("PLC clock set to {}", show(s));
    Ok(())
}

/// Why `serve` sets a PLC clock that reads `plc` when the PC's time is `pc`: unset, or off
/// by more than [`SERVE_TOLERANCE_S`]; `None` leaves it alone.
fn why_set(plc: Option<u32>, pc: DateTime<Utc>) -> Option<String> {
    let Some(s) = plc else {
        return Some("unset".to_string());
    };
    match offset_s(s, pc) {
        Some(o) if o.abs() <= SERVE_TOLERANCE_S => None,
        Some(o) => Some(format!("off by {o:+.1} s")),
        None => Some(format!("at {s} s")),
    }
}

/// `serve` on connecting: sets the clock to the PC's when it is unset or off by more than
/// [`SERVE_TOLERANCE_S`]; returns the line to log when it did.
pub fn sync_on_connect(c: &mut Client) -> Result<Option<String>> {
    let (plc, pc) = get(c)?;
    let Some(why) = why_set(plc, pc) else {
        return Ok(None);
    };
    let s = set(c, None)?;
    Ok(Some(format!("PLC clock was {why}: set to {}", show(s))))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn seconds_since_2000_utc() {
        let t = parse_time("2026-11-29 10:00:00").unwrap();
        assert_eq!(plc_seconds(t), Some(849_261_600));
        assert_eq!(utc(849_261_600), Some(t));
        let t = parse_time("2026-11-29T11:00:00+01:00").unwrap();
        assert_eq!(plc_seconds(t), Some(849_261_600));
        assert_eq!(
            plc_seconds(parse_time("2000-01-01 00:00:00").unwrap()),
            Some(0)
        );
        assert_eq!(
            plc_seconds(parse_time("2099-12-31T23:59:59Z").unwrap()),
            Some(WALL_MAX_S)
        );
        assert_eq!(
            plc_seconds(parse_time("2100-01-01 00:00:00").unwrap()),
            None
        );
        assert_eq!(
            plc_seconds(parse_time("1999-12-31 23:59:59").unwrap()),
            None
        );
        assert!(parse_time("tomorrow").is_err());
    }

    #[test]
    fn the_offset_is_the_plcs_minus_the_pcs() {
        let pc = parse_time("2026-11-29 10:00:03").unwrap();
        assert_eq!(offset_s(849_261_600, pc), Some(-3.0));
    }

    #[test]
    fn serve_sets_an_unset_clock_or_one_off_by_more_than_2_s() {
        let pc = parse_time("2026-11-29 10:00:00").unwrap();
        let plc = 849_261_600;
        assert_eq!(why_set(None, pc).as_deref(), Some("unset"));
        assert_eq!(why_set(Some(plc), pc), None);
        assert_eq!(why_set(Some(plc + 2), pc), None, "2 s ahead: left");
        assert_eq!(why_set(Some(plc - 2), pc), None, "2 s behind: left");
        assert_eq!(why_set(Some(plc + 3), pc).as_deref(), Some("off by +3.0 s"));
        assert_eq!(why_set(Some(plc - 3), pc).as_deref(), Some("off by -3.0 s"));
        // Half a second past the tolerance (the PC's time between whole seconds).
        let pc_half = pc + chrono::Duration::milliseconds(2_500);
        assert_eq!(
            why_set(Some(plc), pc_half).as_deref(),
            Some("off by -2.5 s")
        );
    }
}
