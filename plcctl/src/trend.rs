//! `trend --csv [--plot]`: samples as CSV with hil-sim's column names and number formats
//! (service.md 8), reconnecting every second when the PLC goes away (a gap is missing
//! rows; each step is said on stderr, and only the PLC with the first connection's UID
//! continues the recording). The CSV replaces an existing file only at the end. `--plot` draws them with hil-sim's plotting code (the `trend-plot` crate) for
//! the columns the PLC knows. Ctrl-C ends the recording like the end of `--duration`:
//! the CSV is complete and the plot is drawn.

use std::io::Write;
use std::path::Path;
use std::time::{Duration, Instant};

use shared_protocol::service::{Answer, Request, Sample, MAX_SUBSCRIBED_Q};

use trend_plot::atomic::AtomicFile;
use trend_plot::{Column, Marks};

use crate::client::{unexpected, Client};
use crate::fail::{Fail, Result};
use crate::status::{hundredths, tenths};
use crate::usage;

fn hex(uid: &[u8]) -> String {
    uid.iter().map(|b| format!("{b:02x}")).collect()
}

/// `--q Q04,Q05` as register numbers (default Q00-Q07).
pub fn parse_q(q: &[String]) -> Result<Vec<u8>> {
    if q.is_empty() {
        return Ok((0..8).collect());
    }
    if q.len() > MAX_SUBSCRIBED_Q {
        return Err(usage(format!(
            "--q: at most {MAX_SUBSCRIBED_Q} Q variables"
        )));
    }
    q.iter()
        .map(|s| {
            let n = s
                .trim()
                .strip_prefix(['Q', 'q'])
                .and_then(|d| d.parse::<u8>().ok())
                .filter(|n| *n <= 63);
            n.ok_or_else(|| usage(format!("--q: {s:?} is not Q00-Q63")))
        })
        .collect()
}

/// The header: hil-sim's names for what the PLC knows, plus `imx_a`.
pub fn header(q: &[u8]) -> String {
    let mut cols: Vec<String> = ["t_s", "f_cmd_hz", "dir", "fault", "u_dc_v"]
        .iter()
        .map(|s| s.to_string())
        .collect();
    cols.extend((0..16).map(|n| format!("D{n:02}")));
    cols.extend((0..8).map(|n| format!("O{n:02}")));
    cols.extend(q.iter().map(|n| format!("Q{n:02}")));
    cols.extend((0..4).map(|n| format!("lcd{n}")));
    cols.push("imx_a".into());
    cols.join(",")
}

/// One row; the drive's columns are empty while the link is down.
pub fn row(s: &Sample) -> String {
    let ms = s.uptime_ms;
    let mut r = format!("{}.{:03}000", ms / 1000, ms % 1000);
    match s.drive {
        Some(d) => {
            r += &format!(
                ",{},{},{},{}00",
                tenths(d.freq_dhz.into()),
                if d.reverse { -1 } else { 1 },
                d.fault,
                tenths(d.udc_dv.into())
            );
        }
        None => r += ",,,,",
    }
    for n in 0..16 {
        r += &format!(",{}", (s.d >> n) & 1);
    }
    for n in 0..8 {
        r += &format!(",{}", (s.o >> n) & 1);
    }
    for v in &s.q {
        r += &format!(",{v}");
    }
    for f in s.lcd {
        match f {
            Some(v) => r += &format!(",{v}"),
            None => r.push(','),
        }
    }
    match s.drive {
        Some(d) => r += &format!(",{}", hundredths(d.imax_ca.into())),
        None => r.push(','),
    }
    r
}

/// What the plot needs of a sample: the drive's columns are `None` while the link is down
/// (a gap in the traces, as in the CSV).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlotRow {
    t_s: f64,
    drive: Option<[f64; 5]>,
}

impl PlotRow {
    pub fn of(s: &Sample) -> PlotRow {
        PlotRow {
            t_s: s.uptime_ms as f64 / 1000.0,
            drive: s.drive.map(|d| {
                [
                    f64::from(d.freq_dhz) / 10.0,
                    if d.reverse { -1.0 } else { 1.0 },
                    f64::from(d.fault),
                    f64::from(d.udc_dv) / 10.0,
                    f64::from(d.imax_ca) / 100.0,
                ]
            }),
        }
    }
}

impl trend_plot::Row for PlotRow {
    fn t_s(&self) -> f64 {
        self.t_s
    }

    fn get(&self, c: Column) -> Option<f64> {
        let [f, dir, fault, udc, imx] = self.drive?;
        match c {
            Column::FCmdHz => Some(f),
            Column::Dir => Some(dir),
            Column::Fault => Some(fault),
            Column::UDcV => Some(udc),
            Column::ImxA => Some(imx),
            // Only a simulation knows these (service.md 8).
            Column::SpeedRpm
            | Column::IA
            | Column::IB
            | Column::IC
            | Column::UAbV
            | Column::Brake
            | Column::PwmOn
            | Column::CarMm => None,
        }
    }
}

/// The plot's title: the port and the first sample's uptime.
fn plot_title(port: &str, rows: &[PlotRow]) -> String {
    let from = rows.first().map_or(0.0, |r| r.t_s);
    format!("plcctl trend, {port}, PLC uptime {from:.3} s on")
}

fn subscribe(c: &mut Client, period_ms: u16, q: &[u8]) -> Result<()> {
    let q = heapless::Vec::from_slice(q).map_err(|_| usage("--q: too many"))?;
    match c.ask(Request::Subscribe { period_ms, q })? {
        Answer::Subscribed { .. } => Ok(()),
        other => Err(unexpected("Subscribe", &other)),
    }
}

/// What `trend` records, and where.
pub struct TrendArgs<'a> {
    pub csv: &'a Path,
    pub plot: Option<&'a Path>,
    pub period_ms: u16,
    pub duration: Option<f64>,
    pub q: &'a [String],
    /// The port's name, for the plot's title.
    pub port: &'a str,
}

pub fn trend(connect: impl Fn() -> Result<Client>, args: &TrendArgs<'_>) -> Result<()> {
    let TrendArgs {
        csv,
        plot,
        period_ms,
        duration,
        q,
        port,
    } = *args;
    let q = parse_q(q)?;
    if !(10..=100).contains(&period_ms) {
        return Err(usage("--period-ms must be 10-100"));
    }
    if let Some(p) = plot {
        // A bad name or directory is refused before recording, not after.
        trend_plot::check_target(p).map_err(usage)?;
    }
    let interrupted = crate::interrupt::on_ctrl_c()?;
    let mut plot_rows: Vec<PlotRow> = Vec::new();
    // The CSV is written under a temporary name and renamed at the end: a port that does
    // not open or a PLC that refuses leaves the user's file as it was.
    let mut w = AtomicFile::create(csv).map_err(usage)?;
    writeln!(w, "{}", header(&q))?;
    let end = match duration {
        Some(s) => Some(
            Instant::now()
                .checked_add(
                    Duration::try_from_secs_f64(s)
                        .map_err(|e| usage(format!("--duration: {e}")))?,
                )
                .ok_or_else(|| usage("--duration: too long"))?,
        ),
        None => None,
    };
    let mut client = Some(connect()?);
    let uid = client.as_ref().map(|c| c.identity.uid);
    if let Some(c) = client.as_mut() {
        subscribe(c, period_ms, &q)?;
    }
    let mut rows = 0u64;
    while end.is_none_or(|e| Instant::now() < e) && !interrupted.is_set() {
        let Some(c) = client.as_mut() else {
            std::thread::sleep(Duration::from_secs(1));
            client = match connect() {
                // Only the PLC this recording began with continues it.
                Ok(c) if Some(c.identity.uid) != uid => {
                    eprintln!(
                        "trend: another PLC (UID {}) answers on {port}: not recorded, waiting for UID {}",
                        hex(&c.identity.uid),
                        uid.map_or_else(String::new, |u| hex(&u))
                    );
                    None
                }
                Ok(mut c) => match subscribe(&mut c, period_ms, &q) {
                    Ok(()) => {
                        eprintln!(
                            "trend: reconnected (power-up #{}), recording again",
                            c.identity.power_ups
                        );
                        Some(c)
                    }
                    Err(e) => {
                        eprintln!("trend: {e}; trying again every second");
                        None
                    }
                },
                Err(v @ Fail::Version { .. }) => return Err(v),
                Err(e) => {
                    eprintln!("trend: {e}; trying again every second");
                    None
                }
            };
            continue;
        };
        match c.samples(Duration::from_millis(200)) {
            Ok(samples) => {
                for s in &samples {
                    writeln!(w, "{}", row(s))?;
                    rows += 1;
                    if plot.is_some() {
                        plot_rows.push(PlotRow::of(s));
                    }
                }
                w.flush()?;
            }
            Err(e) => {
                eprintln!("trend: the PLC stopped answering ({e}); reconnecting every second (the gap is missing rows)");
                client = None;
            }
        }
    }
    if let Some(c) = client.as_mut() {
        let _ = c.request(Request::Subscribe {
            period_ms: 0,
            q: heapless::Vec::new(),
        });
    }
    w.commit().map_err(usage)?;
    eprintln!("{rows} samples written to {}", csv.display());
    if let Some(p) = plot {
        trend_plot::plot(
            p,
            &plot_rows,
            &plot_title(port, &plot_rows),
            &Marks::default(),
        )
        .map_err(|e| usage(format!("{e:#}")))?;
        eprintln!("plot written to {}", p.display());
    }
    Ok(())
}
