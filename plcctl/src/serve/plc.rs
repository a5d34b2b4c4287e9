//! The one connection to the PLC behind `serve`: a thread that owns the [`Client`]
//! (one outstanding request, service.md 2), polls the status and the counters at 10 Hz,
//! keeps a trend of samples, re-reads the fault log when its newest entry changes or an
//! action was done, reads the LCD's rows, and executes the page's actions between polls. It reconnects every second like `watch`
//! (service.md 8); a panic in it is reported as a lost connection and the thread's work
//! starts again ([`keep_running`]). The HTTP side only reads [`Shared`].

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
/// The LCD's rows are read this often.
const SCREEN_EVERY: Duration = Duration::from_millis(200);
/// How long a reconnection waits after a failure.
const RECONNECT: Duration = Duration::from_secs(1);

/// Why an action was not done.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ActionError {
    /// The PLC answered and refused (HTTP 409).
    Refused(String),
    /// There is no PLC to ask, or it stopped answering (HTTP 503).
    NoPlc(String),
}

/// An action from the page, with where its answer goes.
pub struct Action {
    pub request: Request,
    pub reply: Sender<std::result::Result<(), ActionError>>,
}

/// What the HTTP side reads.
pub struct State {
    pub connected: bool,
    /// Why the PLC does not answer (shown on the banner).
    pub error: Option<String>,
    pub identity: Value,
    /// The UID of the PLC this server monitors: the first that answered. Another PLC at
    /// the same port is refused (never two PLCs' data mixed).
    pub plc_uid: Option<[u8; 12]>,
    pub status: Value,
    /// When `status` last came from the PLC (its age is shown; older than 2 s: greyed).
    pub status_at: Option<Instant>,
    /// The LCD's rows as shown (`GetScreen`), `null` before the first or when refused.
    pub screen: Value,
    /// `faults --json` rows, newest first (`null` before the first read).
    pub faults: Value,
    /// The profile's texts and value names for them.
    pub log_names: crate::faults::LogNames,
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
                plc_uid: None,
                status: Value::Null,
                status_at: None,
                screen: Value::Null,
                faults: Value::Null,
                log_names: crate::faults::LogNames::default(),
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

/// Runs [`run`] for ever (a thread): a panic in it (a bug, e.g. on data it did not
/// expect) shows as a lost connection with the panic's message, and the work starts
/// again after [`RECONNECT`] with the same actions channel.
pub fn keep_running(
    connect: impl Fn() -> Result<Client>,
    port: String,
    q: Vec<u8>,
    shared: Arc<Shared>,
    actions: Receiver<Action>,
    log: Arc<super::log::Log>,
) {
    loop {
        let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            run(&connect, &port, &q, &shared, &actions, &log)
        }));
        if let Err(panic) = r {
            let text = panic
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| panic.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "panic".into());
            shared.update(|s| {
                s.connected = false;
                s.error = Some(format!("internal error, restarting: {text}"));
            });
            refuse_waiting(&actions, &format!("internal error: {text}"));
            std::thread::sleep(RECONNECT);
        }
    }
}

/// Runs the connection for ever; returns only by a panic.
fn run(
    connect: &impl Fn() -> Result<Client>,
    port: &str,
    q: &[u8],
    shared: &Shared,
    actions: &Receiver<Action>,
    log: &super::log::Log,
) {
    loop {
        let attempt = connect().and_then(|mut c| {
            let mine = check_identity(&mut shared.lock().plc_uid, c.identity.uid, port);
            mine.map_err(|m| Fail::Usage(anyhow::anyhow!(m)))?;
            // The PLC's clock stamps its log: set it when unset or off (docs/serve.md).
            if let Some(line) = crate::time_of_day::sync_on_connect(&mut c)? {
                log.line(None, &line);
            }
            subscribe(&mut c, q).map(|_| c)
        });
        let mut c = match attempt {
            Ok(c) => c,
            Err(e) => {
                shared.update(|s| {
                    s.connected = false;
                    s.error = Some(e.to_string());
                });
                refuse_waiting(actions, &format!("no PLC: {e}"));
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
        let e = serve_connection(&mut c, shared, actions);
        shared.update(|s| {
            s.connected = false;
            s.error = Some(e.to_string());
        });
        std::thread::sleep(RECONNECT);
    }
}

/// Whether the PLC with `uid` at `port` is the one this server monitors: the first
/// that answered (`first`, set here), like `trend` (a different board plugged in at the
/// same port). Else the banner's message.
pub fn check_identity(
    first: &mut Option<[u8; 12]>,
    uid: [u8; 12],
    port: &str,
) -> std::result::Result<(), String> {
    match first {
        None => {
            *first = Some(uid);
            Ok(())
        }
        Some(f) if *f == uid => Ok(()),
        Some(f) => Err(format!(
            "a different PLC (uid {}) answers at {port}, not the one monitored (uid {}); \
             restart serve to monitor it",
            hex(&uid),
            hex(f)
        )),
    }
}

fn hex(uid: &[u8]) -> String {
    uid.iter().map(|b| format!("{b:02x}")).collect()
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
fn refuse_waiting(actions: &Receiver<Action>, why: &str) {
    while let Ok(a) = actions.try_recv() {
        let _ = a.reply.send(Err(ActionError::NoPlc(why.to_string())));
    }
}

/// Polls one connection until it fails; returns why.
fn serve_connection(c: &mut Client, shared: &Shared, actions: &Receiver<Action>) -> Fail {
    let mut newest_log: Option<Option<(u8, u8)>> = None;
    let mut screen_at: Option<Instant> = None;
    let mut screen_refused = false;
    loop {
        let tick = Instant::now();
        let status = match c.ask(Request::GetStatus) {
            Ok(Answer::Status(s)) => s,
            Ok(other) => return crate::client::unexpected("GetStatus", &other),
            Err(e) => return e,
        };
        // The log is re-read when its newest entry changes (a trip, an event, a clear)
        // and after an action (a clear that leaves the same newest entry).
        if newest_log != Some(status.newest_log) {
            let names = shared.lock().log_names.clone();
            match crate::faults::rows(c, &names) {
                Ok(rows) => {
                    let rows = serde_json::to_value(rows).unwrap_or(Value::Null);
                    shared.update(|s| s.faults = rows);
                    newest_log = Some(status.newest_log);
                }
                Err(e) => return e,
            }
        }
        // The counters with every status: they change on events serve cannot see (an
        // application counter's Q rising, a minute in RUN, a link error), so they are
        // as fresh as the status, never older (answered from the PLC's RAM).
        let counters = match c.request(Request::GetCounters) {
            Ok(Answer::Counters(k)) => crate::status::counters_json(&k),
            Ok(Answer::Refused(r)) => json!({ "error": r.text() }),
            Ok(other) => return crate::client::unexpected("GetCounters", &other),
            Err(e) => return e,
        };
        if !screen_refused && screen_at.is_none_or(|t| t.elapsed() >= SCREEN_EVERY) {
            let rows = match c.request(Request::GetScreen) {
                Ok(Answer::Screen(s)) => {
                    json!(s.rows.iter().map(|r| r.as_str()).collect::<Vec<_>>())
                }
                Ok(_) => {
                    screen_refused = true;
                    Value::Null
                }
                Err(e) => return e,
            };
            shared.update(|s| s.screen = rows);
            screen_at = Some(Instant::now());
        }
        let status = serde_json::to_value(status).unwrap_or(Value::Null);
        let samples = match c.samples(Duration::ZERO) {
            Ok(v) => v,
            Err(e) => return e,
        };
        shared.update(|s| {
            s.status = status;
            s.status_at = Some(Instant::now());
            s.counters = counters;
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
                    Ok(Answer::Refused(r)) => Err(ActionError::Refused(format!(
                        "refused by the PLC: {}",
                        r.text()
                    ))),
                    Ok(other) => Err(ActionError::Refused(format!(
                        "unexpected answer: {other:?}"
                    ))),
                    Err(e) => {
                        let _ = a.reply.send(Err(ActionError::NoPlc(e.to_string())));
                        return e;
                    }
                };
                if r.is_ok() {
                    newest_log = None;
                }
                let _ = a.reply.send(r);
            }
            Err(RecvTimeoutError::Timeout) => {}
            // The server is gone: nothing more to serve.
            Err(RecvTimeoutError::Disconnected) => std::thread::sleep(left),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicUsize, Ordering};

    /// Waits (at most 10 s) until the state's error satisfies `f`; the error seen.
    fn wait_error(shared: &Shared, f: impl Fn(&str) -> bool) -> String {
        let end = Instant::now() + Duration::from_secs(10);
        loop {
            let e = shared.lock().error.clone().unwrap_or_default();
            if f(&e) {
                return e;
            }
            assert!(Instant::now() < end, "error never as expected: {e:?}");
            std::thread::sleep(Duration::from_millis(10));
        }
    }

    #[test]
    fn a_panic_in_the_plc_thread_shows_as_disconnected_and_the_work_restarts() {
        let shared = Shared::new(&[0, 1]);
        // A connection up with frozen data, as the issue saw it.
        shared.update(|s| {
            s.connected = true;
            s.error = None;
        });
        let calls = Arc::new(AtomicUsize::new(0));
        let (tx, rx) = std::sync::mpsc::channel::<Action>();
        {
            let shared = Arc::clone(&shared);
            let calls = Arc::clone(&calls);
            std::thread::spawn(move || {
                keep_running(
                    move || {
                        if calls.fetch_add(1, Ordering::SeqCst) == 0 {
                            panic!("DateTime + TimeDelta overflowed");
                        }
                        Err(Fail::NoDevice("no PLC in this test".into()))
                    },
                    "/dev/test".into(),
                    vec![0, 1],
                    shared,
                    rx,
                    Arc::new(crate::serve::log::Log::open(None).unwrap()),
                )
            });
        }
        let e = wait_error(&shared, |e| e.contains("internal error"));
        assert!(e.contains("DateTime + TimeDelta overflowed"), "{e}");
        assert!(!shared.lock().connected);
        // Restarted: the next connection attempt's failure replaces the panic's.
        let e = wait_error(&shared, |e| e.contains("no PLC in this test"));
        assert!(calls.load(Ordering::SeqCst) >= 2, "{e}");
        // And the actions channel still works: an action is answered "no PLC".
        let (reply, answer) = std::sync::mpsc::channel();
        tx.send(Action {
            request: Request::Stop,
            reply,
        })
        .unwrap();
        let r = answer.recv_timeout(Duration::from_secs(10)).unwrap();
        assert!(matches!(r, Err(ActionError::NoPlc(_))), "{r:?}");
    }

    #[test]
    fn only_the_first_plc_is_monitored_another_at_the_port_is_refused() {
        let a = [1u8; 12];
        let mut b = [1u8; 12];
        b[11] = 2;
        let mut first = None;
        assert_eq!(check_identity(&mut first, a, "/dev/ttyACM0"), Ok(()));
        assert_eq!(first, Some(a));
        // The same PLC after a reconnect (a reset, the cable): monitored again.
        assert_eq!(check_identity(&mut first, a, "/dev/ttyACM0"), Ok(()));
        // Another board at the same port: refused, named, and the first stays.
        let e = check_identity(&mut first, b, "/dev/ttyACM0").unwrap_err();
        assert!(
            e.contains("a different PLC (uid 010101010101010101010102) answers at /dev/ttyACM0")
                && e.contains("(uid 010101010101010101010101)")
                && e.contains("restart serve"),
            "{e}"
        );
        assert_eq!(first, Some(a));
    }
}
