//! The eight digital inputs D00..D07 (opto-isolator outputs, active high, pulled down).

use embassy_stm32::gpio::{AnyPin, Input, Pull};
use embassy_stm32::Peri;

use crate::pins::Inputs;

/// D00..D07 in order.
pub struct DigitalInputs {
    pins: [Input<'static>; 8],
}

impl DigitalInputs {
    pub fn new(p: Inputs) -> Self {
        let input = |pin: Peri<'static, AnyPin>| Input::new(pin, Pull::Down);
        Self {
            pins: [
                input(p.i0.into()),
                input(p.i1.into()),
                input(p.i2.into()),
                input(p.i3.into()),
                input(p.i4.into()),
                input(p.i5.into()),
                input(p.i6.into()),
                input(p.i7.into()),
            ],
        }
    }

    /// The raw pin levels, bit n = Dn (debouncing is the core's `debounce` module).
    pub fn sample(&self) -> u8 {
        self.pins
            .iter()
            .enumerate()
            .fold(0u8, |acc, (n, pin)| acc | (u8::from(pin.is_high()) << n))
    }
}
