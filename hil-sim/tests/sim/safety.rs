//! The acceptance scenarios of safety.md 13 (NOT RATED safety functions) on the
//! simulated rig: `safety_lab.plc` as shipped, the scenarios in `hil-sim/scenarios/safety/`
//! (each turns on its function's selection switch at t = 0; none: STO). Times measured by the drive from its request
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

/// `safety_lab.plc` with extra drive lines.
fn lab(extra: &str) -> String {
    format!("{LAB}{extra}")
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

/// safety.md 13's negative checks: the Reset button (D05) and the keypad's `*` `9`
/// pressed while the field is interrupted leave `code` latched (checked at `at_s`, after
/// both) and the outputs off.
fn interrupted_field_keeps(r: &RunReport, code: u8, at_s: f64) {
    let s = crate::common::at(&r.samples, at_s);
    assert_eq!(
        s.fault, code,
        "released at {at_s} s with the field interrupted"
    );
    assert!(!s.pwm_on);
    assert!(s.digital_out & (1 << 5) != 0, "Reset lamp O05 still lit");
}

/// 13.1 (A.2): STO at 10 Hz.
#[test]
fn sto_opens_the_outputs_within_20_ms_and_the_rotor_coasts() {
    let r = run_text(LAB, &scenario("sto"), 36.0);
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
    // D05 at 20.3 s and `*` `9` at 20.6 s, the field still interrupted: code 9 stays.
    interrupted_field_keeps(&r, 9, 20.95);
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
    // The field interrupted again at 38 s, D05 at 38.3 s, `*` `9` at 38.6 s: code 10 stays.
    interrupted_field_keeps(&r, 10, 39.45);
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
    let r = run_text(LAB, &scenario("sos_speed"), 52.0);
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
    let r = run_text(LAB, &scenario("honesty"), 40.0);
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
        &lab("048 ard K39 0020\n"),
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
    let r = run_text(LAB, &scenario("sls"), 56.0);
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
        assert!(me.contains(&format!("\"{stem}\"")), "{name} has no test");
    }
}

/// The first sample at or after `t` whose turns are beyond `limit` (signed).
fn turns_past(r: &RunReport, from_s: f64, limit_e4: i64) -> Option<&Sample> {
    r.samples.iter().find(|s| {
        t_s(s) >= from_s
            && if limit_e4 >= 0 {
                s.turns_e4 > limit_e4
            } else {
                s.turns_e4 < limit_e4
            }
    })
}

/// 13.3(b): the early limit: the end 5.000 s after f fell to the threshold.
#[test]
fn ss1_early_limit_ends_5_000_s_after_f_fell_to_4_hz() {
    let r = run_text(LAB, &scenario("ss1_early"), 32.0);
    let req = request_at(&r, bit("SS1"));
    let t = trip(&r);
    assert_eq!(t.fault, 10);
    let below_from = r
        .samples
        .iter()
        .filter(|s| t_s(s) >= t_s(req) && t_s(s) < t_s(t))
        .rfind(|s| s.f_cmd_hz > 4.0)
        .map(|s| t_s(s) + 0.001)
        .unwrap();
    assert!((below_from - 23.14).abs() < 0.2, "{below_from}");
    let dt = t_s(t) - below_from.max(t_s(req));
    assert!((dt - 5.0).abs() <= 0.002, "{dt}");
    assert!(
        (f64::from(t.sft_ds) / 10.0 - 8.1).abs() <= 0.2,
        "{}",
        t.sft_ds
    );
}

/// 13.4 and (a) (A.5): SS2 reverse at 14 Hz to standstill, then a setpoint of 6.0 Hz trips
/// where f passes 4.0 Hz.
#[test]
fn ss2_reaches_standstill_and_trips_when_moved() {
    let r = run_text(LAB, &scenario("ss2"), 50.0);
    let req = request_at(&r, bit("SS2"));
    assert!(in_window(t_s(req), 20.0, 0.02));
    assert_eq!(crate::common::at(&r.samples, 19.0).dir, -1);
    let safe = r
        .samples
        .iter()
        .find(|s| s.sf_st & bit("SS2") != 0)
        .expect("standstill");
    assert!((t_s(safe) - 29.92).abs() < 0.2, "{}", t_s(safe));
    assert!(!safe.sdc && safe.fault == 0);
    assert!((f64::from(safe.sft_ds) / 10.0 - 9.9).abs() <= 0.2);
    let t = trip(&r);
    assert_eq!(t.fault, 12);
    assert!((t_s(t) - 42.56).abs() < 0.2, "{}", t_s(t));
    let last_on = r
        .samples
        .iter()
        .rfind(|s| s.pwm_on && t_s(s) < t_s(t))
        .unwrap();
    assert!(last_on.f_cmd_hz <= 4.1, "{}", last_on.f_cmd_hz);
}

/// 13.4(c) and 13.5(b): the target missed at the end of the ramp: code 11 at t0 + 15.000 s.
#[test]
fn ss2_and_sls_without_deceleration_trip_ramp_at_15_000_s() {
    for (f, name) in [("SS2", "ss2_no_decel"), ("SL2", "sls_no_decel")] {
        let r = run_text(LAB, &scenario(name), 37.0);
        let req = request_at(&r, bit(f));
        let t = trip(&r);
        assert_eq!(t.fault, 11, "{f}");
        let dt = t_s(t) - t_s(req);
        assert!((dt - 15.0).abs() <= 0.002, "{f}: {dt}");
    }
}

/// 13.5(c) and (d): SL1 at 16.0 Hz; with SL2 on line 198 the lower limit governs.
#[test]
fn sls1_trips_at_16_hz_and_with_sl2_too_at_10_hz() {
    let r = run_text(LAB, &scenario("sls1"), 46.0);
    let req = request_at(&r, bit("SL1"));
    let limited = r
        .samples
        .iter()
        .find(|s| s.sf_st & bit("SL1") != 0)
        .unwrap();
    // Already at 12 Hz <= 16 Hz: the early limit ends it 5.000 s after the request.
    assert!((t_s(limited) - t_s(req) - 5.0).abs() <= 0.002);
    let t = trip(&r);
    assert_eq!(t.fault, 13);
    assert!((t_s(t) - 42.56).abs() < 0.2, "{}", t_s(t));
    let last_on = r
        .samples
        .iter()
        .rfind(|s| s.pwm_on && t_s(s) < t_s(t))
        .unwrap();
    assert!(last_on.f_cmd_hz <= 16.1 && last_on.f_cmd_hz > 15.0);
    // (d): SL1's and SL2's switches on, run as (a) of 13.5: the trip comes at 10.0 Hz.
    let both = scenario("sls").replace("D12 = 1", "D11 = 1, D12 = 1");
    let r = run_text(LAB, &both, 56.0);
    let t = trip(&r);
    assert_eq!(t.fault, 13);
    let last_on = r
        .samples
        .iter()
        .rfind(|s| s.pwm_on && t_s(s) < t_s(t))
        .unwrap();
    assert!(last_on.f_cmd_hz <= 10.1, "{}", last_on.f_cmd_hz);
}

/// 13.6(a) (A.7): SLI requested at standstill; 100 turns later code 14.
#[test]
fn sli_trips_100_turns_from_where_it_was_requested() {
    let r = run_text(LAB, &scenario("sli_stopped"), 24.0);
    let req = request_at(&r, bit("SLI"));
    assert!(in_window(t_s(req), 5.0, 0.02));
    assert_eq!(
        r.samples.iter().find(|s| t_s(s) > t_s(req)).unwrap().sf_st & bit("SLI"),
        bit("SLI")
    );
    let t = trip(&r);
    assert_eq!(t.fault, 14);
    assert!((t_s(t) - 18.3).abs() < 0.2, "{}", t_s(t));
    let past = turns_past(&r, 0.0, 1_000_000).expect("past 100 turns");
    assert!(t_s(past) <= t_s(t) + 0.001);
    // Within one tick's change (10 Hz: 100 units of 10⁻⁴ turn) of the limit.
    assert!(t.turns_e4 <= 1_000_000 + 100, "{}", t.turns_e4);
    assert_eq!(t.sf_st & bit("SLI"), 0);
}

/// 13.6(b): SLI requested while running: code 14 at once.
#[test]
fn sli_requested_while_running_trips_at_once() {
    let r = run_text(LAB, &scenario("sli_running"), 22.0);
    let t = trip(&r);
    assert_eq!(t.fault, 14);
    assert!(in_window(t_s(t), 20.0, 0.02), "{}", t_s(t));
}

/// 13.6(c): after the release SLI stays active for its 10 s disable delay and trips
/// inside it.
#[test]
fn sli_keeps_monitoring_through_its_disable_delay() {
    let r = run_text(LAB, &scenario("sli_delay"), 30.0);
    let released = r
        .samples
        .iter()
        .find(|s| t_s(s) > 6.0 && s.sf_req & bit("SLI") == 0)
        .expect("released");
    assert!(in_window(t_s(released), 15.0, 0.03));
    assert_eq!(released.sf_st & bit("SLI"), bit("SLI"), "still active");
    let t = trip(&r);
    assert_eq!(t.fault, 14);
    assert!((t_s(t) - 23.3).abs() < 0.3, "{}", t_s(t));
    assert!(t_s(t) < t_s(released) + 10.0);
}

/// 13.7(a) (A.8): SDP, driven backwards: code 15 at 200 turns back.
#[test]
fn sdp_trips_200_turns_back() {
    let r = run_text(LAB, &scenario("sdp"), 32.0);
    let req = request_at(&r, bit("SDP"));
    let after = r.samples.iter().find(|s| t_s(s) > t_s(req)).unwrap();
    assert_eq!(after.sf_st & bit("SDP"), bit("SDP"), "tdi 0: at once");
    let t = trip(&r);
    assert_eq!(t.fault, 15);
    assert!((t_s(t) - 28.3).abs() < 0.3, "{}", t_s(t));
    assert!(
        t.turns_e4 >= -2_000_000 - 100 && t.turns_e4 < -1_990_000,
        "{}",
        t.turns_e4
    );
    // (c) SDN forward trips the same way.
    let sdn_fwd = scenario("sdp")
        .replace(", D01 = 1", "")
        .replace("D14 = 1", "D15 = 1");
    let r = run_text(LAB, &sdn_fwd, 32.0);
    let t = trip(&r);
    assert_eq!(t.fault, 15);
    assert!((t_s(t) - 28.3).abs() < 0.3, "{}", t_s(t));
}

/// 13.7(b): SDP forward for 60 s: no trip, status 1 throughout.
#[test]
fn sdp_allows_forward_travel() {
    let r = run_text(LAB, &scenario("sdp_forward"), 68.0);
    assert!(r.faults.is_empty());
    assert!(r
        .samples
        .iter()
        .filter(|s| t_s(s) > 5.1)
        .all(|s| s.sf_st & bit("SDP") != 0));
    assert!(r.samples.last().unwrap().turns_e4 > 5_000_000);
}

/// 13.10(a): `asr` 5.0 Hz/s: the drive decelerates by itself.
#[test]
fn asr_decelerates_at_5_hz_per_s_and_ss1_ends_by_the_early_limit() {
    let r = run_text(&lab("048 asr K39 0050\n"), &scenario("asr_ss1"), 30.0);
    let req = request_at(&r, bit("SS1"));
    let at = |dt: f64| crate::common::at(&r.samples, t_s(req) + dt);
    assert!(at(1.2).f_cmd_hz <= 4.05, "{}", at(1.2).f_cmd_hz);
    assert!(
        (at(0.6).f_cmd_hz - 7.0).abs() <= 0.1,
        "{}",
        at(0.6).f_cmd_hz
    );
    let off = r
        .samples
        .iter()
        .find(|s| t_s(s) > t_s(req) && !s.pwm_on)
        .unwrap();
    assert!((t_s(off) - t_s(req) - 1.8).abs() < 0.05, "{}", t_s(off));
    let t = trip(&r);
    assert_eq!(t.fault, 10);
    assert!((t_s(t) - t_s(req) - 6.2).abs() < 0.01, "{}", t_s(t));
}

/// 13.12(b): SLA with aap 10.0 Hz/s: 10 -> 40 Hz trips within 0.2 s; reverse does not.
#[test]
fn sla_trips_on_the_forward_acceleration_limit_only() {
    let program = LAB
        .replace("043 aap K34 2000", "043 aap K34 0100")
        .replace("044 adp K35 2000", "044 adp K35 9999")
        .replace("045 aan K36 2000", "045 aan K36 9999")
        .replace("046 adn K37 2000", "046 adn K37 9999");
    let r = run_text(&program, &scenario("sla_accel"), 30.0);
    let t = trip(&r);
    assert_eq!(t.fault, 16);
    assert!(in_window(t_s(t), 25.0, 0.2), "{}", t_s(t));
    let reverse = scenario("sla_accel").replace("A01 = 100 }", "A01 = 100, D01 = 1 }");
    let r = run_text(&program, &reverse, 30.0);
    assert!(r.faults.is_empty(), "{:?}", r.faults);
    assert_eq!(crate::common::at(&r.samples, 29.0).dir, -1);
}

/// 13.13: the link cut in SS2's delay: LINK within 60 ms, outputs off.
#[test]
fn a_link_cut_in_ss2s_delay_trips_link() {
    let r = run_text(LAB, &scenario("link_cut_ss2"), 24.0);
    assert!(crate::common::at(&r.samples, 21.9).sdc);
    let t = trip(&r);
    assert_eq!(t.fault, 5);
    assert!(in_window(t_s(t), 22.0, 0.06), "{}", t_s(t));
    assert!(!next(&r, t).pwm_on);
}

/// 13.14: the verifier's rules at RUN and in `hil-sim`, and the signature: documented for
/// safety_lab.plc, changed by any setting changed by 1, not by a setting line moving.
#[test]
fn the_verifier_refuses_missing_or_doubled_settings_and_the_signature_is_stable() {
    let no_ts2 = LAB.replace(
        "035 ts2 K26 0100     ; SS2 ramp monitoring time 10.0 s\n",
        "",
    );
    let e = hil_sim::run::parse_program(&no_ts2, "lab.plc").unwrap_err();
    assert!(e.to_string().ends_with("SS2 needs ts2"), "{e}");
    let twice = lab("049 fss K40 0040\n");
    let e = hil_sim::run::parse_program(&twice, "lab.plc").unwrap_err();
    assert!(e.to_string().ends_with("fss set twice (030)"), "{e}");
    let sig = |text: &str| {
        let p = hil_sim::run::parse_program(text, "lab.plc").unwrap();
        shared_protocol::program::safety_settings(p.lines.iter()).signature()
    };
    assert_eq!(sig(LAB), 0x7C32);
    let moved = LAB.replace("047 tla K38 0000", "099 tla K38 0000");
    assert_eq!(sig(&moved), 0x7C32);
    assert_ne!(
        sig(&LAB.replace("047 tla K38 0000", "047 tla K38 0001")),
        0x7C32
    );
    assert_ne!(
        sig(&LAB.replace("030 fss K21 0040", "030 fss K21 0039")),
        0x7C32
    );
}

/// 13.2(b): SOS at 2.0 Hz trips on the position, 100.000 s after the request.
#[test]
fn sos_trips_when_the_field_has_turned_200_times() {
    let r = run_text(LAB, &scenario("sos_position"), 125.0);
    let req = request_at(&r, bit("SOS"));
    let t = trip(&r);
    assert_eq!(t.fault, 12);
    let dt = t_s(t) - t_s(req);
    // 2.0 Hz = 20 units per tick: 200 turns = 2 000 000 units after 100 000 ticks.
    assert!((dt - 100.0).abs() <= 0.002, "{dt}");
}

/// 13.4(b): SS2's standstill position window.
#[test]
fn ss2_trips_200_turns_from_its_standstill_position() {
    let r = run_text(LAB, &scenario("ss2_position"), 146.0);
    let safe = r
        .samples
        .iter()
        .find(|s| s.sf_st & bit("SS2") != 0)
        .expect("standstill");
    let t = trip(&r);
    assert_eq!(t.fault, 12);
    assert!((t_s(t) - 142.8).abs() < 0.3, "{}", t_s(t));
    let moved = (t.turns_e4 - safe.turns_e4).abs();
    assert!((2_000_000..=2_000_000 + 40).contains(&moved), "{moved}");
}

/// 13.6(d): a new request inside the disable delay keeps the original position.
#[test]
fn sli_rerequested_in_its_delay_keeps_the_original_position() {
    let r = run_text(LAB, &scenario("sli_rerequest"), 32.0);
    // The new curtain at about 9 Hz: no trip then (v > fss would trip a fresh request).
    let again = r
        .samples
        .iter()
        .find(|s| t_s(s) > 21.0 && s.sf_req & bit("SLI") != 0)
        .expect("re-requested");
    assert!(again.f_cmd_hz > 8.0, "{}", again.f_cmd_hz);
    assert_eq!(again.fault, 0);
    let t = trip(&r);
    assert_eq!(t.fault, 14);
    assert!((t_s(t) - 28.3).abs() < 0.3, "{}", t_s(t));
    assert!(
        (1_000_000..=1_000_100).contains(&t.turns_e4),
        "{}",
        t.turns_e4
    );
}

/// 13.7(d): SDP's reference trails the furthest forward point.
#[test]
fn sdp_counts_back_from_the_furthest_point_reached() {
    let r = run_text(LAB, &scenario("sdp_trailing"), 60.0);
    let t = trip(&r);
    assert_eq!(t.fault, 15);
    let max = r
        .samples
        .iter()
        .filter(|s| t_s(s) < t_s(t))
        .map(|s| s.turns_e4)
        .max()
        .unwrap();
    assert!(max > 500_000, "moved forward first: {max}");
    let back = max - t.turns_e4;
    assert!((2_000_000..=2_000_100).contains(&back), "{back}");
    assert!(t.turns_e4 > -2_000_000, "not at -200: {}", t.turns_e4);
}

/// 13.10(b): `asr` with SS2: standstill by the drive's own ramp; the program's setpoint
/// then leaves f at 0.
#[test]
fn asr_brings_ss2_to_standstill_and_holds_it() {
    let r = run_text(&lab("048 asr K39 0050\n"), &scenario("asr_ss2"), 36.0);
    let req = request_at(&r, bit("SS2"));
    let safe = r
        .samples
        .iter()
        .find(|s| s.sf_st & bit("SS2") != 0)
        .expect("standstill");
    assert!((t_s(safe) - t_s(req) - 6.2).abs() < 0.01, "{}", t_s(safe));
    assert!(r.faults.is_empty());
    let late = crate::common::at(&r.samples, 35.0);
    assert_eq!(late.f_cmd_hz, 0.0);
    assert!(!late.pwm_on);
}

/// 13.12(a) and (c): the lab's SLA limits pass the lag's slope; `adp` 10.0 Hz/s trips a
/// fast deceleration.
#[test]
fn sla_passes_the_lag_with_lab_limits_and_trips_a_fast_deceleration() {
    let r = run_text(LAB, &scenario("sla_lab"), 34.0);
    assert!(r.faults.is_empty(), "{:?}", r.faults);
    assert!(crate::common::at(&r.samples, 33.0).f_cmd_hz > 45.0);
    let program = LAB
        .replace("043 aap K34 2000", "043 aap K34 9999")
        .replace("044 adp K35 2000", "044 adp K35 0100")
        .replace("045 aan K36 2000", "045 aan K36 9999")
        .replace("046 adn K37 2000", "046 adn K37 9999");
    let r = run_text(&program, &scenario("sla_decel"), 30.0);
    let t = trip(&r);
    assert_eq!(t.fault, 16);
    assert!(in_window(t_s(t), 25.0, 0.2), "{}", t_s(t));
}

/// 13.3(a) on the LCD: while SS1 decelerates the status row shows `S:SS1 DEC n.ns`
/// counting from the request, then `F10 SS1 done: STO` once it ends.
#[test]
fn the_lcd_counts_ss1_down_then_shows_code_10() {
    use hil_sim::scenario::Scenario;
    use hil_sim::sim::{RunOptions, Simulation};
    let p = hil_sim::run::parse_program(LAB, "safety_lab.plc").unwrap();
    let scen = Scenario::parse(&scenario("ss1_lab")).unwrap();
    let mut sim = Simulation::new(&p, scen, RunOptions::default()).unwrap();
    // The request at 20 s; the status row rotates every 2 s: look every 100 ms.
    let mut counts = Vec::new();
    for k in 201..=340 {
        sim.run_until(k * 100_000_000, |_| {});
        let row = sim.plc().lcd().row(3);
        if let Some(rest) = row.trim_end().strip_prefix("S:SS1 DEC ") {
            let s: f64 = rest.trim_end_matches('s').trim().parse().unwrap();
            counts.push((k as f64 / 10.0, s));
        }
    }
    assert!(counts.len() >= 2, "S:SS1 DEC not on the status row");
    for &(t, shown) in &counts {
        // Time since the request (at 20.0 s + up to 20 ms of input path); the LCD shows
        // the drive's stopwatch from its status frames, refreshed every 100 ms: it trails
        // by up to ~0.2 s (seen: 0.0 s at 20.2 s, 0.1 s at 20.3 s).
        let since = t - 20.0;
        assert!(
            shown <= since && since - shown <= 0.3,
            "at {t} s the LCD said {shown} s"
        );
    }
    assert!(counts.windows(2).all(|w| w[1].1 >= w[0].1), "{counts:?}");
    assert!(counts.last().unwrap().1 - counts[0].1 >= 10.0, "{counts:?}");
    // After the end (35.0 s) the fault alternates with its `*9` hint on the status row.
    let mut rows = Vec::new();
    for k in 351..=390 {
        sim.run_until(k * 100_000_000, |_| {});
        rows.push(sim.plc().lcd().row(3).trim_end().to_string());
    }
    assert!(rows.iter().any(|r| r == "F10 SS1 done: STO"), "{rows:?}");
}

/// 001 4.2.1: the function is chosen at run time by the selection switches, not by
/// editing the program: SOS's switch, then SS2's (make before break) while the curtain's
/// request holds; the Reset releases whatever is selected.
#[test]
fn the_selection_switches_choose_the_function_at_run_time() {
    let r = run_text(LAB, &scenario("selection"), 16.0);
    let req = request_at(&r, bit("SOS"));
    assert!(in_window(t_s(req), 5.0, 0.02), "{}", t_s(req));
    let at = |t: f64| crate::common::at(&r.samples, t);
    assert_eq!(at(7.0).sf_req, bit("SOS"), "SOS's switch on");
    assert_eq!(at(7.0).sf_st, bit("SOS"), "SOS holds the standstill");
    assert_eq!(at(8.05).sf_req, bit("SOS") | bit("SS2"), "both on");
    assert_eq!(at(8.2).sf_req, bit("SS2"), "SOS's switch off: released");
    // SS2 requested at 8.0 s below fss: standstill 5.000 s later (the early limit).
    let ss2 = request_at(&r, bit("SS2"));
    let safe = r
        .samples
        .iter()
        .find(|s| s.sf_st & bit("SS2") != 0)
        .expect("SS2 standstill");
    assert!((t_s(safe) - t_s(ss2) - 5.0).abs() <= 0.002, "{}", t_s(safe));
    assert!(r.faults.is_empty(), "{:?}", r.faults);
    assert_eq!(at(15.1).sf_req, 0, "Reset: nothing requested");
}

/// 001 A.3-A.8 ("Pohon - Pozice"): `SFP`, the whole field turns since the request, in the
/// status and on LCD field 3; 0 after the release, from 0 again at the next request.
#[test]
fn sfp_counts_the_turns_since_the_request_and_resets() {
    let r = run_text(LAB, &scenario("position"), 31.0);
    let req = request_at(&r, bit("SOS"));
    assert!(in_window(t_s(req), 10.0, 0.02));
    let x0 = r
        .samples
        .iter()
        .rfind(|s| s.t_ns < req.t_ns)
        .expect("before")
        .turns_e4;
    assert!(x0 > 100_000, "turned before the request: {x0}");
    for s in r.samples.iter().filter(|s| s.t_ns < req.t_ns) {
        assert_eq!(s.sf_turns, 0, "nothing requested at {}", t_s(s));
    }
    // From the request to the Reset: the drive's own turns since the request, whole,
    // truncated (the status and the sample are of the same tick).
    let reset = r
        .samples
        .iter()
        .find(|s| t_s(s) > 20.0 && s.sf_req == 0)
        .expect("released");
    assert!(in_window(t_s(reset), 25.0, 0.03), "{}", t_s(reset));
    for s in r
        .samples
        .iter()
        .filter(|s| s.t_ns >= req.t_ns && s.t_ns < reset.t_ns)
    {
        let want = (s.turns_e4 - x0) / 10_000;
        assert_eq!(i64::from(s.sf_turns), want, "at {}", t_s(s));
    }
    // About 2 turns/s (the lag near 2.0 Hz): 27 after 14 s.
    let before_reset = crate::common::at(&r.samples, 24.0);
    let n = before_reset.sf_turns;
    assert!((26..=28).contains(&n), "{n}");
    // The PLC's `LD SFP`, on LCD field 3, from the status frames (every 10 ms or less).
    let lcd = before_reset.lcd[2].expect("LCD field 3");
    assert!((n - 1..=n).contains(&lcd), "{lcd}");
    // Released: 0, in the drive and on the LCD.
    for s in r
        .samples
        .iter()
        .filter(|s| t_s(s) > t_s(reset) + 0.05 && t_s(s) < 27.0)
    {
        assert_eq!((s.sf_turns, s.lcd[2]), (0, Some(0)), "at {}", t_s(s));
    }
    // Requested again at 27 s: from 0 again.
    let again = r
        .samples
        .iter()
        .find(|s| t_s(s) > 26.0 && s.sf_req != 0)
        .expect("requested again");
    assert!(in_window(t_s(again), 27.0, 0.02), "{}", t_s(again));
    let n = crate::common::at(&r.samples, 30.0).sf_turns;
    assert!((5..=6).contains(&n), "{n} turns 3 s after the request");
}

/// 001 4.2.4 ("Stopky"): the stopwatch reads 0 once its function is deselected and holds
/// at 15.0 s (the source's TP timer, PT = 15 s).
#[test]
fn the_stopwatch_clears_on_deselect_and_holds_at_15_s() {
    let program = LAB.replace("032 trd K23 0050", "032 trd K23 0100");
    let r = run_text(&program, &scenario("stopwatch"), 31.0);
    let at = |t: f64| crate::common::at(&r.samples, t);
    // The first request (3 s), released by the Reset at 6 s after 3.0 s.
    assert!((29..=30).contains(&at(5.99).sft_ds), "{}", at(5.99).sft_ds);
    assert_eq!(at(6.05).sf_req, 0);
    assert_eq!(at(6.05).sft_ds, 0, "deselected: 0");
    assert_eq!(at(7.9).lcd[1], Some(0), "LCD field 2");
    // The second (8 s): counting from 0, held at 15.0 from 8 + 15 s on.
    let req = r
        .samples
        .iter()
        .find(|s| t_s(s) > 7.0 && s.sf_req != 0)
        .expect("requested again");
    assert!(in_window(t_s(req), 8.0, 0.02));
    assert!((49..=50).contains(&at(t_s(req) + 5.0).sft_ds));
    assert_eq!(at(t_s(req) + 15.01).sft_ds, 150);
    let t = trip(&r);
    assert_eq!(t.fault, 10);
    assert!((t_s(t) - t_s(req) - 20.0).abs() <= 0.002, "{}", t_s(t));
    for s in r
        .samples
        .iter()
        .filter(|s| t_s(s) >= t_s(req) + 15.01 && t_s(s) < 30.0)
    {
        assert_eq!(s.sft_ds, 150, "at {}", t_s(s));
    }
    assert_eq!(at(29.9).lcd[1], Some(150));
    // The Reset at 30 s releases SS1: 0.
    assert_eq!(at(30.05).sf_req, 0);
    assert_eq!(at(30.05).sft_ds, 0);
    assert_eq!(at(30.9).lcd[1], Some(0));
}

/// 001 5.2.2: the curtain's two channels (SF_Equivalent, 200 ms discrepancy time, then
/// SF_ESPE with manual reset). Either channel interrupted requests the function at once;
/// both within 200 ms: the Reset releases it; one channel alone for longer: the
/// discrepancy is latched and the Reset refused until both channels have been 0.
#[test]
fn the_curtain_latches_a_discrepancy_over_200_ms_until_both_channels_drop() {
    let r = run_text(LAB, &scenario("curtain_discrepancy"), 13.0);
    let at = |t: f64| crate::common::at(&r.samples, t);
    let sos = bit("SOS");
    let lamp = |s: &Sample| s.digital_out & (1 << 5) != 0;
    // Both channels 150 ms apart: requested at the first, released by the Reset.
    assert!(in_window(t_s(request_at(&r, sos)), 2.0, 0.02));
    assert_eq!(at(3.9).sf_req, sos);
    assert!(lamp(at(3.9)));
    assert_eq!(at(4.05).sf_req, 0, "no discrepancy: released");
    assert!(!lamp(at(4.1)));
    // D06 alone for 300 ms: requested at once; the Reset at 7 s is refused.
    let second = r
        .samples
        .iter()
        .find(|s| t_s(s) > 5.0 && s.sf_req != 0)
        .expect("requested");
    assert!(in_window(t_s(second), 6.0, 0.02), "{}", t_s(second));
    assert_eq!(at(7.5).sf_req, sos, "discrepancy: the Reset refused");
    assert!(lamp(at(7.5)));
    // Both 0 at 8 s clear the discrepancy; the Reset at 9.5 s releases.
    assert_eq!(at(9.4).sf_req, sos);
    assert_eq!(at(9.55).sf_req, 0);
    // D07 alone for 150 ms: requested, and the Reset releases (no discrepancy).
    let third = r
        .samples
        .iter()
        .find(|s| t_s(s) > 10.0 && s.sf_req != 0)
        .expect("requested");
    assert!(in_window(t_s(third), 11.0, 0.02), "{}", t_s(third));
    assert_eq!(at(11.9).sf_req, sos);
    assert_eq!(at(12.05).sf_req, 0);
    assert!(r.faults.is_empty(), "{:?}", r.faults);
}
