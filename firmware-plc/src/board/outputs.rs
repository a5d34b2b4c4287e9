//! The six digital outputs Q0..Q5, all off until the scan loop writes them.

use embassy_stm32::gpio::{AnyPin, Level, Output, Speed};
use embassy_stm32::Peri;

use crate::pins::Outputs;

/// Number of digital outputs.
pub const COUNT: usize = 6;

/// Q0..Q5 in order.
pub struct DigitalOutputs {
    pins: [Output<'static>; COUNT],
}

impl DigitalOutputs {
    /// Takes the pins, all low (off).
    pub fn new(p: Outputs) -> Self {
        let off = |pin: Peri<'static, AnyPin>| Output::new(pin, Level::Low, Speed::Low);
        Self {
            pins: [
                off(p.q0.into()),
                off(p.q1.into()),
                off(p.q2.into()),
                off(p.q3.into()),
                off(p.q4.into()),
                off(p.q5.into()),
            ],
        }
    }

    /// Writes the output image: bit n drives Qn.
    pub fn write(&mut self, image: u8) {
        for (n, pin) in self.pins.iter_mut().enumerate() {
            pin.set_level(Level::from(image & (1 << n) != 0));
        }
    }
}
