//! The PLC's time of day on the real image: `plcctl clock set` through the emulated
//! LPUART1 writes the RTC on the NUCLEO's LSE crystal; a system reset keeps it (the backup
//! domain), a power-on loses it (no battery on VBAT).

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

#[test]
#[ignore = "The sources, second pass: the image reads its clock back unset after a system reset (RTC written, cause not found yet)"]
fn a_set_clock_survives_a_reset_and_a_power_on_loses_it() {
    let mut sim = emu(MOTOR_PLC, MOTOR_TOML);
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
