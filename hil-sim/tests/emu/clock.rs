//! The PLC's time of day on the real image: `plcctl clock set` through the emulated
//! LPUART1 writes the RTC on the NUCLEO's LSE crystal; a system reset keeps it (the backup
//! domain), a power-on loses it (no battery on VBAT); a fault-log entry made once it is
//! set carries it (entries without it: `firmware-plc`'s fault-log tests and plcctl's).

use g431_emu::periph::rcc::ResetKind;

use crate::common::{assert_stack_headroom, emu, ns, MOTOR_PLC, MOTOR_TOML};
use crate::service::plcctl_on_the_image;

/// The PLC's time in `plcctl clock`'s first line (`PLC clock [set to ]YYYY-MM-DD HH:MM:SS UTC`),
/// as seconds since 2000; `None` when it says unset.
fn plc_clock(out: &str) -> Option<u32> {
    let line = out.lines().next()?;
    let t = line.strip_prefix("PLC clock ")?;
    let t = t.strip_prefix("set to ").unwrap_or(t).get(..19)?;
    let t = chrono::NaiveDateTime::parse_from_str(t, "%Y-%m-%d %H:%M:%S").ok()?;
    u32::try_from(t.and_utc().timestamp() - 946_684_800).ok()
}

/// The newest fault-log entry's time of day in `plcctl faults --json` (newest first):
/// `Some(None)` when it says the clock was not set, `None` without an entry.
fn newest_wall_s(json: &str) -> Option<Option<u32>> {
    let at = json.find("\"wall_s\"")? + "\"wall_s\"".len();
    let v = json.get(at..)?.trim_start().strip_prefix(':')?.trim_start();
    if v.starts_with("null") {
        return Some(None);
    }
    let digits: String = v.chars().take_while(char::is_ascii_digit).collect();
    digits.parse().ok().map(Some)
}

/// The PLC's newest log entry (the drive's link trip that a reset of the PLC causes while
/// the motor runs).
fn newest_entry(sim: &mut crate::common::Checked) -> Option<Option<u32>> {
    let (st, out, err) = plcctl_on_the_image(sim, &["faults", "--json"]);
    assert!(st.success(), "plcctl faults: {st}\n{out}\n{err}");
    newest_wall_s(&out)
}

/// About 3.5 s of simulated time (the LSE's 2 s start-up included).
#[test]
fn a_set_clock_survives_a_reset_and_a_power_on_loses_it() {
    // The test resets the PLC itself.
    let scenario = format!("{MOTOR_TOML}\n[emu]\nexpect = [\"software_reset\"]\n");
    let mut sim = emu(MOTOR_PLC, &scenario);
    sim.run_until(ns(0.5), |_| {});
    let (st, out, err) = plcctl_on_the_image(&mut sim, &["clock"]);
    assert!(st.success(), "plcctl clock: {st}\n{out}\n{err}");
    assert!(out.starts_with("PLC clock unset"), "after power-on: {out}");
    // 2030-01-02 03:04:05 UTC.
    const SET: u32 = 946_868_645;
    let (st, out, err) = plcctl_on_the_image(
        &mut sim,
        &["clock", "set", "--time", "2030-01-02T03:04:05Z"],
    );
    assert!(st.success(), "plcctl clock set: {st}\n{out}\n{err}");
    assert_eq!(plc_clock(&out), Some(SET), "{out}");
    let set_at = sim.now_ns();
    // The image writes the RTC once the LSE runs (tSU(LSE) 2 s after its boot).
    let until = ns(2.3).max(sim.now_ns() + 100_000_000);
    sim.run_until(until, |_| {});
    let log: String = sim.plc().log().iter().map(|l| format!("{l}\n")).collect();
    assert!(log.contains("rtc: set to"), "PLC log:\n{log}");
    sim.plc_mut().cpu_mut().reset(ResetKind::Software);
    let until = sim.now_ns() + 300_000_000;
    sim.run_until(until, |_| {});
    let (st, out, err) = plcctl_on_the_image(&mut sim, &["clock"]);
    assert!(st.success(), "plcctl clock: {st}\n{out}\n{err}");
    let read = plc_clock(&out).unwrap_or_else(|| {
        let log: String = sim.plc().log().iter().map(|l| format!("{l}\n")).collect();
        let reports = sim.plc().diagnostics();
        panic!("set after the reset: {out}\nPLC log:\n{log}\n{reports:?}")
    });
    let elapsed_s = u32::try_from((sim.now_ns() - set_at) / 1_000_000_000).unwrap();
    assert!(
        (SET..=SET + elapsed_s + 1).contains(&read),
        "{read} s: set {SET} s, {elapsed_s} s of virtual time since\n{out}"
    );
    // The reset made the drive trip on the link: its entry carries the time of day.
    let stamped = newest_entry(&mut sim).flatten();
    assert!(
        stamped.is_some_and(|s| (SET..=SET + elapsed_s + 1).contains(&s)),
        "the entry after the reset: {stamped:?}, set {SET} s"
    );
    sim.power_cycle_plc();
    let until = sim.now_ns() + 300_000_000;
    sim.run_until(until, |_| {});
    let (st, out, err) = plcctl_on_the_image(&mut sim, &["clock"]);
    assert!(st.success(), "plcctl clock: {st}\n{out}\n{err}");
    assert!(
        out.starts_with("PLC clock unset"),
        "after a power-on: {out}"
    );
    assert_stack_headroom(&sim);
}
