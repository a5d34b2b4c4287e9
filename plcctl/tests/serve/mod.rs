//! `plcctl serve` against `hil-sim run … --service-pty` (service.md 11, 14): the JSON API,
//! the event stream, the actions and the token, over real HTTP on a free port. Part of
//! the `sim` test binary (its `Sim` helpers).

use std::io::{Read, Write};
use std::net::TcpStream;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use super::{announced, motor, temp, Sim, PLCCTL};

mod browser;
mod cdp;

/// A running `plcctl serve` on a free loopback port.
pub struct Serve {
    child: Child,
    pub base: String,
    token: Option<String>,
}

impl Serve {
    /// `plcctl --port <sim's pty> serve --bind 127.0.0.1:0 [extra]`.
    pub fn start(sim: &Sim, extra: &[&str]) -> Serve {
        let mut child = Command::new(PLCCTL)
            .env("XDG_CACHE_HOME", temp("cache"))
            .args(["--port", &sim.path, "serve", "--bind", "127.0.0.1:0"])
            .args(extra)
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        let served = announced(child.stdout.take().unwrap(), "serving ");
        let base = served.trim_end_matches('/').to_string();
        assert!(base.starts_with("http://127.0.0.1:"), "{base}");
        assert!(!base.ends_with(":0"), "port 0 picks a free port: {base}");
        let token = extra
            .iter()
            .position(|a| *a == "--token")
            .map(|i| extra[i + 1].to_string());
        Serve { child, base, token }
    }

    fn addr(&self) -> String {
        self.base.trim_start_matches("http://").to_string()
    }

    /// One request; (status, headers, body). `headers` are sent as given; the token
    /// goes as a bearer header unless `bare`.
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
        let mut req = format!("{method} {path} HTTP/1.1\r\nHost: {}\r\n", self.addr());
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
    write!(s, "GET /api/stream HTTP/1.1\r\nHost: x\r\n{t}\r\n").unwrap();
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
    let serve = Serve::start(
        &sim,
        &[
            "--token",
            "0123abcd",
            "--profile",
            profile.to_str().unwrap(),
        ],
    );
    // Token (service.md 14): nothing without it, the page's URL sets the cookie.
    let (code, _, _) = serve.raw("GET", "/api/status", &[], "", true);
    assert_eq!(code, 401);
    let (code, head, _) = serve.raw("GET", "/?token=0123abcd", &[], "", true);
    assert_eq!(code, 200);
    assert!(
        head.contains("Set-Cookie: plcctl_token=0123abcd; Path=/; HttpOnly; SameSite=Strict"),
        "{head}"
    );
    let (code, _, _) = serve.raw(
        "GET",
        "/api/status",
        &[("Cookie", "plcctl_token=0123abcd")],
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
    let (code, body) = serve.post("/api/stop");
    assert_eq!((code, &body), (200, &serde_json::json!({ "ok": true })));
    serve.wait_status(3.0, |s| s["status"]["plc"] == "Stop");
    // hil-sim gone: the connection is reported lost, and retried every second.
    let mut sim = sim;
    sim.child.kill().unwrap();
    sim.child.wait().unwrap();
    let s = serve.wait_status(5.0, |s| s["connected"] == false);
    assert!(s["error"].is_string(), "{s}");
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
