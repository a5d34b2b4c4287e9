//! The PLC's clock from plcctl against the simulated PLC (hil-sim's `--service-pty`):
//! `clock set` and `clock`, and `serve`'s rule (set on connect when unset or off by more
//! than 2 s, with a log line; left alone otherwise).

use super::Serve;
use crate::{code, text, Sim};

fn clock_line(sim: &Sim) -> String {
    let o = sim.plcctl(&["clock"]);
    assert_eq!(code(&o), 0, "{}", String::from_utf8_lossy(&o.stderr));
    text(&o)
}

#[test]
fn clock_set_and_clock_against_the_simulator() {
    let sim = Sim::with_scenario("clock.toml", "duration_s = 6.0\n", "0");
    let hold = sim.hold();
    assert!(clock_line(&sim).starts_with("PLC clock unset"));
    let o = sim.plcctl(&["clock", "set", "--time", "2030-01-02T04:04:05+01:00"]);
    assert_eq!(code(&o), 0, "{}", String::from_utf8_lossy(&o.stderr));
    assert!(
        text(&o).starts_with("PLC clock set to 2030-01-02 03:04:05 UTC"),
        "{}",
        text(&o)
    );
    // Beyond the RTC's century: a usage error before anything is sent.
    let o = sim.plcctl(&["clock", "set", "--time", "2100-01-01 00:00:00"]);
    assert_eq!(code(&o), 1);
    // The PC's time: the simulated PLC follows the wall clock, so the offset is small.
    let o = sim.plcctl(&["clock", "set"]);
    assert_eq!(code(&o), 0, "{}", String::from_utf8_lossy(&o.stderr));
    let out = clock_line(&sim);
    let offset: f64 = out
        .lines()
        .find_map(|l| l.strip_prefix("offset to this PC "))
        .and_then(|l| l.trim_end_matches(" s").parse().ok())
        .unwrap_or_else(|| panic!("{out}"));
    assert!((-2.0..=2.0).contains(&offset), "{out}");
    drop(hold);
    sim.finish();
}

#[test]
fn serve_sets_an_unset_or_wrong_clock_on_connect_and_leaves_a_right_one() {
    let sim = Sim::with_scenario("serve-clock.toml", "duration_s = 10.0\n", "0");
    let hold = sim.hold();
    // Unset: serve sets it and says so.
    let serve = Serve::start(&sim, &[]);
    serve.wait_log(&["PLC clock was unset: set to"]);
    drop(serve);
    assert!(clock_line(&sim).starts_with("PLC clock 20"));
    // Off by an hour: set again.
    let o = sim.plcctl(&["clock", "set", "--time", "2030-01-02 03:04:05"]);
    assert_eq!(code(&o), 0);
    let serve = Serve::start(&sim, &[]);
    serve.wait_log(&["PLC clock was off by", "set to"]);
    drop(serve);
    // Right (within 2 s): left alone, no line.
    let serve = Serve::start(&sim, &[]);
    serve.wait_status(5.0, |s| s["connected"] == true);
    std::thread::sleep(std::time::Duration::from_millis(300));
    assert!(!serve.log().contains("PLC clock"), "{}", serve.log());
    drop(serve);
    drop(hold);
    sim.finish();
}
