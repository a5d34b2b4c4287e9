//! The one connection to the PLC behind `serve`: a thread that owns the [`Client`]
//! (one outstanding request, service.md 2), polls the status at 10 Hz, keeps a trend of
//! samples, re-reads the fault log when its newest position changes and the counters
//! every few seconds, and executes the page's actions between polls. It reconnects
//! every second like `watch` (service.md 8). The HTTP side only reads [`Shared`].

use std::collections::VecDeque;
use std::sync::mpsc::{Receiver, RecvTimeoutError, Sender};
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

use serde_json::{json, Value};
use shared_protocol::service::{Answer, Request, Sample};

use crate::client::Client;
use crate::fail::{Fail, Result};
use crate::trend;

/// Status poll and sample period (service.md 11: status and samples at 10 Hz).
pub const PERIOD: Duration = Duration::from_millis(100);
/// Samples kept for `/api/trend` (10 minutes at 10 Hz).
const TREND_KEEP: usize = 6000;
/// Counters are read this often (they change by the minute).
const COUNTERS_EVERY: Duration = Duration::from_secs(5);
/// How long a reconnection waits after a failure.
const RECONNECT: Duration = Duration::from_secs(1);

/// An action from the page, with where its answer goes.
pub struct Action {
    pub request: Request,
    pub reply: Sender<std::result::Result<(), String>>,
}

/// What the HTTP side reads.
pub struct State {
    pub connected: bool,
    /// Why the PLC does not answer (shown on the banner).
    pub error: Option<String>,
    pub identity: Value,
    pub status: Value,
    /// `faults --json` rows, newest first.
    pub faults: Value,
    pub counters: Value,
    /// The trend's column names (hil-sim's, as `trend --csv`).
    pub columns: Vec<String>,
    /// Samples, oldest first; each with a serial number for the stream.
    pub samples: VecDeque<(u64, Sample)>,
    next_serial: u64,
    /// Bumped with every change: the stream waits on it.
    pub generation: u64,
}

/// The state and its change signal.
pub struct Shared {
    pub state: Mutex<State>,
    pub changed: Condvar,
}

impl Shared {
    pub fn new(q: &[u8]) -> Arc<Shared> {
        Arc::new(Shared {
            state: Mutex::new(State {
                connected: false,
                error: Some("connecting".into()),
                identity: Value::Null,
                status: Value::Null,
                faults: json!([]),
                counters: Value::Null,
                columns: trend::header(q).split(',').map(String::from).collect(),
                samples: VecDeque::new(),
                next_serial: 0,
                generation: 0,
            }),
            changed: Condvar::new(),
        })
    }

    /// Runs `f` on the state and wakes the streams.
    pub fn update(&self, f: impl FnOnce(&mut State)) {
        let mut s = self.state.lock().unwrap_or_else(|p| p.into_inner());
        f(&mut s);
        s.generation += 1;
        self.changed.notify_all();
    }

    pub fn lock(&self) -> std::sync::MutexGuard<'_, State> {
        self.state.lock().unwrap_or_else(|p| p.into_inner())
    }
}

/// One sample as a row of the trend's columns ([`State::columns`], hil-sim's names), with
/// the CSV's numbers (an empty CSV field, e.g. the drive's while the link is down, is
/// `null`).
pub fn sample_row(s: &Sample) -> Value {
    trend::row(s)
        .split(',')
        .map(|field| {
            field
                .parse::<f64>()
                .ok()
                .and_then(serde_json::Number::from_f64)
                .map_or(Value::Null, Value::Number)
        })
        .collect()
}

/// Runs the connection for ever (a thread).
pub fn run(
    connect: impl Fn() -> Result<Client>,
    q: Vec<u8>,
    shared: Arc<Shared>,
    actions: Receiver<Action>,
) {
    loop {
        let mut c = match connect().and_then(|mut c| subscribe(&mut c, &q).map(|_| c)) {
            Ok(c) => c,
            Err(e) => {
                shared.update(|s| {
                    s.connected = false;
                    s.error = Some(e.to_string());
                });
                refuse_waiting(&actions, &e);
                std::thread::sleep(RECONNECT);
                continue;
            }
        };
        let identity = serde_json::to_value(&c.identity).unwrap_or(Value::Null);
        shared.update(|s| {
            s.connected = true;
            s.error = None;
            s.identity = identity;
        });
        let e = serve_connection(&mut c, &shared, &actions);
        shared.update(|s| {
            s.connected = false;
            s.error = Some(e.to_string());
        });
        std::thread::sleep(RECONNECT);
    }
}

fn subscribe(c: &mut Client, q: &[u8]) -> Result<()> {
    let q = heapless::Vec::from_slice(q)
        .map_err(|_| Fail::Usage(anyhow::anyhow!("too many Q variables")))?;
    match c.ask(Request::Subscribe {
        period_ms: PERIOD.as_millis() as u16,
        q,
    })? {
        Answer::Subscribed { .. } => Ok(()),
        other => Err(crate::client::unexpected("Subscribe", &other)),
    }
}

/// Actions that arrive while there is no PLC are answered at once.
fn refuse_waiting(actions: &Receiver<Action>, e: &Fail) {
    while let Ok(a) = actions.try_recv() {
        let _ = a.reply.send(Err(format!("no PLC: {e}")));
    }
}

/// Polls one connection until it fails; returns why.
fn serve_connection(c: &mut Client, shared: &Shared, actions: &Receiver<Action>) -> Fail {
    let mut newest_log: Option<Option<(u8, u8)>> = None;
    let mut counters_at: Option<Instant> = None;
    loop {
        let tick = Instant::now();
        let status = match c.ask(Request::GetStatus) {
            Ok(Answer::Status(s)) => s,
            Ok(other) => return crate::client::unexpected("GetStatus", &other),
            Err(e) => return e,
        };
        if newest_log != Some(status.newest_log) {
            match crate::faults::rows(c) {
                Ok(rows) => {
                    let rows = serde_json::to_value(rows).unwrap_or(Value::Null);
                    shared.update(|s| s.faults = rows);
                    newest_log = Some(status.newest_log);
                }
                Err(e) => return e,
            }
        }
        if counters_at.is_none_or(|t| t.elapsed() >= COUNTERS_EVERY) {
            let v = match c.request(Request::GetCounters) {
                Ok(Answer::Counters(k)) => crate::status::counters_json(&k),
                Ok(Answer::Refused(r)) => json!({ "error": r.text() }),
                Ok(other) => return crate::client::unexpected("GetCounters", &other),
                Err(e) => return e,
            };
            shared.update(|s| s.counters = v);
            counters_at = Some(Instant::now());
        }
        let status = serde_json::to_value(status).unwrap_or(Value::Null);
        let samples = match c.samples(Duration::ZERO) {
            Ok(v) => v,
            Err(e) => return e,
        };
        shared.update(|s| {
            s.status = status;
            for x in samples {
                let n = s.next_serial;
                s.next_serial += 1;
                s.samples.push_back((n, x));
            }
            while s.samples.len() > TREND_KEEP {
                s.samples.pop_front();
            }
        });
        // The rest of the period: actions from the page.
        let left = PERIOD.saturating_sub(tick.elapsed());
        match actions.recv_timeout(left) {
            Ok(a) => {
                let r = match c.request(a.request) {
                    Ok(Answer::Done) => Ok(()),
                    Ok(Answer::Refused(r)) => Err(format!("refused by the PLC: {}", r.text())),
                    Ok(other) => Err(format!("unexpected answer: {other:?}")),
                    Err(e) => {
                        let _ = a.reply.send(Err(e.to_string()));
                        return e;
                    }
                };
                let _ = a.reply.send(r);
            }
            Err(RecvTimeoutError::Timeout) => {}
            // The server is gone: nothing more to serve.
            Err(RecvTimeoutError::Disconnected) => std::thread::sleep(left),
        }
    }
}
