//! The acceptance scenarios of safety.md 13 (NOT RATED safety functions) on the
//! simulated rig: `safety_lab.plc` with the function under test on line 197, the
//! scenarios in `hil-sim/scenarios/safety/`. Times measured by the drive from its request
//! (the rise of the bit in `sf_req`) are asserted to ±2 ms; input edges to 20 ms.

use crate::common::{run_text, t_s};
use hil_sim::run::RunReport;
use hil_sim::sim::Sample;

const LAB: &str = include_str!("../../../shared-protocol/programs/safety_lab.plc");

fn scenario(name: &str) -> String {
    let path = format!(
        "{}/scenarios/safety/{name}.toml",
        env!("CARGO_MANIFEST_DIR")
    );
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"))
}

/// `safety_lab.plc` with `SFR <f>` on line 197 and extra drive lines.
fn lab(function: &str, extra: &str) -> String {
    let text = LAB.replace("197 SFR SS1", &format!("197 SFR {function}"));
    format!("{text}{extra}")
}

fn bit(name: &str) -> u16 {
    let names = [
        "STO", "SS1", "SS2", "SOS", "SL1", "SL2", "SL3", "SL4", "SLI", "SDP", "SDN", "SLA",
    ];
    1 << names.iter().position(|n| *n == name).expect("function")
}

/// The first sample whose `sf_req` has `mask`'s bit (the request as the drive saw it).
fn request_at(r: &RunReport, mask: u16) -> &Sample {
    r.samples
        .iter()
        .find(|s| s.sf_req & mask != 0)
        .expect("requested")
}

/// The first sample with a fault latched.
fn trip(r: &RunReport) -> &Sample {
    r.samples.iter().find(|s| s.fault != 0).expect("a trip")
}

/// The sample after `s`.
fn next<'a>(r: &'a RunReport, s: &Sample) -> &'a Sample {
    r.samples
        .iter()
        .find(|x| x.t_ns > s.t_ns)
        .expect("a later sample")
}

fn in_window(t: f64, from: f64, width: f64) -> bool {
    (from..=from + width).contains(&t)
}

/// safety.md 13's common ending after a trip at `trip_s`: no sample switches after the
/// trip (the tick that latches the code turns the outputs off; TIM1's MOE follows at the
/// next PWM period, before the next sample) until the START at `start_s`; the field cleared alone changes nothing; the Reset
/// at `reset_s` (field clear) releases and acknowledges (`fault` 0 within 20 ms, O05 off,
/// outputs still off); after STOP, RUN and START the outputs switch within 1 s.
fn common_ending(r: &RunReport, trip_s: f64, reset_s: f64, start_s: f64) {
    let fault = trip(r).fault;
    for s in r
        .samples
        .iter()
        .filter(|s| t_s(s) > trip_s && t_s(s) < start_s)
    {
        assert!(
            !s.pwm_on,
            "outputs on at {:.3} s before the new START",
            t_s(s)
        );
    }
    // Field clear since trip + 1 s: still latched just before the Reset.
    let before = r
        .samples
        .iter()
        .rfind(|s| t_s(s) < reset_s)
        .expect("sample");
    assert_eq!(
        before.fault, fault,
        "clearing the field alone changes nothing"
    );
    assert!(before.digital_out & (1 << 5) != 0, "Reset lamp O05 lit");
    let acked = r
        .samples
        .iter()
        .find(|s| t_s(s) >= reset_s && s.fault == 0)
        .expect("ACK accepted");
    assert!(
        in_window(t_s(acked), reset_s, 0.025),
        "ACK at {}",
        t_s(acked)
    );
    let lamp_off = r
        .samples
        .iter()
        .find(|s| t_s(s) >= reset_s && s.digital_out & (1 << 5) == 0)
        .expect("O05 off");
    assert!(in_window(t_s(lamp_off), reset_s, 0.03));
    let on = r
        .samples
        .iter()
        .find(|s| t_s(s) >= start_s && s.pwm_on)
        .expect("running again after START");
    assert!(in_window(t_s(on), start_s, 1.0), "outputs at {}", t_s(on));
    assert!(r.samples.iter().all(|s| t_s(s) < start_s || s.fault == 0));
}

/// 13.1 (A.2): STO at 10 Hz.
#[test]
fn sto_opens_the_outputs_within_20_ms_and_the_rotor_coasts() {
    let r = run_text(&lab("STO", ""), &scenario("sto"), 36.0);
    let t = trip(&r);
    assert!(in_window(t_s(t), 20.0, 0.02), "trip at {}", t_s(t));
    assert_eq!(t.fault, 9);
    // The tick that latched the code applies nothing more (f 0); MOE is off from the
    // next PWM period, before the next sample.
    assert_eq!(t.f_cmd_hz, 0.0);
    assert!(!next(&r, t).pwm_on);
    assert_eq!(t.sf_st & bit("STO"), bit("STO"));
    // The rotor coasts down (not braked).
    let later = crate::common::at(&r.samples, 22.0);
    assert!(later.speed_rpm > 100.0 && later.speed_rpm < t.speed_rpm);
    assert_eq!(r.faults.len(), 1);
    common_ending(&r, t_s(t), 30.0, 33.0);
    assert_eq!(r.signature, Some(0x7C32));
    assert!(r.summary().contains("NOT RATED, parameter signature 7C32"));
}

/// 13.3(a) (A.4): the lab's SS1, nobody decelerates: 5 s delay + 10 s ramp time.
#[test]
fn ss1_lab_case_ends_15_000_s_after_the_request_with_code_10() {
    let r = run_text(LAB, &scenario("ss1_lab"), 52.0);
    let req = request_at(&r, bit("SS1"));
    assert!(in_window(t_s(req), 20.0, 0.02));
    let t = trip(&r);
    assert_eq!(t.fault, 10);
    let dt = t_s(t) - t_s(req);
    assert!(
        (dt - 15.0).abs() <= 0.002,
        "SS1 ended {dt} s after the request"
    );
    assert_eq!(t.sf_st & bit("SS1"), bit("SS1"));
    assert!(!t.sdc && t.f_cmd_hz == 0.0 && !next(&r, t).pwm_on);
    assert_eq!(t.sft_ds, 150, "the stopwatch's 15000 ms");
    // SDC on [t0, t0 + 15 s), motor unchanged meanwhile.
    for s in r
        .samples
        .iter()
        .filter(|s| (t_s(req)..t_s(t)).contains(&t_s(s)))
    {
        assert!(s.sdc && s.pwm_on && (s.f_cmd_hz - 10.0).abs() < 0.05);
    }
    common_ending(&r, t_s(t), 45.0, 48.0);
}

/// 13.3(c): stopped: the early limit counts from the request (t0 + 5.000 s).
#[test]
fn ss1_stopped_ends_5_000_s_after_the_request() {
    let r = run_text(LAB, &scenario("ss1_stopped"), 30.0);
    let req = request_at(&r, bit("SS1"));
    let t = trip(&r);
    assert_eq!(t.fault, 10);
    let dt = t_s(t) - t_s(req);
    assert!((dt - 5.0).abs() <= 0.002, "{dt}");
}

/// 13.2(a) (A.3): SOS holds at 2.0 Hz; a setpoint of 6.0 Hz trips where f passes 4.0 Hz.
#[test]
fn sos_holds_at_2_hz_and_trips_where_f_would_pass_4_hz() {
    let r = run_text(&lab("SOS", ""), &scenario("sos_speed"), 52.0);
    let req = request_at(&r, bit("SOS"));
    assert!(in_window(t_s(req), 20.0, 0.02));
    let held = crate::common::at(&r.samples, 25.0);
    assert_eq!(held.sf_st & bit("SOS"), bit("SOS"));
    assert!(!held.sdc && held.pwm_on && held.fault == 0);
    let t = trip(&r);
    assert_eq!(t.fault, 12);
    // ≈ t0 + 11.7 s (the lag from 2 to 6 Hz passes 4 Hz after 2.333·ln 2 s).
    assert!((t_s(t) - 31.7).abs() < 0.2, "{}", t_s(t));
    // Nothing above the limit was applied: the last switching sample is at most one
    // tick's change above 4.0 Hz.
    let last_on = r
        .samples
        .iter()
        .rfind(|s| s.pwm_on && t_s(s) < t_s(t))
        .unwrap();
    assert!(last_on.f_cmd_hz <= 4.0 + 0.1, "{}", last_on.f_cmd_hz);
    assert_eq!(t.sf_st & bit("SOS"), 0, "NOK");
    common_ending(&r, t_s(t), 42.0, 45.0);
}

/// 13.8: the honesty test. SOS reports standstill while the rotor coasts.
#[test]
fn sos_reports_standstill_while_the_rotor_coasts_unseen() {
    let r = run_text(&lab("SOS", ""), &scenario("honesty"), 40.0);
    let off = r
        .samples
        .iter()
        .find(|s| t_s(s) > 30.0 && !s.pwm_on)
        .expect("outputs off");
    // ≈ t0 + 11.6 s: f falls below fmn 1.0 Hz.
    assert!((t_s(off) - 31.6).abs() < 0.3, "{}", t_s(off));
    let coasting: Vec<&Sample> = r
        .samples
        .iter()
        .filter(|s| t_s(s) >= t_s(off) && s.speed_rpm > 20.0)
        .collect();
    let span = t_s(coasting.last().unwrap()) - t_s(coasting[0]);
    assert!(
        span >= 1.0,
        "the rotor turns for {span} s after the outputs went off"
    );
    for s in coasting {
        assert_eq!(s.sf_st & bit("SOS"), bit("SOS"), "standstill reported");
        assert_eq!(s.fault, 0);
        assert_eq!(s.f_cmd_hz, 0.0, "v = 0: the monitor sees nothing");
    }
    assert!(r.faults.is_empty());
}

/// 13.9(a)(c): `STO_IN` low opens the inverter in the same period, code 9; ACK refused
/// while low; the common ending once it is high.
#[test]
fn sto_in_low_opens_the_inverter_at_once_and_blocks_the_ack() {
    let r = run_text(LAB, &scenario("sto_in"), 42.0);
    let low = r.samples.iter().find(|s| t_s(s) >= 20.0).expect("sample");
    assert!(
        !low.pwm_on,
        "off at the first sample: the break, not the software"
    );
    let t = trip(&r);
    assert!(in_window(t_s(t), 20.0, 0.0015), "code 9 at {}", t_s(t));
    assert_eq!(t.fault, 9);
    assert_eq!(t.sf_st & 1, 1);
    assert_eq!(t.sf_req & 1, 1);
    // `*` `9` at 23 s: refused (the input is still low).
    assert_eq!(crate::common::at(&r.samples, 24.0).fault, 9);
    common_ending(&r, t_s(t), 35.0, 38.0);
}

/// 13.9(b): RUN refused while `STO_IN` is low.
#[test]
fn run_is_refused_while_sto_in_is_low() {
    let r = run_text(LAB, &scenario("sto_in_at_start"), 3.0);
    assert!(r.samples.iter().all(|s| !s.pwm_on));
    assert_eq!(r.drive_state, "IDLE");
    assert!(!r.drive_states.iter().any(|(_, s)| *s == "RUN"));
    assert!(
        r.lcd.framed().contains("RUN REFUSED:STO_IN"),
        "{}",
        r.lcd.framed()
    );
}

/// 13.11: ramp monitoring (`ard` 2.0 Hz/s) on SS1 at 10 Hz: code 11 at t0 + 5.050 s.
#[test]
fn ramp_monitoring_trips_50_ms_into_the_ramp() {
    let r = run_text(
        &lab("SS1", "048 ard K39 0020\n"),
        &scenario("ramp_monitoring"),
        27.0,
    );
    let req = request_at(&r, bit("SS1"));
    let t = trip(&r);
    assert_eq!(t.fault, 11);
    let dt = t_s(t) - t_s(req);
    assert!((dt - 5.050).abs() <= 0.002, "{dt}");
}

/// 13.5 and (a) (A.6): SL2 reaches LIMITED 5 s after f fell to 10.0 Hz; a setpoint of
/// 12.0 Hz then trips where f passes 10.0 Hz.
#[test]
fn sls_limits_at_10_hz_after_the_early_limit_and_trips_above_it() {
    let r = run_text(&lab("SL2", ""), &scenario("sls"), 56.0);
    let req = request_at(&r, bit("SL2"));
    assert!(in_window(t_s(req), 20.0, 0.02));
    // The end: 5.000 s after the later of the request and the start of the last run of
    // samples at or below 10.0 Hz.
    let limited = r
        .samples
        .iter()
        .find(|s| s.sf_st & bit("SL2") != 0)
        .expect("LIMITED");
    let below_from = r
        .samples
        .iter()
        .filter(|s| t_s(s) >= t_s(req) && t_s(s) < t_s(limited))
        .rfind(|s| s.f_cmd_hz > 10.0)
        .map_or(t_s(req), |s| t_s(s) + 0.001)
        .max(t_s(req));
    let dt = t_s(limited) - below_from;
    assert!((dt - 5.0).abs() <= 0.002, "{dt}");
    assert!((t_s(limited) - 28.62).abs() < 0.2, "{}", t_s(limited));
    assert!(!limited.sdc);
    let t = trip(&r);
    assert_eq!(t.fault, 13);
    assert!((t_s(t) - 41.62).abs() < 0.2, "{}", t_s(t));
    let last_on = r
        .samples
        .iter()
        .rfind(|s| s.pwm_on && t_s(s) < t_s(t))
        .unwrap();
    assert!(last_on.f_cmd_hz <= 10.1, "{}", last_on.f_cmd_hz);
    common_ending(&r, t_s(t), 51.0, 54.0);
}

/// Every scenario in `scenarios/safety/` is one of the tests above.
#[test]
fn every_safety_scenario_has_its_test() {
    let dir = format!("{}/scenarios/safety", env!("CARGO_MANIFEST_DIR"));
    let me = include_str!("safety.rs");
    for e in std::fs::read_dir(dir).unwrap() {
        let name = e.unwrap().file_name().into_string().unwrap();
        let stem = name.trim_end_matches(".toml");
        assert!(
            me.contains(&format!("scenario(\"{stem}\")")),
            "{name} has no test"
        );
    }
}
