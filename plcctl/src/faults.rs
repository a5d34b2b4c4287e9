//! `faults`: the whole fault log, newest first, each entry with its time of day on the
//! PLC's clock (or `clock not set`), the host's estimate of it from the uptime, its text
//! (an application fault's from the application profile) and its two application values
//! (service.md 6).

use serde::Serialize;
use shared_protocol::service::{
    app_fault_of, field_fault_name, log_name, Answer, LogEntry, LogText, Request,
    LOG_ENTRIES_PER_ANSWER, LOG_FROM_NEWEST, LOG_POSITIONS, UPTIME_LIMIT_S,
};

use crate::client::{unexpected, Client};
use crate::clock::{date_of, power_up_start_ms};
use crate::fail::Result;
use crate::serve::profile::Profile;

/// What the `time` of an entry without the PLC's time of day says.
pub const CLOCK_NOT_SET: &str = "clock not set";

/// One row of `faults` (CSV columns and JSON keys).
#[derive(Debug, Serialize)]
pub struct Row {
    pub pos: u8,
    /// The PLC's time of day when it was logged, local `YYYY-MM-DD HH:MM:SS`, or
    /// [`CLOCK_NOT_SET`].
    pub time: String,
    /// The same as seconds since 2000-01-01 00:00:00 UTC (`null`: clock not set).
    pub wall_s: Option<u32>,
    /// The host's estimate from the power-up's start and the uptime (as before the PLC
    /// had a clock): local time, or `power-up #N + hh:mm:ss`.
    pub host_time: String,
    pub power_up: u16,
    pub uptime_s: u32,
    pub code: u8,
    pub name: &'static str,
    pub text: String,
    /// The two application values (the program's first two `LCD` fields at the time),
    /// named by `value_names`.
    pub values: [Option<i16>; 2],
    pub value_names: [String; 2],
}

/// What the application profile says about the log: the texts of application faults and
/// the names of the two values (without a profile: `application fault n`, `lcd0`,
/// `lcd1`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LogNames {
    pub faults: std::collections::BTreeMap<u8, String>,
    pub values: [String; 2],
}

impl Default for LogNames {
    fn default() -> Self {
        LogNames::of(&Profile::default())
    }
}

impl LogNames {
    pub fn of(p: &Profile) -> LogNames {
        LogNames {
            faults: p.faults.clone(),
            values: p.log_values.clone(),
        }
    }

    /// The text of `code`: the profile's for an application fault it names.
    pub fn text(&self, code: u8) -> String {
        app_fault_of(code)
            .and_then(|n| self.faults.get(&n).cloned())
            .unwrap_or_else(|| LogText(code).to_string())
    }
}

/// Every entry, newest first: pages of [`LOG_ENTRIES_PER_ANSWER`] from the newest
/// position down.
pub fn read_log(c: &mut Client) -> Result<Vec<LogEntry>> {
    let mut all: Vec<LogEntry> = Vec::new();
    let mut from = LOG_FROM_NEWEST;
    loop {
        let log = match c.ask(Request::ReadFaultLog {
            from,
            count: LOG_ENTRIES_PER_ANSWER as u8,
        })? {
            Answer::FaultLog(l) => l,
            other => return Err(unexpected("ReadFaultLog", &other)),
        };
        let Some(last) = log.entries.last().copied() else {
            return Ok(all);
        };
        all.extend(log.entries.iter().copied());
        if all.len() >= usize::from(log.total) || all.len() >= usize::from(LOG_POSITIONS) {
            all.truncate(usize::from(log.total));
            return Ok(all);
        }
        from = (last.pos + LOG_POSITIONS - 1) % LOG_POSITIONS;
    }
}

/// The entry's time of day on the PLC's clock, local time, or [`CLOCK_NOT_SET`].
pub fn wall_time(e: &LogEntry) -> String {
    e.wall_s
        .and_then(crate::time_of_day::utc)
        .map(|t| {
            t.with_timezone(&chrono::Local)
                .format("%Y-%m-%d %H:%M:%S")
                .to_string()
        })
        .unwrap_or_else(|| CLOCK_NOT_SET.to_string())
}

/// The host's estimate of the entry's time: on the host's clock for the current power-up
/// (now − (uptime now − entry uptime)), for older ones from the recorded start of that
/// power-up ([`crate::clock`]), else `power-up #N + hh:mm:ss`.
fn time_of(c: &Client, e: &LogEntry) -> String {
    let id = &c.identity;
    let hms = |s: u32| {
        if s >= UPTIME_LIMIT_S {
            "≥ 194 d".to_string()
        } else {
            format!("{:02}:{:02}:{:02}", s / 3600, s / 60 % 60, s % 60)
        }
    };
    let local = |t: chrono::DateTime<chrono::Utc>| {
        t.with_timezone(&chrono::Local)
            .format("%Y-%m-%d %H:%M:%S")
            .to_string()
    };
    // Every step checked: a PLC's uptime or a cache line can be anything.
    let current = (e.power_up == id.power_ups as u16)
        .then(|| power_up_start_ms(c.identified_at.timestamp_millis(), id.uptime_ms))
        .flatten();
    // A long-lived connection (`serve`, `watch`) reads entries written after its
    // `Identify`: they are simply later in the same power-up.
    let start = current.or_else(|| c.power_ups.start_of(e.power_up));
    if let Some(t) = start
        .filter(|_| e.uptime_s < UPTIME_LIMIT_S)
        .and_then(|s| date_of(s, e.uptime_s))
    {
        return local(t);
    }
    format!("power-up #{} + {}", e.power_up, hms(e.uptime_s))
}

/// The newest `count` entries as text lines (`watch`), or `fault log empty`.
pub fn newest_text(c: &mut Client, count: u8) -> Result<String> {
    let log = match c.ask(Request::ReadFaultLog {
        from: LOG_FROM_NEWEST,
        count,
    })? {
        Answer::FaultLog(l) => l,
        other => return Err(unexpected("ReadFaultLog", &other)),
    };
    if log.entries.is_empty() {
        return Ok("fault log empty\n".into());
    }
    let names = LogNames::default();
    let mut t = format!("fault log ({} entries), newest first:\n", log.total);
    for e in &log.entries {
        t += &format!("  {}\n", line(&row(c, e, &names)));
    }
    Ok(t)
}

fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

/// The row of entry `e`.
fn row(c: &Client, e: &LogEntry, names: &LogNames) -> Row {
    Row {
        pos: e.pos,
        time: wall_time(e),
        wall_s: e.wall_s,
        host_time: time_of(c, e),
        power_up: e.power_up,
        uptime_s: e.uptime_s,
        code: e.code,
        name: field_fault_name(e.code).unwrap_or(log_name(e.code)),
        text: names.text(e.code),
        values: e.values,
        value_names: names.values.clone(),
    }
}

/// A row as a line of text: position, time (without the PLC's clock the host's estimate
/// follows in brackets), code, name, text, and the values that are there.
pub fn line(r: &Row) -> String {
    let time = if r.wall_s.is_some() {
        r.time.clone()
    } else {
        format!("{} [~{}]", r.time, r.host_time)
    };
    let mut t = format!(
        "#{:<2} {:<36} {:>3} {:<7} {}",
        r.pos, time, r.code, r.name, r.text
    );
    for (name, v) in r.value_names.iter().zip(r.values) {
        if let Some(v) = v {
            t += &format!(", {name} {v}");
        }
    }
    t
}

/// The whole log as `faults --json` rows, newest first (also `serve`'s `/api/faults`).
pub fn rows(c: &mut Client, names: &LogNames) -> Result<Vec<Row>> {
    Ok(read_log(c)?.iter().map(|e| row(c, e, names)).collect())
}

/// The CSV's header: the row's columns, the two values under their names.
fn csv_header(names: &LogNames) -> String {
    format!(
        "pos,time,wall_s,host_time,power_up,uptime_s,code,name,text,{},{}",
        csv_field(&names.values[0]),
        csv_field(&names.values[1])
    )
}

pub fn faults(c: &mut Client, csv: bool, json: bool, profile: &Profile) -> Result<()> {
    let names = LogNames::of(profile);
    let rows = rows(c, &names)?;
    let opt = |v: Option<i64>| v.map(|v| v.to_string()).unwrap_or_default();
    if json {
        println!(
            "{}",
            serde_json::to_string_pretty(&rows).map_err(anyhow::Error::from)?
        );
    } else if csv {
        println!("{}", csv_header(&names));
        for r in &rows {
            println!(
                "{},{},{},{},{},{},{},{},{},{},{}",
                r.pos,
                csv_field(&r.time),
                opt(r.wall_s.map(i64::from)),
                csv_field(&r.host_time),
                r.power_up,
                r.uptime_s,
                r.code,
                r.name,
                csv_field(&r.text),
                opt(r.values[0].map(i64::from)),
                opt(r.values[1].map(i64::from)),
            );
        }
    } else if rows.is_empty() {
        println!("fault log empty");
    } else {
        for r in &rows {
            println!("{}", line(r));
        }
    }
    Ok(())
}
