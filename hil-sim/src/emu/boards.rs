//! The glue between hil-sim's plant and the two emulated boards.
//!
//! The boards themselves are `g431_emu::boards` (built from the boards' documents: the
//! B-G431B-ESC1, the source's sensor carrier, the NUCLEO-G431RB). This module only turns
//! the plant's state into the physical quantities those models take (phase currents,
//! DC-link volts, the STO wire) and TIM1's gate state into the inverter's command, and
//! wires what the rig adds around the boards (the STO wire, the PLC's I/O):
//!
//! * [`DriveBoard`]: the drive board of the image's `DRIVE_BOARD_PROFILE` marker
//!   ([`image_board`]); TIM1's outputs drive hil-sim's inverter and motor ([`Rig`]). On the
//!   bare ESC1, PB5 enables the BEMF dividers (there is no brake chopper); on the source's
//!   carrier it is the chopper's gate.
//! * [`PlcBoard`]: a NUCLEO-G431RB with the PLC's inputs, outputs, analog inputs, the 4x4
//!   keypad matrix and, on I2C3 (PA8/PB5), the same 24C256 and PCF8574 + HD44780 LCD the
//!   simulator's panel uses, as device models.
//!
//! The pin tables here are the rig's wiring (the README's pin maps); the images configure
//! their side of it. An image that uses other pins finds nothing there, as on a real board.

use std::cell::RefCell;
use std::collections::BTreeSet;
use std::rc::Rc;

use g431_emu::boards::{
    b_g431b_esc1 as esc1, source_sensors, DriveBoardId, ExternalWire, NetLevel,
    PowerStageQuantities, VDDA_VOLTS,
};
use g431_emu::periph::comp::CompConfig;
use g431_emu::periph::gpio::{Drive, External, PinReader, Pull};
use g431_emu::periph::tim_adv::{GateState, PinDrive, TimEvent};
use g431_emu::soc::Board;
use g431_emu::time::{cycles_to_ns, ns_to_cycles, Cycles};

use crate::plant::{Comparators, GateCommand, Leg, Plant};
use crate::scenario::{BoardKind, Esc1Sense};

/// ADC reference of both boards.
pub const VREF: f64 = VDDA_VOLTS;

/// Full scale of the 12-bit ADC, counts (the scenario's `COM` is given in them).
const ADC_FULL_COUNTS: f64 = 4095.0;

/// `"PA1"` → (0, 1).
pub fn pin_id(name: &str) -> Option<(u8, u8)> {
    let b = name.as_bytes();
    if b.len() < 3 || b[0] != b'P' {
        return None;
    }
    let port = b[1].checked_sub(b'A')?;
    let n: u8 = name.get(2..)?.parse().ok()?;
    Some((port, n))
}

impl Esc1Sense {
    /// VINP volts at 0 A that the image assumes: 2048 counts after its PGA x16.
    const ASSUMED_VINP_ZERO_V: f64 = 2048.0 / ADC_FULL_COUNTS * VDDA_VOLTS / 16.0;
    /// VINP volts per ampere that the image assumes: -34.03 counts/A after its PGA x16.
    const ASSUMED_VINP_V_PER_A: f64 = -34.03 / ADC_FULL_COUNTS * VDDA_VOLTS / 16.0;
}

/// The power stage, the motor and the drive's analog signals, shared between the drive
/// board (called from inside the emulated MCU) and the co-simulation (samples, scenario).
pub struct Rig {
    pub plant: Plant,
    /// Time the plant has been advanced to.
    pub plant_ns: u64,
    /// The drive's auxiliary input (`COM`, PB12), 12-bit counts.
    pub aux_counts: u16,
    /// TIM1's gate state from the last update (for the record: duties, outputs on).
    pub gate: Option<GateState>,
    /// Disturbances of the sensed phase currents (switching spikes on a shunt): what the
    /// sense pins carry on top of the plant's current, not the motor's current.
    pub sense_spikes: Vec<SenseSpikeAt>,
    /// The drive board (from the image's marker).
    pub board: DriveBoardId,
    /// What the ESC1's amplifier pins carry (the documented network unless a test says).
    pub esc1_sense: Esc1Sense,
    /// The rig's STO wire at [`drive_pins::STO_IN`] (safety.md 6): driven high while STO is
    /// not requested.
    pub sto_wire: ExternalWire,
    /// How the image drives the CAN transceiver's SHDN (PC11), as last seen.
    pub can_shdn: Drive,
    /// The ESC1's BEMF dividers are switched on (PB5 high).
    pub bemf_dividers_on: bool,
    /// Times the STO wire and the CAN transceiver drove the STO net to opposite levels.
    pub sto_contentions: u64,
    /// Disturbances of the sensed DC-link voltage (what the divider's pin carries on top
    /// of the plant's DC link).
    pub udc_spikes: Vec<UdcSpikeAt>,
    /// When `Some`, every TIM1 gate event the board receives is copied here (the seeded
    /// campaign observes the gates at each of them, `campaign::emu`).
    pub tim_trace: Option<Vec<TimEvent>>,
}

/// A disturbance of one sensed phase current from `from_ns` to `to_ns` (emulated time).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SenseSpikeAt {
    /// Inverter leg 0..=2.
    pub phase: usize,
    pub amps: f64,
    pub from_ns: u64,
    pub to_ns: u64,
}

/// A disturbance of the sensed DC-link voltage from `from_ns` to `to_ns` (emulated time).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UdcSpikeAt {
    pub volts: f64,
    pub from_ns: u64,
    pub to_ns: u64,
}

impl Rig {
    /// The rig around `plant` with the drive board `board`. The plant's own comparator
    /// model is switched off: in the emulator the comparators are the emulated COMP/DAC
    /// registers (sampled by the SoC at every TIM1 event), and TIM1's break opens the
    /// switches.
    pub fn new(mut plant: Plant, board: DriveBoardId) -> Self {
        let profile = plant.comparators().board;
        plant.set_comparators(Comparators::off(profile));
        Rig {
            plant,
            plant_ns: 0,
            aux_counts: 0,
            gate: None,
            sense_spikes: Vec::new(),
            board,
            esc1_sense: Esc1Sense::default(),
            sto_wire: ExternalWire::DrivenHigh,
            can_shdn: Drive::Released { pull: Pull::None },
            bemf_dividers_on: false,
            sto_contentions: 0,
            udc_spikes: Vec::new(),
            tim_trace: None,
        }
    }

    /// The phase currents the sense pins carry at `ns`: the plant's plus any spike.
    pub fn sensed_currents(&self, ns: u64) -> [f64; 3] {
        let mut i = self.plant.outputs().i_abc_a;
        for s in &self.sense_spikes {
            if (s.from_ns..=s.to_ns).contains(&ns) {
                if let Some(x) = i.get_mut(s.phase) {
                    *x += s.amps;
                }
            }
        }
        i
    }

    /// The first cycle after `after` at which a sense spike starts or ends (the sensed
    /// current steps there; the plant's own current is continuous between TIM1's events).
    pub fn next_sense_step(&self, after: Cycles) -> Option<Cycles> {
        self.sense_spikes
            .iter()
            .map(|s| (s.from_ns, s.to_ns))
            .chain(self.udc_spikes.iter().map(|s| (s.from_ns, s.to_ns)))
            .flat_map(|(from, to)| [from, to.saturating_add(1)])
            .map(ns_to_cycles)
            .filter(|&c| c > after)
            .min()
    }

    /// What the board senses at `ns`.
    pub fn quantities(&self, ns: u64) -> PowerStageQuantities {
        PowerStageQuantities {
            phase_currents_a: self.sensed_currents(ns),
            dc_link_v: self.plant.outputs().u_dc_v
                + self
                    .udc_spikes
                    .iter()
                    .filter(|s| (s.from_ns..=s.to_ns).contains(&ns))
                    .map(|s| s.volts)
                    .sum::<f64>(),
        }
    }

    /// Volts on analog pin `pin` at `ns` (0 V for a pin the board leaves unconnected).
    pub fn pin_volts(&self, pin: &str, ns: u64) -> f64 {
        let q = self.quantities(ns);
        let aux = f64::from(self.aux_counts) / ADC_FULL_COUNTS;
        let v = match self.board {
            DriveBoardId::Esc1 => match self.esc1_sense {
                Esc1Sense::AsImageAssumes => {
                    assumed_esc1_pin_volts(pin, &q).or_else(|| esc1::pin_volts(pin, &q, aux))
                }
                Esc1Sense::Documented => esc1::pin_volts(pin, &q, aux),
            },
            DriveBoardId::SourceSensors => source_sensors::pin_volts(pin, &q, aux),
        };
        v.unwrap_or(0.0)
    }

    /// The level of the net the STO wire is brought to.
    pub fn sto_net(&self) -> NetLevel {
        if drive_pins::STO_IN == esc1::CAN_RX {
            // Both drive boards keep the ESC1's CAN transceiver on PA11 (where
            // STO_IN was).
            esc1::can_rx_net(self.can_shdn, Some(self.sto_wire))
        } else {
            NetLevel {
                level: match self.sto_wire {
                    ExternalWire::DrivenHigh => External::High,
                    ExternalWire::DrivenLow => External::Low,
                    ExternalWire::Open => External::Floating,
                },
                contention: false,
            }
        }
    }

    /// Advances the plant to `ns`.
    pub fn advance_to(&mut self, ns: u64) {
        if ns > self.plant_ns {
            self.plant.advance(ns - self.plant_ns);
            self.plant_ns = ns;
        }
    }

    /// The leg duties of the gate state in effect (0..1 each), `None` for a leg that is
    /// not switching.
    pub fn duties(&self) -> [Option<f64>; 3] {
        match self.gate {
            Some(g) if g.outputs_enabled => gate_command(&g).1.legs.map(|l| match l {
                Leg::Duty(d) => Some(d),
                Leg::Off => None,
            }),
            _ => [None; 3],
        }
    }
}

/// [`Esc1Sense::AsImageAssumes`]: the amplifier pins as the image assumes them.
fn assumed_esc1_pin_volts(pin: &str, q: &PowerStageQuantities) -> Option<f64> {
    for (s, &i) in esc1::SHUNTS.iter().zip(q.phase_currents_a.iter()) {
        if pin == s.vinp {
            let v = Esc1Sense::ASSUMED_VINP_ZERO_V + Esc1Sense::ASSUMED_VINP_V_PER_A * i;
            return Some(v.clamp(0.0, VDDA_VOLTS));
        }
        if pin == s.vinm0 {
            return Some(0.0);
        }
    }
    None
}

/// The inverter command a TIM1 gate state gives: (PWM period in ns, gate command).
///
/// Centre-aligned PWM mode 1 keeps OCxREF active while CNT < CCRx, on the way up and down,
/// so a leg's duty is CCRx / ARR (CCRx ≥ ARR: always on; 0: always off); PWM mode 2 is the
/// complement. OCx drives the high switch and OCxN the low one; a channel whose outputs are
/// not both following the reference (disabled, forced inactive) leaves its leg open.
pub fn gate_command(g: &GateState) -> (u64, GateCommand) {
    let counts = 2 * u64::from(g.arr.max(1));
    let period_ns = cycles_to_ns(counts * g.cycles_per_count.max(1));
    let dead_time_ns = cycles_to_ns(u64::from(g.dead_time_rising));
    let mut legs = [Leg::Off; 3];
    if g.outputs_enabled {
        for (leg, ch) in legs.iter_mut().zip(g.channels.iter()) {
            *leg = match (ch.high, ch.low) {
                (PinDrive::Ref { .. }, PinDrive::Ref { .. }) => {
                    let arr = f64::from(g.arr.max(1));
                    let on = (f64::from(ch.oc.ccr) / arr).clamp(0.0, 1.0);
                    match ch.oc.mode {
                        7 => Leg::Duty(1.0 - on),
                        6 => Leg::Duty(on),
                        // Forced active/inactive references.
                        5 => Leg::Duty(1.0),
                        4 => Leg::Duty(0.0),
                        _ => Leg::Duty(if ch.oc.held { 1.0 } else { 0.0 }),
                    }
                }
                (PinDrive::Forced(true), PinDrive::Forced(false)) => Leg::Duty(1.0),
                (PinDrive::Forced(false), PinDrive::Forced(true)) => Leg::Duty(0.0),
                _ => Leg::Off,
            };
        }
    }
    (period_ns, GateCommand { legs, dead_time_ns })
}

/// The drive board a drive image was built for, from its `DRIVE_BOARD_PROFILE` marker
/// (ids defined by the board layer, `g431_emu::boards::DriveBoardId`).
pub fn image_board(image: &g431_emu::elf::Image) -> Option<DriveBoardId> {
    DriveBoardId::from_marker(image.flash_symbol("DRIVE_BOARD_PROFILE")?)
}

/// The scenario's `[plant] board` for the emulated drive board `b`: the cores' scaling and
/// comparators that `hil-sim run` uses for that board.
pub fn board_kind(b: DriveBoardId) -> BoardKind {
    match b {
        DriveBoardId::Esc1 => BoardKind::Esc1,
        DriveBoardId::SourceSensors => BoardKind::Source,
    }
}

/// The drive board around the emulated drive MCU.
pub struct DriveBoard {
    rig: Rc<RefCell<Rig>>,
}

/// Drive pins the rig wires (README "Drive board"; the boards' own nets are in
/// `g431_emu::boards`).
pub mod drive_pins {
    /// The rig's STO wire (safety.md 6): brought to PA15 (`STO_IN` in the README's pin
    /// map), TIM1_BKIN and, on the ESC1, the `PWM` command pad
    /// (`g431_emu::boards::b_g431b_esc1::PWM_INPUT`; no longer PA11, the CAN
    /// transceiver's RX net).
    pub const STO_IN: (u8, u8) = (0, 15);
    /// The link's wires: TX and RX of the drive.
    pub const LINK_TX: &str = "PB6";
    pub const LINK_RX: &str = "PB7";
}

impl DriveBoard {
    pub fn new(rig: Rc<RefCell<Rig>>) -> Self {
        DriveBoard { rig }
    }
}

impl PinReader for DriveBoard {
    fn external(
        &mut self,
        port: u8,
        pin: u8,
        _: Cycles,
        drives: &dyn Fn(u8, u8) -> Drive,
    ) -> External {
        if (port, pin) == drive_pins::STO_IN {
            let mut rig = self.rig.borrow_mut();
            let (sp, sn) = esc1::CAN_SHDN;
            rig.can_shdn = drives(sp, sn);
            return rig.sto_net().level;
        }
        External::Floating
    }
}

impl Board for DriveBoard {
    fn outputs_changed(&mut self, now: Cycles, drives: &dyn Fn(u8, u8) -> Drive) {
        let mut rig = self.rig.borrow_mut();
        rig.advance_to(cycles_to_ns(now));
        let (sp, sn) = esc1::CAN_SHDN;
        rig.can_shdn = drives(sp, sn);
        match rig.board {
            DriveBoardId::Esc1 => {
                let (p, n) = esc1::BEMF_ENABLE;
                rig.bemf_dividers_on = drives(p, n) == Drive::High;
            }
            DriveBoardId::SourceSensors => {
                let (p, n) = source_sensors::BRAKE_GATE;
                let on = drives(p, n) == Drive::High;
                rig.plant.set_brake(on);
            }
        }
    }

    fn pin_volts(&mut self, pin: &str, at: Cycles) -> f64 {
        let mut rig = self.rig.borrow_mut();
        let ns = cycles_to_ns(at);
        rig.advance_to(ns);
        rig.pin_volts(pin, ns)
    }

    fn power_stage(&mut self, ev: &TimEvent) {
        let mut rig = self.rig.borrow_mut();
        if let Some(t) = rig.tim_trace.as_mut() {
            t.push(*ev);
        }
        match *ev {
            TimEvent::Update { at, gate } => {
                rig.advance_to(cycles_to_ns(at));
                rig.gate = Some(gate);
                let (period_ns, cmd) = gate_command(&gate);
                rig.plant.start_period(period_ns, cmd);
            }
            TimEvent::GateChanged { at, gate } => {
                rig.advance_to(cycles_to_ns(at));
                rig.gate = Some(gate);
                let (_, cmd) = gate_command(&gate);
                rig.plant.set_command(cmd);
            }
            TimEvent::OutputsOff { at, .. } => {
                rig.advance_to(cycles_to_ns(at));
                if let Some(g) = rig.gate.as_mut() {
                    g.outputs_enabled = false;
                }
                rig.plant.set_command(GateCommand::OFF);
            }
            TimEvent::OutputsOn { at } => {
                rig.advance_to(cycles_to_ns(at));
                // The image's TIM1 set MOE again: its break inputs are inactive (TIM1
                // refuses MOE otherwise), so the plant's latched break follows (review
                // E4): the record shows what the gates really do.
                rig.plant.release_break();
                if let Some(mut g) = rig.gate {
                    g.outputs_enabled = true;
                    g.moe = true;
                    rig.gate = Some(g);
                    let (_, cmd) = gate_command(&g);
                    rig.plant.set_command(cmd);
                }
            }
            _ => {}
        }
    }

    fn comparator_above(&mut self, cfg: &CompConfig, inm_volts: f64, at: Cycles) -> bool {
        self.pin_volts(cfg.inp, at) > inm_volts
    }

    fn next_input_change(&self, after: Cycles) -> Option<Cycles> {
        // Not borrowed while the SoC runs; a test holding the rig sees no steps.
        self.rig.try_borrow().ok()?.next_sense_step(after)
    }
}

/// The PLC board's I/O as the scenario and the panel set it.
#[derive(Debug, Clone, Default)]
pub struct PlcIo {
    /// D00..D15, bit n = Dn.
    pub digital_in: u16,
    /// A00..A03, 10-bit counts.
    pub analog: [u16; 4],
    /// Keys held down.
    pub keys_down: BTreeSet<char>,
    /// O00..O07 as the pins drive them, bit n = On.
    pub outputs: u8,
}

/// PLC pins (the README's "PLC board" pin map), as (port, pin) with port
/// 0 = A, 1 = B, 2 = C, 3 = D.
pub mod plc_pins {
    use shared_protocol::program::{DIGITAL_INPUTS, DIGITAL_OUTPUTS};

    /// Inputs D00..D15 (active high, the board's opto outputs drive them high when on).
    pub const INPUTS: [(u8, u8); DIGITAL_INPUTS as usize] = [
        (2, 6),  // D00 PC6
        (2, 7),  // D01 PC7
        (2, 8),  // D02 PC8
        (2, 9),  // D03 PC9
        (2, 10), // D04 PC10
        (2, 11), // D05 PC11
        (2, 12), // D06 PC12
        (3, 2),  // D07 PD2
        (0, 4),  // D08 PA4
        (0, 11), // D09 PA11
        (0, 12), // D10 PA12
        (0, 15), // D11 PA15
        (1, 1),  // D12 PB1
        (1, 2),  // D13 PB2
        (1, 4),  // D14 PB4
        (2, 0),  // D15 PC0
    ];
    /// Outputs O00..O07.
    pub const OUTPUTS: [(u8, u8); DIGITAL_OUTPUTS as usize] = [
        (1, 10), // O00 PB10
        (1, 11), // O01 PB11
        (1, 12), // O02 PB12
        (1, 13), // O03 PB13
        (1, 14), // O04 PB14
        (1, 15), // O05 PB15
        (1, 9),  // O06 PB9
        (1, 8),  // O07 PB8
    ];
    /// Analog A00..A03.
    pub const ANALOG: [&str; 4] = ["PA0", "PA1", "PB0", "PC1"];
    /// Keypad rows R0..R3 (driven low one at a time) and columns C0..C3.
    pub const ROWS: [(u8, u8); 4] = [(0, 6), (0, 7), (1, 6), (1, 7)];
    pub const COLS: [(u8, u8); 4] = [(2, 2), (2, 3), (2, 4), (2, 5)];
    /// The keypad's layout: `KEYS[row][col]`.
    pub const KEYS: [[char; 4]; 4] = [
        ['1', '2', '3', 'A'],
        ['4', '5', '6', 'B'],
        ['7', '8', '9', 'C'],
        ['*', '0', '#', 'D'],
    ];
    /// I2C3 SCL / SDA (24C256 at 0x50, PCF8574 at 0x27), pulled up on the modules.
    pub const I2C_SCL: (u8, u8) = (0, 8);
    pub const I2C_SDA: (u8, u8) = (1, 5);
    /// The link's wires: TX and RX of the PLC.
    pub const LINK_TX: &str = "PA9";
    pub const LINK_RX: &str = "PA10";
    /// The service port (LPUART1 on the ST-LINK's virtual COM port): TX and RX of the PLC.
    pub const SERVICE_TX: &str = "PA2";
    pub const SERVICE_RX: &str = "PA3";
}

/// The PLC board (NUCLEO-G431RB with the PLC's I/O).
pub struct PlcBoard {
    io: Rc<RefCell<PlcIo>>,
}

impl PlcBoard {
    pub fn new(io: Rc<RefCell<PlcIo>>) -> Self {
        PlcBoard { io }
    }
}

impl PinReader for PlcBoard {
    fn external(
        &mut self,
        port: u8,
        pin: u8,
        _now: Cycles,
        drives: &dyn Fn(u8, u8) -> Drive,
    ) -> External {
        let io = self.io.borrow();
        if let Some(k) = plc_pins::INPUTS.iter().position(|p| *p == (port, pin)) {
            // An opto output pulls the pin high when on and lets it go when off (the
            // image's pull-down then reads 0).
            return if io.digital_in & (1 << k) != 0 {
                External::High
            } else {
                External::Floating
            };
        }
        if let Some(c) = plc_pins::COLS.iter().position(|p| *p == (port, pin)) {
            // A closed key connects its column to its row; a row driven low pulls it low.
            for (r, &(rp, rn)) in plc_pins::ROWS.iter().enumerate() {
                let key = plc_pins::KEYS[r][c];
                if io.keys_down.contains(&key) && drives(rp, rn) == Drive::Low {
                    return External::Low;
                }
            }
            return External::Floating;
        }
        External::Floating
    }
}

impl Board for PlcBoard {
    fn lse_hz(&self) -> Option<u64> {
        Some(g431_emu::boards::nucleo_g431rb::LSE_HZ)
    }

    fn outputs_changed(&mut self, _now: Cycles, drives: &dyn Fn(u8, u8) -> Drive) {
        let mut out = 0u8;
        for (k, &(p, n)) in plc_pins::OUTPUTS.iter().enumerate() {
            if drives(p, n) == Drive::High {
                out |= 1 << k;
            }
        }
        self.io.borrow_mut().outputs = out;
    }

    fn pin_volts(&mut self, pin: &str, _at: Cycles) -> f64 {
        let io = self.io.borrow();
        match plc_pins::ANALOG.iter().position(|p| *p == pin) {
            Some(k) => f64::from(io.analog[k]) / 1023.0 * VREF,
            None => 0.0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plant::RigParams;

    fn rig(board: DriveBoardId) -> Rig {
        Rig::new(Plant::new(RigParams::default()), board)
    }

    #[test]
    fn each_emulated_drive_board_runs_the_cores_profile_of_its_kind() {
        assert_eq!(board_kind(DriveBoardId::Esc1), BoardKind::Esc1);
        assert_eq!(board_kind(DriveBoardId::SourceSensors), BoardKind::Source);
    }

    #[test]
    fn the_esc1_pins_carry_the_documented_network_unless_a_test_asks() {
        let mut r = rig(DriveBoardId::Esc1);
        // At rest both amplifier pins of a leg sit at the network's bias.
        let (p, m) = esc1::shunt_pins_volts(0.0);
        assert_eq!(r.pin_volts("PA1", 0), p);
        assert_eq!(r.pin_volts("PA3", 0), m);
        assert!(m > 1.0, "VINM0 carries the bias: {m} V");
        r.esc1_sense = Esc1Sense::AsImageAssumes;
        assert!((r.pin_volts("PA1", 0) - 0.1031).abs() < 0.001);
        assert_eq!(r.pin_volts("PA3", 0), 0.0);
        // The divider is the board's in both cases.
        let u = r.plant.outputs().u_dc_v;
        assert_eq!(r.pin_volts("PA0", 0), esc1::dc_link_pin_volts(u));
        assert_eq!(pin_id("PC13"), Some((2, 13)));
    }

    /// The STO wire is on PA15, the ESC1's `PWM` pad, with nothing of the board
    /// on its net: an open wire floats (the image's pull-down then reads STO requested),
    /// and the CAN transceiver (PA11) no longer meets it.
    #[test]
    fn the_sto_wire_is_alone_on_the_pwm_pad() {
        assert_eq!(drive_pins::STO_IN, esc1::PWM_INPUT);
        assert_ne!(drive_pins::STO_IN, esc1::CAN_RX);
        let mut r = rig(DriveBoardId::Esc1);
        r.sto_wire = ExternalWire::Open;
        assert_eq!(
            r.sto_net().level,
            External::Floating,
            "a broken wire floats"
        );
        r.sto_wire = ExternalWire::DrivenLow;
        let n = r.sto_net();
        assert_eq!((n.level, n.contention), (External::Low, false));
        r.sto_wire = ExternalWire::DrivenHigh;
        assert_eq!(r.sto_net().level, External::High);
    }
}
