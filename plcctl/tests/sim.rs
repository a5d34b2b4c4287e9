//! `plcctl` against `hil-sim run … --service-pty` through a real pty (service.md 10):
//! `pull` = `hil-sim disasm` byte for byte, `faults --json` = the run summary's faults,
//! `trend --csv` = hil-sim's CSV (names and values), refusals and exit codes.
//!
//! hil-sim's binary is taken from this test's own target directory (`cargo test
//! --workspace` builds it; alone: `cargo build -p hil-sim --release` first).

use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};

const PLCCTL: &str = env!("CARGO_BIN_EXE_plcctl");

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn motor() -> PathBuf {
    root().join("shared-protocol/programs/motor.plc")
}

/// hil-sim next to this test's binary (`target/<profile>/`).
fn hil_sim() -> PathBuf {
    let exe = std::env::current_exe().unwrap();
    let dir = exe.parent().and_then(Path::parent).unwrap();
    let p = dir.join(format!("hil-sim{}", std::env::consts::EXE_SUFFIX));
    assert!(
        p.exists(),
        "{} missing: build it first (cargo build -p hil-sim --release)",
        p.display()
    );
    p
}

fn temp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("plcctl-test-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d.join(name)
}

/// What a child announces on the first line of `pipe` after `prefix` (hil-sim its pty,
/// `serve` its address); the rest of the pipe is drained so that it never fills.
fn announced(pipe: impl Read + Send + 'static, prefix: &str) -> String {
    let mut pipe = BufReader::new(pipe);
    let mut first = String::new();
    pipe.read_line(&mut first).unwrap();
    let what = first
        .trim_end()
        .strip_prefix(prefix)
        .unwrap_or_else(|| panic!("first line {first:?}, not {prefix:?}"))
        .to_string();
    std::thread::spawn(move || {
        let mut sink = String::new();
        let _ = pipe.read_to_string(&mut sink);
    });
    what
}

/// A `hil-sim run --service-pty` and its pty path.
struct Sim {
    child: Child,
    path: String,
}

impl Sim {
    /// Without `--service-linger` in `args`, no linger (the run follows the wall clock
    /// to the end of the linger, with or without a client).
    fn start(args: &[&str]) -> Sim {
        let linger: &[&str] = if args.contains(&"--service-linger") {
            &[]
        } else {
            &["--service-linger", "0"]
        };
        let mut child = Command::new(hil_sim())
            .arg("run")
            .args(args)
            .args(linger)
            .arg("--service-pty")
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let path = announced(child.stderr.take().unwrap(), "service: ");
        Sim { child, path }
    }

    /// `motor.plc` with the scenario `toml` (written to the temp file `name`), lingering
    /// `linger_s` after its duration.
    fn with_scenario(name: &str, toml: &str, linger_s: &str) -> Sim {
        let scen = temp(name);
        std::fs::write(&scen, toml).unwrap();
        Sim::start(&[
            motor().to_str().unwrap(),
            "--scenario",
            scen.to_str().unwrap(),
            "--service-linger",
            linger_s,
        ])
    }

    /// `motor.plc` whose scenario types `*` `7` (remote service on) at 0.05 s, held open
    /// (see [`Sim::hold`]) until remote service is seen on.
    fn with_remote_service(name: &str, duration_s: f64) -> (Sim, std::fs::File) {
        let toml = format!("duration_s = {duration_s:?}\n[[event]]\nat_s = 0.05\nkeys = \"*7\"\n");
        let sim = Sim::with_scenario(name, &toml, "0");
        let hold = sim.hold();
        sim.wait_status("remote service on", |s| s["status"]["remote"] == true);
        (sim, hold)
    }

    /// Holds the pty open (a client for the whole of a step of a test).
    fn hold(&self) -> std::fs::File {
        std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .open(&self.path)
            .unwrap()
    }

    /// `plcctl status --json`, which must succeed.
    fn status(&self) -> serde_json::Value {
        let o = self.plcctl(&["status", "--json"]);
        assert_eq!(code(&o), 0);
        serde_json::from_str(&text(&o)).unwrap()
    }

    /// Polls `status --json` every 20 ms until `holds` (about 1 s at most, else fails
    /// naming `what`).
    fn wait_status(&self, what: &str, holds: impl Fn(&serde_json::Value) -> bool) {
        for _ in 0..50 {
            if holds(&self.status()) {
                return;
            }
            std::thread::sleep(std::time::Duration::from_millis(20));
        }
        panic!("{what} never happened");
    }

    fn plcctl(&self, args: &[&str]) -> Output {
        Command::new(PLCCTL)
            .env("XDG_CACHE_HOME", temp("cache"))
            .args(["--port", &self.path])
            .args(args)
            .output()
            .unwrap()
    }

    /// Waits for the end; the summary.
    fn finish(mut self) -> String {
        let mut out = String::new();
        self.child
            .stdout
            .take()
            .unwrap()
            .read_to_string(&mut out)
            .unwrap();
        assert!(self.child.wait().unwrap().success(), "{out}");
        out
    }
}

/// A test that fails leaves no hil-sim behind (a browser run's lasts minutes).
impl Drop for Sim {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn text(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn code(o: &Output) -> i32 {
    o.status.code().unwrap_or(-1)
}

#[test]
fn pull_equals_disasm_byte_for_byte_and_guarded_requests_need_remote_service() {
    let sim = Sim::start(&[motor().to_str().unwrap(), "--duration", "1"]);
    let hold = sim.hold();
    let disasm = Command::new(hil_sim())
        .arg("disasm")
        .arg(motor())
        .output()
        .unwrap();
    assert!(disasm.status.success());
    for slot in ["1", "0"] {
        let out = temp(&format!("pull{slot}.plc"));
        let o = sim.plcctl(&["pull", slot, "-o", out.to_str().unwrap()]);
        assert_eq!(code(&o), 0, "{}", String::from_utf8_lossy(&o.stderr));
        assert_eq!(std::fs::read(&out).unwrap(), disasm.stdout, "pull {slot}");
    }
    // Remote service is off: run, ack and clear-faults exit 5 and say why; stop works.
    for cmd in ["run", "ack", "clear-faults"] {
        let o = sim.plcctl(&[cmd]);
        assert_eq!(code(&o), 5, "{cmd}");
        assert!(
            String::from_utf8_lossy(&o.stderr).contains("remote service is off"),
            "{cmd}"
        );
    }
    assert_eq!(code(&sim.plcctl(&["stop"])), 0);
    let o = sim.plcctl(&["status", "--json"]);
    assert_eq!(code(&o), 0);
    let v: serde_json::Value = serde_json::from_str(&text(&o)).unwrap();
    assert_eq!(v["status"]["plc"], "Stop", "{v}");
    assert_eq!(v["status"]["remote"], false);
    assert_eq!(v["status"]["slot"], 1);
    // The host recorded when this power-up (#1) began, under the UID (seed 1, `HSIM`).
    let cache = temp("cache").join("plcctl/01000000000000004853494d.txt");
    let rec = std::fs::read_to_string(&cache).unwrap();
    let start_ms: i64 = rec.strip_prefix("1 ").unwrap().trim().parse().unwrap();
    let now_ms = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_millis() as i64;
    assert!((now_ms - start_ms).abs() < 60_000, "{rec}");
    drop(hold);
    assert!(sim.finish().contains("final state: PLC STOP"));
}

#[test]
fn faults_json_equals_the_run_summary() {
    // motor.plc sets U< = 25 V: the supply drops to 20 V at 1 s and the drive trips UV.
    let sim = Sim::with_scenario(
        "uv.toml",
        "duration_s = 1.6\n[plant]\nload_torque_nm = 0.03\n\
         [[event]]\nat_s = 0.0\nset = { A00 = 980, A01 = 500 }\n\
         [[event]]\nat_s = 0.2\npress = \"D00\"\n\
         [[event]]\nat_s = 1.0\ndc_link_v = 20.0\n",
        "20",
    );
    let hold = sim.hold();
    // Real time while held: wait until the PLC's uptime is past the run's 1.6 s (the
    // run then lingers with the inputs held), so the log holds every trip of the summary.
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(30);
    loop {
        let o = sim.plcctl(&["status", "--json"]);
        assert_eq!(code(&o), 0);
        let v: serde_json::Value = serde_json::from_str(&text(&o)).unwrap();
        if v["status"]["uptime_ms"].as_u64().unwrap() > 1_700 {
            break;
        }
        assert!(
            std::time::Instant::now() < deadline,
            "the run never reached 1.7 s"
        );
        std::thread::sleep(std::time::Duration::from_millis(100));
    }
    let o = sim.plcctl(&["faults", "--json"]);
    assert_eq!(code(&o), 0, "{}", String::from_utf8_lossy(&o.stderr));
    let rows: Vec<serde_json::Value> = serde_json::from_str(&text(&o)).unwrap();
    let csv = sim.plcctl(&["faults", "--csv"]);
    assert!(text(&csv)
        .starts_with("pos,time,wall_s,host_time,power_up,uptime_s,code,name,text,lcd0,lcd1\n"));
    // `watch` shows the LCD and the newest log entries.
    let w = sim.plcctl(&["watch", "--duration", "0.3"]);
    assert_eq!(code(&w), 0);
    let view = text(&w);
    assert!(view.contains("+--------------------+"), "{view}");
    assert!(view.contains(" UV "), "{view}");
    drop(hold);
    let summary = sim.finish();
    // `  1.234 s  4 UV` lines after `faults:`.
    let trips: Vec<(f64, u64)> = summary
        .lines()
        .skip_while(|l| *l != "faults:")
        .skip(1)
        .take_while(|l| l.starts_with("  "))
        .map(|l| {
            let f: Vec<&str> = l.split_whitespace().collect();
            (f[0].parse().unwrap(), f[2].parse().unwrap())
        })
        .collect();
    assert!(!trips.is_empty(), "{summary}");
    // Newest first in the log, oldest first in the summary; events are not trips.
    let logged: Vec<&serde_json::Value> = rows
        .iter()
        .rev()
        .filter(|r| r["code"].as_u64().unwrap() < 240)
        .collect();
    assert_eq!(logged.len(), trips.len(), "{rows:?} vs {summary}");
    for (r, (t, c)) in logged.iter().zip(&trips) {
        assert_eq!(r["code"].as_u64().unwrap(), *c);
        let up = r["uptime_s"].as_f64().unwrap();
        assert!((up - t).abs() <= 1.0, "log {up} s, summary {t} s");
        assert_eq!(r["name"], "UV");
        for k in ["pos", "time", "power_up", "text"] {
            assert!(r.get(k).is_some(), "{k}");
        }
    }
}

fn csv_rows(text: &str) -> (Vec<String>, Vec<Vec<String>>) {
    // hil-sim's CSV starts with `# board: ...` comment lines.
    let mut lines = text.lines().filter(|l| !l.starts_with('#'));
    let header = lines
        .next()
        .unwrap()
        .split(',')
        .map(str::to_string)
        .collect();
    let rows = lines
        .map(|l| l.split(',').map(str::to_string).collect())
        .collect();
    (header, rows)
}

#[test]
fn trend_csv_has_hil_sims_names_and_agrees_with_its_record() {
    let sim_csv = temp("sim.csv");
    let trend_csv = temp("trend.csv");
    let trend_svg = temp("trend.svg");
    let sim = Sim::start(&[
        motor().to_str().unwrap(),
        "--scenario",
        root()
            .join("hil-sim/scenarios/motor.toml")
            .to_str()
            .unwrap(),
        "--duration",
        "2",
        "--csv",
        sim_csv.to_str().unwrap(),
    ]);
    let o = sim.plcctl(&[
        "trend",
        "--csv",
        trend_csv.to_str().unwrap(),
        "--duration",
        "1.5",
        "--q",
        "Q00,Q01,Q02",
        "--plot",
        trend_svg.to_str().unwrap(),
    ]);
    assert_eq!(code(&o), 0, "{}", String::from_utf8_lossy(&o.stderr));
    sim.finish();
    // hil-sim's plot, with the panels of the columns the PLC has (trend-plot's tests
    // check the selection; this checks plcctl hands its samples over).
    let svg = std::fs::read_to_string(&trend_svg).unwrap();
    for caption in [
        "f_cmd_hz * dir (blue)",
        "imx_a (orange)",
        "u_dc_v (brown)",
        "fault (red)",
    ] {
        assert!(svg.contains(caption), "plot lacks {caption}");
    }
    assert!(!svg.contains("speed_rpm"), "no simulation-only panel");
    let (sh, srows) = csv_rows(&std::fs::read_to_string(&sim_csv).unwrap());
    let (th, trows) = csv_rows(&std::fs::read_to_string(&trend_csv).unwrap());
    // Every column is hil-sim's, except the PLC-only ones of service.md 8 (16 D, 8 O,
    // `imx_a`; this hil-sim records 8 D and 6 O).
    let extra = |c: &str| {
        c == "imx_a"
            || (c.starts_with('D') && c[1..].parse::<u8>().is_ok_and(|n| n < 16))
            || (c.starts_with('O') && c[1..].parse::<u8>().is_ok_and(|n| n < 8))
    };
    for c in &th {
        assert!(sh.contains(c) || extra(c), "column {c} is not hil-sim's");
    }
    assert!(trows.len() > 100, "{} samples", trows.len());
    let col = |h: &[String], name: &str| h.iter().position(|c| c == name).unwrap();
    let by_t: std::collections::HashMap<&str, &Vec<String>> =
        srows.iter().map(|r| (r[0].as_str(), r)).collect();
    let index: std::collections::HashMap<&str, usize> = srows
        .iter()
        .enumerate()
        .map(|(i, r)| (r[0].as_str(), i))
        .collect();
    let mut compared = 0;
    for tr in &trows {
        let Some(sr) = by_t.get(tr[0].as_str()) else {
            continue;
        };
        compared += 1;
        let exact = [
            "O00", "O01", "O02", "O03", "O04", "O05", "Q00", "Q01", "Q02",
        ]
        .iter()
        .chain(&["lcd0", "lcd1", "lcd2", "lcd3"]);
        for name in exact {
            assert_eq!(
                tr[col(&th, name)],
                sr[col(&sh, name)],
                "{name} at t = {}",
                tr[0]
            );
        }
        // Debounced inputs: hil-sim's value at some instant of the preceding 6 ms; the
        // drive's frequency within 20 ms (status period and transport).
        let i = index[tr[0].as_str()];
        for (names, window) in [(vec!["D00", "D01"], 6), (vec!["f_cmd_hz", "fault"], 20)] {
            for name in names {
                let v = &tr[col(&th, name)];
                if v.is_empty() {
                    continue;
                }
                let seen = (i.saturating_sub(window)..=i).any(|k| &srows[k][col(&sh, name)] == v);
                assert!(
                    seen,
                    "{name} = {v} at t = {} not in hil-sim's last {window} ms",
                    tr[0]
                );
            }
        }
    }
    assert!(compared > 100, "{compared} rows at common instants");
}

/// Ctrl-C ends `trend` as its duration would: exit 0, every row complete, the plot drawn.
#[test]
fn ctrl_c_ends_a_trend_with_the_csv_complete_and_the_plot_drawn() {
    let csv = temp("ctrlc.csv");
    let png = temp("ctrlc.png");
    let sim = Sim::start(&[motor().to_str().unwrap(), "--duration", "6"]);
    let trend = Command::new(PLCCTL)
        .args(["--port", &sim.path, "trend", "--csv"])
        .arg(&csv)
        .arg("--plot")
        .arg(&png)
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Until a second of samples is recorded (the CSV is written under a temporary
    // name next to it until the end).
    let t0 = std::time::Instant::now();
    let partial = csv.with_file_name(format!(".ctrlc.csv.{}.partial", trend.id()));
    while std::fs::read_to_string(&partial).map_or(0, |t| t.lines().count()) < 100 {
        assert!(t0.elapsed().as_secs() < 60, "no samples (hang guard)");
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    let kill = Command::new("kill")
        .args(["-INT", &trend.id().to_string()])
        .status()
        .unwrap();
    assert!(kill.success());
    let out = trend.wait_with_output().unwrap();
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(&csv).unwrap();
    assert!(text.ends_with('\n'));
    let (header, rows) = csv_rows(&text);
    assert!(rows.len() >= 99);
    assert!(rows.iter().all(|r| r.len() == header.len()), "a cut row");
    assert_eq!(&std::fs::read(&png).unwrap()[1..4], b"PNG");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("plot written to"), "{stderr}");
    sim.finish();
}

#[test]
fn exit_codes_no_device_timeout_and_version_mismatch() {
    let o = Command::new(PLCCTL)
        .args(["--port", "/nonexistent/tty", "status"])
        .output()
        .unwrap();
    assert_eq!(code(&o), 2);
    // A pty nobody serves: 3 attempts, then exit 3.
    let pair = nix::pty::openpty(None, None).unwrap();
    let path = nix::unistd::ttyname(&pair.slave).unwrap();
    let o = Command::new(PLCCTL)
        .arg("--port")
        .arg(&path)
        .arg("status")
        .output()
        .unwrap();
    assert_eq!(code(&o), 3, "{}", String::from_utf8_lossy(&o.stderr));
    drop(pair);
    let sim = Sim::start(&[
        motor().to_str().unwrap(),
        "--duration",
        "0.5",
        "--service-version",
        "99",
        "--service-linger",
        "0",
    ]);
    let o = sim.plcctl(&["status"]);
    assert_eq!(code(&o), 4);
    let err = String::from_utf8_lossy(&o.stderr);
    let ours = shared_protocol::service::SERVICE_VERSION.to_string();
    assert!(err.contains("99") && err.contains(&ours), "{err}");
    sim.finish();
}

#[test]
fn run_ack_and_clear_faults_work_with_remote_service_on() {
    let (sim, hold) = Sim::with_remote_service("remote.toml", 3.0);
    assert_eq!(code(&sim.plcctl(&["stop"])), 0);
    assert_eq!(sim.status()["status"]["plc"], "Stop");
    // In STOP the log may be cleared; in RUN it may not (exit 5, in RUN).
    assert_eq!(code(&sim.plcctl(&["clear-faults"])), 0);
    let o = sim.plcctl(&["faults", "--json"]);
    let rows: Vec<serde_json::Value> = serde_json::from_str(&text(&o)).unwrap();
    assert_eq!(rows.len(), 1, "{rows:?}");
    assert_eq!(rows[0]["name"], "LOGCLR");
    assert_eq!(code(&sim.plcctl(&["run", "--slot", "1"])), 0);
    sim.wait_status("RUN", |s| s["status"]["plc"] == "Run");
    assert_eq!(code(&sim.plcctl(&["ack"])), 0);
    let o = sim.plcctl(&["clear-faults"]);
    assert_eq!(code(&o), 5);
    assert!(String::from_utf8_lossy(&o.stderr).contains("RUN"));
    drop(hold);
    sim.finish();
}

#[test]
fn push_writes_reads_back_and_pull_round_trips() {
    let lift = root().join("shared-protocol/programs/lift.plc");
    // Without remote service: exit 5 (the diff is shown first; nothing is written).
    let sim = Sim::start(&[motor().to_str().unwrap(), "--duration", "1"]);
    let hold = sim.hold();
    let o = sim.plcctl(&["push", lift.to_str().unwrap(), "--slot", "2", "--yes"]);
    assert_eq!(code(&o), 5, "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stderr).contains("remote service is off"));
    // Said before any diff: nothing on stdout.
    assert_eq!(text(&o), "");
    drop(hold);
    sim.finish();

    // Remote service on; motor.plc runs.
    let (sim, hold) = Sim::with_remote_service("push.toml", 30.0);
    // In RUN: exit 5.
    assert_ne!(sim.status()["status"]["plc"], "Stop");
    let o = sim.plcctl(&["push", lift.to_str().unwrap(), "--slot", "2", "--yes"]);
    assert_eq!(code(&o), 5, "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stderr).contains("RUN"));
    assert_eq!(text(&o), "", "the diff before the refusal");
    assert_eq!(code(&sim.plcctl(&["stop"])), 0);

    // An assembler error: file:line:col: message, exit 1.
    let bad = temp("bad.plc");
    std::fs::write(&bad, "000 LD K00 0001\n001 XYZ Q00\n").unwrap();
    let o = sim.plcctl(&["push", bad.to_str().unwrap(), "--slot", "2", "--yes"]);
    assert_eq!(code(&o), 1);
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(err.contains(&format!("{}:2:5: ", bad.display())), "{err}");
    // Without --yes and without a terminal on stdin: refused, exit 1.
    let o = sim.plcctl(&["push", lift.to_str().unwrap(), "--slot", "2"]);
    assert_eq!(code(&o), 1);
    assert!(String::from_utf8_lossy(&o.stderr).contains("not a terminal"));

    // Into the empty slot 2: the whole program is added; pull gives `hil-sim disasm`.
    let o = sim.plcctl(&["push", lift.to_str().unwrap(), "--slot", "2", "--yes"]);
    assert_eq!(code(&o), 0, "{}", String::from_utf8_lossy(&o.stderr));
    let out = text(&o);
    let disasm = Command::new(hil_sim())
        .arg("disasm")
        .arg(&lift)
        .output()
        .unwrap();
    let lines = String::from_utf8_lossy(&disasm.stdout).lines().count();
    assert!(
        out.starts_with(&format!(
            "--- slot 2 (PLC)\n+++ {}\n@@ -0,0 +1,{lines} @@\n+",
            lift.display()
        )),
        "{out}"
    );
    assert!(out.contains("read back: identical"), "{out}");
    let pulled = temp("pull2.plc");
    let o = sim.plcctl(&["pull", "2", "-o", pulled.to_str().unwrap()]);
    assert_eq!(code(&o), 0);
    assert_eq!(std::fs::read(&pulled).unwrap(), disasm.stdout);

    // One line changed in slot 1 (the program in RAM came from it): a one-line hunk,
    // and RAM holds the new program.
    let motor_text = Command::new(hil_sim())
        .arg("disasm")
        .arg(motor())
        .output()
        .unwrap();
    let motor_text = String::from_utf8(motor_text.stdout).unwrap();
    let old_line = motor_text
        .lines()
        .find(|l| l.contains("2333"))
        .unwrap()
        .to_string();
    let changed = motor_text.replacen("2333", "2334", 1);
    let file = temp("changed.plc");
    std::fs::write(&file, &changed).unwrap();
    let o = sim.plcctl(&["push", file.to_str().unwrap(), "--slot", "1", "--yes"]);
    let out = text(&o);
    assert_eq!(code(&o), 0, "{out}{}", String::from_utf8_lossy(&o.stderr));
    assert!(out.contains(&format!("\n-{old_line}\n+")), "{out}");
    assert_eq!(
        out.matches("\n@@ ").count() + usize::from(out.starts_with("@@")),
        1,
        "{out}"
    );
    let ram = temp("pull0.plc");
    std::thread::sleep(std::time::Duration::from_millis(500));
    assert_eq!(
        code(&sim.plcctl(&["pull", "0", "-o", ram.to_str().unwrap()])),
        0
    );
    let slot1 = temp("pull1.plc");
    assert_eq!(
        code(&sim.plcctl(&["pull", "1", "-o", slot1.to_str().unwrap()])),
        0
    );
    assert_eq!(std::fs::read(&ram).unwrap(), std::fs::read(&slot1).unwrap());
    // The log has the event PGMSVC twice.
    let o = sim.plcctl(&["faults", "--json"]);
    let rows: Vec<serde_json::Value> = serde_json::from_str(&text(&o)).unwrap();
    assert_eq!(
        rows.iter().filter(|r| r["name"] == "PGMSVC").count(),
        2,
        "{rows:?}"
    );
    drop(hold);
    sim.finish();
}

/// service.md 10: after lift scenario L3 the application counters (Q60-Q63, arrivals at
/// floors 1-4 in `lift.plc`) equal the arrivals in hil-sim's CSV of the same run: the
/// level stops, each a rising edge of O00 (door open) at the plant's `at_floor`.
#[test]
fn counters_after_lift_l3_equal_the_arrivals_in_the_csv() {
    let csv = temp("l3.csv");
    let sim = Sim::start(&[
        root()
            .join("shared-protocol/programs/lift.plc")
            .to_str()
            .unwrap(),
        "--scenario",
        root()
            .join("hil-sim/scenarios/lift/l3_press_order.toml")
            .to_str()
            .unwrap(),
        "--csv",
        csv.to_str().unwrap(),
        "--service-linger",
        "30",
        "--service-speed",
        "5",
    ]);
    // Five times real time, held or not (50 s of lift in about 10 s). Look now and then,
    // and stay once the run is near its end (50 s).
    let hold = loop {
        let hold = sim.hold();
        let o = sim.plcctl(&["status", "--json"]);
        assert_eq!(code(&o), 0, "{}", String::from_utf8_lossy(&o.stderr));
        let v: serde_json::Value = serde_json::from_str(&text(&o)).unwrap();
        if v["status"]["uptime_ms"].as_u64().unwrap() > 44_000 {
            break hold;
        }
        drop(hold);
        std::thread::sleep(std::time::Duration::from_millis(10));
    };
    let counters = |sim: &Sim| -> serde_json::Value {
        let o = sim.plcctl(&["counters", "--json"]);
        assert_eq!(code(&o), 0, "{}", String::from_utf8_lossy(&o.stderr));
        serde_json::from_str(&text(&o)).unwrap()
    };
    // Past the duration: the CSV is complete (it covers the duration only).
    loop {
        let o = sim.plcctl(&["status", "--json"]);
        let v: serde_json::Value = serde_json::from_str(&text(&o)).unwrap();
        if v["status"]["uptime_ms"].as_u64().unwrap() > 50_200 {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(200));
    }
    let got = counters(&sim);
    let o = sim.plcctl(&["counters"]);
    assert!(text(&o).contains("app counter 1 (Q60)"), "{}", text(&o));
    drop(hold);
    // Ends the run during its linger, whose length is only a margin for a loaded machine
    // (the CSV and summary were written when the duration ended).
    drop(sim);

    let (h, rows) = csv_rows(&std::fs::read_to_string(&csv).unwrap());
    let col = |name: &str| h.iter().position(|c| c == name).unwrap();
    let (door, floor) = (col("O00"), col("at_floor"));
    let mut arrivals = [0u64; 4];
    let mut was_open = false;
    for r in &rows {
        let open = r[door] == "1";
        if open && !was_open {
            let f: usize = r[floor].parse().unwrap();
            arrivals[f - 1] += 1;
        }
        was_open = open;
    }
    assert!(arrivals.iter().sum::<u64>() >= 3, "{arrivals:?}");
    let app: Vec<u64> = got["app"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_u64().unwrap())
        .collect();
    assert_eq!(app, arrivals.to_vec(), "counters {got}");
    // One RUN start (the power-up RUN of the image), no trips.
    assert_eq!(got["run_starts"], 1, "{got}");
    assert!(got["trips"].as_array().unwrap().iter().all(|t| t == 0));
}

/// An entry's time as a date: the PLC's time of day, else the host's estimate.
fn time_of_row(r: &serde_json::Value) -> &str {
    if r["wall_s"].is_null() {
        assert_eq!(r["time"], "clock not set", "{r}");
        r["host_time"].as_str().unwrap()
    } else {
        r["time"].as_str().unwrap()
    }
}

/// issue 35 item 2: a lift fault reaches the fault log and `plcctl faults` shows it with
/// the profile's text, floor and target. `lift.plc` with the door forced open during the
/// initialisation run (moving, floor 0 = not yet known, target 1): fault 10 at about 1.2 s.
#[test]
fn faults_shows_a_lift_fault_with_its_text_floor_and_target() {
    let scen = temp("lift_door.toml");
    std::fs::write(
        &scen,
        "duration_s = 2.0\n[lift]\n[[event]]\nat_s = 1.0\ndoor_block = true\n",
    )
    .unwrap();
    let lift = root().join("shared-protocol/programs/lift.plc");
    let profile = root().join("shared-protocol/programs/lift.profile.toml");
    let profile = profile.to_str().unwrap();
    let sim = Sim::start(&[
        lift.to_str().unwrap(),
        "--scenario",
        scen.to_str().unwrap(),
        "--service-linger",
        "20",
    ]);
    let hold = sim.hold();
    // Real time while held.
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(30);
    while sim.status()["status"]["uptime_ms"].as_u64().unwrap() <= 1_600 {
        assert!(
            std::time::Instant::now() < deadline,
            "the run never reached 1.6 s"
        );
        std::thread::sleep(std::time::Duration::from_millis(100));
    }
    let o = sim.plcctl(&["faults", "--json", "--profile", profile]);
    assert_eq!(code(&o), 0, "{}", String::from_utf8_lossy(&o.stderr));
    let rows: Vec<serde_json::Value> = serde_json::from_str(&text(&o)).unwrap();
    assert_eq!(rows.len(), 1, "{rows:?}");
    let r = &rows[0];
    assert_eq!(r["code"], 110, "{r}");
    assert_eq!(r["name"], "ALM", "{r}");
    assert_eq!(r["text"], "door open in travel", "{r}");
    assert_eq!(r["values"], serde_json::json!([0, 1]), "{r}");
    assert_eq!(
        r["value_names"],
        serde_json::json!(["floor", "target"]),
        "{r}"
    );
    time_of_row(r);
    // Text and CSV, with and without the profile.
    let t = text(&sim.plcctl(&["faults", "--profile", profile]));
    assert!(t.contains("door open in travel, floor 0, target 1"), "{t}");
    let t = text(&sim.plcctl(&["faults"]));
    assert!(t.contains("application fault 10, lcd0 0, lcd1 1"), "{t}");
    let csv = text(&sim.plcctl(&["faults", "--csv", "--profile", profile]));
    let mut lines = csv.lines();
    assert_eq!(
        lines.next(),
        Some("pos,time,wall_s,host_time,power_up,uptime_s,code,name,text,floor,target")
    );
    let row = lines.next().unwrap();
    assert!(row.contains(",110,ALM,door open in travel,0,1"), "{row}");
    drop(hold);
    drop(sim);
}

/// `plcctl serve` (service.md part B), on the helpers above.
mod serve;

/// README "Connect a PC": its commands one after another, each a new client of one
/// `hil-sim run --service-pty`, none holding the pty in between (after one
/// short client the run raced to its end and the second command found no device). The
/// run's duration ends during the sequence: the linger takes the later clients.
#[test]
fn the_readmes_commands_run_one_after_another_against_one_simulator() {
    let toml = "duration_s = 3.0\n[[event]]\nat_s = 0.05\nkeys = \"*7\"\n";
    // Whole seconds: the fault log's times have no fraction.
    let started = chrono::Local::now().naive_local() - chrono::Duration::seconds(1);
    let sim = Sim::with_scenario("readme.toml", toml, "120");
    let (csv, png, pulled) = (temp("readme.csv"), temp("readme.png"), temp("readme1.plc"));
    let motor = motor();
    let steps: Vec<Vec<&str>> = vec![
        vec!["status"],
        vec!["watch", "--duration", "0.3"],
        vec![
            "trend",
            "--csv",
            csv.to_str().unwrap(),
            "--plot",
            png.to_str().unwrap(),
            "--duration",
            "0.5",
            "--q",
            "Q04,Q05",
        ],
        vec!["faults", "--json"],
        vec!["counters", "--json"],
        vec!["pull", "1", "-o", pulled.to_str().unwrap()],
        vec!["stop"],
        vec!["clear-faults"],
        vec!["push", motor.to_str().unwrap(), "--slot", "1", "--yes"],
        vec!["run", "--slot", "1"],
        vec!["ack"],
        vec!["status", "--json"],
    ];
    // Remote service comes on at 0.05 s of virtual time; the guarded steps come later.
    sim.wait_status("remote service on", |s| s["status"]["remote"] == true);
    for args in &steps {
        let o = sim.plcctl(args);
        assert_eq!(
            code(&o),
            0,
            "plcctl {args:?}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
    }
    assert!(std::fs::read_to_string(&csv).unwrap().starts_with("t_s,"));
    assert_eq!(&std::fs::read(&png).unwrap()[1..4], b"PNG");
    assert!(std::fs::read_to_string(&pulled).unwrap().contains("000 "));
    // The log's wall-clock times (LOGCLR, PGMSVC of this sequence) fall within the run,
    // never before the simulation started (virtual time raced ahead of the
    // wall clock between clients).
    let o = sim.plcctl(&["faults", "--json"]);
    let rows: Vec<serde_json::Value> = serde_json::from_str(&text(&o)).unwrap();
    let names: Vec<&str> = rows.iter().map(|r| r["name"].as_str().unwrap()).collect();
    assert_eq!(names, ["PGMSVC", "LOGCLR"], "{rows:?}");
    let now = chrono::Local::now().naive_local() + chrono::Duration::seconds(1);
    for r in &rows {
        let t = chrono::NaiveDateTime::parse_from_str(time_of_row(r), "%Y-%m-%d %H:%M:%S").unwrap();
        assert!(t >= started && t <= now, "{t} outside {started} .. {now}");
    }
    drop(sim);
}

/// Bad numbers are usage errors (exit 1) before any port is opened, NaN and infinity
/// included; nothing panics.
#[test]
fn bad_numbers_are_refused_with_exit_1() {
    let cases: &[&[&str]] = &[
        &["--baud", "0", "status"],
        &["watch", "--duration", "nan"],
        &["trend", "--csv", "x.csv", "--duration", "nan"],
        &["trend", "--csv", "x.csv", "--duration", "inf"],
        &["trend", "--csv", "x.csv", "--duration", "1e20"],
        &["pull", "9"],
        &["push", "x.plc", "--slot", "0"],
        &["push", "x.plc", "--slot", "5"],
        &["run", "--slot", "7"],
    ];
    for args in cases {
        let o = Command::new(PLCCTL)
            .args(["--port", "/nonexistent/tty"])
            .args(*args)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(code(&o), 1, "{args:?}: {err}");
        assert!(err.contains("invalid value"), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{err}");
    }
}

/// `trend --csv keep.csv` on a port that does not open leaves `keep.csv` as it was
/// (it was replaced by a header line), and no temporary file.
#[test]
fn a_failed_trend_or_pull_keeps_the_users_file() {
    let dir = temp("keep");
    std::fs::create_dir_all(&dir).unwrap();
    let keep = dir.join("keep.csv");
    let plc = dir.join("keep.plc");
    std::fs::write(&keep, "mine\n").unwrap();
    std::fs::write(&plc, "mine\n").unwrap();
    for args in [
        vec!["trend", "--csv", keep.to_str().unwrap(), "--duration", "1"],
        vec!["pull", "1", "-o", plc.to_str().unwrap()],
    ] {
        let o = Command::new(PLCCTL)
            .args(["--port", "/nonexistent/tty"])
            .args(&args)
            .output()
            .unwrap();
        assert_eq!(code(&o), 2, "{}", String::from_utf8_lossy(&o.stderr));
    }
    assert_eq!(std::fs::read_to_string(&keep).unwrap(), "mine\n");
    assert_eq!(std::fs::read_to_string(&plc).unwrap(), "mine\n");
    let names: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names.len(), 2, "{names:?}");
}
