//! A small client of the Chrome DevTools protocol for the browser test: a headless
//! Chromium on a free debugging port, pages attached in flat mode over the browser's one
//! websocket, `Runtime.evaluate` and screenshots. Events arriving between answers are
//! kept (console errors, requests).

use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use base64::Engine as _;
use serde_json::{json, Value};
use tungstenite::{Message, WebSocket};

/// The browser binary: `$CHROMIUM`, else the Debian package's and the usual names.
pub fn find_chromium() -> Option<PathBuf> {
    if let Some(p) = std::env::var_os("CHROMIUM") {
        return Some(PathBuf::from(p));
    }
    let path = std::env::var_os("PATH").unwrap_or_default();
    for name in ["chromium", "chromium-browser", "google-chrome"] {
        for dir in std::env::split_paths(&path) {
            let p = dir.join(name);
            if p.is_file() {
                return Some(p);
            }
        }
    }
    None
}

pub struct Browser {
    child: Child,
    ws: WebSocket<TcpStream>,
    next_id: u64,
    /// Every event received so far (with its `sessionId`).
    pub events: Vec<Value>,
    _profile_dir: PathBuf,
}

impl Browser {
    /// A headless Chromium with its own profile in `dir`.
    pub fn launch(exe: &Path, dir: &Path) -> Browser {
        let _ = std::fs::remove_dir_all(dir);
        std::fs::create_dir_all(dir).unwrap();
        let child = Command::new(exe)
            .args([
                "--headless=new",
                "--no-sandbox",
                "--disable-gpu",
                "--hide-scrollbars",
                "--no-first-run",
                "--no-default-browser-check",
                "--disable-extensions",
                "--disable-background-networking",
                "--disable-component-update",
                "--disable-sync",
                "--disable-background-timer-throttling",
                "--disable-renderer-backgrounding",
                "--disable-backgrounding-occluded-windows",
                "--mute-audio",
                "--remote-debugging-port=0",
            ])
            .arg(format!("--user-data-dir={}", dir.display()))
            .arg("about:blank")
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap_or_else(|e| panic!("{}: {e}", exe.display()));
        // Chromium writes its port and the browser's websocket path here.
        let port_file = dir.join("DevToolsActivePort");
        let end = Instant::now() + Duration::from_secs(30);
        let (port, path) = loop {
            if let Ok(t) = std::fs::read_to_string(&port_file) {
                let mut l = t.lines();
                if let (Some(a), Some(b)) = (l.next(), l.next()) {
                    break (a.to_string(), b.to_string());
                }
            }
            assert!(Instant::now() < end, "Chromium gave no DevTools port");
            std::thread::sleep(Duration::from_millis(50));
        };
        let stream = TcpStream::connect(format!("127.0.0.1:{port}")).unwrap();
        stream
            .set_read_timeout(Some(Duration::from_secs(60)))
            .unwrap();
        let (ws, _) = tungstenite::client(format!("ws://127.0.0.1:{port}{path}"), stream)
            .unwrap_or_else(|e| panic!("DevTools websocket: {e}"));
        Browser {
            child,
            ws,
            next_id: 1,
            events: Vec::new(),
            _profile_dir: dir.to_path_buf(),
        }
    }

    /// One command (of a page when `session` is given); its result, or a panic with the
    /// protocol's error.
    pub fn call(&mut self, session: Option<&str>, method: &str, params: Value) -> Value {
        let id = self.next_id;
        self.next_id += 1;
        let mut msg = json!({ "id": id, "method": method, "params": params });
        if let Some(s) = session {
            msg["sessionId"] = json!(s);
        }
        self.ws.send(Message::text(msg.to_string())).unwrap();
        loop {
            let m = self.ws.read().unwrap_or_else(|e| panic!("{method}: {e}"));
            let Message::Text(t) = m else { continue };
            let v: Value = serde_json::from_str(t.as_str()).unwrap();
            if v["id"] == id {
                if let Some(e) = v.get("error") {
                    panic!("{method}: {e}");
                }
                return v["result"].clone();
            }
            if v.get("method").is_some() {
                self.events.push(v);
            }
        }
    }

    /// A new page of `width` x `height` CSS pixels with console, log and network events
    /// on; its session id.
    pub fn page(&mut self, width: u32, height: u32) -> String {
        let t = self.call(
            None,
            "Target.createTarget",
            json!({ "url": "about:blank", "width": width, "height": height, "newWindow": true }),
        );
        let a = self.call(
            None,
            "Target.attachToTarget",
            json!({ "targetId": t["targetId"], "flatten": true }),
        );
        let s = a["sessionId"].as_str().unwrap().to_string();
        for m in [
            "Runtime.enable",
            "Log.enable",
            "Network.enable",
            "Page.enable",
        ] {
            self.call(Some(&s), m, json!({}));
        }
        self.call(
            Some(&s),
            "Emulation.setDeviceMetricsOverride",
            json!({ "width": width, "height": height, "deviceScaleFactor": 1, "mobile": false }),
        );
        s
    }

    /// Runs `script` in the page at the start of every document it loads, before the
    /// page's own scripts (a DevTools script: the page's CSP does not apply to it).
    pub fn on_new_document(&mut self, s: &str, script: &str) {
        self.call(
            Some(s),
            "Page.addScriptToEvaluateOnNewDocument",
            json!({ "source": script }),
        );
    }

    pub fn navigate(&mut self, s: &str, url: &str) {
        self.call(Some(s), "Page.navigate", json!({ "url": url }));
    }

    /// The value of a JavaScript expression (JSON-serialisable), or a panic with the
    /// exception.
    pub fn eval(&mut self, s: &str, expr: &str) -> Value {
        let r = self.call(
            Some(s),
            "Runtime.evaluate",
            json!({ "expression": expr, "returnByValue": true, "awaitPromise": true }),
        );
        if let Some(e) = r.get("exceptionDetails") {
            panic!("{expr}: {e}");
        }
        r["result"]["value"].clone()
    }

    /// The page's viewport as a PNG file's bytes.
    pub fn screenshot(&mut self, s: &str) -> Vec<u8> {
        let r = self.call(
            Some(s),
            "Page.captureScreenshot",
            // Lossless still (the banner's pixel is checked), encoded fast.
            json!({ "format": "png", "optimizeForSpeed": true }),
        );
        base64::engine::general_purpose::STANDARD
            .decode(r["data"].as_str().unwrap())
            .unwrap()
    }

    /// Console errors, uncaught exceptions and error log entries of a page so far.
    pub fn errors(&self, s: &str) -> Vec<Value> {
        self.events
            .iter()
            .filter(|e| e["sessionId"] == s)
            .filter(|e| match e["method"].as_str() {
                Some("Runtime.consoleAPICalled") => e["params"]["type"] == "error",
                Some("Runtime.exceptionThrown") => true,
                Some("Log.entryAdded") => e["params"]["entry"]["level"] == "error",
                _ => false,
            })
            .cloned()
            .collect()
    }

    /// The URLs a page requested so far.
    pub fn requests(&self, s: &str) -> Vec<String> {
        self.events
            .iter()
            .filter(|e| e["sessionId"] == s && e["method"] == "Network.requestWillBeSent")
            .filter_map(|e| e["params"]["request"]["url"].as_str().map(String::from))
            .collect()
    }
}

impl Drop for Browser {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// The RGB of pixel (`x`, `y`) of a PNG.
pub fn pixel(png_bytes: &[u8], x: u32, y: u32) -> [u8; 3] {
    let mut d = png::Decoder::new(png_bytes);
    d.set_transformations(png::Transformations::EXPAND | png::Transformations::STRIP_16);
    let mut r = d.read_info().unwrap();
    let mut buf = vec![0; r.output_buffer_size()];
    let info = r.next_frame(&mut buf).unwrap();
    let ch = info.color_type.samples();
    let i = (y as usize * info.width as usize + x as usize) * ch;
    [buf[i], buf[i + 1], buf[i + 2]]
}
