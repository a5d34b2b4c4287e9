//! service.md 15: the page in a real headless Chromium, over the DevTools protocol, at
//! 1920 x 1080 and 720 x 1520 at once (two pages of one browser), against
//! `hil-sim run lift.plc --service-pty` and `plcctl serve --profile lift.profile.toml`.
//!
//! The run (virtual time = wall time while the pty is held): the initialisation, a call
//! to floor 2 (the car button held 2 s) with its door cycle and the in-car bell held 3 s
//! in it, `*7` (remote service on), a call to floor 1 and a supply drop to 18 V on the way
//! (lift scenario L7's UV trip; the supply is back 0.8 s later). Then the page stops the
//! PLC, acknowledges the trip and starts RUN again, `serve` is restarted and hil-sim
//! ended. Screenshots go to `target/serve-screens/`. Without a Chromium the test is
//! skipped with a message, unless `CI` is set.
//!
//! Nothing here races the scenario's clock: each page records every state it renders
//! ([`RECORDER`], a mutation observer injected before the page's own script), and the
//! test checks what the pages showed from those records, however late it reads them.
//! Screenshots are taken in states that last until the test moves on (red after the
//! trip, orange after the page's RUN with remote service on, red without hil-sim) or for
//! many seconds (green from the end of the initialisation until `*7`), the banner read
//! before and after each. Every wait is for a condition, bounded only to fail.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use serde_json::Value;

use super::cdp::{find_chromium, pixel, Browser};
use super::Serve;
use crate::Sim;

/// Events in simulated seconds (the initialisation ends at about 6.1 s; floor 2's door
/// opens at about 12.8 s and is closed again at about 19.8 s; the trip at about 27.2 s,
/// with the car at about 96 mm, between floors 1 and 2). The test ends the run, long
/// before `duration_s`.
const SCENARIO: &str = "\
duration_s = 600.0
[lift]
[[event]]
at_s = 7.0
call = 2
hold_s = 2.0
[[event]]
at_s = 14.0
press = \"D14\"
hold_s = 3.0
[[event]]
at_s = 22.0
keys = \"*7\"
[[event]]
at_s = 24.0
call = 1
[[event]]
at_s = 27.0
dc_link_v = 18.0
[[event]]
at_s = 28.0
dc_link_v = 30.0
";

/// The banner colours of `app.css`.
const GREEN: [u8; 3] = [0x1e, 0x8e, 0x3e];
const ORANGE: [u8; 3] = [0xe3, 0x74, 0x00];
const RED: [u8; 3] = [0xc5, 0x22, 0x1f];

/// Injected into every document: records each distinct state the page renders (banner,
/// actions, mimic, car panel, the `lcd0` it was given) in `window.__seen`, which the test
/// drains.
const RECORDER: &str = r##"(() => {
  const seen = [];
  window.__seen = seen;
  let last = "";
  const snap = () => {
    const $ = (i) => document.getElementById(i);
    const b = $("banner"), m = $("mimic");
    if (!b || !m || !$("act-clear-faults") || !$("action-note")) return;
    const mon = window.monitor;
    const lcd0 = mon && mon.values && mon.values.lcd0 !== undefined ? mon.values.lcd0 : null;
    const disp = m.querySelector("[data-panel=display] .panel-floor");
    const s = {
      colour: b.dataset.colour, title: $("banner-title").textContent,
      detail: $("banner-detail").textContent,
      stop: $("act-stop").disabled, run: $("act-run").disabled, ack: $("act-ack").disabled,
      clear: $("act-clear-faults").disabled, note: $("action-note").textContent,
      floor: m.dataset.floor === undefined ? null : m.dataset.floor,
      door: m.dataset.door === undefined ? null : m.dataset.door,
      lcd0, display: disp ? disp.textContent : null,
      counters: $("counters") ? $("counters").textContent : null,
      lit: [...m.querySelectorAll("[data-panel][data-on='1']")].map((e) => e.dataset.panel),
    };
    const k = JSON.stringify(s);
    if (k !== last) { last = k; seen.push(s); }
  };
  new MutationObserver(snap).observe(document,
    { subtree: true, childList: true, attributes: true, characterData: true });
})()"##;

/// The banner's colour and a point inside it, for a screenshot.
const BANNER: &str = r##"(() => {
  const b = document.getElementById("banner");
  if (!b) return null;
  const r = b.getBoundingClientRect();
  return { colour: b.dataset.colour, bx: Math.round(r.left + 4), by: Math.round(r.top + r.height / 2) };
})()"##;

/// What the test reads of a page now (the page keeps its state in `data-*` attributes).
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
    car_y: (() => { const c = m.querySelector("[data-car] rect");
                    return c ? Number(c.getAttribute("y")) : null; })(),
    panel: [...m.querySelectorAll("[data-car-panel] [data-panel]")].map((e) => e.dataset.panel),
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
    seen: window.__seen ? window.__seen.splice(0) : [],
  };
})()"##;

struct Page {
    name: &'static str,
    session: String,
    /// Every state the page rendered ([`RECORDER`]), oldest first.
    seen: Vec<Value>,
    max_span_s: f64,
}

struct Run {
    browser: Browser,
    pages: Vec<Page>,
    serve: Option<Serve>,
    screens: PathBuf,
    /// When the scenario's clock started (for the log of each step's wall time).
    t0: Instant,
}

impl Run {
    /// Page `i` now (`null` while it loads); what it rendered since is added to its
    /// record.
    fn observe(&mut self, i: usize) -> Value {
        let s = self.pages[i].session.clone();
        let mut o = self.browser.eval(&s, OBSERVE);
        let p = &mut self.pages[i];
        if let Some(seen) = o.get_mut("seen").map(Value::take) {
            p.seen.extend(seen.as_array().cloned().unwrap_or_default());
        }
        p.max_span_s = p.max_span_s.max(o["span"].as_f64().unwrap_or(0.0));
        o
    }

    fn observe_all(&mut self) -> Vec<Value> {
        (0..self.pages.len()).map(|i| self.observe(i)).collect()
    }

    /// Polls the pages every 100 ms until `done` holds for every page now (at most
    /// `secs`, a bound for a failure, never reached when all is well).
    fn until(&mut self, what: &str, secs: f64, done: impl Fn(&Value) -> bool) -> Vec<Value> {
        let end = Instant::now() + Duration::from_secs_f64(secs);
        loop {
            let obs = self.observe_all();
            if obs.iter().all(|o| !o.is_null() && done(o)) {
                eprintln!("{:6.1} s: {what}", self.t0.elapsed().as_secs_f64());
                return obs;
            }
            assert!(
                Instant::now() < end,
                "{what}: never so in {secs} s: {obs:#?}"
            );
            std::thread::sleep(Duration::from_millis(100));
        }
    }

    /// Polls the pages until each has rendered a state for which `shown` holds (at most
    /// `secs`); the first such state of each page.
    fn until_shown(&mut self, what: &str, secs: f64, shown: impl Fn(&Value) -> bool) -> Vec<Value> {
        let end = Instant::now() + Duration::from_secs_f64(secs);
        loop {
            self.observe_all();
            let found: Vec<Option<&Value>> = self
                .pages
                .iter()
                .map(|p| p.seen.iter().find(|s| shown(s)))
                .collect();
            if found.iter().all(Option::is_some) {
                eprintln!("{:6.1} s: {what}", self.t0.elapsed().as_secs_f64());
                return found.into_iter().flatten().cloned().collect();
            }
            assert!(
                Instant::now() < end,
                "{what}: never shown in {secs} s; the pages showed {:#?}",
                self.pages.iter().map(|p| p.seen.last()).collect::<Vec<_>>()
            );
            std::thread::sleep(Duration::from_millis(100));
        }
    }

    /// Screenshots of every page as `<page>-<moment>.png`, taken while the banner is
    /// `css` before and after; the banner's pixel checked against `colour`.
    fn screens(&mut self, moment: &str, colour: [u8; 3], css: &str) {
        for i in 0..self.pages.len() {
            let s = self.pages[i].session.clone();
            let before = self.browser.eval(&s, BANNER);
            assert_eq!(before["colour"], css, "{moment}: {before:#}");
            let png = self.browser.screenshot(&s);
            let after = self.browser.eval(&s, BANNER);
            assert_eq!(
                after["colour"], css,
                "{moment}: moved on during the screenshot"
            );
            let file = self
                .screens
                .join(format!("{}-{moment}.png", self.pages[i].name));
            std::fs::write(&file, &png).unwrap();
            let (x, y) = (
                before["bx"].as_u64().unwrap(),
                before["by"].as_u64().unwrap(),
            );
            let px = pixel(&png, x as u32, y as u32);
            let near = px.iter().zip(colour).all(|(a, b)| a.abs_diff(b) <= 6);
            assert!(
                near,
                "{}: banner pixel ({x}, {y}) is {px:?}, expected {colour:?}",
                file.display()
            );
        }
        eprintln!(
            "{:6.1} s: screenshots {moment}",
            self.t0.elapsed().as_secs_f64()
        );
    }

    /// Clicks the action button `id` on the wide page, checks that its dialog asks and
    /// says `asks` (each part), confirms, and waits for the page's `<action>: done`.
    fn act(&mut self, id: &str, asks: &[&str]) {
        let s = self.pages[0].session.clone();
        let asked = self.browser.eval(
            &s,
            &format!(
                r#"document.getElementById("{id}").click();
                   document.getElementById("confirm").hidden === false
                     ? document.getElementById("confirm-text").textContent : null"#
            ),
        );
        let asked = asked
            .as_str()
            .unwrap_or_else(|| panic!("{id}: no dialog: {asked}"));
        for part in asks {
            assert!(asked.contains(part), "{id}: {asked}");
        }
        self.browser.eval(
            &s,
            r#"document.getElementById("confirm-yes").click(); true"#,
        );
        let action = id.trim_start_matches("act-");
        let end = Instant::now() + Duration::from_secs(60);
        loop {
            let note = self
                .browser
                .eval(&s, r#"document.getElementById("action-note").textContent"#);
            if note
                .as_str()
                .is_some_and(|n| n.starts_with(&format!("{action}: done")))
            {
                break;
            }
            assert!(Instant::now() < end, "{id}: {note}");
            std::thread::sleep(Duration::from_millis(100));
        }
        eprintln!("{:6.1} s: {action} done", self.t0.elapsed().as_secs_f64());
    }
}

/// The values of `key` in `seen` that are floors (1 and up), repeats dropped.
fn floors(seen: &[Value], key: &str) -> Vec<i64> {
    let mut out: Vec<i64> = Vec::new();
    for s in seen {
        let v = match &s[key] {
            Value::String(t) => t.parse().ok(),
            v => v.as_i64(),
        };
        if let Some(f) = v.filter(|f| *f >= 1) {
            if out.last() != Some(&f) {
                out.push(f);
            }
        }
    }
    out
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
    for s in &sessions {
        browser.on_new_document(s, RECORDER);
    }
    let mut sim = Sim::start(&[
        lift.to_str().unwrap(),
        "--scenario",
        scen.to_str().unwrap(),
        "--service-linger",
        "0",
    ]);
    let serve = Serve::start(&sim, &["--profile", &profile]);
    // Virtual time follows the wall clock while the pty is held, also between servers.
    let hold = sim.hold();
    let t0 = Instant::now();
    let mut pages = Vec::new();
    for (name, session) in ["wide", "narrow"].into_iter().zip(sessions) {
        browser.navigate(&session, &format!("{}/", serve.base));
        pages.push(Page {
            name,
            session,
            seen: Vec::new(),
            max_span_s: 0.0,
        });
    }
    let base = serve.base.clone();
    let mut run = Run {
        browser,
        pages,
        serve: Some(serve),
        screens: screens_dir(),
        t0,
    };

    // RUN after the initialisation: green, and it stays green (idle at floor 1, the
    // travel to floor 2, its door cycle) until `*7`. The lift's first scan (state 0) is
    // green too, before its initialisation run (orange): wait for the idle state.
    run.until("green, idle", 60.0, |o| {
        o["colour"] == "green" && o["detail"] == "idle at a floor"
    });
    run.screens("idle", GREEN, "green");
    // Idle at a floor: the guarded actions are disabled without remote service, with
    // the reason; Stop is not.
    let shown = run.until_shown("green, idle at a floor", 60.0, |o| {
        o["colour"] == "green" && o["detail"] == "idle at a floor"
    });
    for o in &shown {
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
    // serve reads them with every status and the stream brings them when they change.
    // (textContent runs the cells together: "RUN starts1minutes in RUN0...")
    let o = run.until("the counters show the RUN start", 60.0, |o| {
        o["counters"]
            .as_str()
            .is_some_and(|c| c.contains("RUN starts1"))
    });
    for o in &o {
        let c = o["counters"].as_str().unwrap();
        assert!(c.contains("arrivals floor 1 (Q60)"), "{c}");
        // The car panel (004 §2.7.1): the floor display, the floor buttons and what
        // lift.plc has of the rest (the alarm push and its bell, the in-car STOP); no
        // door-open button and no priority key (lift.plc has neither).
        assert_eq!(
            o["panel"],
            serde_json::json!([
                "display",
                "floor-4",
                "floor-3",
                "floor-2",
                "floor-1",
                "alarm",
                "alarm_bell",
                "stop"
            ]),
            "{o}"
        );
        // Lamp names wrap, none is cut off ("O05 fault / overload lamp").
        assert_eq!(o["lamps_cut"], serde_json::json!([]), "{o}");
        let lamps = o["lamps"].as_array().unwrap();
        assert!(
            lamps.iter().any(|l| l == "O05 fault / overload lamp"),
            "{lamps:?}"
        );
    }
    let lit = |o: &Value, what: &str| o["lit"].as_array().unwrap().iter().any(|l| l == what);
    // The car button of floor 2 lit while held.
    run.until_shown("the car button of floor 2 lit", 60.0, |o| lit(o, "floor-2"));
    // The door shown open during the door cycle at floor 2, and the arrival counted:
    // the counters come with every status, so the arrival (counted in the scan that
    // opens the door) is on the page before the door is shown opening.
    let door_open = |o: &Value| o["door"] == "open" && o["floor"] == "2";
    run.until_shown("door open at floor 2", 60.0, door_open);
    for p in &run.pages {
        for s in p.seen.iter().filter(|s| door_open(s)) {
            let c = s["counters"].as_str().unwrap_or("");
            assert!(c.contains("arrivals floor 2 (Q61)1"), "{}: {c}", p.name);
        }
    }
    // The in-car bell: the alarm push and its bell lit.
    run.until_shown("the alarm and its bell lit", 60.0, |o| {
        lit(o, "alarm") && lit(o, "alarm_bell")
    });
    // `*7`: remote service on, orange; the guarded actions enabled.
    let shown = run.until_shown("orange, remote service", 60.0, |o| {
        o["colour"] == "orange"
            && o["detail"]
                .as_str()
                .unwrap()
                .contains("remote service enabled")
    });
    for o in &shown {
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
    // The call to floor 1 and the UV trip on the way: red with the drive's fault
    // (latched).
    run.until("red, drive trip", 60.0, |o| {
        o["colour"] == "red" && o["detail"].as_str().unwrap_or("").contains("drive fault 4")
    });
    run.screens("trip", RED, "red");
    // The trip left the car mid-shaft, off both vanes (D10, D11): the mimic draws it
    // between two floors, not level at the floor it passed last.
    let st = run.serve.as_ref().unwrap().get("/api/status");
    let d = st["status"]["d"].as_u64().unwrap_or_else(|| panic!("{st}"));
    assert_ne!(d >> 10 & 3, 3, "the car stopped level at a floor: {st}");
    run.until("the car drawn between floors after the trip", 60.0, |o| {
        // app.js: the car's rect is at y = 20 + (4 - pos) * 90 + 6.
        let pos = o["car_y"]
            .as_f64()
            .map(|y| 4.0 - (y - 26.0) / 90.0)
            .unwrap_or(0.0);
        pos > 1.0 && pos < 4.0 && pos.fract() != 0.0
    });
    // The trip in the fault archive (the stream brings the log when its newest entry
    // changes) and in the counters (with the same status).
    let o = run.until(
        "the trip in the fault archive and the counters",
        60.0,
        |o| {
            o["rows"]
                .as_array()
                .is_some_and(|r| !r.is_empty() && r[0][3] == "4")
                && o["counters"]
                    .as_str()
                    .is_some_and(|c| c.contains("trips code 41"))
        },
    );
    // What the pages recorded up to here: the car has stood still for seconds, so the
    // floors drawn (from the samples) and the `lcd0` values (from the status) are
    // complete; later records may end with one ahead of the other by a poll.
    let upto: Vec<usize> = run.pages.iter().map(|p| p.seen.len()).collect();
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
    // The LCD's four rows as the PLC shows them (GetScreen), as the server has them
    // (the trip's screen stays).
    let end = Instant::now() + Duration::from_secs(60);
    loop {
        let st = run.serve.as_ref().unwrap().get("/api/status");
        let rows: Vec<&str> = st["lcd_text"]
            .as_array()
            .unwrap_or_else(|| panic!("{st}"))
            .iter()
            .map(|r| r.as_str().unwrap())
            .collect();
        assert_eq!(rows.len(), 4, "{st}");
        let want = rows.join("\n");
        let obs = run.observe_all();
        if !want.trim().is_empty() && obs.iter().all(|o| o["lcd"] == want.as_str()) {
            break;
        }
        assert!(Instant::now() < end, "LCD {want:?}, pages {obs:#?}");
        std::thread::sleep(Duration::from_millis(100));
    }
    eprintln!(
        "{:6.1} s: the LCD's four rows",
        run.t0.elapsed().as_secs_f64()
    );
    // Stop asks first, saying what it means for the lift; confirmed, it puts the PLC in
    // STOP. Then Ack and Run (remote service is on): the trip acknowledged, RUN again.
    run.act("act-stop", &["between floors", "keypad"]);
    run.serve
        .as_ref()
        .unwrap()
        .wait_status(60.0, |s| s["status"]["plc"] == "Stop");
    run.act("act-ack", &["Acknowledge"]);
    run.serve
        .as_ref()
        .unwrap()
        .wait_status(60.0, |s| s["status"]["drive"]["fault"] == 0);
    run.act("act-run", &["RUN"]);
    // Orange (remote service on) until the test moves on; the counters follow the
    // second RUN start at once.
    let o = run.until("orange after RUN, RUN starts 2", 60.0, |o| {
        o["colour"] == "orange"
            && o["counters"]
                .as_str()
                .is_some_and(|c| c.contains("RUN starts2"))
    });
    run.screens("restarted", ORANGE, "orange");
    for (i, (p, o)) in run.pages.iter().zip(&o).enumerate() {
        assert!(
            p.seen.iter().any(|s| s["door"] == "closed"),
            "{}: the door never shown closed",
            p.name
        );
        // The mimic followed the floor: up to the trip, the floors it drew are the
        // floors the PLC reported (`lcd0`), in order: floor 1, up to 2, the trip before
        // floor 1. The panel's display always shows the mimic's floor.
        let before_trip = &p.seen[..upto[i]];
        let drawn = floors(before_trip, "floor");
        assert_eq!(drawn, floors(before_trip, "lcd0"), "{}", p.name);
        assert_eq!(drawn, [1, 2], "{}", p.name);
        for s in &p.seen {
            if s["floor"]
                .as_str()
                .is_some_and(|f| !f.is_empty() && f != "0")
            {
                assert_eq!(s["display"], s["floor"], "{}: {s}", p.name);
            }
        }
        assert!(
            p.max_span_s >= 10.0,
            "{}: trend spans {} s",
            p.name,
            p.max_span_s
        );
        let errors = run.browser.errors(&p.session);
        assert!(errors.is_empty(), "{}: console errors {errors:#?}", p.name);
        for url in run.browser.requests(&p.session) {
            assert!(
                url.starts_with(&format!("{base}/")),
                "{}: request outside the server: {url}",
                p.name
            );
        }
        // The fault archive's rows as shown now, for the comparison below.
        assert!(!o["rows"].as_array().unwrap().is_empty(), "{o}");
    }
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
    // A new server; the pages connect to it; then hil-sim ends: red, no answer.
    let serve = Serve::start(&sim, &["--profile", &profile]);
    for i in 0..run.pages.len() {
        let s = run.pages[i].session.clone();
        run.browser.navigate(&s, &format!("{}/", serve.base));
    }
    run.serve = Some(serve);
    run.until("connected again, RUN", 60.0, |o| {
        o["title"].as_str().unwrap_or("").starts_with("PLC RUN")
    });
    drop(hold);
    sim.child.kill().unwrap();
    sim.child.wait().unwrap();
    let o = run.until(
        "red, hil-sim gone, values greyed with their age",
        60.0,
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
    run.screens("no-answer", RED, "red");
}
