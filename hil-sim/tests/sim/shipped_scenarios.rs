//! Every scenario shipped in `hil-sim/scenarios/` parses and does what its comment says.

use super::common::*;
use hil_sim::run::{parse_program, run};
use hil_sim::scenario::Scenario;
use hil_sim::sim::RunOptions;

fn run_file(name: &str, program: &str) -> Vec<u8> {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenarios")
        .join(name);
    let s = Scenario::load(&path).unwrap();
    let d = s.duration_s(None);
    let p = parse_program(program, name).unwrap();
    let r = run(
        &p,
        s,
        d,
        RunOptions::default(),
        hil_sim::decimate::KeepSamples::None,
        |_| {},
        |_| {},
    )
    .unwrap();
    r.faults.iter().map(|f| f.code).collect()
}

fn example(name: &str) -> String {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../shared-protocol/programs")
        .join(name);
    std::fs::read_to_string(path).unwrap()
}

#[test]
fn shipped_scenarios_behave_as_described() {
    let none = Vec::<u8>::new();
    let checks: &[(&str, String, Vec<u8>)] = &[
        ("motor.toml", MOTOR_PLC.to_string(), none.clone()),
        ("locked_rotor.toml", MOTOR_PLC.to_string(), vec![1]),
        ("link_cut.toml", MOTOR_PLC.to_string(), vec![5]),
        ("regen_brake.toml", MOTOR_PLC.to_string(), none.clone()),
        ("undervoltage.toml", MOTOR_PLC.to_string(), vec![4]),
        // The source's drive examples on the RL rig variant (tests/sim/examples_on_rig.rs).
        ("pi_ramp.toml", example("pi_ramp.plc"), none.clone()),
        (
            "three_phase_sine.toml",
            example("three_phase_sine.plc"),
            none.clone(),
        ),
        // The source's lab chapter (tests/sim/lab.rs).
        (
            "lab_5_1_runup.toml",
            example("lab_5_1_runup.plc"),
            none.clone(),
        ),
        ("lab_5_2_reversal.toml", MOTOR_PLC.to_string(), none.clone()),
        (
            "lab_5_3_rundown_runup.toml",
            example("lab_5_3_rundown_runup.plc"),
            none.clone(),
        ),
        (
            "lab_5_4_switching_9990hz.toml",
            example("lab_5_4_switching.plc"),
            none.clone(),
        ),
        (
            "lab_5_4_switching_5000hz.toml",
            example("lab_5_4_switching.plc"),
            none.clone(),
        ),
        (
            "lab_5_4_switching_2500hz.toml",
            example("lab_5_4_switching.plc"),
            none.clone(),
        ),
        (
            "lab_5_4_switching_1250hz.toml",
            example("lab_5_4_switching.plc"),
            none.clone(),
        ),
    ];
    for (scenario, program, faults) in checks {
        assert_eq!(&run_file(scenario, program), faults, "{scenario}");
    }
    // `scenarios/safety/` holds safety.md 13's scenarios, each checked by its own test in
    // `safety.rs`.
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios");
    assert_eq!(
        std::fs::read_dir(dir)
            .unwrap()
            .filter(|e| e.as_ref().unwrap().path().is_file())
            .count(),
        checks.len(),
        "a new scenario needs a check here"
    );
}
