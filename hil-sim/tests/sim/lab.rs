//! The source's lab chapter (§5, Obr 5.1-5.7) as acceptance tests:
//! the programs `shared-protocol/programs/lab_*.plc` and the motor example under the
//! scenarios `hil-sim/scenarios/lab_*.toml`. The figures and the measured values are in
//! `hil-sim/docs/lab.md` (`cargo run --release -p hil-sim --example lab_figures`).

use super::common::*;
use hil_sim::lab::{current_ripple, fine_window, first};
use hil_sim::sim::Sample;

fn program(name: &str) -> String {
    std::fs::read_to_string(format!(
        "{}/../shared-protocol/programs/{name}.plc",
        env!("CARGO_MANIFEST_DIR")
    ))
    .unwrap()
}

fn scenario(name: &str) -> String {
    std::fs::read_to_string(format!(
        "{}/scenarios/{name}.toml",
        env!("CARGO_MANIFEST_DIR")
    ))
    .unwrap()
}

fn within_10_percent(measured: f64, source: f64, what: &str) {
    assert!(
        (measured - source).abs() <= 0.1 * source,
        "{what}: {measured:.3} s, the source's {source} s"
    );
    println!("{what}: {measured:.3} s (source {source} s)");
}

/// The shaft follows the ramp: within 12 % of synchronous speed, forward.
fn follows(s: &Sample) {
    let sync = s.f_cmd_hz * 30.0;
    assert!(
        s.speed_rpm > 0.88 * sync && s.speed_rpm <= sync,
        "shaft at {} rpm, synchronous {sync}: {s:?}",
        s.speed_rpm
    );
}

#[test]
fn obr_5_1_run_up_from_6_to_20_hz_in_2_s() {
    let r = run_text(&program("lab_5_1_runup"), &scenario("lab_5_1_runup"), 5.0);
    assert!(r.faults.is_empty(), "{:?}", r.faults);
    let s = &r.samples;
    let t6 = first(s, 0.0, |x| x.pwm_on).unwrap();
    assert_eq!(at(s, t6).f_cmd_hz, 6.0);
    let t20 = first(s, t6, |x| x.f_cmd_hz >= 20.0).unwrap();
    within_10_percent(t20 - t6, 2.0, "Obr 5.1 run-up 6 -> 20 Hz");
    follows(at(s, t20 + 0.5));
    assert!(peak_current(s) < 2.0);
}

#[test]
fn obr_5_3_run_down_20_to_6_hz_in_5_s_and_run_up_6_to_50_hz_in_4_s() {
    let r = run_text(
        &program("lab_5_3_rundown_runup"),
        &scenario("lab_5_3_rundown_runup"),
        16.0,
    );
    assert!(r.faults.is_empty(), "{:?}", r.faults);
    let s = &r.samples;
    let at20 = first(s, 0.0, |x| x.f_cmd_hz >= 20.0).unwrap();
    follows(at(s, at20 + 2.5));
    let down = first(s, at20, |x| x.f_cmd_hz < 20.0).unwrap();
    let at6 = first(s, down, |x| x.f_cmd_hz <= 6.0).unwrap();
    within_10_percent(at6 - down, 5.0, "Obr 5.3 run-down 20 -> 6 Hz");
    let up = first(s, at6, |x| x.f_cmd_hz > 6.0).unwrap();
    let at50 = first(s, up, |x| x.f_cmd_hz >= 50.0).unwrap();
    within_10_percent(at50 - up, 4.0, "Obr 5.3 run-up 6 -> 50 Hz");
    follows(at(s, at50 + 0.5));
    // Braking down: the shaft never runs ahead of the field by more than the slip.
    assert!(s.iter().all(|x| x.speed_rpm >= 0.0));
    assert!(peak_current(s) < 2.0);
}

/// The sense of rotation of the phase currents over `w`: the mean angular velocity of
/// their space vector (rad/s; positive for the sequence a-b-c, negative for a-c-b).
fn rotation(w: &[&Sample]) -> f64 {
    let vec = |x: &Sample| {
        let (a, b) = (x.i_abc_a[0], x.i_abc_a[1]);
        (a, (a + 2.0 * b) / 3f64.sqrt())
    };
    let mut sum = 0.0;
    for p in w.windows(2) {
        let ((a0, b0), (a1, b1)) = (vec(p[0]), vec(p[1]));
        let dt = t_s(p[1]) - t_s(p[0]);
        let r2 = a0 * a0 + b0 * b0;
        if r2 > 1e-6 {
            sum += (a0 * (b1 - b0) - b0 * (a1 - a0)) / r2 / dt;
        }
    }
    sum / (w.len() - 1) as f64
}

fn rms(w: &[&Sample], y: impl Fn(&Sample) -> f64) -> f64 {
    (w.iter().map(|x| y(x).powi(2)).sum::<f64>() / w.len() as f64).sqrt()
}

#[test]
fn obr_5_2_current_and_line_voltage_through_a_reversal() {
    let r = run_text(MOTOR_PLC, &scenario("lab_5_2_reversal"), 22.0);
    assert!(r.faults.is_empty(), "{:?}", r.faults);
    let s = &r.samples;
    // 30 Hz forward, then REV: down for 7 s, the flip at the turning point, up reversed.
    // The turning point (about 1.5 Hz) is below fmn = 5 Hz: the phases swap while the
    // outputs are off, when the setpoint returns 7 s after REV.
    let flip = first(s, 8.0, |x| x.dir == -1).unwrap();
    assert!((15.0..15.2).contains(&flip), "flipped at {flip} s");
    assert!(!at(s, flip).pwm_on);
    let on = first(s, flip, |x| x.pwm_on).unwrap();
    assert_eq!(at(s, on).dir, -1);
    assert!(at(s, flip - 0.1).speed_rpm > 0.0 && s.last().unwrap().speed_rpm < -500.0);
    let win = |a: f64, b: f64| -> Vec<&Sample> {
        s.iter().filter(|x| (a..b).contains(&t_s(x))).collect()
    };
    // The currents' phase sequence reverses: their space vector turns the other way, at
    // 2 pi f.
    let (before, after) = (win(6.0, 7.9), win(20.0, 22.0));
    let (wb, wa) = (rotation(&before), rotation(&after));
    let f_b = before[before.len() / 2].f_cmd_hz;
    let f_a = after[after.len() / 2].f_cmd_hz;
    assert!(wb * wa < 0.0, "sequence kept: {wb} {wa} rad/s");
    assert!(
        (wb.abs() / (std::f64::consts::TAU * f_b) - 1.0).abs() < 0.1,
        "{wb} at {f_b} Hz"
    );
    assert!(
        (wa.abs() / (std::f64::consts::TAU * f_a) - 1.0).abs() < 0.1,
        "{wa} at {f_a} Hz"
    );
    // The line voltage keeps its V/f amplitude through the reversal.
    let (ub, ua) = (rms(&before, |x| x.u_ab_v), rms(&after, |x| x.u_ab_v));
    assert!(
        ((ub / f_b) / (ua / f_a) - 1.0).abs() < 0.1,
        "{ub} V at {f_b} Hz, {ua} V at {f_a} Hz"
    );
    assert!(peak_current(s) < 2.0);
}

#[test]
fn obr_5_4_to_5_7_current_ripple_halves_with_each_doubling_of_the_switching_frequency() {
    let prog = program("lab_5_4_switching");
    let mut ripple = Vec::new();
    for hz in [9990.0, 5000.0, 2500.0, 1250.0] {
        let scen = scenario(&format!("lab_5_4_switching_{hz}hz"));
        // Two 50 Hz cycles at 2 us, in steady state.
        let w = fine_window(&prog, &scen, 2.9, 0.04, 2.0).unwrap();
        assert!(w
            .iter()
            .all(|x| x.f_cmd_hz == 50.0 && x.fault == 0 && x.pwm_on));
        let r = current_ripple(&w, 0, hz);
        println!(
            "f_sw {hz} Hz: ripple {:.2} mA rms, {:.1} mA peak-to-peak per period",
            r.rms_a * 1e3,
            r.pp_a * 1e3
        );
        ripple.push((hz, r));
    }
    for pair in ripple.windows(2) {
        let ((f_hi, hi), (f_lo, lo)) = (pair[0], pair[1]);
        // Expected: ripple proportional to 1/f_sw (9990 -> 5000 Hz is 1.998x).
        let expect = f_hi / f_lo;
        for (what, ratio) in [("rms", lo.rms_a / hi.rms_a), ("p-p", lo.pp_a / hi.pp_a)] {
            assert!(
                (ratio - expect).abs() <= 0.15 * expect,
                "{what} ripple {f_lo} Hz / {f_hi} Hz = {ratio:.3}, expected {expect:.3}"
            );
        }
    }
}
