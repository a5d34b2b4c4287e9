//! `faults`: the whole fault log, newest first, with times on the host's clock where
//! they can be known (service.md 6).

use serde::Serialize;
use shared_protocol::service::{
    log_name, Answer, LogEntry, LogText, Request, LOG_ENTRIES_PER_ANSWER, LOG_FROM_NEWEST,
    UPTIME_LIMIT_S,
};

use crate::client::{unexpected, Client};
use crate::clock::{date_of, power_up_start_ms};
use crate::fail::Result;

/// Ring positions of the log.
const RING: u8 = 32;

/// One row of `faults` (CSV columns and JSON keys).
#[derive(Debug, Serialize)]
pub struct Row {
    pub pos: u8,
    pub time: String,
    pub power_up: u16,
    pub uptime_s: u32,
    pub code: u8,
    pub name: &'static str,
    pub text: String,
}

/// Every entry, newest first: pages of 8 from the newest position down.
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
        if all.len() >= usize::from(log.total) || all.len() >= usize::from(RING) {
            all.truncate(usize::from(log.total));
            return Ok(all);
        }
        from = (last.pos + RING - 1) % RING;
    }
}

/// The entry's time: on the host's clock for the current power-up (now − (uptime now −
/// entry uptime)), for older ones from the recorded start of that power-up
/// ([`crate::clock`]), else `power-up #N + hh:mm:ss`.
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
    let mut t = format!("fault log ({} entries), newest first:\n", log.total);
    for e in &log.entries {
        t += &format!(
            "  #{:<2} {:<26} {:>3} {:<7} {}\n",
            e.pos,
            time_of(c, e),
            e.code,
            log_name(e.code),
            LogText(e.code)
        );
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

/// The whole log as `faults --json` rows, newest first (also `serve`'s `/api/faults`).
pub fn rows(c: &mut Client) -> Result<Vec<Row>> {
    Ok(read_log(c)?
        .iter()
        .map(|e| Row {
            pos: e.pos,
            time: time_of(c, e),
            power_up: e.power_up,
            uptime_s: e.uptime_s,
            code: e.code,
            name: log_name(e.code),
            text: LogText(e.code).to_string(),
        })
        .collect())
}

pub fn faults(c: &mut Client, csv: bool, json: bool) -> Result<()> {
    let rows = rows(c)?;
    if json {
        println!(
            "{}",
            serde_json::to_string_pretty(&rows).map_err(anyhow::Error::from)?
        );
    } else if csv {
        println!("pos,time,power_up,uptime_s,code,name,text");
        for r in &rows {
            println!(
                "{},{},{},{},{},{},{}",
                r.pos,
                csv_field(&r.time),
                r.power_up,
                r.uptime_s,
                r.code,
                r.name,
                csv_field(&r.text)
            );
        }
    } else if rows.is_empty() {
        println!("fault log empty");
    } else {
        for r in &rows {
            println!(
                "#{:<2} {:<28} {:>3} {:<7} {}",
                r.pos, r.time, r.code, r.name, r.text
            );
        }
    }
    Ok(())
}
