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
        let [r0, r1, r2, r3] = k.rows;
        let [c0, c1, c2, c3] = k.cols;
        Self {
            rows: [row(r0), row(r1), row(r2), row(r3)],
            cols: [col(c0), col(c1), col(c2), col(c3)],
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
