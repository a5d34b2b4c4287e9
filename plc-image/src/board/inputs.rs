//! The digital inputs D00..D15 (opto-isolator outputs, active high, pulled down).

use embassy_stm32::gpio::{Input, Pull};

use crate::pins::Inputs;

/// D00..D15 in order.
pub struct DigitalInputs {
    pins: [Input<'static>; firmware_plc::vm::INPUTS as usize],
}

impl DigitalInputs {
    pub fn new(p: Inputs) -> Self {
        Self {
            pins: p.pins.map(|pin| Input::new(pin, Pull::Down)),
        }
    }

    /// The raw pin levels, bit n = Dn (debouncing is the core's `debounce` module).
    pub fn sample(&self) -> u16 {
        self.pins
            .iter()
            .enumerate()
            .fold(0u16, |acc, (n, pin)| acc | (u16::from(pin.is_high()) << n))
    }
}
