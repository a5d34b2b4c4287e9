//! The digital outputs O00..O07, all off until the scan loop writes them.

use embassy_stm32::gpio::{Level, Output, Speed};

use crate::pins::Outputs;

/// Number of digital outputs.
pub const COUNT: usize = firmware_plc::vm::OUTPUTS as usize;

/// O00..O07 in order.
pub struct DigitalOutputs {
    pins: [Output<'static>; COUNT],
}

impl DigitalOutputs {
    /// Takes the pins, all low (off).
    pub fn new(p: Outputs) -> Self {
        Self {
            pins: p.pins.map(|pin| Output::new(pin, Level::Low, Speed::Low)),
        }
    }

    /// Writes the output image: bit n drives On.
    pub fn write(&mut self, image: u8) {
        for (n, pin) in self.pins.iter_mut().enumerate() {
            pin.set_level(Level::from(image & (1 << n) != 0));
        }
    }
}
