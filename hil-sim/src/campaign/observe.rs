//! What the invariants see at one simulation step: a copy of the observable state, so
//! that the invariants can be tested on hand-made traces without a simulation.

use shared_protocol::drive_state::DriveState;

use crate::plant::Leg;
use crate::sim::Simulation;

/// The lift's part of an observation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LiftView {
    pub car_mm: f64,
    pub car_mms: f64,
    /// Door position, 0 closed .. 1 open (lift.md 4.3).
    pub door: f64,
    pub limit_low_mm: f64,
    pub limit_high_mm: f64,
}

/// The rig at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Observation {
    pub t_ns: u64,
    /// The gates drive at least one leg (MOE set, no break holding the legs open).
    pub outputs_on: bool,
    /// Legs the gate command drives.
    pub legs_driven: [bool; 3],
    /// The dead time the gate command inserts, ns.
    pub dead_time_ns: u64,
    /// CCR1-3 in effect and ARR, timer counts.
    pub compares: [u16; 3],
    pub arr: u16,
    /// The PWM period running, ns.
    pub pwm_period_ns: u64,
    /// A break (a comparator or `STO_IN`) has opened the legs and software has not set
    /// MOE again.
    pub hw_break: bool,
    /// A comparator is high (break 2 active).
    pub comparator_high: bool,
    /// `STO_IN` is low (break 1 active).
    pub sto_in_low: bool,
    pub drive_state: DriveState,
    /// The drive's latched fault code (0: none).
    pub drive_fault: u8,
    /// The PLC is in RUN.
    pub plc_running: bool,
    pub lift: Option<LiftView>,
}

impl Default for Observation {
    /// Everything off and quiet at t = 0 (tests start from it).
    fn default() -> Self {
        Observation {
            t_ns: 0,
            outputs_on: false,
            legs_driven: [false; 3],
            dead_time_ns: 0,
            compares: [0; 3],
            arr: 1000,
            pwm_period_ns: 100_000,
            hw_break: false,
            comparator_high: false,
            sto_in_low: false,
            drive_state: DriveState::Idle,
            drive_fault: 0,
            plc_running: false,
            lift: None,
        }
    }
}

impl Observation {
    pub fn of(sim: &Simulation) -> Self {
        let plant = sim.plant();
        let gate = plant.gate_command();
        let legs_driven = gate.legs.map(|l| matches!(l, Leg::Duty(_)));
        let status = sim.drive().status();
        let lift = sim.lift().map(|l| {
            let s = l.sample();
            LiftView {
                car_mm: s.car_mm,
                car_mms: s.car_mms,
                door: s.door,
                limit_low_mm: l.params().limit_low_mm,
                limit_high_mm: l.params().limit_high_mm(),
            }
        });
        Observation {
            t_ns: sim.now_ns(),
            outputs_on: legs_driven.iter().any(|d| *d) && !plant.hw_break(),
            legs_driven,
            dead_time_ns: gate.dead_time_ns,
            compares: sim.tim1().compares(),
            arr: sim.tim1().timing().arr,
            pwm_period_ns: plant.period_ns(),
            hw_break: plant.hw_break(),
            comparator_high: plant.break_input_active(),
            sto_in_low: plant.sto_in_low(),
            drive_state: status.state,
            drive_fault: status.fault.map_or(0, |f| f.code()),
            plc_running: sim.plc().running(),
            lift,
        }
    }
}
