//! The source's full motor program (program.md section 5) on the default rig.

use super::common::*;

/// pot A01 = 500 (50.0 Hz), A00 = 980 (9800 Hz PWM); START at 0.5 s; REV at 8 s;
/// START/STOP again at 22 s.
/// On the source's rig (`motor.toml`): its chopper takes the reversal's energy.
const SCENARIO: &str = r#"
[plant]
board = "source"

[[event]]
at_s = 0.0
set = { A00 = 980, A01 = 500 }

[[event]]
at_s = 0.5
press = "D00"
hold_s = 0.2

[[event]]
at_s = 8.0
press = "D01"
hold_s = 0.2

[[event]]
at_s = 22.0
press = "D00"
hold_s = 0.2
"#;

const TAU_S: f64 = 2.333;

#[test]
fn full_motor_example_runs_as_the_source_describes() {
    let r = run_text(MOTOR_PLC, SCENARIO, 26.0);
    let s = &r.samples;
    assert_eq!(s.len(), 26_001);

    // No trip anywhere, and the currents stay well inside I> = 2 A.
    assert!(r.faults.is_empty(), "faults: {:?}", r.faults);
    assert!(s.iter().all(|x| x.fault == 0));
    let peak = peak_current(s);
    assert!(peak < 1.8, "peak current {peak}");

    // Before START: nothing moves, the PWM is off.
    assert!(s
        .iter()
        .take_while(|x| t_s(x) < 0.5)
        .all(|x| !x.pwm_on && x.f_cmd_hz == 0.0));

    // START: the PLC writes the setpoint A01 into Q02; the frequency follows as a
    // first-order lag with T = 2.333 s.
    let t0 = t_s(s.iter().find(|x| x.q[2] == 500).expect("setpoint written"));
    assert!((0.5..0.52).contains(&t0), "setpoint at {t0}");
    for k in [1.0, 2.0, 3.0] {
        let expect = 50.0 * (1.0 - f64::exp(-k));
        let f = at(s, t0 + k * TAU_S).f_cmd_hz;
        assert!(
            (f - expect).abs() < 0.5,
            "f({k} tau) = {f}, expected {expect}"
        );
    }
    // The motor follows with a small slip, forward.
    let x = at(s, 7.9);
    assert_eq!(x.dir, 1);
    let sync_rpm = x.f_cmd_hz * 30.0;
    assert!(
        x.speed_rpm > 0.9 * sync_rpm && x.speed_rpm < sync_rpm,
        "{x:?}"
    );

    // LCD: field 1 = A01, field 2 = A00 x 10.
    assert_eq!(at(s, 5.0).lcd, [Some(500), Some(9800), None, None]);
    assert!(r.lcd.row(1).contains("500") && r.lcd.row(1).contains("9800"));

    // REV: the setpoint drops to 0 and the motor ramps down (braking, no reversal yet).
    assert_eq!(at(s, 8.1).q[2], 0);
    let f_rev = at(s, 8.01).f_cmd_hz;
    let f = at(s, 8.01 + TAU_S).f_cmd_hz;
    assert!(
        (f - f_rev * f64::exp(-1.0)).abs() < 0.6,
        "ramp down: {f} from {f_rev}"
    );
    assert!(s.iter().filter(|x| t_s(x) < 14.9).all(|x| x.dir == 1));

    // 7 s after REV the setpoint returns; the direction flips at the turning point,
    // below frv (20 Hz), and only once.
    let flips: Vec<_> = s.windows(2).filter(|w| w[0].dir != w[1].dir).collect();
    assert_eq!(flips.len(), 1, "direction changes: {}", flips.len());
    let t_flip = t_s(&flips[0][1]);
    assert!((15.0..15.1).contains(&t_flip), "reversal at {t_flip}");
    assert_eq!(at(s, 15.05).q[2], 500);
    // The frequency then was the ramp's low point, about 2 Hz: below fmn the PWM is off.
    let expect_low = f_rev * f64::exp(-(15.0 - 8.0) / TAU_S);
    assert!((1.0..4.0).contains(&expect_low));
    assert!(!at(s, 14.9).pwm_on);

    // The motor runs up in the other direction.
    let x = at(s, 21.9);
    assert_eq!(x.dir, -1);
    assert!(x.f_cmd_hz > 45.0, "{x:?}");
    assert!(x.speed_rpm < -0.9 * x.f_cmd_hz * 30.0, "{x:?}");

    // START/STOP again: setpoint 0, the frequency ramps down.
    assert_eq!(at(s, 22.1).q[2], 0);
    let f22 = at(s, 22.01).f_cmd_hz;
    let f25 = at(s, 25.01).f_cmd_hz;
    let expect = f22 * f64::exp(-3.0 / TAU_S);
    assert!((f25 - expect).abs() < 0.6, "stop ramp: {f25} vs {expect}");
}

#[test]
fn speed_follows_the_pot_with_the_2_333_s_lag() {
    // Running at 30 Hz, the pot goes to 60 Hz at 10 s: the frequency moves toward the new
    // setpoint as a first-order lag from where it was.
    let scen = r#"
[[event]]
at_s = 0.0
set = { A00 = 980, A01 = 300 }

[[event]]
at_s = 0.2
press = "D00"

[[event]]
at_s = 10.0
set = { A01 = 600 }
"#;
    let r = run_text(MOTOR_PLC, scen, 16.0);
    assert!(r.faults.is_empty(), "{:?}", r.faults);
    let s = &r.samples;
    let f0 = at(s, 10.0).f_cmd_hz;
    assert!((f0 - 30.0).abs() < 0.5, "{f0}");
    // The PLC reads the pot in the next scan; the lag starts from there.
    let t0 = t_s(s.iter().find(|x| x.q[2] == 600).unwrap());
    assert!((10.0..10.003).contains(&t0));
    for k in [0.5, 1.0, 2.0] {
        let expect = 60.0 + (f0 - 60.0) * f64::exp(-k);
        let f = at(s, t0 + k * TAU_S).f_cmd_hz;
        assert!(
            (f - expect).abs() < 0.5,
            "f({k} tau) = {f}, expected {expect}"
        );
    }
    assert_eq!(at(s, 12.0).lcd[0], Some(600));
    // 60 Hz is within fmx (70 Hz): the motor follows, above 1600 rpm.
    assert!(at(s, 15.9).speed_rpm > 1600.0);
}
