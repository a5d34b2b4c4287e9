//! The two boards around the emulated MCUs, wired as the README's pin maps say: what each
//! pin of the G431 sees (the rig's sensors, inputs, keypad, the I2C bus) and where each
//! output goes (the power stage, the brake chopper, the PLC's outputs).
//!
//! * [`DriveBoard`]: a B-G431B-ESC1 whose current and DC-link pins carry the voltages of
//!   the board profile the image was built for ([`image_board`]): the bare ESC1's shunt
//!   networks in front of the on-chip PGAs, or the source's sensors (±10 A and 0..45 V on
//!   0..3.3 V); TIM1's outputs drive hil-sim's inverter and motor ([`Rig`]), PB5 is the
//!   brake chopper's gate.
//! * [`PlcBoard`]: a NUCLEO-G431RB with the PLC's inputs, outputs, analog inputs, the 4x4
//!   keypad matrix and, on I2C3 (PA8/PB5), the same 24C256 and PCF8574 + HD44780 LCD the
//!   simulator's panel uses, as device models.
//!
//! The pin tables here are the physical wiring; the images configure their side of it.
//! An image that uses other pins finds nothing there, as on a real board.

use std::cell::RefCell;
use std::collections::BTreeSet;
use std::rc::Rc;

use g431_emu::periph::comp::CompConfig;
use g431_emu::periph::gpio::{Drive, External, PinReader};
use g431_emu::periph::tim_adv::{GateState, PinDrive, TimEvent};
use g431_emu::soc::Board;
use g431_emu::time::{cycles_to_ns, Cycles};

use firmware_drive::comparators::{BoardProfile, Signal};

use crate::plant::{sensors, Comparators, GateCommand, Leg, Plant};

/// ADC reference of both boards.
pub const VREF: f64 = 3.3;

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

impl Rig {
    /// The rig around `plant`. The plant's own comparator model is switched off: in the
    /// emulator the comparators are the emulated COMP/DAC registers (sampled by the SoC at
    /// every TIM1 event), and TIM1's break opens the switches.
    pub fn new(mut plant: Plant) -> Self {
        let board = plant.comparators().board;
        plant.set_comparators(Comparators {
            board,
            dacs: firmware_drive::comparators::DacValues::default(),
        });
        Rig {
            plant,
            plant_ns: 0,
            aux_counts: 0,
            gate: None,
            sense_spikes: Vec::new(),
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

/// Volts on the sense pin of `signal` for a phase current of `i_a` on a board with the
/// front end of `profile`: the ADC-scale voltage of the profile's scaling
/// (`plant::sensors`), divided by the gain of the on-chip amplifier that follows the pin
/// (the ESC1's PGA x16: about 0.103 V at 0 A, falling 1.71 mV/A).
pub fn current_volts(profile: &BoardProfile, signal: Signal, i_a: f64) -> f64 {
    let counts = sensors::current_signal_counts(&profile.scaling, i_a);
    let adc_volts = counts / f64::from(sensors::ADC_MAX) * VREF;
    (adc_volts / f64::from(profile.front_end.gain_of(signal))).clamp(0.0, VREF)
}

/// The phase current a sense-pin voltage stands for (inverse of [`current_volts`]).
pub fn volts_current(profile: &BoardProfile, signal: Signal, v: f64) -> f64 {
    let sc = &profile.scaling;
    let adc_volts = v * f64::from(profile.front_end.gain_of(signal));
    let counts = adc_volts / VREF * f64::from(sensors::ADC_MAX);
    (counts - f64::from(sc.current_zero_counts)) * 1000.0
        / f64::from(sc.current_millicounts_per_amp)
}

/// Volts on the DC-link pin.
pub fn udc_volts(profile: &BoardProfile, u: f64) -> f64 {
    (sensors::udc_signal_counts(&profile.scaling, u) / f64::from(sensors::ADC_MAX) * VREF)
        .clamp(0.0, VREF)
}

/// The board profile a drive image was built for, from its `DRIVE_BOARD_PROFILE` marker
/// (`firmware_drive::config::IMAGE_BOARD`): the emulated board must put that profile's
/// voltages on the pins.
pub fn image_board(image: &g431_emu::elf::Image) -> Option<&'static BoardProfile> {
    let marker = image.flash_symbol("DRIVE_BOARD_PROFILE")?;
    [
        &firmware_drive::comparators::B_G431B_ESC1,
        &firmware_drive::comparators::SOURCE_SENSORS,
    ]
    .into_iter()
    .find(|p| p.key_bytes().as_slice() == marker)
}

/// The drive board: a B-G431B-ESC1 whose sense pins carry the voltages of the rig's board
/// profile (the plant's `RigParams::board`, which `EmuSim` sets from the image's marker).
pub struct DriveBoard {
    rig: Rc<RefCell<Rig>>,
}

/// Drive pins (README "Drive board").
pub mod drive_pins {
    pub const CURRENT_A: &str = "PA1";
    pub const CURRENT_B: &str = "PA7";
    /// Phase W's shunt (the ESC1's third current sense, COMP4's input).
    pub const CURRENT_C: &str = "PB0";
    pub const DC_LINK: &str = "PA0";
    pub const AUX: &str = "PB12";
    /// Brake chopper gate (GPIO out, active high).
    pub const BRAKE: (u8, u8) = (1, 5);
    /// The hardware STO input (safety.md 6): PA11 = TIM1_BKIN2.
    pub const STO_IN: (u8, u8) = (0, 11);
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
    fn external(&mut self, port: u8, pin: u8, _: Cycles, _: &dyn Fn(u8, u8) -> Drive) -> External {
        // STO_IN (PA11): driven high while not requested; low (or a broken wire, read
        // low through the image's pull-down) requests STO.
        if (port, pin) == drive_pins::STO_IN {
            return if self.rig.borrow().plant.sto_in_low() {
                External::Low
            } else {
                External::High
            };
        }
        External::Floating
    }
}

impl Board for DriveBoard {
    fn outputs_changed(&mut self, now: Cycles, drives: &dyn Fn(u8, u8) -> Drive) {
        let (port, pin) = drive_pins::BRAKE;
        let on = drives(port, pin) == Drive::High;
        let mut rig = self.rig.borrow_mut();
        rig.advance_to(cycles_to_ns(now));
        rig.plant.set_brake(on);
    }

    fn pin_volts(&mut self, pin: &str, at: Cycles) -> f64 {
        let mut rig = self.rig.borrow_mut();
        rig.advance_to(cycles_to_ns(at));
        let o = rig.plant.outputs();
        let i = rig.sensed_currents(cycles_to_ns(at));
        let p = rig.plant.params().board;
        match pin {
            drive_pins::CURRENT_A => current_volts(p, Signal::CurrentA, i[0]),
            drive_pins::CURRENT_B => current_volts(p, Signal::CurrentB, i[1]),
            drive_pins::CURRENT_C => current_volts(p, Signal::CurrentC, i[2]),
            drive_pins::DC_LINK => udc_volts(p, o.u_dc_v),
            drive_pins::AUX => f64::from(rig.aux_counts) / f64::from(sensors::ADC_MAX) * VREF,
            _ => 0.0,
        }
    }

    fn power_stage(&mut self, ev: &TimEvent) {
        let mut rig = self.rig.borrow_mut();
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

/// PLC pins (README "PLC board", `firmware-plc/src/pins.rs`), as (port, pin) with port
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

    #[test]
    fn current_scaling_matches_the_plants_sensor() {
        use firmware_drive::comparators::{B_G431B_ESC1, SOURCE_SENSORS};
        for p in [&SOURCE_SENSORS, &B_G431B_ESC1] {
            let gain = f64::from(p.front_end.gain_of(Signal::CurrentA));
            for i in [-9.0, -1.234, 0.0, 0.5, 3.0, 9.9] {
                let v = current_volts(p, Signal::CurrentA, i);
                // What the ADC converts: the pin, times the amplifier's gain.
                let counts = (v * gain / VREF * f64::from(sensors::ADC_MAX)).round() as u16;
                assert_eq!(counts, sensors::current_counts(&p.scaling, i), "{i} A");
                assert!((volts_current(p, Signal::CurrentA, v) - i).abs() < 1e-9);
            }
        }
        // The bare ESC1 at 0 A: about 0.103 V at the PGA input (review D4).
        let v = current_volts(&B_G431B_ESC1, Signal::CurrentB, 0.0);
        assert!((v - 0.1031).abs() < 0.001, "{v} V");
        assert_eq!(pin_id("PC13"), Some((2, 13)));
    }
}
