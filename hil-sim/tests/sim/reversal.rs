//! Reversal at standstill (program.md 4.2 `frv`, lift.md 2.2): after any stop the motor
//! restarts in the requested direction, with the default `frv` (0.1 Hz).

use super::common::*;

/// Direct frequency steps (no ramp): D00 = 1 runs at 10.0 Hz, D00 = 0 stops (f = 0, below
/// fmn, outputs off); D01 is the direction request. `REV` comes before the `WR` that
/// starts the motor, as lift.md 2.2 asks of a program reversing from standstill.
const STEP_PLC: &str = "
000 LD  Q02
001 LD  Q02
002 LD  K00 0000
003 SN1
004 LD  K01 1200
005 SN2
006 LD  K02 2400
007 SN3
008 fmn K03 0010
009 Rs= K04 0195
010 Uc= K05 0030
011 Iz= K06 0050
012 =dU
150 LD  D01
151 REV
152 LD  D00
153 LD  K07 0100
154 WR  Q02
155 LDC D00
156 LD  K08 0000
157 WR  Q02
";

/// A brake load stops the coasting motor within about 1.5 s.
fn scenario(rev_at_s: f64, restart_at_s: f64) -> String {
    format!(
        r#"
[plant]
load_torque_nm = 0.01

[[event]]
at_s = 0.2
set = {{ D00 = 1 }}

[[event]]
at_s = 2.0
set = {{ D00 = 0 }}

[[event]]
at_s = {rev_at_s}
set = {{ D01 = 1 }}

[[event]]
at_s = {restart_at_s}
set = {{ D00 = 1 }}
"#
    )
}

fn check_restart_reverse(rev_at_s: f64, restart_at_s: f64) {
    let r = run_text(STEP_PLC, &scenario(rev_at_s, restart_at_s), 7.0);
    let s = &r.samples;
    assert!(r.faults.is_empty(), "faults {:?}", r.faults);
    // Forward at 10 Hz first.
    let fwd = at(s, 1.9);
    assert!(
        fwd.pwm_on && fwd.dir == 1 && fwd.f_cmd_hz == 10.0,
        "{fwd:?}"
    );
    assert!(fwd.speed_rpm > 250.0, "{fwd:?}");
    // Stopped: outputs off, and the shaft at rest before the restart.
    let stopped = at(s, restart_at_s - 0.01);
    assert!(
        !stopped.pwm_on && stopped.speed_rpm.abs() < 1.0,
        "{stopped:?}"
    );
    // The first period with the outputs on after the restart is already reversed.
    let first_on = s
        .iter()
        .find(|x| t_s(x) >= restart_at_s && x.pwm_on)
        .expect("restarted");
    assert_eq!(first_on.dir, -1, "{first_on:?}");
    // After the request the motor never turns forward again, and it runs up reversed.
    let max_fwd = s
        .iter()
        .filter(|x| t_s(x) >= rev_at_s)
        .map(|x| x.speed_rpm)
        .fold(f64::NEG_INFINITY, f64::max);
    assert!(max_fwd <= 5.0, "forward speed {max_fwd} rpm after REV");
    let end = s.last().expect("samples");
    assert!(end.dir == -1 && end.speed_rpm < -250.0, "{end:?}");
}

#[test]
fn stop_then_reverse_then_start_runs_reversed() {
    check_restart_reverse(4.0, 5.0);
}

#[test]
fn reverse_and_start_in_the_same_scan_run_reversed() {
    check_restart_reverse(5.0, 5.0);
}

/// The source's motor example at a steady setpoint, `REV` at 8 s: the program sets the
/// setpoint to 0 for 7 s (its lag ramps the command down) and back (up again). 002 4.2
/// (`frv` = 20 Hz here): the phases swap only when the command rises again below frv, or
/// at standstill, never at a steady speed (plugging: an OC trip 14-30 ms later at 15 and
/// 19 Hz before this rule) nor while the command falls. On the source's board (its
/// sensors and brake chopper: `motor.plc`'s `U>` is the chopper's level); on the bare
/// ESC1, without a chopper, the run-down from 50 Hz on a 30 V supply trips `OV_HW`
/// whatever the direction (`docs/drive-core.md`, "Overvoltage without a chopper").
fn reverse_motor_example_at(setpoint_dhz: u16) {
    let scenario = format!(
        r#"
duration_s = 22.0

[plant]
board = "source"

[[event]]
at_s = 0.0
set = {{ A00 = 980, A01 = {setpoint_dhz} }}

[[event]]
at_s = 0.5
press = "D00"

[[event]]
at_s = 8.0
press = "D01"
hold_s = 0.2
"#
    );
    let r = run_text(MOTOR_PLC, &scenario, 22.0);
    let hz = f64::from(setpoint_dhz) / 10.0;
    assert!(r.faults.is_empty(), "at {hz} Hz: {:?}", r.faults);
    let s = &r.samples;
    let flip = hil_sim::lab::first(s, 0.0, |x| x.dir == -1)
        .unwrap_or_else(|| panic!("at {hz} Hz: never reversed"));
    // The setpoint comes back at 15 s: the command's turning point.
    assert!(
        flip >= 14.99,
        "at {hz} Hz the phases swapped at {flip:.3} s, before the turning point (15 s)"
    );
    let before = at(s, flip - 0.01);
    let here = at(s, flip);
    assert!(
        here.f_cmd_hz < 20.0 && (here.f_cmd_hz > before.f_cmd_hz || before.f_cmd_hz == 0.0),
        "at {hz} Hz: swapped at {} Hz after {} Hz",
        here.f_cmd_hz,
        before.f_cmd_hz
    );
    let end = s.last().unwrap();
    assert!(
        end.speed_rpm < -0.8 * hz * 30.0,
        "at {hz} Hz: the shaft ends at {} rpm",
        end.speed_rpm
    );
}

#[test]
fn rev_at_a_steady_8_hz_waits_for_the_turning_point() {
    reverse_motor_example_at(80);
}

#[test]
fn rev_at_a_steady_15_hz_waits_for_the_turning_point() {
    reverse_motor_example_at(150);
}

#[test]
fn rev_at_a_steady_19_hz_waits_for_the_turning_point() {
    reverse_motor_example_at(190);
}

#[test]
fn rev_at_25_hz_reverses_at_the_turning_point() {
    reverse_motor_example_at(250);
}

#[test]
fn rev_at_50_hz_reverses_at_the_turning_point() {
    reverse_motor_example_at(500);
}
