//! `plcctl serve` (service.md part B): the web monitor. One page with embedded assets,
//! a JSON API and a Server-Sent Events stream over the PLC connection of
//! [`plc`], access by [`access`], HTTP by [`http`]. Usage and decisions:
//! `plcctl/docs/serve.md`.
//!
//! | route | answer |
//! | --- | --- |
//! | `GET /` | the page (`assets/index.html`), its `app.js` and `app.css` |
//! | `GET /api/profile` | the profile (`--profile`, else a table without names) |
//! | `GET /api/status` | `{connected, error, identity, status, service_version, drive_fault_text}`: `status --json` plus the connection |
//! | `GET /api/faults` | `faults --json` |
//! | `GET /api/counters` | `counters --json` (`{error}` while the PLC has none) |
//! | `GET /api/trend?s=60` | `{columns, rows}`: `trend --csv`'s columns and rows of the last `s` seconds |
//! | `GET /api/stream` | SSE: `status` (as `/api/status`) and `sample` (`{serial, row}`) events, 10 Hz |
//! | `POST /api/stop`, `run`, `ack`, `clear-faults` | `{ok}` or `{error}` (409); `Content-Type: application/json` required (415) |

pub mod access;
pub mod http;
pub mod plc;
pub mod profile;

use std::net::{SocketAddr, TcpListener, TcpStream};
use std::sync::mpsc::{self, Sender};
use std::sync::Arc;
use std::time::Duration;

use serde_json::{json, Value};
use shared_protocol::service::{LogText, Request, SERVICE_VERSION};

use crate::client::Client;
use crate::fail::{Fail, Result};
use access::{Access, COOKIE};
use http::Response;
use plc::{Action, Shared};

const INDEX_HTML: &str = include_str!("../../assets/index.html");
const APP_JS: &str = include_str!("../../assets/app.js");
const APP_CSS: &str = include_str!("../../assets/app.css");

/// How long a POST waits for the PLC's answer (a clear of the log writes the EEPROM:
/// 3 s, resent after 5 s).
const ACTION_WAIT: Duration = Duration::from_secs(20);
/// The stream sends a comment this often when nothing changes (proxies, dead clients).
const KEEPALIVE: Duration = Duration::from_secs(5);

/// What `serve` was asked for.
pub struct ServeArgs {
    pub bind: String,
    pub profile: Option<std::path::PathBuf>,
    pub token: Option<String>,
}

/// Everything a connection's thread needs.
struct Ctx {
    shared: Arc<Shared>,
    access: Access,
    actions: Sender<Action>,
    profile: Value,
}

pub fn serve(connect: impl Fn() -> Result<Client> + Send + 'static, args: ServeArgs) -> Result<()> {
    let profile = match &args.profile {
        Some(p) => profile::Profile::load(p)?,
        None => profile::Profile::default(),
    };
    let q = profile.subscribed_q();
    let listener = TcpListener::bind(&args.bind)
        .map_err(|e| Fail::Usage(anyhow::anyhow!("cannot bind {}: {e}", args.bind)))?;
    let addr: SocketAddr = listener.local_addr()?;
    let access = Access::for_bind(&addr, args.token).map_err(|e| {
        anyhow::anyhow!("no random source for the token ({e}): give one with --token")
    })?;
    println!("serving http://{addr}/");
    if let Access::Token(t) = &access {
        println!("token: {t}");
        println!("open http://{addr}/?token={t}");
    }
    use std::io::Write as _;
    std::io::stdout().flush()?;
    let shared = Shared::new(&q);
    let (tx, rx) = mpsc::channel();
    {
        let shared = Arc::clone(&shared);
        std::thread::spawn(move || plc::run(connect, q, shared, rx));
    }
    let ctx = Arc::new(Ctx {
        shared,
        access,
        actions: tx,
        profile: serde_json::to_value(&profile).map_err(anyhow::Error::from)?,
    });
    for stream in listener.incoming() {
        let Ok(stream) = stream else { continue };
        let ctx = Arc::clone(&ctx);
        std::thread::spawn(move || handle(stream, &ctx));
    }
    Ok(())
}

fn handle(mut stream: TcpStream, ctx: &Ctx) {
    let _ = stream.set_read_timeout(Some(Duration::from_secs(10)));
    let Some(req) = http::read_request(&mut stream) else {
        let _ = Response::error(400, "bad request").write_to(&mut stream);
        return;
    };
    if !ctx.access.allows(req.query.as_deref(), &req.headers) {
        let _ = Response::error(401, "token required (open the URL serve printed)")
            .write_to(&mut stream);
        return;
    }
    if req.method == "GET" && req.path == "/api/stream" {
        let _ = stream_events(&mut stream, &ctx.shared);
        return;
    }
    let mut resp = route(&req, ctx);
    // The page's URL carries the token once; the cookie carries it afterwards.
    if let (Access::Token(t), Some(q)) = (&ctx.access, req.query.as_deref()) {
        if access::query_value(q, "token").is_some() {
            resp = resp.with_header(
                "Set-Cookie",
                format!("{COOKIE}={t}; Path=/; HttpOnly; SameSite=Strict"),
            );
        }
    }
    let _ = resp.write_to(&mut stream);
}

fn route(req: &http::Request, ctx: &Ctx) -> Response {
    let get = req.method == "GET";
    match req.path.as_str() {
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
        "/api/stop" | "/api/run" | "/api/ack" | "/api/clear-faults" if req.method == "POST" => {
            action(req, ctx)
        }
        "/" | "/index.html" | "/app.js" | "/app.css" | "/api/profile" | "/api/status"
        | "/api/faults" | "/api/counters" | "/api/trend" | "/api/stop" | "/api/run"
        | "/api/ack" | "/api/clear-faults" => Response::error(405, "method not allowed"),
        _ => Response::error(404, "not found"),
    }
}

fn status_json(shared: &Shared) -> Value {
    status_view(&shared.lock())
}

/// `/api/status` and the stream's `status` event: `status --json` plus the connection,
/// the service version and the latched drive fault's text (the fault log's words).
fn status_view(s: &plc::State) -> Value {
    let fault = s.status["drive"]["fault"].as_u64().unwrap_or(0);
    json!({
        "connected": s.connected,
        "error": s.error,
        "identity": s.identity,
        "status": s.status,
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
/// this server never grants), then the PLC's answer.
fn action(req: &http::Request, ctx: &Ctx) -> Response {
    let json_type = req
        .header("content-type")
        .and_then(|t| t.split(';').next())
        .is_some_and(|t| t.trim().eq_ignore_ascii_case("application/json"));
    if !json_type {
        return Response::error(415, "Content-Type: application/json required");
    }
    let request = match req.path.as_str() {
        "/api/stop" => Request::Stop,
        "/api/run" => Request::Run { slot: 0 },
        "/api/ack" => Request::Ack,
        _ => Request::ClearFaultLog,
    };
    let (reply, answer) = mpsc::channel();
    if ctx.actions.send(Action { request, reply }).is_err() {
        return Response::error(503, "the PLC connection has stopped");
    }
    match answer.recv_timeout(ACTION_WAIT) {
        Ok(Ok(())) => Response::json(200, &json!({ "ok": true })),
        Ok(Err(e)) => Response::error(409, &e),
        Err(_) => Response::error(503, "no answer from the PLC"),
    }
}

/// The stream: the status whenever it changes, every new sample, a keep-alive comment.
fn stream_events(stream: &mut TcpStream, shared: &Shared) -> std::io::Result<()> {
    use std::io::Write as _;
    http::start_events(stream)?;
    let mut last_status = Value::Null;
    let mut next_serial = shared.lock().samples.back().map_or(0, |(n, _)| n + 1);
    let mut generation = u64::MAX;
    loop {
        let mut out = String::new();
        {
            let mut s = shared.lock();
            if s.generation == generation {
                let (g, _) = shared
                    .changed
                    .wait_timeout(s, KEEPALIVE)
                    .unwrap_or_else(|p| p.into_inner());
                s = g;
            }
            if s.generation == generation {
                out += ": keep-alive\n\n";
            }
            generation = s.generation;
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
        if !out.is_empty() {
            stream.write_all(out.as_bytes())?;
            stream.flush()?;
        }
    }
}
