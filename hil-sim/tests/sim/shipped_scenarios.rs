//! Every scenario shipped in `hil-sim/scenarios/` parses and does what its comment says.

use super::common::*;
use hil_sim::run::{parse_program, run};
use hil_sim::scenario::Scenario;
use hil_sim::sim::RunOptions;

fn run_file(name: &str) -> Vec<u8> {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenarios")
        .join(name);
    let s = Scenario::load(&path).unwrap();
    let d = s.duration_s(None);
    let p = parse_program(MOTOR_PLC, "motor.plc").unwrap();
    let r = run(&p, s, d, RunOptions::default(), false, |_| {}, |_| {}).unwrap();
    r.faults.iter().map(|f| f.code).collect()
}

#[test]
fn shipped_scenarios_behave_as_described() {
    assert_eq!(run_file("motor.toml"), Vec::<u8>::new());
    assert_eq!(run_file("locked_rotor.toml"), vec![1]);
    assert_eq!(run_file("link_cut.toml"), vec![5]);
    assert_eq!(run_file("regen_brake.toml"), Vec::<u8>::new());
    assert_eq!(run_file("undervoltage.toml"), vec![4]);
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios");
    assert_eq!(
        std::fs::read_dir(dir).unwrap().count(),
        5,
        "a new scenario needs a check here"
    );
}
