//! service.md 15: the page in a real headless Chromium, over the DevTools protocol, at
//! 1920 x 1080 and 720 x 1520 at once (two pages of one browser), against
//! `hil-sim run lift.plc --service-pty` and `plcctl serve --profile lift.profile.toml`.
//!
//! The run (virtual time = wall time while the pty is held): the initialisation, a call
//! to floor 3 with its door cycle, `*7` twice (remote service on, off), a call to floor 1
//! and a supply drop to 18 V on the way (lift scenario L7's UV trip). Screenshots go to
//! `target/serve-screens/`. Without a Chromium the test is skipped with a message, unless
//! `CI` is set.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use serde_json::Value;

use super::cdp::{find_chromium, pixel, Browser};
use super::Serve;
use crate::Sim;

const SCENARIO: &str = "\
duration_s = 45.0
[lift]
[[event]]
at_s = 7.0
call = 3
[[event]]
at_s = 27.0
keys = \"*7\"
[[event]]
at_s = 29.0
keys = \"*7\"
[[event]]
at_s = 30.0
call = 1
[[event]]
at_s = 33.0
dc_link_v = 18.0
";

/// The banner colours of `app.css`.
const GREEN: [u8; 3] = [0x1e, 0x8e, 0x3e];
const ORANGE: [u8; 3] = [0xe3, 0x74, 0x00];
const RED: [u8; 3] = [0xc5, 0x22, 0x1f];

/// What the test reads of a page (the page keeps its state in `data-*` attributes).
const OBSERVE: &str = r##"(() => {
  const $ = (i) => document.getElementById(i);
  const b = $("banner"), m = $("mimic"), t = $("trend");
  // A page still being parsed (a navigation) has only part of its elements.
  if (document.readyState === "loading" || !b || !m || !$("counters")) return null;
  const r = b.getBoundingClientRect();
  return {
    colour: b.dataset.colour, title: $("banner-title").textContent,
    detail: $("banner-detail").textContent,
    floor: m.dataset.floor === undefined ? null : m.dataset.floor,
    door: m.dataset.door === undefined ? null : m.dataset.door,
    car_y: (() => { const c = m.querySelector("[data-car] rect");
                    return c ? Number(c.getAttribute("y")) : null; })(),
    stop: $("act-stop").disabled, run: $("act-run").disabled, ack: $("act-ack").disabled,
    clear: $("act-clear-faults").disabled, note: $("action-note").textContent,
    span: Number(t.dataset.span || 0),
    rows: [...document.querySelectorAll("#faults tbody tr[data-pos]")]
      .map((tr) => [tr.dataset.pos, ...[...tr.cells].map((c) => c.textContent)]),
    counters: $("counters").textContent,
    lcd: $("lcd").textContent,
    stale: $("values-block").dataset.stale || null, age: $("values-age").textContent,
    time_ticks: t.dataset.timeTicks || "", units: t.dataset.units || "",
    legend: $("trend-legend").textContent,
    lamps_cut: [...document.querySelectorAll(".lamp")]
      .filter((l) => l.scrollWidth > l.clientWidth + 1 || l.scrollHeight > l.clientHeight + 1)
      .map((l) => l.textContent),
    lamps: [...document.querySelectorAll(".lamp")].map((l) => l.textContent),
    bx: Math.round(r.left + 4), by: Math.round(r.top + r.height / 2),
  };
})()"##;

struct Page {
    name: &'static str,
    session: String,
    /// The newest `lcd0` change this page's mimic has not shown yet: (when, value).
    pending_floor: Option<(Instant, i64)>,
    doors: Vec<String>,
    max_span_s: f64,
}

struct Run {
    browser: Browser,
    pages: Vec<Page>,
    serve: Option<Serve>,
    lcd0: Option<i64>,
    floor_changes: usize,
    screens: PathBuf,
}

impl Run {
    fn observe(&mut self, i: usize) -> Value {
        let s = self.pages[i].session.clone();
        self.browser.eval(&s, OBSERVE)
    }

    /// Polls the server and the pages every 100 ms until `done` holds for every page
    /// (at most `secs`), checking on the way that each mimic follows `lcd0` within 1 s.
    fn until(&mut self, what: &str, secs: f64, done: impl Fn(&Value) -> bool) -> Vec<Value> {
        let end = Instant::now() + Duration::from_secs_f64(secs);
        loop {
            let now = Instant::now();
            if let Some(serve) = &self.serve {
                let st = serve.get("/api/status");
                let lcd0 = st["status"]["lcd"][0].as_i64();
                if lcd0.is_some() && lcd0 != self.lcd0 && lcd0 >= Some(1) {
                    self.floor_changes += 1;
                    for p in &mut self.pages {
                        p.pending_floor = Some((now, lcd0.unwrap_or(0)));
                    }
                }
                self.lcd0 = lcd0;
            }
            let obs: Vec<Value> = (0..self.pages.len()).map(|i| self.observe(i)).collect();
            for (p, o) in self.pages.iter_mut().zip(&obs) {
                if let Some((t, v)) = p.pending_floor {
                    if o["floor"].as_str().and_then(|f| f.parse().ok()) == Some(v) {
                        p.pending_floor = None;
                    } else {
                        assert!(
                            now - t <= Duration::from_millis(1000),
                            "{}: lcd0 = {v} for {:?}, the mimic shows floor {}",
                            p.name,
                            now - t,
                            o["floor"]
                        );
                    }
                }
                if let Some(d) = o["door"].as_str() {
                    if !p.doors.iter().any(|x| x == d) {
                        p.doors.push(d.to_string());
                    }
                }
                p.max_span_s = p.max_span_s.max(o["span"].as_f64().unwrap_or(0.0));
            }
            if obs.iter().all(|o| !o.is_null() && done(o)) {
                return obs;
            }
            assert!(now < end, "{what}: never so in {secs} s: {obs:#?}");
            std::thread::sleep(Duration::from_millis(100));
        }
    }

    /// Screenshots of every page as `<page>-<moment>.png`, the banner's pixels checked.
    fn screens(&mut self, moment: &str, colour: [u8; 3], obs: &[Value]) {
        for (i, o) in obs.iter().enumerate() {
            let s = self.pages[i].session.clone();
            let png = self.browser.screenshot(&s);
            let file = self
                .screens
                .join(format!("{}-{moment}.png", self.pages[i].name));
            std::fs::write(&file, &png).unwrap();
            let (x, y) = (o["bx"].as_u64().unwrap(), o["by"].as_u64().unwrap());
            let px = pixel(&png, x as u32, y as u32);
            let near = px.iter().zip(colour).all(|(a, b)| a.abs_diff(b) <= 6);
            assert!(
                near,
                "{}: banner pixel ({x}, {y}) is {px:?}, expected {colour:?}",
                file.display()
            );
        }
    }
}

fn screens_dir() -> PathBuf {
    // target/<profile>/deps/sim-… → target/serve-screens
    let exe = std::env::current_exe().unwrap();
    let target = exe.ancestors().nth(3).unwrap().to_path_buf();
    let d = target.join("serve-screens");
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn the_page_in_headless_chromium_follows_the_lift() {
    let Some(chromium) = find_chromium() else {
        assert!(
            std::env::var_os("CI").is_none(),
            "CI is set and no Chromium was found (apt-get install chromium, or set CHROMIUM)"
        );
        eprintln!("SKIPPED: no Chromium found (install the chromium package or set CHROMIUM)");
        return;
    };
    let scen = crate::temp("browser-lift.toml");
    std::fs::write(&scen, SCENARIO).unwrap();
    let lift = crate::root().join("shared-protocol/programs/lift.plc");
    let profile = crate::root().join("shared-protocol/programs/lift.profile.toml");
    let profile = profile.to_str().unwrap().to_string();
    // The browser and its pages first: however long Chromium takes to start on a busy
    // machine, it is not taken from the scenario's (wall-clock) time.
    let mut browser = Browser::launch(&chromium, &crate::temp("chromium-profile"));
    let sessions: Vec<String> = [(1920, 1080), (720, 1520)]
        .iter()
        .map(|&(w, h)| browser.page(w, h))
        .collect();
    let sim = Sim::start(&[
        lift.to_str().unwrap(),
        "--scenario",
        scen.to_str().unwrap(),
        "--service-linger",
        "0",
    ]);
    let serve = Serve::start(&sim, &["--profile", &profile]);
    // Virtual time follows the wall clock while the pty is held, also between servers.
    let hold = sim.hold();
    let mut pages = Vec::new();
    for (name, session) in ["wide", "narrow"].into_iter().zip(sessions) {
        browser.navigate(&session, &format!("{}/", serve.base));
        pages.push(Page {
            name,
            session,
            pending_floor: None,
            doors: Vec::new(),
            max_span_s: 0.0,
        });
    }
    let base = serve.base.clone();
    let mut run = Run {
        browser,
        pages,
        serve: Some(serve),
        lcd0: None,
        floor_changes: 0,
        screens: screens_dir(),
    };

    // RUN, idle at floor 1 after the initialisation: green; the guarded actions are
    // disabled without remote service, with the reason; Stop is not.
    let o = run.until("green, idle at a floor", 20.0, |o| {
        o["colour"] == "green" && o["detail"] == "idle at a floor"
    });
    for o in &o {
        assert_eq!(
            (&o["run"], &o["ack"], &o["clear"], &o["stop"]),
            (
                &Value::Bool(true),
                &Value::Bool(true),
                &Value::Bool(true),
                &Value::Bool(false)
            ),
            "{o}"
        );
        assert!(
            o["note"].as_str().unwrap().contains("remote service"),
            "{o}"
        );
        assert!(o["title"].as_str().unwrap().starts_with("PLC RUN"), "{o}");
    }
    // The counters block shows the PLC's counters (service.md 7), named by the profile.
    // serve reads them when the PLC's state changes (the RUN start) and the stream
    // brings them: no poll against a cache, nothing here races.
    // (textContent runs the cells together: "RUN starts1minutes in RUN0...")
    let o = run.until("the counters show the RUN start", 15.0, |o| {
        o["counters"]
            .as_str()
            .is_some_and(|c| c.contains("RUN starts1"))
    });
    for o in &o {
        let c = o["counters"].as_str().unwrap();
        assert!(c.contains("arrivals floor 1 (Q60)"), "{c}");
    }
    // The call to floor 3: the mimic follows lcd0 (checked while polling), the door
    // shows open during the door cycle.
    let o = run.until("door open at floor 3", 30.0, |o| {
        o["door"] == "open" && o["floor"] == "3"
    });
    run.screens("door-open", GREEN, &o);
    // Lamp names wrap, none is cut off ("O05 fault / overload lamp").
    // (Checked after the time-critical door cycle.)
    for o in &o {
        assert_eq!(o["lamps_cut"], serde_json::json!([]), "{o}");
        let lamps = o["lamps"].as_array().unwrap();
        assert!(
            lamps.iter().any(|l| l == "O05 fault / overload lamp"),
            "{lamps:?}"
        );
    }
    // The LCD's rows as the PLC shows them (GetScreen), as the server has them.
    let end = Instant::now() + Duration::from_secs(5);
    loop {
        let st = run.serve.as_ref().unwrap().get("/api/status");
        let rows: Vec<&str> = st["lcd_text"]
            .as_array()
            .unwrap_or_else(|| panic!("{st}"))
            .iter()
            .map(|r| r.as_str().unwrap())
            .collect();
        let want = rows.join("\n");
        let obs: Vec<Value> = (0..run.pages.len()).map(|i| run.observe(i)).collect();
        if !want.trim().is_empty() && obs.iter().all(|o| o["lcd"] == want.as_str()) {
            break;
        }
        assert!(Instant::now() < end, "LCD {want:?}, pages {obs:#?}");
        std::thread::sleep(Duration::from_millis(100));
    }
    // `*7`: remote service on, orange; the guarded actions enabled.
    let o = run.until("orange, remote service", 15.0, |o| o["colour"] == "orange");
    for o in &o {
        assert!(
            o["detail"]
                .as_str()
                .unwrap()
                .contains("remote service enabled"),
            "{o}"
        );
        assert_eq!(
            (&o["run"], &o["ack"], &o["clear"]),
            (
                &Value::Bool(false),
                &Value::Bool(false),
                &Value::Bool(false)
            ),
            "{o}"
        );
    }
    run.screens("remote", ORANGE, &o);
    // The call to floor 1 and the UV trip on the way: red with the drive's fault.
    let o = run.until("red, drive trip", 15.0, |o| {
        o["colour"] == "red" && o["detail"].as_str().unwrap_or("").contains("drive fault 4")
    });
    run.screens("trip", RED, &o);
    // The trip left the car mid-shaft, off both vanes (D10, D11): the mimic draws it
    // between two floors, not level at the floor it passed last.
    let st = run.serve.as_ref().unwrap().get("/api/status");
    let d = st["status"]["d"].as_u64().unwrap_or_else(|| panic!("{st}"));
    assert_ne!(d >> 10 & 3, 3, "the car stopped level at a floor: {st}");
    run.until("the car drawn between floors after the trip", 5.0, |o| {
        // app.js: the car's rect is at y = 20 + (4 - pos) * 90 + 6.
        let pos = o["car_y"]
            .as_f64()
            .map(|y| 4.0 - (y - 26.0) / 90.0)
            .unwrap_or(0.0);
        pos > 1.0 && pos < 4.0 && pos.fract() != 0.0
    });
    let o = run.until("the trip in the fault archive", 5.0, |o| {
        o["rows"]
            .as_array()
            .is_some_and(|r| !r.is_empty() && r[0][3] == "4")
    });
    // The trend's time ticks (seconds of PLC uptime) and units.
    for o in &o {
        let ticks: Vec<&str> = o["time_ticks"].as_str().unwrap().split('|').collect();
        assert!(
            ticks.len() >= 3 && ticks.iter().all(|t| t.ends_with(" s")),
            "{o}"
        );
        assert!(o["units"].as_str().unwrap().starts_with("Hz, V"), "{o}");
        let legend = o["legend"].as_str().unwrap();
        assert!(
            legend.contains("(Hz)") && legend.contains("(V)"),
            "{legend}"
        );
        assert!(!o["time_ticks"].as_str().unwrap().contains("-0 "), "{o}");
    }
    for p in &run.pages {
        assert!(
            p.max_span_s >= 10.0,
            "{}: trend spans {} s",
            p.name,
            p.max_span_s
        );
        assert!(
            p.doors.iter().any(|d| d == "closed"),
            "{}: {:?}",
            p.name,
            p.doors
        );
        assert!(p.pending_floor.is_none(), "{}", p.name);
        let errors = run.browser.errors(&p.session);
        assert!(errors.is_empty(), "{}: console errors {errors:#?}", p.name);
        for url in run.browser.requests(&p.session) {
            assert!(
                url.starts_with(&format!("{base}/")),
                "{}: request outside the server: {url}",
                p.name
            );
        }
    }
    assert!(
        run.floor_changes >= 3,
        "lcd0 changed {} times",
        run.floor_changes
    );
    // Stop asks first, saying what it means for the lift; confirmed, it puts the PLC in
    // STOP.
    let s = run.pages[0].session.clone();
    let asked = run.browser.eval(
        &s,
        r#"document.getElementById("act-stop").click();
           document.getElementById("confirm").hidden === false
             ? document.getElementById("confirm-text").textContent : null"#,
    );
    let asked = asked
        .as_str()
        .unwrap_or_else(|| panic!("no dialog: {asked}"));
    assert!(
        asked.contains("between floors") && asked.contains("keypad"),
        "{asked}"
    );
    run.browser.eval(
        &s,
        r#"document.getElementById("confirm-yes").click(); true"#,
    );
    run.serve
        .as_ref()
        .unwrap()
        .wait_status(5.0, |s| s["status"]["plc"] == "Stop");
    // The fault archive's rows = `plcctl faults --json` (serve gives the port up first).
    drop(run.serve.take());
    let out = sim.plcctl(&["faults", "--json", "--profile", &profile]);
    assert_eq!(
        crate::code(&out),
        0,
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let log: Vec<Value> = serde_json::from_str(&crate::text(&out)).unwrap();
    for o in &o {
        let rows = o["rows"].as_array().unwrap();
        assert_eq!(rows.len(), log.len(), "{rows:?} vs {log:?}");
        for (r, f) in rows.iter().zip(&log) {
            assert_eq!(r[0], f["pos"].to_string(), "{r} vs {f}");
            assert_eq!(r[3], f["code"].to_string(), "{r} vs {f}");
            assert_eq!(r[4], f["text"], "{r} vs {f}");
            // The floor and target (the lift's values) as the CLI has them.
            for k in 0..2 {
                let v = &f["values"][k];
                let want = if v.is_null() {
                    String::new()
                } else {
                    v.to_string()
                };
                assert_eq!(r[5 + k], want, "{r} vs {f}");
            }
            if !f["wall_s"].is_null() {
                // The PLC's time of day: the same text.
                assert_eq!(
                    format!("{} {}", r[1].as_str().unwrap(), r[2].as_str().unwrap()),
                    f["time"].as_str().unwrap(),
                    "{r} vs {f}"
                );
                continue;
            }
            // Without the PLC's clock: "clock not set" and the host's estimate of the
            // same power-up's time, mapped twice from the PLC's uptime (the second may
            // round the other way).
            assert_eq!(r[1], "clock not set", "{r}");
            assert_eq!(f["time"], "clock not set", "{f}");
            let t = r[2].as_str().unwrap().strip_prefix('~').unwrap();
            let cli = f["host_time"].as_str().unwrap();
            let cli = chrono::NaiveDateTime::parse_from_str(cli, "%Y-%m-%d %H:%M:%S").unwrap();
            let page = chrono::NaiveTime::parse_from_str(t, "%H:%M:%S").unwrap();
            let d = (page - cli.time()).num_seconds().rem_euclid(86_400);
            assert!(d <= 1 || d >= 86_399, "{r} vs {f}");
        }
    }
    // A new server; the pages show the latched trip; then hil-sim ends: red, no answer.
    let serve = Serve::start(&sim, &["--profile", &profile]);
    for i in 0..run.pages.len() {
        let s = run.pages[i].session.clone();
        run.browser.navigate(&s, &format!("{}/", serve.base));
    }
    run.serve = Some(serve);
    run.until("red, connected again", 10.0, |o| {
        o["colour"] == "red" && o["title"].as_str().unwrap_or("").starts_with("PLC STOP")
    });
    drop(hold);
    let summary = sim.finish();
    assert!(summary.contains("LCD"), "{summary}");
    let o = run.until(
        "red, hil-sim gone, values greyed with their age",
        10.0,
        |o| o["colour"] == "red" && o["title"] == "no answer from the PLC" && o["stale"] == "1",
    );
    for o in &o {
        let age = o["age"].as_str().unwrap();
        let secs: f64 = age
            .strip_prefix("values ")
            .and_then(|a| a.strip_suffix(" s old"))
            .and_then(|a| a.parse().ok())
            .unwrap_or_else(|| panic!("{age:?}"));
        // Greyed from 2 s on; the text has one decimal ("2.0" for 2.04 s).
        assert!(secs >= 2.0, "{age}");
    }
    run.screens("no-answer", RED, &o);
}
