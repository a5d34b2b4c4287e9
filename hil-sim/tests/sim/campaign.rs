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

/// The PLC's supply fails inside a keypad save (`C` `2`, the digit at 1.0 s) at several
/// bytes of it, between and inside page writes: the PLC restarts, slot 2 loads empty or
/// with the program (`storage_decodes`), and nothing else breaks.
#[test]
fn a_power_cut_inside_a_keypad_save_leaves_the_slot_old_or_new() {
    use firmware_plc::storage::Job;
    use firmware_plc::storage::{MemEeprom, Storage};
    use hil_sim::campaign::faults::KEY_HOLD_NS;
    let program = motor_world(Vec::new(), 0).program;
    let mut s = Storage::new(MemEeprom::new());
    s.save(2, &program).unwrap();
    let full = s.eeprom().bytes_written();
    for at_byte in [0, 63, 64, full / 2, full - 1] {
        let at_ns = 1_000_000_000;
        let mut w = motor_world(
            vec![Fault {
                at_ns,
                kind: FaultKind::CutInSave { slot: 2, at_byte },
            }],
            1_300_000_000,
        );
        w.scenario
            .actions
            .extend(hil_sim::campaign::world::save_keys(
                2,
                at_ns - 2 * KEY_HOLD_NS,
            ));
        w.scenario.actions.sort_by_key(|a| a.at_ns);
        let out = runner::run(&w, &w.faults);
        assert_eq!(out.violation, None, "cut at byte {at_byte}");
        assert_eq!(
            out.write_cuts,
            [Some(Job::Save { slot: 2 })],
            "cut at byte {at_byte}"
        );
        assert!(out.checks.storage_after_cut >= 1);
    }
}

/// An STO pulse trips the running drive (code 9); the PLC's supply fails inside the log
/// entry's page write: the torn entry may be lost (it was in flight), nothing is logged
/// twice, the storage decodes.
#[test]
fn a_power_cut_inside_the_log_write_of_a_trip_loses_at_most_that_entry() {
    use firmware_plc::storage::Job;
    for at_byte in [0, 7, 15] {
        let w = motor_world(
            vec![Fault {
                at_ns: 1_000_000_000,
                kind: FaultKind::CutInLog {
                    sto_width_ns: 5_000_000,
                    at_byte,
                },
            }],
            1_300_000_000,
        );
        let out = runner::run(&w, &w.faults);
        assert_eq!(out.violation, None, "cut at byte {at_byte}");
        assert!(out.trips.contains(&9), "{:?}", out.trips);
        assert!(
            matches!(out.write_cuts.as_slice(), [Some(Job::LogFault(e))] if e.code == 9),
            "{:?}",
            out.write_cuts
        );
    }
}

/// Seed 6618 of the 10 000-seed run (`--duration 3 --max-faults 6`): a power cut inside a
/// keypad save came in the event in which the running PLC wrote Q02 = 70 and sent it.
/// `command_fresh` read the PLC's Q after the cut had restarted it (Q02 = 0) and called
/// the 70 the drive then applied corrupted. The Qs are read before a cut can restart the
/// PLC; the world runs its 3 s through the save's cut without a violation.
#[test]
fn a_q_write_sent_just_before_a_cut_in_a_save_is_part_of_the_plcs_history() {
    let o = WorldOptions {
        duration_ns: 3_000_000_000,
        max_faults: 6,
        ..WorldOptions::default()
    };
    let r = run_seed(6618, &o, false).unwrap();
    assert!(r.failure.is_none(), "{:?}", r.failure.map(|f| f.violation));
    assert_eq!(r.sim_ns, 3_000_000_000);
    assert_eq!(r.write_cuts.iter().sum::<u64>(), 1, "the save was cut");
    assert!(r.checks.q_applied > 0, "the drive applied the PLC's writes");
}
