//! The seeded fault campaign (`hil-sim campaign`, docs/campaign.md): a seed is a
//! reproduction, the observation sees the gates, and a fault the firmware must answer
//! goes through the runner to the drive.

use hil_sim::campaign::faults::{Baseline, Fault, FaultKind};
use hil_sim::campaign::invariants::{self, check_all};
use hil_sim::campaign::observe::Observation;
use hil_sim::campaign::world::{World, WorldOptions, TEMPLATES};
use hil_sim::campaign::{run_seed, runner};
use hil_sim::plant::{GateCommand, Leg};
use hil_sim::scenario::Scenario;
use hil_sim::sim::{RunOptions, Simulation};

/// The motor template (motor.plc on motor.toml: START at 0.5 s) with `faults`.
fn motor_world(faults: Vec<Fault>, duration_ns: u64) -> World {
    let t = TEMPLATES.iter().find(|t| t.name == "motor").unwrap();
    let scenario = Scenario::parse(t.scenario).unwrap();
    World {
        seed: 1,
        template: t,
        program: hil_sim::run::parse_program(t.program, t.name).unwrap(),
        baseline: Baseline {
            supply_v: scenario.rig.supply_v,
            bit_error_rate: 0.0,
        },
        scenario,
        duration_ns,
        faults,
        summary: String::new(),
    }
}

#[test]
fn a_seed_gives_the_same_run_twice() {
    let o = WorldOptions {
        duration_ns: 1_000_000_000,
        ..WorldOptions::default()
    };
    for seed in [3, 11] {
        let a = run_seed(seed, &o, false).unwrap();
        let b = run_seed(seed, &o, false).unwrap();
        assert_eq!(
            (a.sim_ns, a.outputs_on_ns, &a.trips, a.injected_by_class),
            (b.sim_ns, b.outputs_on_ns, &b.trips, b.injected_by_class)
        );
        assert_eq!(a.failure.is_some(), b.failure.is_some());
    }
}

#[test]
fn the_observation_sees_the_gates_the_plant_is_given() {
    let w = motor_world(Vec::new(), 0);
    let mut sim = Simulation::new(&w.program, w.scenario.clone(), RunOptions::default()).unwrap();
    sim.run_until(10_000_000, |_| {});
    let mut inv = invariants::all();
    assert_eq!(check_all(&mut inv, &Observation::of(&sim)), None);
    // A gate command with no dead time (what no firmware path writes): both switches of
    // a leg together at every edge.
    sim.plant_mut().set_command(GateCommand {
        legs: [Leg::Duty(0.5); 3],
        dead_time_ns: 0,
    });
    let v = check_all(&mut inv, &Observation::of(&sim)).unwrap();
    assert_eq!(v.invariant, "leg_interlock", "{v:?}");
}

#[test]
fn a_sub_period_sto_pulse_while_running_latches_code_9_and_breaks_nothing() {
    // safety.md 6: a low pulse of any width that reaches the break input latches code 9.
    let pulse = Fault {
        at_ns: 2_000_000_000,
        kind: FaultKind::StoPulse { width_ns: 300_000 },
    };
    let w = motor_world(vec![pulse], 2_500_000_000);
    let out = runner::run(&w, &w.faults);
    assert_eq!(out.violation, None);
    assert_eq!(out.injected, 1);
    assert_eq!(out.trips, [9], "the pulse latched STO (code 9)");
    assert!(
        out.outputs_on_ns > 1_000_000_000,
        "the motor ran before the pulse: {} ns",
        out.outputs_on_ns
    );
}
