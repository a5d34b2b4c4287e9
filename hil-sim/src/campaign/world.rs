//! A seed's world: a shipped program with a shipped scenario as its base (the inputs that
//! start it), a plant drawn within physical ranges, user actions and faults at random
//! times. Everything comes from the seed through [`Rng`], so `--first S --seeds 1` builds
//! the same world on any machine.

use anyhow::{Context, Result};
use shared_protocol::program::Program;

use firmware_plc::storage::layout::FAULT_ENTRY_BYTES;
use firmware_plc::storage::{MemEeprom, Storage, PAGE_BYTES, SLOTS};

use super::faults::{Baseline, Fault, FaultKind, KEY_HOLD_NS};
use super::rng::Rng;
use crate::plant::Load;
use crate::scenario::{Action, Input, Scenario, TimedAction, KEY_HOLD_S, RUN_KEY};

/// A base world: a shipped program and the scenario that runs it.
pub struct Template {
    pub name: &'static str,
    pub program: &'static str,
    pub scenario: &'static str,
    /// Digital inputs the user may toggle (the lift drives D10-D15 itself).
    pub digital: &'static [u8],
    /// Analog inputs (pots) the user may turn.
    pub analog: &'static [u8],
}

macro_rules! program {
    ($f:literal) => {
        include_str!(concat!("../../../shared-protocol/programs/", $f))
    };
}
macro_rules! scenario {
    ($f:literal) => {
        include_str!(concat!("../../scenarios/", $f))
    };
}

const ALL_D: &[u8] = &[0, 1, 2, 3, 4, 5, 6, 7, 8, 9];
const ALL_A: &[u8] = &[0, 1, 2, 3];

/// The shipped examples, the lift and the safety lab (docs/campaign.md "Worlds").
pub const TEMPLATES: &[Template] = &[
    Template {
        name: "motor",
        program: program!("motor.plc"),
        scenario: scenario!("motor.toml"),
        digital: ALL_D,
        analog: ALL_A,
    },
    Template {
        name: "regen_brake",
        program: program!("motor.plc"),
        scenario: scenario!("regen_brake.toml"),
        digital: ALL_D,
        analog: ALL_A,
    },
    Template {
        name: "lab_5_1_runup",
        program: program!("lab_5_1_runup.plc"),
        scenario: scenario!("lab_5_1_runup.toml"),
        digital: ALL_D,
        analog: ALL_A,
    },
    Template {
        name: "pi_ramp",
        program: program!("pi_ramp.plc"),
        scenario: scenario!("pi_ramp.toml"),
        digital: ALL_D,
        analog: ALL_A,
    },
    Template {
        name: "three_phase_sine",
        program: program!("three_phase_sine.plc"),
        scenario: scenario!("three_phase_sine.toml"),
        digital: ALL_D,
        analog: ALL_A,
    },
    Template {
        name: "lift",
        program: program!("lift.plc"),
        scenario: scenario!("lift/l2_call_up.toml"),
        digital: ALL_D,
        analog: &[],
    },
    Template {
        name: "safety_lab_sto_in",
        program: program!("safety_lab.plc"),
        scenario: scenario!("safety/sto_in.toml"),
        digital: ALL_D,
        analog: &[0, 1],
    },
    Template {
        name: "safety_lab_ss1",
        program: program!("safety_lab.plc"),
        scenario: scenario!("safety/ss1_lab.toml"),
        digital: ALL_D,
        analog: &[0, 1],
    },
];

/// The campaign's settings of every world.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WorldOptions {
    /// Simulated time of each world, ns.
    pub duration_ns: u64,
    /// At most this many faults per world (at least one).
    pub max_faults: u32,
    /// At most this many user actions per world.
    pub max_actions: u32,
}

impl Default for WorldOptions {
    fn default() -> Self {
        WorldOptions {
            duration_ns: 2_000_000_000,
            max_faults: 6,
            max_actions: 6,
        }
    }
}

/// One generated world.
pub struct World {
    pub seed: u64,
    pub template: &'static Template,
    pub program: Program,
    pub scenario: Scenario,
    pub duration_ns: u64,
    pub baseline: Baseline,
    /// In time order.
    pub faults: Vec<Fault>,
    /// What the seed drew besides the faults, for the report.
    pub summary: String,
}

/// The boot record's bytes (`firmware-plc/src/storage/boot.rs`, `RECORD_BYTES`;
/// docs/eeprom-image.md).
pub const BOOT_RECORD_BYTES: usize = 18;

/// Faults start no earlier than this: the drive has booted and the program runs.
const FIRST_FAULT_NS: u64 = 100_000_000;

impl World {
    pub fn generate(seed: u64, opts: &WorldOptions) -> Result<World> {
        let mut rng = Rng::new(seed);
        let template = rng.pick(TEMPLATES).context("no templates")?;
        let program = crate::run::parse_program(template.program, template.name)?;
        let mut scenario = Scenario::parse(template.scenario)
            .with_context(|| format!("template {}", template.name))?;
        let dur = opts.duration_ns.max(FIRST_FAULT_NS + 1);

        // The plant within physical ranges (scenario::physics): the supply +-10 %, and a
        // motor's inertia and load torque (the lift brings its own mechanics, the RL load
        // has none).
        scenario.rig.supply_v *= rng.uniform(0.9, 1.1);
        let motor = scenario.lift.is_none() && matches!(scenario.rig.load, Load::Motor);
        if motor {
            scenario.rig.motor.inertia_kgm2 *= rng.uniform(0.7, 2.0);
            if rng.chance(0.5) {
                scenario.rig.motor.load_torque_nm += rng.uniform(0.0, 0.1);
            }
        }
        let baseline = Baseline {
            supply_v: scenario.rig.supply_v,
            bit_error_rate: scenario.bit_error_rate,
        };

        let actions = user_actions(&mut rng, template, opts, dur);
        let n_actions = actions.len();
        scenario.actions.extend(actions);
        scenario.actions.sort_by_key(|a| a.at_ns);

        let save_bytes = save_bytes(&program);
        let n = rng.range(1, u64::from(opts.max_faults.max(1)) + 1);
        let mut faults: Vec<Fault> = (0..n)
            .map(|_| Fault {
                at_ns: rng.range(FIRST_FAULT_NS, dur),
                kind: fault_kind(&mut rng, save_bytes),
            })
            .collect();
        faults.sort_by_key(|f| f.at_ns);
        // A cut in a save: the user types `C` `n`, the cut is armed as the digit goes down.
        for f in &faults {
            if let FaultKind::CutInSave { slot, .. } = f.kind {
                let at = f.at_ns.saturating_sub(2 * KEY_HOLD_NS);
                scenario.actions.extend(save_keys(slot, at));
            }
        }
        scenario.actions.sort_by_key(|a| a.at_ns);
        let summary = format!(
            "template {}, supply {:.2} V, inertia {:.2e} kg m2, load {:.3} N m, {n_actions} user actions",
            template.name,
            scenario.rig.supply_v,
            scenario.rig.motor.inertia_kgm2,
            scenario.rig.motor.load_torque_nm
        );
        Ok(World {
            seed,
            template,
            program,
            scenario,
            duration_ns: dur,
            baseline,
            faults,
            summary,
        })
    }
}

/// Inputs toggled, pots turned, RUN/STOP, saves and ACK typed, at random times.
fn user_actions(rng: &mut Rng, t: &Template, opts: &WorldOptions, dur: u64) -> Vec<TimedAction> {
    let key_ns = (KEY_HOLD_S * 1e9) as u64;
    let mut out = Vec::new();
    let n = rng.range(0, u64::from(opts.max_actions) + 1);
    for _ in 0..n {
        let at_ns = rng.range(0, dur);
        let key = |c: char, at_ns: u64, out: &mut Vec<TimedAction>| {
            out.push(TimedAction {
                at_ns,
                action: Action::KeyDown(c),
            });
            out.push(TimedAction {
                at_ns: at_ns + key_ns,
                action: Action::KeyUp(c),
            });
        };
        match rng.range(0, 5) {
            0 => {
                if let Some(&d) = rng.pick(t.digital) {
                    let v = rng.range(0, 2) as u16;
                    out.push(TimedAction {
                        at_ns,
                        action: Action::Set(Input::Digital(d), v),
                    });
                }
            }
            1 => {
                if let Some(&a) = rng.pick(t.analog) {
                    let v = rng.range(0, 1024) as u16;
                    out.push(TimedAction {
                        at_ns,
                        action: Action::Set(Input::Analog(a), v),
                    });
                }
            }
            2 => key(RUN_KEY, at_ns, &mut out),
            3 => out.extend(save_keys(rng.range(1, 5) as u8, at_ns)),
            _ => {
                // ACK from the keypad (`*` `9`, firmware-plc/docs/keymap.md).
                key('*', at_ns, &mut out);
                key('9', at_ns + 2 * key_ns, &mut out);
            }
        }
    }
    out
}

/// A keypad save into `slot` (`C` `n`, firmware-plc/docs/keymap.md) from `at_ns`: the
/// digit goes down at `at_ns + 2 KEY_HOLD`.
pub fn save_keys(slot: u8, at_ns: u64) -> Vec<TimedAction> {
    let digit = char::from(b'0' + slot);
    let mut out = Vec::new();
    for (i, c) in ['C', digit].into_iter().enumerate() {
        let t = at_ns + 2 * i as u64 * KEY_HOLD_NS;
        out.push(TimedAction {
            at_ns: t,
            action: Action::KeyDown(c),
        });
        out.push(TimedAction {
            at_ns: t + KEY_HOLD_NS,
            action: Action::KeyUp(c),
        });
    }
    out
}

/// Bytes a save of `program` writes (both copies): what a cut in a save draws from.
fn save_bytes(program: &Program) -> u32 {
    let mut s = Storage::new(MemEeprom::new());
    match s.save(1, program) {
        Ok(_) => s.eeprom().bytes_written().max(1),
        Err(_) => 1,
    }
}

fn fault_kind(rng: &mut Rng, save_bytes: u32) -> FaultKind {
    let ms = |x: f64| (x * 1e6) as u64;
    let us = |x: f64| (x * 1e3) as u64;
    match rng.range(0, 17) {
        0 => FaultKind::LinkBitErrors {
            rate: rng.log_uniform(1e-5, 1e-2),
            for_ns: ms(rng.log_uniform(1.0, 500.0)),
        },
        1 => FaultKind::LinkBurst {
            to_drive: rng.chance(0.5),
            bytes: rng.range(1, 64) as u32,
        },
        2 => FaultKind::LinkCut {
            for_ns: ms(rng.log_uniform(0.1, 200.0)),
        },
        3 => FaultKind::CurrentSpike {
            phase: rng.range(0, 3) as usize,
            amps: if rng.chance(0.5) { 1.0 } else { -1.0 } * rng.uniform(1.0, 15.0),
            from_ns: us(rng.uniform(0.0, 120.0)),
            width_ns: us(rng.log_uniform(0.1, 5000.0)),
        },
        4 => FaultKind::UdcSpike {
            volts: rng.uniform(2.0, 30.0),
            from_ns: us(rng.uniform(0.0, 120.0)),
            width_ns: us(rng.log_uniform(0.1, 5000.0)),
        },
        5 => FaultKind::StoPulse {
            width_ns: us(rng.log_uniform(1.0, 50_000.0)),
        },
        6 => FaultKind::Supply {
            delta_v: -rng.uniform(1.0, 12.0),
            for_ns: ms(rng.log_uniform(1.0, 1000.0)),
        },
        7 => FaultKind::Supply {
            delta_v: rng.uniform(1.0, 10.0),
            for_ns: ms(rng.log_uniform(1.0, 1000.0)),
        },
        8 => FaultKind::LoadStep {
            nm: rng.uniform(0.0, 0.3),
        },
        9 => FaultKind::LockedRotor {
            for_ns: ms(rng.log_uniform(10.0, 1000.0)),
        },
        10 => FaultKind::DrivePowerCut,
        11 => FaultKind::PlcPowerCut,
        12 => FaultKind::CutInSave {
            slot: rng.range(1, u64::from(SLOTS) + 1) as u8,
            at_byte: rng.range(0, u64::from(save_bytes)) as u32,
        },
        13 => FaultKind::CutInLog {
            sto_width_ns: ms(rng.log_uniform(1.0, 20.0)),
            at_byte: rng.range(0, FAULT_ENTRY_BYTES as u64) as u32,
        },
        15 => FaultKind::DriveWatchdog,
        16 => FaultKind::EepromBusy {
            polls: rng.range(1, 6) as u32,
            for_ns: ms(rng.log_uniform(10.0, 2000.0)),
        },
        _ => FaultKind::CutInCounters {
            // A stop writes the boot record, then the counters record (one page).
            at_byte: rng.range(0, (BOOT_RECORD_BYTES + PAGE_BYTES) as u64) as u32,
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_template_parses() {
        for t in TEMPLATES {
            crate::run::parse_program(t.program, t.name).unwrap();
            Scenario::parse(t.scenario).unwrap();
        }
    }

    #[test]
    fn a_seed_gives_the_same_world_twice_and_seeds_differ() {
        let o = WorldOptions::default();
        let a = World::generate(42, &o).unwrap();
        let b = World::generate(42, &o).unwrap();
        assert_eq!(a.faults, b.faults);
        assert_eq!(a.summary, b.summary);
        assert_eq!(a.scenario.actions, b.scenario.actions);
        let c = World::generate(43, &o).unwrap();
        assert!(a.faults != c.faults || a.summary != c.summary);
        assert!(a.faults.iter().all(|f| f.at_ns < o.duration_ns));
    }
}
