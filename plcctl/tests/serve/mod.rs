//! `plcctl serve` against `hil-sim run … --service-pty` (service.md 11, 14): the JSON API,
//! the event stream, the actions, the token, the Host and Origin checks, the limits on
//! what a request may be and the access log, over real HTTP on a free port
//! (docs/serve.md's threat model). Part of the `sim` test binary (its `Sim` helpers).

use std::io::{Read, Write};
use std::net::TcpStream;
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use super::{announced, motor, temp, Sim, PLCCTL};

mod browser;
mod cdp;
mod clock;
mod limits;

/// A running `plcctl serve` on a free loopback port.
pub struct Serve {
    child: Child,
    pub base: String,
    token: Option<String>,
    /// Its stderr so far: the access log.
    log: Arc<Mutex<String>>,
}

impl Serve {
    /// `plcctl --port <sim's pty> serve --bind 127.0.0.1:0 [extra]`.
    pub fn start(sim: &Sim, extra: &[&str]) -> Serve {
        Serve::start_on(&sim.path, None, extra)
    }

    /// `plcctl --port <port> serve --bind 127.0.0.1:0 [extra]`, with `token` in a
    /// `--token-file`.
    pub fn start_on(port: &str, token: Option<&str>, extra: &[&str]) -> Serve {
        let mut cmd = Command::new(PLCCTL);
        cmd.env("XDG_CACHE_HOME", temp("cache"))
            .env_remove("PLCCTL_TOKEN")
            .args(["--port", port, "serve", "--bind", "127.0.0.1:0"])
            .args(extra);
        if let Some(t) = token {
            let f = temp(&format!("token-{t}"));
            std::fs::write(&f, format!("{t}\n")).unwrap();
            cmd.arg("--token-file").arg(f);
        }
        let mut child = cmd
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let log = Arc::new(Mutex::new(String::new()));
        {
            let log = Arc::clone(&log);
            let mut err = child.stderr.take().unwrap();
            std::thread::spawn(move || {
                let mut buf = [0u8; 4096];
                while let Ok(n) = err.read(&mut buf) {
                    if n == 0 {
                        break;
                    }
                    log.lock()
                        .unwrap()
                        .push_str(&String::from_utf8_lossy(&buf[..n]));
                }
            });
        }
        let served = announced(child.stdout.take().unwrap(), "serving ");
        let base = served.trim_end_matches('/').to_string();
        assert!(base.starts_with("http://127.0.0.1:"), "{base}");
        assert!(!base.ends_with(":0"), "port 0 picks a free port: {base}");
        Serve {
            child,
            base,
            token: token.map(String::from),
            log,
        }
    }

    pub fn addr(&self) -> String {
        self.base.trim_start_matches("http://").to_string()
    }

    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    /// The access log so far (serve's stderr).
    pub fn log(&self) -> String {
        self.log.lock().unwrap().clone()
    }

    /// Waits (at most 5 s) for a log line containing every one of `parts`; that line.
    pub fn wait_log(&self, parts: &[&str]) -> String {
        let end = Instant::now() + Duration::from_secs(5);
        loop {
            let log = self.log();
            if let Some(l) = log.lines().find(|l| parts.iter().all(|p| l.contains(p))) {
                return l.to_string();
            }
            assert!(
                Instant::now() < end,
                "no log line with {parts:?} in:\n{log}"
            );
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// One request; (status, headers, body). `headers` are sent as given (with
    /// `Host: <addr>` unless they have a `Host`); the token goes as a bearer header
    /// unless `bare`.
    pub fn raw(
        &self,
        method: &str,
        path: &str,
        headers: &[(&str, &str)],
        body: &str,
        bare: bool,
    ) -> (u16, String, String) {
        let mut s = TcpStream::connect(self.addr()).unwrap();
        s.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
        let mut req = format!("{method} {path} HTTP/1.1\r\n");
        if !headers.iter().any(|(k, _)| k.eq_ignore_ascii_case("host")) {
            req += &format!("Host: {}\r\n", self.addr());
        }
        for (k, v) in headers {
            req += &format!("{k}: {v}\r\n");
        }
        if let (Some(t), false) = (&self.token, bare) {
            req += &format!("Authorization: Bearer {t}\r\n");
        }
        req += &format!("Content-Length: {}\r\n\r\n{body}", body.len());
        s.write_all(req.as_bytes()).unwrap();
        let mut resp = String::new();
        s.read_to_string(&mut resp).unwrap();
        let (head, body) = resp.split_once("\r\n\r\n").unwrap();
        let code = head.split(' ').nth(1).unwrap().parse().unwrap();
        (code, head.to_string(), body.to_string())
    }

    pub fn get(&self, path: &str) -> serde_json::Value {
        let (code, _, body) = self.raw("GET", path, &[], "", false);
        assert_eq!(code, 200, "GET {path}: {body}");
        serde_json::from_str(&body).unwrap()
    }

    pub fn post(&self, path: &str) -> (u16, serde_json::Value) {
        let (code, _, body) = self.raw(
            "POST",
            path,
            &[("Content-Type", "application/json")],
            "{}",
            false,
        );
        (code, serde_json::from_str(&body).unwrap())
    }

    /// Polls `/api/status` until `f` holds (at most `secs`).
    pub fn wait_status(
        &self,
        secs: f64,
        f: impl Fn(&serde_json::Value) -> bool,
    ) -> serde_json::Value {
        let end = Instant::now() + Duration::from_secs_f64(secs);
        loop {
            let s = self.get("/api/status");
            if f(&s) {
                return s;
            }
            assert!(Instant::now() < end, "status never as expected: {s}");
            std::thread::sleep(Duration::from_millis(100));
        }
    }
}

impl Drop for Serve {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// The events of `/api/stream` for `secs` seconds: (name, data) pairs.
fn events(serve: &Serve, secs: f64) -> Vec<(String, serde_json::Value)> {
    let mut s = TcpStream::connect(serve.addr()).unwrap();
    let t = serve
        .token
        .as_ref()
        .map(|t| format!("Authorization: Bearer {t}\r\n"))
        .unwrap_or_default();
    write!(
        s,
        "GET /api/stream HTTP/1.1\r\nHost: {}\r\n{t}\r\n",
        serve.addr()
    )
    .unwrap();
    s.set_read_timeout(Some(Duration::from_millis(200)))
        .unwrap();
    let end = Instant::now() + Duration::from_secs_f64(secs);
    let mut text = String::new();
    let mut buf = [0u8; 4096];
    while Instant::now() < end {
        if let Ok(n) = s.read(&mut buf) {
            text += &String::from_utf8_lossy(&buf[..n]);
        }
    }
    assert!(text.starts_with("HTTP/1.1 200"), "{text}");
    assert!(text.contains("Content-Type: text/event-stream"));
    let body = text.split_once("\r\n\r\n").unwrap().1;
    body.split("\n\n")
        .filter_map(|ev| {
            let name = ev.lines().find_map(|l| l.strip_prefix("event: "))?;
            let data = ev.lines().find_map(|l| l.strip_prefix("data: "))?;
            Some((name.to_string(), serde_json::from_str(data).unwrap()))
        })
        .collect()
}

#[test]
fn serve_api_stream_actions_and_token_against_the_simulator() {
    let sim = Sim::start(&[
        motor().to_str().unwrap(),
        "--scenario",
        super::root()
            .join("hil-sim/scenarios/motor.toml")
            .to_str()
            .unwrap(),
        "--duration",
        "30",
        "--service-linger",
        "0",
    ]);
    let profile = super::root().join("shared-protocol/programs/motor.profile.toml");
    const TOKEN: &str = "0123abcd0123abcd0123abcd0123abcd";
    let log_file = temp("serve-access.log");
    let _ = std::fs::remove_file(&log_file);
    let serve = Serve::start_on(
        &sim.path,
        Some(TOKEN),
        &[
            "--profile",
            profile.to_str().unwrap(),
            "--log",
            log_file.to_str().unwrap(),
        ],
    );
    // Token (service.md 14): nothing without it, the page's URL sets the cookie.
    let (code, _, _) = serve.raw("GET", "/api/status", &[], "", true);
    assert_eq!(code, 401);
    let (code, _, _) = serve.raw("GET", "/api/status?token=", &[], "", true);
    assert_eq!(code, 401, "an empty token is no token");
    let (code, head, _) = serve.raw("GET", &format!("/?token={TOKEN}"), &[], "", true);
    assert_eq!(code, 200);
    assert!(
        head.contains(&format!(
            "Set-Cookie: plcctl_token={TOKEN}; Path=/; HttpOnly; SameSite=Strict"
        )),
        "{head}"
    );
    // Never framed (clickjacking), nothing loaded from elsewhere.
    assert!(head.contains("X-Frame-Options: DENY\r\n"), "{head}");
    let csp = head
        .lines()
        .find_map(|l| l.strip_prefix("Content-Security-Policy: "))
        .unwrap_or_else(|| panic!("no CSP: {head}"));
    assert!(csp.contains("frame-ancestors 'none'"), "{csp}");
    assert!(csp.contains("default-src 'none'"), "{csp}");
    assert!(!csp.contains("unsafe-inline"), "{csp}");
    let (code, _, _) = serve.raw(
        "GET",
        "/api/status",
        &[("Cookie", &format!("plcctl_token={TOKEN}"))],
        "",
        true,
    );
    assert_eq!(code, 200);
    assert!(
        !head.to_ascii_lowercase().contains("access-control"),
        "no CORS"
    );
    // Status: `status --json` plus the connection.
    let s = serve.wait_status(10.0, |s| {
        s["connected"] == true && s["status"]["plc"] == "Run"
    });
    assert_eq!(s["identity"]["firmware"], env!("CARGO_PKG_VERSION"));
    assert_eq!(s["status"]["slot"], 1);
    assert_eq!(s["status"]["remote"], false);
    // The stream: status events and samples at 10 Hz.
    let ev = events(&serve, 2.0);
    let samples: Vec<_> = ev.iter().filter(|(n, _)| n == "sample").collect();
    assert!(ev.iter().any(|(n, _)| n == "status"), "{ev:?}");
    assert!(
        (15..=25).contains(&samples.len()),
        "{} samples in 2 s",
        samples.len()
    );
    // A new stream starts with the fault log and the counters, each before the first
    // status (the page needs no other request for them).
    let at = |name: &str| ev.iter().position(|(n, _)| n == name);
    let (faults, counters, status) = (at("faults"), at("counters"), at("status"));
    assert!(faults.is_some() && counters.is_some(), "{ev:?}");
    assert!(faults < status && counters < status, "{ev:?}");
    assert!(ev[faults.unwrap()].1.is_array(), "{ev:?}");
    assert!(ev[counters.unwrap()].1["run_starts"].is_u64(), "{ev:?}");
    let serials: Vec<u64> = samples
        .iter()
        .map(|(_, d)| d["serial"].as_u64().unwrap())
        .collect();
    assert!(serials.windows(2).all(|w| w[1] == w[0] + 1), "{serials:?}");
    // The trend: hil-sim's columns, at least the last second at 10 Hz.
    let t = serve.get("/api/trend?s=60");
    let cols: Vec<&str> = t["columns"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c.as_str().unwrap())
        .collect();
    assert_eq!(&cols[..5], ["t_s", "f_cmd_hz", "dir", "fault", "u_dc_v"]);
    // The profile's Q variables are subscribed (motor.profile.toml: Q00 and Q02).
    assert!(cols.contains(&"Q02") && !cols.contains(&"Q03"), "{cols:?}");
    assert!(cols.contains(&"lcd3") && cols.contains(&"imx_a"));
    let p = serve.get("/api/profile");
    assert_eq!(p["kind"], "table");
    assert_eq!(p["vars"]["speed pot"], "A01");
    let rows = t["rows"].as_array().unwrap();
    assert!(rows.len() >= 20, "{} rows", rows.len());
    assert!(rows
        .iter()
        .all(|r| r.as_array().unwrap().len() == cols.len()));
    let ts: Vec<f64> = rows.iter().map(|r| r[0].as_f64().unwrap()).collect();
    assert!(ts.windows(2).all(|w| w[1] > w[0]), "t_s increases");
    let short = serve.get("/api/trend?s=1");
    let n = short["rows"].as_array().unwrap().len();
    assert!((9..=12).contains(&n), "{n} rows in 1 s");
    // Faults and counters answer (the log's content is compared in the browser test).
    assert!(serve.get("/api/faults").is_array());
    assert!(serve.get("/api/counters").is_object());
    // The LCD's rows as shown, and the values' age.
    let s = serve.get("/api/status");
    let rows = s["lcd_text"].as_array().unwrap_or_else(|| panic!("{s}"));
    assert!(
        !rows.is_empty() && rows.iter().all(|r| r.is_string()),
        "{s}"
    );
    assert!(s["age_ms"].as_u64().is_some_and(|a| a < 2000), "{s}");
    // Actions: JSON only; guarded ones refused without remote service; STOP always.
    let (code, _, _) = serve.raw(
        "POST",
        "/api/stop",
        &[("Content-Type", "text/plain")],
        "x",
        false,
    );
    assert_eq!(code, 415);
    let (code, _, _) = serve.raw("GET", "/api/stop", &[], "", false);
    assert_eq!(code, 405);
    let (code, body) = serve.post("/api/run");
    assert_eq!(code, 409);
    assert!(
        body["error"].as_str().unwrap().contains("remote service"),
        "{body}"
    );
    // DNS rebinding: a page on another name that resolves to 127.0.0.1 posts from its
    // own origin; Host names the attacker's name: 421, nothing done.
    let port = serve.addr().rsplit_once(':').unwrap().1.to_string();
    let evil = format!("rebind.example:{port}");
    let evil_origin = format!("http://{evil}");
    for path in ["/api/stop", "/api/status", "/"] {
        let (code, _, body) = serve.raw(
            "POST",
            path,
            &[
                ("Host", &evil),
                ("Origin", &evil_origin),
                ("Content-Type", "application/json"),
            ],
            "{}",
            false,
        );
        assert_eq!(code, 421, "{path}: {body}");
    }
    let (code, _, _) = serve.raw("GET", "/api/status", &[("Host", &evil)], "", false);
    assert_eq!(code, 421);
    // CSRF: a page elsewhere posting to the right name: 403, nothing done.
    for (k, v) in [
        ("Origin", "http://evil.example"),
        ("Origin", "null"),
        ("Sec-Fetch-Site", "cross-site"),
    ] {
        let (code, _, body) = serve.raw(
            "POST",
            "/api/stop",
            &[(k, v), ("Content-Type", "application/json")],
            "{}",
            false,
        );
        assert_eq!(code, 403, "{k}: {v}: {body}");
    }
    assert_eq!(
        serve.get("/api/status")["status"]["plc"],
        "Run",
        "nothing stopped"
    );
    // The other names of this server; its own origin may post.
    for host in [format!("localhost:{port}"), format!("[::1]:{port}")] {
        let (code, _, _) = serve.raw("GET", "/api/status", &[("Host", &host)], "", false);
        assert_eq!(code, 200, "{host}");
    }
    let own = serve.base.clone();
    let (code, _, body) = serve.raw(
        "POST",
        "/api/stop",
        &[
            ("Origin", &own),
            ("Sec-Fetch-Site", "same-origin"),
            ("Content-Type", "application/json"),
        ],
        "{}",
        false,
    );
    assert_eq!((code, body.as_str()), (200, r#"{"ok":true}"#));
    serve.wait_status(3.0, |s| s["status"]["plc"] == "Stop");
    // The log: who (the peer), what, the result; in the file as on stderr.
    let stop = serve.wait_log(&["127.0.0.1:", "POST /api/stop 200 ok"]);
    serve.wait_log(&["POST /api/run 409 refused by the PLC"]);
    serve.wait_log(&["POST /api/stop host \"rebind.example", "421"]);
    serve.wait_log(&["POST /api/stop origin \"http://evil.example\" 403"]);
    let file = std::fs::read_to_string(&log_file).unwrap();
    assert!(file.contains(&stop), "{file}");
    assert!(!file.contains(TOKEN), "the token is never logged: {file}");
    // hil-sim gone: the connection is reported lost, and retried every second; the
    // values' age grows past 2 s; an action has no PLC to ask: 503.
    let mut sim = sim;
    sim.child.kill().unwrap();
    sim.child.wait().unwrap();
    let s = serve.wait_status(5.0, |s| s["connected"] == false);
    assert!(s["error"].is_string(), "{s}");
    let (code, body) = serve.post("/api/stop");
    assert_eq!(code, 503, "{body}");
    assert!(
        body["error"].as_str().unwrap().starts_with("no PLC"),
        "{body}"
    );
    let s = serve.wait_status(5.0, |s| s["age_ms"].as_u64() > Some(2000));
    assert_eq!(
        s["status"]["plc"], "Stop",
        "the last values stay, with their age"
    );
}

#[test]
fn a_bad_profile_exits_1_naming_the_key() {
    let bad = temp("bad.profile.toml");
    std::fs::write(&bad, "kind = \"lift\"\n[vars]\nfloor = \"Q99\"\n").unwrap();
    let o = Command::new(PLCCTL)
        .args([
            "--port",
            "/dev/null",
            "serve",
            "--bind",
            "127.0.0.1:0",
            "--profile",
        ])
        .arg(&bad)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("vars.floor") && err.contains("Q99"), "{err}");
    assert!(o.stdout.is_empty(), "nothing served");
}
