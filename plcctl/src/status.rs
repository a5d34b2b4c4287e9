//! `status`, `watch` and `counters`.

use std::io::Write;
use std::time::{Duration, Instant};

use serde_json::json;
use shared_protocol::service::{Answer, Counters, LinkView, LogText, Request, RunWarning, Status};

use crate::client::{unexpected, Client};
use crate::fail::{Fail, Result};

fn get_status(c: &mut Client) -> Result<Status> {
    match c.ask(Request::GetStatus)? {
        Answer::Status(s) => Ok(s),
        other => Err(unexpected("GetStatus", &other)),
    }
}

/// Tenths as text with one decimal (exact).
pub fn tenths(v: i32) -> String {
    let sign = if v < 0 { "-" } else { "" };
    format!("{sign}{}.{}", v.unsigned_abs() / 10, v.unsigned_abs() % 10)
}

/// Hundredths as text with two decimals (exact).
pub fn hundredths(v: i32) -> String {
    let sign = if v < 0 { "-" } else { "" };
    format!(
        "{sign}{}.{:02}",
        v.unsigned_abs() / 100,
        v.unsigned_abs() % 100
    )
}

/// The status as text lines.
pub fn status_text(s: &Status) -> String {
    let mut t = String::new();
    let link = match s.link {
        LinkView::Up => "up".to_string(),
        LinkView::Lost => "lost".to_string(),
        LinkView::VersionMismatch { drive_version } => {
            format!("version mismatch (drive {drive_version})")
        }
    };
    t += &format!(
        "PLC {}  remote service {}  link {link}\n",
        s.plc.text(),
        if s.remote { "ON" } else { "OFF" }
    );
    if let Some(d) = s.drive {
        t += &format!(
            "drive {}  FRQ {} Hz {}  UDC {} V  IMX {} A  COM {}  FLT {}\n",
            d.state.name(),
            tenths(d.freq_dhz.into()),
            if d.reverse { "REV" } else { "FWD" },
            tenths(d.udc_dv.into()),
            hundredths(d.imax_ca.into()),
            d.com,
            d.fault
        );
    }
    let bits = |v: u32, n: u32| -> String {
        (0..n)
            .map(|i| if (v >> i) & 1 == 1 { '1' } else { '0' })
            .collect()
    };
    t += &format!(
        "D00-D15 {}  O00-O07 {}  A {} {} {} {}\n",
        bits(s.d.into(), 16),
        bits(s.o.into(), 8),
        s.a[0],
        s.a[1],
        s.a[2],
        s.a[3]
    );
    let lcd: Vec<String> = s
        .lcd
        .iter()
        .map(|f| f.map_or("-".to_string(), |v| v.to_string()))
        .collect();
    t += &format!("LCD fields {}\n", lcd.join(" "));
    t += &format!(
        "scan {} us (max {} us)  uptime {} s  slot {}{}\n",
        s.scan_last_us,
        s.scan_max_us,
        s.uptime_ms as f64 / 1000.0,
        s.slot.map_or("-".to_string(), |n| n.to_string()),
        if s.unsaved { " (unsaved edits)" } else { "" }
    );
    if let Some(RunWarning::Div0 { line }) = s.warning {
        t += &format!("warning: DIV0 @ {line:03}\n");
    }
    if let Some((pos, code)) = s.newest_log {
        t += &format!("newest log entry: #{pos} code {code} {}\n", LogText(code));
    }
    t
}

pub fn status(c: &mut Client, json: bool) -> Result<()> {
    let s = get_status(c)?;
    if json {
        let v = json!({ "identity": c.identity, "status": s });
        println!(
            "{}",
            serde_json::to_string_pretty(&v).map_err(anyhow::Error::from)?
        );
    } else {
        let id = &c.identity;
        println!(
            "firmware {} ({}), power-up #{}",
            id.firmware, id.git, id.power_ups
        );
        print!("{}", status_text(&s));
    }
    Ok(())
}

/// Log entries `watch` shows.
const WATCH_FAULTS: u8 = 4;

/// `watch`: the screen, the status and the newest log entries at 10 Hz; reconnects every second when the PLC
/// goes away.
pub fn watch(connect: impl Fn() -> Result<Client>, duration: Option<f64>) -> Result<()> {
    // `--duration` is at most a year (crate::args): the sum cannot overflow, checked anyway.
    let end = duration
        .and_then(|s| Duration::try_from_secs_f64(s).ok())
        .and_then(|d| Instant::now().checked_add(d));
    let mut client: Option<Client> = None;
    let mut out = std::io::stdout();
    // The newest log entries, read again when the newest position changes.
    let mut faults: (Option<(u8, u8)>, String) = (None, String::new());
    while end.is_none_or(|e| Instant::now() < e) {
        let tick = Instant::now();
        if client.is_none() {
            match connect() {
                Ok(c) => client = Some(c),
                Err(Fail::Version { host, plc }) => return Err(Fail::Version { host, plc }),
                Err(e) => {
                    writeln!(out, "\x1b[2J\x1b[Hwaiting for the PLC: {e}")?;
                    out.flush()?;
                    std::thread::sleep(Duration::from_secs(1));
                    continue;
                }
            }
        }
        let Some(c) = client.as_mut() else { continue };
        let view = (|| -> Result<String> {
            let screen = match c.ask(Request::GetScreen)? {
                Answer::Screen(s) => s,
                other => return Err(unexpected("GetScreen", &other)),
            };
            let s = get_status(c)?;
            if s.newest_log != faults.0 || faults.1.is_empty() {
                faults = (s.newest_log, crate::faults::newest_text(c, WATCH_FAULTS)?);
            }
            let mut v = String::from("+--------------------+\n");
            for r in &screen.rows {
                v += &format!("|{:<20}|\n", r.as_str());
            }
            v += "+--------------------+\n";
            v += &status_text(&s);
            v += &faults.1;
            Ok(v)
        })();
        match view {
            Ok(v) => write!(out, "\x1b[2J\x1b[H{v}")?,
            Err(Fail::Refused(r)) => return Err(Fail::Refused(r)),
            Err(_) => client = None,
        }
        out.flush()?;
        let spent = tick.elapsed();
        std::thread::sleep(Duration::from_millis(100).saturating_sub(spent));
    }
    Ok(())
}

/// `counters --json` (also `serve`'s `/api/counters`).
pub fn counters_json(c: &Counters) -> serde_json::Value {
    json!({
        "run_starts": c.run_starts,
        "run_minutes": c.run_minutes,
        "pwm_minutes": c.pwm_minutes,
        "link_errors": c.link_errors,
        "program_saves": c.program_saves,
        "trips": c.trips.0,
        "app": c.app,
        "power_ups": c.power_ups,
        "since_write_s": c.since_write_s,
    })
}

pub fn counters(c: &mut Client, json: bool) -> Result<()> {
    let counters = match c.request(Request::GetCounters)? {
        Answer::Counters(k) => k,
        Answer::Refused(r) => {
            eprintln!(
                "plcctl: counters are not supported by this PLC ({})",
                r.text()
            );
            return Err(Fail::Refused(r));
        }
        other => return Err(unexpected("GetCounters", &other)),
    };
    if json {
        let v = counters_json(&counters);
        println!(
            "{}",
            serde_json::to_string_pretty(&v).map_err(anyhow::Error::from)?
        );
        return Ok(());
    }
    let k = &counters;
    println!("RUN starts       {}", k.run_starts);
    println!("minutes in RUN   {}", k.run_minutes);
    println!("minutes PWM on   {}", k.pwm_minutes);
    println!("link errors      {}", k.link_errors);
    println!("program saves    {}", k.program_saves);
    println!("power-ups        {}", k.power_ups);
    for (i, n) in k.trips.0.iter().enumerate().filter(|(_, n)| **n > 0) {
        println!("trips code {:>2}    {n}", i + 1);
    }
    for (i, n) in k.app.iter().enumerate() {
        println!("app counter {} (Q{}) {n}", i + 1, 60 + i);
    }
    Ok(())
}
