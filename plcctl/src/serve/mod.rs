//! `plcctl serve` (service.md part B): the web monitor. One page with embedded assets,
//! a JSON API and a Server-Sent Events stream over the PLC connection of
//! [`plc`], access by [`access`] (Host, Origin, token), HTTP by [`http`], the access
//! log by [`log`]. Usage, decisions and the threat model: `plcctl/docs/serve.md`.
//!
//! | route | answer |
//! | --- | --- |
//! | `GET /` | the page (`assets/index.html`), its `app.js` and `app.css` |
//! | `GET /api/profile` | the profile (`--profile`, else a table without names) |
//! | `GET /api/status` | `{connected, error, identity, status, age_ms, lcd_text, service_version, drive_fault_text}`: `status --json` plus the connection, the status's age and the LCD's rows |
//! | `GET /api/faults` | `faults --json` |
//! | `GET /api/counters` | `counters --json` (`{error}` while the PLC has none) |
//! | `GET /api/trend?s=60` | `{columns, rows}`: `trend --csv`'s columns and rows of the last `s` seconds |
//! | `GET /api/stream` | SSE: `status` (as `/api/status`), `sample` (`{serial, row}`, 10 Hz) and `counters` events |
//! | `POST /api/stop`, `run`, `ack`, `clear-faults` | `{ok}`, or `{error}`: 409 refused by the PLC, 503 no PLC; `Content-Type: application/json` required (415); same origin only (403) |

pub mod access;
pub mod http;
pub mod log;
pub mod plc;
pub mod profile;

use std::net::{SocketAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::mpsc::{self, Sender};
use std::sync::Arc;
use std::time::{Duration, Instant};

use serde_json::{json, Value};
use shared_protocol::service::{LogText, Request, SERVICE_VERSION};

use crate::client::Client;
use crate::fail::{Fail, Result};
use access::{Access, Hosts, COOKIE};
use http::Response;
use plc::{Action, ActionError, Shared};

const INDEX_HTML: &str = include_str!("../../assets/index.html");
const APP_JS: &str = include_str!("../../assets/app.js");
const APP_CSS: &str = include_str!("../../assets/app.css");

/// How long a POST waits for the PLC's answer (a clear of the log writes the EEPROM:
/// 3 s, resent after 5 s).
const ACTION_WAIT: Duration = Duration::from_secs(20);
/// The stream sends a comment this often when nothing changes (proxies, dead clients).
const KEEPALIVE: Duration = Duration::from_secs(5);
/// The stream looks at the state at least this often: a status that stops changing
/// is sent again with its growing age.
const STREAM_TICK: Duration = Duration::from_secs(1);
/// The whole request head (and the small body) must arrive within this (slow clients
/// cannot hold a connection by trickling bytes).
const HEAD_DEADLINE: Duration = Duration::from_secs(5);
/// A write that blocks this long ends the connection (a client that stopped reading).
const WRITE_TIMEOUT: Duration = Duration::from_secs(10);
/// Connections served at once (each a thread; a page holds one for its event stream);
/// more are answered 503 at once and closed.
pub const MAX_CONNECTIONS: usize = 32;
/// After an error answer to a request that was not read to its end, at most this much
/// more is read (so that closing does not reset the connection before the client reads
/// the answer) and never for longer than [`DRAIN_TIME`].
const DRAIN_BYTES: u64 = 64 * 1024;
const DRAIN_TIME: Duration = Duration::from_secs(1);

/// What `serve` was asked for.
pub struct ServeArgs {
    pub bind: String,
    pub profile: Option<std::path::PathBuf>,
    /// The access token (from a file or the environment, already checked).
    pub token: Option<String>,
    /// More names the server answers to (`--host`).
    pub hosts: Vec<String>,
    /// The access log's file (`--log`), besides stderr.
    pub log: Option<std::path::PathBuf>,
    /// The PLC's port (in the message when another PLC answers there).
    pub port: String,
}

/// Everything a connection's thread needs.
struct Ctx {
    shared: Arc<Shared>,
    access: Access,
    hosts: Hosts,
    log: Arc<log::Log>,
    actions: Sender<Action>,
    profile: Value,
}

pub fn serve(connect: impl Fn() -> Result<Client> + Send + 'static, args: ServeArgs) -> Result<()> {
    let profile = match &args.profile {
        Some(p) => profile::Profile::load(p)?,
        None => profile::Profile::default(),
    };
    let q = profile.subscribed_q();
    let log = Arc::new(log::Log::open(args.log.as_deref()).map_err(|e| {
        Fail::Usage(anyhow::anyhow!(
            "cannot open the log {}: {e}",
            args.log
                .as_deref()
                .unwrap_or(std::path::Path::new(""))
                .display()
        ))
    })?);
    let listener = TcpListener::bind(&args.bind)
        .map_err(|e| Fail::Usage(anyhow::anyhow!("cannot bind {}: {e}", args.bind)))?;
    let addr: SocketAddr = listener.local_addr()?;
    let access = Access::for_bind(&addr, args.token).map_err(|e| {
        anyhow::anyhow!("no random source for the token ({e}): give one with --token-file")
    })?;
    println!("serving http://{addr}/");
    if let Access::Token(t) = &access {
        println!("token: {t}");
        println!("open http://{addr}/?token={t}");
    }
    use std::io::Write as _;
    std::io::stdout().flush()?;
    let shared = Shared::new(&q);
    shared.update(|s| s.log_names = crate::faults::LogNames::of(&profile));
    let (tx, rx) = mpsc::channel();
    {
        let shared = Arc::clone(&shared);
        let port = args.port.clone();
        let log = Arc::clone(&log);
        std::thread::spawn(move || plc::keep_running(connect, port, q, shared, rx, log));
    }
    let ctx = Arc::new(Ctx {
        shared,
        access,
        hosts: Hosts::new(&addr, &args.hosts),
        log,
        actions: tx,
        profile: serde_json::to_value(&profile).map_err(anyhow::Error::from)?,
    });
    // Connections over the cap are answered 503 by one thread, in turn; when even its
    // queue is full they are closed unanswered.
    let (over, over_rx) = mpsc::sync_channel::<(TcpStream, Option<SocketAddr>)>(MAX_CONNECTIONS);
    {
        let ctx = Arc::clone(&ctx);
        std::thread::spawn(move || {
            for (stream, peer) in over_rx {
                let _ = stream.set_write_timeout(Some(Duration::from_secs(1)));
                let resp = Response::error(503, "too many connections")
                    .with_header("Retry-After", "1".into());
                refuse(stream, &ctx, peer, "connection refused:", resp);
            }
        });
    }
    let active = Arc::new(AtomicUsize::new(0));
    for stream in listener.incoming() {
        let Ok(stream) = stream else { continue };
        let peer = stream.peer_addr().ok();
        if active.fetch_add(1, Ordering::SeqCst) >= MAX_CONNECTIONS {
            active.fetch_sub(1, Ordering::SeqCst);
            let _ = over.try_send((stream, peer));
            continue;
        }
        let slot = Slot(Arc::clone(&active));
        let ctx = Arc::clone(&ctx);
        std::thread::spawn(move || {
            let _slot = slot;
            handle(stream, peer, &ctx);
        });
    }
    Ok(())
}

/// One of the [`MAX_CONNECTIONS`], given back when the connection's thread ends.
struct Slot(Arc<AtomicUsize>);

impl Drop for Slot {
    fn drop(&mut self) {
        self.0.fetch_sub(1, Ordering::SeqCst);
    }
}

/// Answers `resp`, logs it, and reads (a bounded amount of) what the client still sends
/// so that the answer is not lost to a reset.
fn refuse(mut stream: TcpStream, ctx: &Ctx, peer: Option<SocketAddr>, what: &str, resp: Response) {
    use std::io::Read as _;
    ctx.log.line(peer, &format!("{what} {}", resp.status));
    let _ = resp.write_to(&mut stream);
    let _ = stream.shutdown(std::net::Shutdown::Write);
    let deadline = Instant::now() + DRAIN_TIME;
    let _ = std::io::copy(
        &mut http::Deadline {
            stream: &stream,
            deadline,
        }
        .take(DRAIN_BYTES),
        &mut std::io::sink(),
    );
}

fn handle(mut stream: TcpStream, peer: Option<SocketAddr>, ctx: &Ctx) {
    let _ = stream.set_write_timeout(Some(WRITE_TIMEOUT));
    let read = http::read_request(http::Deadline {
        stream: &stream,
        deadline: Instant::now() + HEAD_DEADLINE,
    });
    let req = match read {
        Ok(r) => r,
        Err(bad) => {
            let (status, text) = bad.status();
            return refuse(stream, ctx, peer, "-", Response::error(status, text));
        }
    };
    let what = format!("{} {}", req.method, req.path);
    // DNS rebinding: only this server's own names (421: the request names a server this
    // is not; see docs/serve.md).
    let local = stream
        .local_addr()
        .map_or(std::net::Ipv4Addr::LOCALHOST.into(), |a| a.ip());
    let host = match (req.count("host"), req.header("host")) {
        (1, Some(h)) => h.to_string(),
        _ => {
            let resp = Response::error(400, "exactly one Host header is required");
            return refuse(stream, ctx, peer, &what, resp);
        }
    };
    if !ctx.hosts.allows(&host, local) {
        let resp = Response::error(
            421,
            "this server does not answer to that name (serve --host NAME adds one)",
        );
        return refuse(stream, ctx, peer, &format!("{what} host {host:?}"), resp);
    }
    if !ctx.access.allows(req.query.as_deref(), &req.headers) {
        let resp = Response::error(401, "token required (open the URL serve printed)");
        return refuse(stream, ctx, peer, &what, resp);
    }
    // Cross-site requests: anything but GET only from this server's own page.
    if req.method != "GET"
        && (req.count("origin") > 1
            || !access::same_origin(&host, req.header("origin"), req.header("sec-fetch-site")))
    {
        let resp = Response::error(403, "cross-origin request refused");
        let origin = req.header("origin").unwrap_or("");
        return refuse(
            stream,
            ctx,
            peer,
            &format!("{what} origin {origin:?}"),
            resp,
        );
    }
    if req.method == "GET" && req.path == "/api/stream" {
        ctx.log.line(peer, &format!("{what} 200 stream opened"));
        let r = stream_events(&mut stream, &ctx.shared);
        let why = r.err().map_or_else(String::new, |e| format!(": {e}"));
        ctx.log.line(peer, &format!("{what} stream closed{why}"));
        return;
    }
    let (mut resp, result) = route(&req, ctx);
    // The page's URL carries the token once; the cookie carries it afterwards.
    if let (Access::Token(t), Some(q)) = (&ctx.access, req.query.as_deref()) {
        if access::query_value(q, "token").is_some() {
            resp = resp.with_header(
                "Set-Cookie",
                format!("{COOKIE}={t}; Path=/; HttpOnly; SameSite=Strict"),
            );
        }
    }
    let result = result.map_or_else(String::new, |r| format!(" {r}"));
    ctx.log
        .line(peer, &format!("{what} {}{result}", resp.status));
    let _ = resp.write_to(&mut stream);
}

/// The answer, and for an action what the PLC said (for the log).
fn route(req: &http::Request, ctx: &Ctx) -> (Response, Option<String>) {
    let get = req.method == "GET";
    if matches!(
        req.path.as_str(),
        "/api/stop" | "/api/run" | "/api/ack" | "/api/clear-faults"
    ) && req.method == "POST"
    {
        let (resp, said) = action(req, ctx);
        return (resp, Some(said));
    }
    let resp = match req.path.as_str() {
        "/" | "/index.html" if get => {
            Response::new(200, "text/html; charset=utf-8", INDEX_HTML.as_bytes())
        }
        "/app.js" if get => Response::new(200, "text/javascript; charset=utf-8", APP_JS.as_bytes()),
        "/app.css" if get => Response::new(200, "text/css; charset=utf-8", APP_CSS.as_bytes()),
        "/api/profile" if get => Response::json(200, &ctx.profile),
        "/api/status" if get => Response::json(200, &status_json(&ctx.shared)),
        "/api/faults" if get => Response::json(200, &ctx.shared.lock().faults.clone()),
        "/api/counters" if get => Response::json(200, &ctx.shared.lock().counters.clone()),
        "/api/trend" if get => {
            let s = req
                .query
                .as_deref()
                .and_then(|q| access::query_value(q, "s"))
                .and_then(|v| v.parse::<f64>().ok())
                .unwrap_or(60.0)
                .clamp(0.1, 600.0);
            Response::json(200, &trend_json(&ctx.shared, s))
        }
        "/" | "/index.html" | "/app.js" | "/app.css" | "/api/profile" | "/api/status"
        | "/api/faults" | "/api/counters" | "/api/trend" | "/api/stop" | "/api/run"
        | "/api/ack" | "/api/clear-faults" => Response::error(405, "method not allowed"),
        _ => Response::error(404, "not found"),
    };
    (resp, None)
}

fn status_json(shared: &Shared) -> Value {
    status_view(&shared.lock())
}

/// `/api/status` and the stream's `status` event: `status --json` plus the connection,
/// the age of `status` (ms since the PLC last answered `GetStatus`; `null` before the
/// first answer), the LCD's rows as shown, the service version and the latched drive
/// fault's text (the fault log's words).
fn status_view(s: &plc::State) -> Value {
    let fault = s.status["drive"]["fault"].as_u64().unwrap_or(0);
    json!({
        "connected": s.connected,
        "error": s.error,
        "identity": s.identity,
        "status": s.status,
        "age_ms": s.status_at.map(|t| t.elapsed().as_millis() as u64),
        "lcd_text": s.screen,
        "service_version": SERVICE_VERSION,
        "drive_fault_text": (fault != 0).then(|| LogText(fault as u8).to_string()),
    })
}

/// The samples of the last `seconds` of PLC uptime.
fn trend_json(shared: &Shared, seconds: f64) -> Value {
    let s = shared.lock();
    let newest = s.samples.back().map_or(0, |(_, x)| x.uptime_ms);
    let from = newest.saturating_sub((seconds * 1000.0) as u64);
    let rows: Vec<Value> = s
        .samples
        .iter()
        .filter(|(_, x)| x.uptime_ms >= from)
        .map(|(_, x)| plc::sample_row(x))
        .collect();
    json!({ "columns": s.columns, "rows": rows })
}

/// A POST: JSON only (a form cannot send it cross-site without a CORS preflight, which
/// this server never grants), then the PLC's answer: 200, 409 when the PLC refuses,
/// 503 when there is no PLC to ask (docs/serve.md). The second value is for the log.
fn action(req: &http::Request, ctx: &Ctx) -> (Response, String) {
    let json_type = req
        .header("content-type")
        .and_then(|t| t.split(';').next())
        .is_some_and(|t| t.trim().eq_ignore_ascii_case("application/json"));
    if !json_type {
        let e = "Content-Type: application/json required";
        return (Response::error(415, e), e.into());
    }
    let request = match req.path.as_str() {
        "/api/stop" => Request::Stop,
        "/api/run" => Request::Run { slot: 0 },
        "/api/ack" => Request::Ack,
        _ => Request::ClearFaultLog,
    };
    let no_plc = |e: &str| (Response::error(503, e), e.to_string());
    {
        let s = ctx.shared.lock();
        if !s.connected {
            let why = s.error.clone().unwrap_or_else(|| "not connected".into());
            return no_plc(&format!("no PLC: {why}"));
        }
    }
    let (reply, answer) = mpsc::channel();
    if ctx.actions.send(Action { request, reply }).is_err() {
        return no_plc("the PLC connection has stopped");
    }
    match answer.recv_timeout(ACTION_WAIT) {
        Ok(Ok(())) => (Response::json(200, &json!({ "ok": true })), "ok".into()),
        Ok(Err(ActionError::Refused(e))) => (Response::error(409, &e), e),
        Ok(Err(ActionError::NoPlc(e))) => no_plc(&e),
        Err(_) => no_plc("no answer from the PLC"),
    }
}

/// The stream: the fault log and the counters when they change (before the status that
/// came with them), the status whenever it changes (its age at least every second while
/// the PLC does not answer), every new sample, a keep-alive comment when there was nothing
/// for [`KEEPALIVE`]. A new stream starts with all of them.
fn stream_events(stream: &mut TcpStream, shared: &Shared) -> std::io::Result<()> {
    use std::io::Write as _;
    http::start_events(stream)?;
    let mut last_status = Value::Null;
    let mut last_counters = Value::Null;
    let mut last_faults = Value::Null;
    let mut next_serial = shared.lock().samples.back().map_or(0, |(n, _)| n + 1);
    let mut generation = u64::MAX;
    let mut last_write = Instant::now();
    loop {
        let mut out = String::new();
        {
            let mut s = shared.lock();
            if s.generation == generation {
                let (g, _) = shared
                    .changed
                    .wait_timeout(s, STREAM_TICK)
                    .unwrap_or_else(|p| p.into_inner());
                s = g;
            }
            generation = s.generation;
            if s.faults != last_faults && !s.faults.is_null() {
                out += &http::event("faults", &s.faults.to_string());
                last_faults = s.faults.clone();
            }
            if s.counters != last_counters {
                out += &http::event("counters", &s.counters.to_string());
                last_counters = s.counters.clone();
            }
            let status = status_view(&s);
            if status != last_status {
                out += &http::event("status", &status.to_string());
                last_status = status;
            }
            let from = next_serial;
            for (n, x) in s.samples.iter().filter(|(n, _)| *n >= from) {
                let ev = json!({ "serial": n, "row": plc::sample_row(x) });
                out += &http::event("sample", &ev.to_string());
                next_serial = n + 1;
            }
        }
        if out.is_empty() && last_write.elapsed() >= KEEPALIVE {
            out += ": keep-alive\n\n";
        }
        if !out.is_empty() {
            stream.write_all(out.as_bytes())?;
            stream.flush()?;
            last_write = Instant::now();
        }
    }
}
