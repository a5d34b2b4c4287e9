//! The keypad in a scenario: typing the RUN key starts the program (then it does not start
//! at power-up), and the LCD shows what the firmware's editor draws.

use super::common::*;
use hil_sim::run::parse_program;
use hil_sim::scenario::Scenario;
use hil_sim::sim::{RunOptions, Simulation};

const SCENARIO: &str = r#"
[[event]]
at_s = 0.0
set = { A00 = 980, A01 = 500 }

[[event]]
at_s = 0.1
press = "D00"

[[event]]
at_s = 1.0
keys = "A"
"#;

#[test]
fn the_run_key_starts_the_program() {
    let p = parse_program(MOTOR_PLC, "motor.plc").unwrap();
    let scen = Scenario::parse(SCENARIO).unwrap();
    assert!(scen.keys_start_run);
    let mut sim = Simulation::new(&p, scen, RunOptions::default()).unwrap();
    let mut samples = Vec::new();
    sim.run_until(900_000_000, |s| samples.push(s.clone()));
    // Not running: no scan output, no setpoint, the listing is on the LCD.
    assert!(!sim.plc().running());
    assert!(samples.iter().all(|s| s.lcd == [None; 4] && s.q[2] == 0));
    assert!(
        sim.plc().lcd().row(0).contains("000 PWF"),
        "{}",
        sim.plc().lcd().framed()
    );
    sim.run_until(3_000_000_000, |s| samples.push(s.clone()));
    assert!(sim.plc().running());
    // RUN started after the key; D00 was pressed before RUN, so the motor is not started
    // (no rising edge is seen on the first scan), but the LCD fields are live.
    let last = samples.last().unwrap();
    assert_eq!(last.lcd, [Some(500), Some(9800), None, None]);
    assert_eq!(last.q[2], 0);
    assert!(
        sim.plc().lcd().row(0).starts_with("RUN"),
        "{}",
        sim.plc().lcd().framed()
    );
}

#[test]
fn without_the_run_key_run_starts_at_power_up() {
    let r = run_text(MOTOR_PLC, "[[event]]\nat_s = 0.5\nkeys = \"B\"\n", 1.0);
    assert!(r.plc_running);
    // The 5th sample (4 ms) already has the program's LCD fields (A01 = 0, A00 x 10 = 0).
    assert!(r
        .samples
        .iter()
        .any(|s| s.lcd == [Some(0), Some(0), None, None]));
}
