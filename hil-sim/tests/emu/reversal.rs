//! The source's motor example reverses on the real images as 002 §4.2 (`frv`) says: a
//! `REV` at a steady speed below frv (20 Hz in `motor.plc`) never swaps the phases at
//! speed; the phases swap at the turning point of the command, when the program's 7 s
//! ramp-down ends and the setpoint returns, and the motor runs up reversed without a trip.
//! hil-sim's `sim::reversal` runs the same at 8, 15, 19, 25 and 50 Hz on the source's board;
//! here, on the emulated ESC1, the cases that plugged the motor, within a small emulated
//! time: the full reversal at 19 Hz (the highest speed that may reverse) and the first
//! 150 ms after `REV` at 8 and 15 Hz (where the phases swapped at speed). A `REV` above
//! frv behaves as at 19 Hz after its ramp-down (hil-sim, 25 Hz); from 50 Hz the ESC1, which
//! has no brake chopper, trips `OV_HW` on the ramp-down whatever the direction rule (hil-sim
//! with the ESC1 board: the same `OV_HW` 0.26 s after `REV` before and after it).

use hil_sim::sim::Sample;

use crate::common::{emu, ns, MOTOR_PLC};

/// `START` (D00) at this time.
const START_S: f64 = 0.3;
/// The pot at twice the setpoint until the command (the program's 2.333 s lag) reaches
/// the setpoint, 2.333 s * ln 2 after `START`; then the setpoint: the motor is at speed
/// sooner than with the lag alone (about 7 s).
const SETPOINT_AT_S: f64 = START_S + 1.62;
/// `REV` (D01) at this time, the motor at speed.
const REV_S: f64 = 2.1;
/// The program's ramp-down pulse after `REV` (line 167, `IMP K16 0070`).
const PULSE_S: f64 = 7.0;
/// `motor.plc`'s fmn (line 011).
const FMN_HZ: f64 = 5.0;

fn scenario(setpoint_dhz: u16) -> String {
    let boost = 2 * setpoint_dhz;
    format!(
        r#"
[[event]]
at_s = 0.0
set = {{ A00 = 980, A01 = {boost} }}

[[event]]
at_s = {START_S}
press = "D00"

[[event]]
at_s = {SETPOINT_AT_S}
set = {{ A01 = {setpoint_dhz} }}

[[event]]
at_s = {REV_S}
press = "D01"
hold_s = 0.2
"#
    )
}

/// Runs the motor example to `end_s` with `REV` at a steady `setpoint_dhz`; checks that
/// the motor was at speed, forward, when `REV` came. Returns the samples from `REV` on.
fn run_rev_at(setpoint_dhz: u16, end_s: f64) -> (Vec<Sample>, crate::common::Checked) {
    let hz = f64::from(setpoint_dhz) / 10.0;
    let mut sim = emu(MOTOR_PLC, &scenario(setpoint_dhz));
    let mut at_rev: Option<Sample> = None;
    let mut after: Vec<Sample> = Vec::new();
    sim.run_until(ns(end_s), |s| {
        if s.t_ns < ns(REV_S) {
            at_rev = Some(s.clone());
        } else {
            after.push(s.clone());
        }
    });
    let at_rev = at_rev.expect("samples before REV");
    assert!(
        at_rev.pwm_on
            && at_rev.dir == 1
            && (at_rev.f_cmd_hz - hz).abs() <= 0.3
            && at_rev.speed_rpm > 0.9 * 30.0 * hz,
        "at {hz} Hz: not running forward at speed when REV came: {at_rev:?}, faults {:?}",
        sim.faults()
    );
    (after, sim)
}

/// The first sample with the phases swapped, as the drive reports it.
fn first_reversed(after: &[Sample]) -> Option<&Sample> {
    after.iter().find(|s| s.dir == -1)
}

/// The 150 ms after `REV` at a steady speed below frv: the command falls, the phases stay
/// as they are, nothing trips. (Before the rule the phases swapped at once: at 8 Hz the
/// motor was reversed at speed, at 15 and 19 Hz it tripped `OC` 14-30 ms later.)
fn check_no_swap_at_speed(setpoint_dhz: u16) {
    let hz = f64::from(setpoint_dhz) / 10.0;
    let (after, sim) = run_rev_at(setpoint_dhz, REV_S + 0.15);
    if let Some(s) = first_reversed(&after) {
        panic!(
            "at {hz} Hz the phases swapped at {:.3} s, {:.0} ms after REV, at {} Hz with \
             the shaft at {:.0} rpm; faults {:?}",
            s.t_ns as f64 * 1e-9,
            (s.t_ns as f64 * 1e-9 - REV_S) * 1e3,
            s.f_cmd_hz,
            s.speed_rpm,
            sim.faults()
        );
    }
    assert!(sim.faults().is_empty(), "at {hz} Hz: {:?}", sim.faults());
    let last = after.last().expect("samples after REV");
    assert!(
        last.pwm_on && last.f_cmd_hz < hz,
        "at {hz} Hz: the ramp-down did not start: {last:?}"
    );
}

#[test]
fn rev_at_a_steady_8_hz_does_not_swap_the_phases_at_speed() {
    check_no_swap_at_speed(80);
}

#[test]
fn rev_at_a_steady_15_hz_does_not_swap_the_phases_at_speed() {
    check_no_swap_at_speed(150);
}

/// The whole reversal at 19 Hz: the phases swap only after the 7 s ramp-down, at the
/// turning point (below fmn there: the outputs are off), and the motor runs up reversed
/// without a trip.
#[test]
fn rev_at_a_steady_19_hz_reverses_at_the_turning_point_without_a_trip() {
    let end_s = REV_S + PULSE_S + 0.9;
    let (after, sim) = run_rev_at(190, end_s);
    assert!(
        sim.faults().is_empty(),
        "REV at 19 Hz: faults {:?}, phases swapped at {:?} s",
        sim.faults(),
        first_reversed(&after).map(|s| s.t_ns as f64 * 1e-9)
    );
    let flip = first_reversed(&after).unwrap_or_else(|| panic!("never reversed"));
    let flip_s = flip.t_ns as f64 * 1e-9;
    assert!(
        flip_s >= REV_S + PULSE_S && flip.f_cmd_hz < FMN_HZ,
        "the phases swapped at {flip_s:.3} s at {} Hz, before the turning point \
         ({:.1} s, below {FMN_HZ} Hz)",
        flip.f_cmd_hz,
        REV_S + PULSE_S
    );
    // The command fell all the way while the request waited.
    let lowest = after
        .iter()
        .filter(|s| s.t_ns <= flip.t_ns)
        .map(|s| s.f_cmd_hz)
        .fold(f64::INFINITY, f64::min);
    assert!(lowest < 1.0, "the command only fell to {lowest} Hz");
    let end = after.last().expect("samples");
    assert!(
        end.pwm_on && end.dir == -1 && end.f_cmd_hz > FMN_HZ && end.speed_rpm < 0.0,
        "not running reversed at {end_s:.1} s: {end:?}"
    );
}
