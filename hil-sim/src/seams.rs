//! One trait per simulated peripheral: what the scheduler ([`crate::sim`]) needs from the
//! hardware models, so any of them can be replaced (a different motor model, a recorded
//! UART trace...) without touching the firmware side or the scheduler.
//!
//! | peripheral | trait | model |
//! | --- | --- | --- |
//! | UART wire (one direction) | [`UartWire`] | `shared_protocol::link::channel::Channel` |
//! | TIM1 outputs, MOE, brake GPIO -> power stage | [`PowerStage`] | [`crate::plant::Plant`] |
//! | drive ADC (phase currents, DC link) | [`AdcFrontEnd`] | [`crate::plant::Plant`] |
//! | TIM1 break input + comparators | [`BreakInput`] | [`crate::plant::Plant`] |
//! | the continuous-time plant as a whole | [`Rig`] | [`crate::plant::Plant`] |
//! | PLC digital and analog inputs | [`InputPins`] | [`crate::mcu::PlcPins`] |
//! | LCD | [`CharDisplay`] | [`crate::mcu::Lcd`] |
//! | I2C EEPROM | `firmware_plc::storage::Eeprom` | `firmware_plc::storage::MemEeprom` |
//!
//! The firmware's side of each seam is the application's entry point listed in
//! `docs/simulation.md` (`DriveApp::pwm_period`, `PlcApp::scan`, ...).

use shared_protocol::link::channel::Channel;
use shared_protocol::units::Micros;

use crate::mcu::{Lcd, PlcPins};
use crate::plant::{
    AdcSample, BreakCause, Comparators, GateCommand, Plant, PlantOutputs, RigParams,
};

/// One direction of a UART wire, timed to the byte.
pub trait UartWire {
    /// A frame handed to the transmitter at `now`.
    fn send(&mut self, bytes: &[u8], now: Micros);
    /// The transmitter can take another frame.
    fn is_idle(&self, now: Micros) -> bool;
    /// When the transmitter becomes free.
    fn free_at(&self) -> Micros;
    /// When the next byte arrives at the receiver.
    fn next_arrival(&self) -> Option<Micros>;
    /// Bytes that have arrived by `now`.
    fn receive(&mut self, now: Micros, out: &mut [u8]) -> usize;
    /// Cut (or reconnect) the wire.
    fn set_cut(&mut self, cut: bool);
}

impl UartWire for Channel {
    fn send(&mut self, bytes: &[u8], now: Micros) {
        Channel::send(self, bytes, now)
    }
    fn is_idle(&self, now: Micros) -> bool {
        Channel::is_idle(self, now)
    }
    fn free_at(&self) -> Micros {
        Channel::free_at(self)
    }
    fn next_arrival(&self) -> Option<Micros> {
        Channel::next_arrival(self)
    }
    fn receive(&mut self, now: Micros, out: &mut [u8]) -> usize {
        Channel::receive(self, now, out)
    }
    fn set_cut(&mut self, cut: bool) {
        Channel::set_cut(self, cut)
    }
}

/// What TIM1's outputs and the brake GPIO do to the power stage.
pub trait PowerStage {
    /// A PWM period of `period_ns` starts with the preloaded gate command.
    fn start_period(&mut self, period_ns: u64, gate: GateCommand);
    /// A command that acts at once (outputs disabled).
    fn set_command(&mut self, gate: GateCommand);
    fn set_brake(&mut self, on: bool);
}

/// The drive's ADC: one conversion of phase currents a, b and the DC link.
pub trait AdcFrontEnd {
    fn convert(&self) -> AdcSample;
}

/// TIM1's break input and the comparators behind it.
pub trait BreakInput {
    /// A break that fired since the last call.
    fn take_break(&mut self) -> Option<BreakCause>;
    /// Comparator outputs now: [overcurrent, overvoltage].
    fn comparator_levels(&self) -> [bool; 2];
    /// The comparators as configured now (board table and DAC values).
    fn comparators(&self) -> Comparators;
    /// The drive (re)wrote its threshold DACs.
    fn set_comparators(&mut self, c: Comparators);
}

/// The continuous-time plant: advanced between events, observed for the record.
pub trait Rig: PowerStage + AdcFrontEnd + BreakInput {
    fn advance(&mut self, dt_ns: u64);
    fn outputs(&self) -> PlantOutputs;
    /// Parameters changed at run time by the scenario.
    fn params_mut(&mut self) -> &mut RigParams;
}

impl PowerStage for Plant {
    fn start_period(&mut self, period_ns: u64, gate: GateCommand) {
        Plant::start_period(self, period_ns, gate)
    }
    fn set_command(&mut self, gate: GateCommand) {
        Plant::set_command(self, gate)
    }
    fn set_brake(&mut self, on: bool) {
        Plant::set_brake(self, on)
    }
}

impl AdcFrontEnd for Plant {
    fn convert(&self) -> AdcSample {
        self.adc_sample()
    }
}

impl BreakInput for Plant {
    fn take_break(&mut self) -> Option<BreakCause> {
        Plant::take_break(self)
    }
    fn comparator_levels(&self) -> [bool; 2] {
        Plant::comparator_levels(self)
    }
    fn comparators(&self) -> Comparators {
        *Plant::comparators(self)
    }
    fn set_comparators(&mut self, c: Comparators) {
        Plant::set_comparators(self, c)
    }
}

impl Rig for Plant {
    fn advance(&mut self, dt_ns: u64) {
        Plant::advance(self, dt_ns)
    }
    fn outputs(&self) -> PlantOutputs {
        Plant::outputs(self)
    }
    fn params_mut(&mut self) -> &mut RigParams {
        Plant::params_mut(self)
    }
}

/// The PLC's input pins as the scan samples them.
pub trait InputPins {
    /// D00..D07, bit n = Dn.
    fn digital(&self) -> u8;
    /// A00..A03, 10-bit counts.
    fn analog(&self) -> [u16; 4];
}

impl InputPins for PlcPins {
    fn digital(&self) -> u8 {
        self.digital
    }
    fn analog(&self) -> [u16; 4] {
        self.analog
    }
}

/// A character display.
pub trait CharDisplay {
    fn set_row(&mut self, row: usize, text: &str);
    fn row(&self, row: usize) -> String;
}

impl CharDisplay for Lcd {
    fn set_row(&mut self, row: usize, text: &str) {
        Lcd::set_row(self, row, text)
    }
    fn row(&self, row: usize) -> String {
        Lcd::row(self, row)
    }
}
