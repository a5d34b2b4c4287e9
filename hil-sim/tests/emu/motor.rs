//! The source's motor example on the real images agrees with `hil-sim run`.

use hil_sim::run::{parse_program, run};
use hil_sim::scenario::Scenario;
use hil_sim::sim::{RunOptions, Sample};

use crate::common::{emu, ns, MOTOR_PLC, MOTOR_TOML};

#[test]
fn motor_example_matches_the_simulation_of_the_cores() {
    let program = parse_program(MOTOR_PLC, "motor.plc").expect("assembles");
    let reference = run(
        &program,
        Scenario::parse(MOTOR_TOML).expect("scenario"),
        3.0,
        RunOptions::default(),
        hil_sim::decimate::KeepSamples::All,
        |_| {},
        |_| {},
    )
    .expect("hil-sim run");
    let mut emulated: Vec<Sample> = Vec::new();
    let mut sim = emu(MOTOR_PLC, MOTOR_TOML);
    sim.run_until(ns(3.0), |s| emulated.push(s.clone()));
    let at = |v: &[Sample], t: f64| {
        let t_ns = ns(t);
        v.iter().find(|s| s.t_ns >= t_ns).cloned().expect("sample")
    };
    // START at 0.5 s (debounced): the real drive switches, at the frequency the simulated
    // cores give, and the motor follows, within 5 %.
    for t in [1.0, 1.5, 2.0, 2.5, 3.0] {
        let (r, e) = (at(&reference.samples, t), at(&emulated, t));
        assert!(
            e.pwm_on && r.pwm_on,
            "{t} s: PWM on? emu {} run {}",
            e.pwm_on,
            r.pwm_on
        );
        let f_err = (e.f_cmd_hz - r.f_cmd_hz).abs() / r.f_cmd_hz;
        let n_err = (e.speed_rpm - r.speed_rpm).abs() / r.speed_rpm;
        assert!(
            f_err < 0.05 && n_err < 0.05,
            "{t} s: f {} vs {} Hz, speed {} vs {} rpm",
            e.f_cmd_hz,
            r.f_cmd_hz,
            e.speed_rpm,
            r.speed_rpm
        );
    }
    assert!(sim.faults().is_empty(), "{:?}", sim.faults());
}
