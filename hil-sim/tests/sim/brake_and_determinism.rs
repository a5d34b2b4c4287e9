//! The brake chopper on a regenerative stop, and run-to-run determinism.

use super::common::*;
use hil_sim::record::{header, row};

/// A large inertia (6x the default) run up to 30 Hz, then stopped with START/STOP: the
/// ramp brakes it down and the energy comes back into the DC link.
fn regen_scenario(brake_resistor_ohm: f64) -> String {
    format!(
        r#"
[plant]
# The source's sensors and chopper (regen_brake.toml): the bare ESC1 has neither.
board = "source"
inertia_kgm2 = 0.003
brake_resistor_ohm = {brake_resistor_ohm}

[[event]]
at_s = 0.0
set = {{ A00 = 980, A01 = 300 }}

[[event]]
at_s = 0.2
press = "D00"

[[event]]
at_s = 10.0
press = "D00"
"#
    )
}

#[test]
fn brake_chopper_holds_the_dc_link_on_a_regenerative_stop() {
    let r = run_text(MOTOR_PLC, &regen_scenario(10.0), 16.0);
    assert!(r.faults.is_empty(), "{:?}", r.faults);
    let s = &r.samples;
    let braking: Vec<_> = s.iter().filter(|x| t_s(x) >= 10.0).collect();
    let u_max = braking.iter().map(|x| x.u_dc_v).fold(0.0, f64::max);
    // U> = 35 V with 1 V hysteresis: the chopper holds the link there, below the
    // hardware limit (40 V).
    assert!(u_max > 34.9 && u_max < 36.5, "u_dc max {u_max}");
    let on = braking.iter().filter(|x| x.brake).count();
    assert!(on > 10, "brake on in {on} samples");
    // Before the stop (motoring) the chopper never switched.
    assert!(s.iter().filter(|x| t_s(x) < 10.0).all(|x| !x.brake));
    // The brake switches only above 34 V (hysteresis band).
    assert!(braking.iter().filter(|x| x.brake).all(|x| x.u_dc_v > 33.9));
    // The motor did slow down.
    assert!(at(s, 15.9).speed_rpm < 0.3 * at(s, 9.9).speed_rpm);
}

#[test]
fn without_a_working_brake_resistor_the_same_stop_trips_ov_hw() {
    let r = run_text(MOTOR_PLC, &regen_scenario(1e6), 16.0);
    assert_eq!(
        r.faults.iter().map(|f| f.code).collect::<Vec<_>>(),
        vec![3],
        "{:?}",
        r.faults
    );
    let t = r.faults[0].t_ns as f64 * 1e-9;
    assert!(t > 10.0);
    assert!(r
        .samples
        .iter()
        .filter(|x| t_s(x) > t + 0.002)
        .all(|x| !x.pwm_on));
}

fn csv_bytes(scenario: &str, seed: u64) -> String {
    use hil_sim::run::{parse_program, run};
    use hil_sim::scenario::Scenario;
    use hil_sim::sim::RunOptions;
    let p = parse_program(MOTOR_PLC, "motor.plc").unwrap();
    let s = Scenario::parse(scenario).unwrap();
    let mut out = header();
    out.push('\n');
    run(
        &p,
        s,
        6.0,
        RunOptions {
            seed,
            sample_ns: 1_000_000,
        },
        hil_sim::decimate::KeepSamples::None,
        |x| {
            out.push_str(&row(x));
            out.push('\n');
        },
        |_| {},
    )
    .unwrap();
    out
}

#[test]
fn two_runs_give_identical_csv() {
    // With bit errors on the link, so the random stream is part of what must repeat.
    let scen = r#"
[plant]
pwm_mode = "switching"

[link]
bit_error_rate = 2e-4

[[event]]
at_s = 0.0
set = { A00 = 980, A01 = 400 }

[[event]]
at_s = 0.3
press = "D00"

[[event]]
at_s = 3.0
press = "D01"
"#;
    let a = csv_bytes(scen, 7);
    let b = csv_bytes(scen, 7);
    assert_eq!(a.lines().count(), 6002);
    assert!(a == b, "two runs differ");
}

/// The bare ESC1 (the default board: no chopper, `OV_HW` 28 V by default):
/// stopping from 50 Hz on a supply that cannot absorb energy (the rig's rectified 20 V
/// supply) with six times the rig's inertia. The overvoltage controller lengthens the
/// deceleration while the DC link is above its level (1 V above the supply): the
/// motor's losses alone take the energy, so the stop takes about 19 s instead of the
/// program's 5.4 s; the applied frequency ends at 0 Hz, the DC link stays below the
/// board's 25 V and `OV_HW`, and nothing trips.
#[test]
fn without_a_chopper_the_overvoltage_controller_stops_under_ov_hw() {
    let program = MOTOR_PLC.replace("015 U<  K10 0025", "015 U<  K10 0015");
    let scen = r#"
[plant]
dc_link_v = 20.0
inertia_kgm2 = 0.003

[[event]]
at_s = 0.0
set = { A00 = 980, A01 = 500 }

[[event]]
at_s = 0.3
press = "D00"

[[event]]
at_s = 7.0
press = "D00"
"#;
    let r = run_text(&program, scen, 30.0);
    let s = &r.samples;
    assert!(at(s, 6.99).f_cmd_hz > 45.0, "{}", at(s, 6.99).f_cmd_hz);
    let peak = s.iter().map(|x| x.u_dc_v).fold(0.0, f64::max);
    let last = s.last().expect("samples");
    assert!(
        r.faults.is_empty() && peak < 25.0 && last.f_cmd_hz == 0.0,
        "faults {:?}, DC link peak {peak:.2} V, f {} Hz at 30 s",
        r.faults,
        last.f_cmd_hz
    );
    // The controller acted: the DC link rose to its level (21 V) and the applied frequency
    // fell more slowly than the program's ramp (below fmn, 5 Hz, within 5.4 s of the
    // stop), and nothing switched a chopper.
    assert!(peak > 20.9, "DC link peak {peak:.2} V");
    assert!(at(s, 13.0).f_cmd_hz > 5.0, "{}", at(s, 13.0).f_cmd_hz);
    assert!(s.iter().all(|x| !x.brake));
}
