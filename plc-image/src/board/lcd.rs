//! HD44780 character LCD (20 x 4, or 16 x 2) in 4-bit mode behind a PCF8574 I2C backpack:
//! the [`CharLcd`] port of the LCD sync (`firmware_plc::task::lcd`, which decides what
//! to write: one changed cell per pass, then the cursor back).
//!
//! Backpack wiring (the common one): P0 = RS, P1 = R/W, P2 = E, P3 = backlight,
//! P4..P7 = D4..D7. At 100 kHz one byte to the controller is 7 bytes on the bus: the
//! address and 3 per nibble (data, data|E, data, so that RS and D4-D7 are stable before
//! E rises, tAS), about 0.63 ms. A cell next to the last one written costs 0.63 ms, a
//! scattered cell 1.26 ms (goto + data), and putting the editor's cursor back another
//! 0.63 ms.

use embassy_time::{block_for, Duration};
use firmware_plc::task::{CharLcd, Cursor};

use super::i2c_bus::SharedI2c;

/// 7-bit address of a PCF8574 backpack with A2..A0 high (PCF8574A parts: 0x3F).
pub const ADDRESS: u8 = 0x27;
/// Geometry of the fitted display.
pub const COLS: u8 = 20;
pub const ROWS: u8 = 4;

/// Wait after the clear command.
const CLEAR_MS: u64 = 3;
/// The controller's power-on time (40 ms after VCC reaches 2.7 V), with margin.
const POWER_ON_MS: u64 = 50;

const RS: u8 = 1 << 0;
const E: u8 = 1 << 2;
const BACKLIGHT: u8 = 1 << 3;
/// DDRAM address of each row's first cell (20 x 4 layout; the 16 x 2 uses the first two).
const ROW_ADDR: [u8; 4] = [0x00, 0x40, 0x14, 0x54];

/// Why the LCD did not take a write: the bus error.
#[derive(Debug, Clone, Copy, PartialEq, Eq, defmt::Format)]
pub struct LcdError(pub embassy_stm32::i2c::Error);

/// The display on the shared I2C bus.
pub struct Lcd {
    bus: SharedI2c,
}

impl Lcd {
    pub fn new(bus: SharedI2c) -> Self {
        Lcd { bus }
    }

    /// The first initialisation, just after power-on: waits the controller's power-on
    /// time first (a retry, [`CharLcd::init`], skips it, so that it blocks the
    /// application task for about 8 ms only).
    pub fn power_on(&mut self) -> Result<(), LcdError> {
        block_for(Duration::from_millis(POWER_ON_MS));
        self.init()
    }

    fn write_raw(&mut self, bytes: &[u8]) -> Result<(), LcdError> {
        self.bus
            .borrow_mut()
            .blocking_write(ADDRESS, bytes)
            .map_err(LcdError)
    }

    /// One 4-bit transfer: the high nibble of `value`, then E high, then E low, each one
    /// PCF8574 write (90 µs apart at 100 kHz): RS and the data are stable before E rises
    /// (tAS >= 40 ns) and after it falls.
    fn nibble(&mut self, value: u8, rs: u8) -> Result<(), LcdError> {
        let b = (value & 0xF0) | rs | BACKLIGHT;
        self.write_raw(&[b, b | E, b])
    }

    fn byte(&mut self, value: u8, rs: u8) -> Result<(), LcdError> {
        let hi = (value & 0xF0) | rs | BACKLIGHT;
        let lo = (value << 4) | rs | BACKLIGHT;
        // One I2C transaction per byte, each nibble as in `nibble`.
        self.write_raw(&[hi, hi | E, hi, lo, lo | E, lo])
    }

    fn command(&mut self, c: u8) -> Result<(), LcdError> {
        self.byte(c, 0)
    }
}

impl CharLcd for Lcd {
    type Error = LcdError;

    /// Into 4-bit, 2-line mode, display on, cursor off, cleared (HD44780 datasheet,
    /// "initialising by instruction", 4-bit interface).
    fn init(&mut self) -> Result<(), LcdError> {
        for wait_us in [4500, 150, 150] {
            self.nibble(0x30, 0)?;
            block_for(Duration::from_micros(wait_us));
        }
        self.nibble(0x20, 0)?;
        self.command(0x28)?; // 4-bit, 2 lines (also rows 3-4 of a 20x4), 5x8 font
        self.command(0x08)?; // display off
        self.command(0x01)?; // clear
                             // 1.52 ms at 270 kHz, up to about 2.2 ms at the slowest oscillator (190 kHz).
        block_for(Duration::from_millis(CLEAR_MS));
        self.command(0x06)?; // entry mode: increment, no shift
        self.command(0x0C) // display on, cursor off
    }

    fn set_address(&mut self, row: u8, col: u8) -> Result<(), LcdError> {
        let base = ROW_ADDR.get(usize::from(row)).copied().unwrap_or(0);
        self.command(0x80 | base.wrapping_add(col))
    }

    fn write_char(&mut self, c: u8) -> Result<(), LcdError> {
        self.byte(c, RS)
    }

    fn set_cursor(&mut self, cursor: Cursor) -> Result<(), LcdError> {
        self.command(match cursor {
            Cursor::Hidden => 0x0C,
            Cursor::Underline => 0x0E,
            Cursor::Blink => 0x0D,
        })
    }
}
