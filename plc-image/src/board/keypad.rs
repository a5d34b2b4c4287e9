//! The 4x4 keypad matrix: rows driven low one at a time (open drain), columns read with
//! pull-ups. Returns the raw matrix; debouncing and key events are the core's
//! `debounce::KeyMatrix`.

use embassy_stm32::gpio::{AnyPin, Input, Level, OutputOpenDrain, Pull, Speed};
use embassy_stm32::Peri;

use crate::pins::Keypad;

/// Settling time after a row goes low before the columns are read (line capacitance and
/// the pull-ups' RC).
const SETTLE_CYCLES: u32 = 170 * 5;

/// The matrix pins.
pub struct KeypadScanner {
    rows: [OutputOpenDrain<'static>; 4],
    cols: [Input<'static>; 4],
}

impl KeypadScanner {
    pub fn new(k: Keypad) -> Self {
        let row = |pin: Peri<'static, AnyPin>| OutputOpenDrain::new(pin, Level::High, Speed::Low);
        let col = |pin: Peri<'static, AnyPin>| Input::new(pin, Pull::Up);
        Self {
            rows: [
                row(k.r0.into()),
                row(k.r1.into()),
                row(k.r2.into()),
                row(k.r3.into()),
            ],
            cols: [
                col(k.c0.into()),
                col(k.c1.into()),
                col(k.c2.into()),
                col(k.c3.into()),
            ],
        }
    }

    /// One scan of the whole matrix: bit `4 * row + column` set = that key closed.
    pub fn scan(&mut self) -> u16 {
        let mut pressed = 0u16;
        for (r, row) in self.rows.iter_mut().enumerate() {
            row.set_low();
            cortex_m::asm::delay(SETTLE_CYCLES);
            for (c, col) in self.cols.iter().enumerate() {
                if col.is_low() {
                    pressed |= 1 << (4 * r + c);
                }
            }
            row.set_high();
        }
        pressed
    }
}
