//! The digital inputs at GPIO pins (opto-isolator outputs, active high, pulled down):
//! D00..D15, or D08..D15 in the shield profile.

use embassy_stm32::gpio::{Input, Pull};

use crate::pins::{Inputs, GPIO_INPUTS};

/// The GPIO inputs in order.
pub struct DigitalInputs {
    pins: [Input<'static>; GPIO_INPUTS],
}

impl DigitalInputs {
    pub fn new(p: Inputs) -> Self {
        Self {
            pins: p.pins.map(|pin| Input::new(pin, Pull::Down)),
        }
    }

    /// The raw pin levels, bit n = the nth pin of [`Inputs`] (debouncing is the core's
    /// `debounce` module).
    pub fn sample(&self) -> u16 {
        self.pins
            .iter()
            .enumerate()
            .fold(0u16, |acc, (n, pin)| acc | (u16::from(pin.is_high()) << n))
    }
}
