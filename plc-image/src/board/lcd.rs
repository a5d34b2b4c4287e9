//! HD44780 character LCD (20 x 4, or 16 x 2) in 4-bit mode behind a PCF8574 I2C backpack.
//!
//! Backpack wiring (the common one): P0 = RS, P1 = R/W, P2 = E, P3 = backlight,
//! P4..P7 = D4..D7. The display mirrors the core's [`Screen`]: [`Lcd::refresh`] sends only the
//! cells that differ from what the LCD shows, at most [`CELLS_PER_REFRESH`] per call, so
//! one call blocks the application task for a bounded time. At 100 kHz one byte to the
//! controller is 7 bytes on the bus (address + 3 per nibble: data, data|E, data, so that RS
//! and D4-D7 are stable before E rises, tAS; review D14), about 0.63 ms: a cell next to the
//! last one written costs 0.63 ms, a scattered cell 1.26 ms (goto + data), and putting the
//! editor's cursor back another 0.63 ms. A full 20 x 4 redraw is 80 cells, one per pass
//! of the application task: about 80 passes.

use embassy_time::{block_for, Duration};
use firmware_plc::editor::{Screen, MAX_COLS, MAX_ROWS};

use super::i2c_bus::SharedI2c;

/// 7-bit address of a PCF8574 backpack with A2..A0 high (PCF8574A parts: 0x3F).
pub const ADDRESS: u8 = 0x27;
/// Geometry of the fitted display.
pub const COLS: u8 = 20;
pub const ROWS: u8 = 4;
/// Cells written per [`Lcd::refresh`].
pub const CELLS_PER_REFRESH: usize = 1;

/// Wait after the clear command (review D14).
const CLEAR_MS: u64 = 3;

const RS: u8 = 1 << 0;
const E: u8 = 1 << 2;
const BACKLIGHT: u8 = 1 << 3;
/// DDRAM address of each row's first cell (20 x 4 layout; the 16 x 2 uses the first two).
const ROW_ADDR: [u8; 4] = [0x00, 0x40, 0x14, 0x54];

/// Why the LCD did not take a write: the bus error.
#[derive(Debug, Clone, Copy, PartialEq, Eq, defmt::Format)]
pub struct LcdError(pub embassy_stm32::i2c::Error);

/// The display and a copy of what it shows.
pub struct Lcd {
    bus: SharedI2c,
    shown: [[u8; MAX_COLS]; MAX_ROWS],
    cursor: Option<(u8, u8)>,
    blink: bool,
    /// The controller's address counter is known (after a write we set ourselves).
    at: Option<(u8, u8)>,
}

impl Lcd {
    /// Initialises the controller into 4-bit, 2-line mode, display on, cursor off, cleared.
    /// `cold`: just after power-on, wait the controller's 40 ms power-on time first (a retry
    /// after an I2C error skips it, so that it blocks the application task for about 8 ms
    /// only).
    pub fn new(bus: SharedI2c, cold: bool) -> Result<Self, LcdError> {
        let mut lcd = Lcd {
            bus,
            shown: [[b' '; MAX_COLS]; MAX_ROWS],
            cursor: None,
            blink: false,
            at: None,
        };
        // HD44780 datasheet, "initialising by instruction", 4-bit interface.
        if cold {
            block_for(Duration::from_millis(50));
        }
        for wait_us in [4500, 150, 150] {
            lcd.nibble(0x30, 0)?;
            block_for(Duration::from_micros(wait_us));
        }
        lcd.nibble(0x20, 0)?;
        lcd.command(0x28)?; // 4-bit, 2 lines (also rows 3-4 of a 20x4), 5x8 font
        lcd.command(0x08)?; // display off
        lcd.command(0x01)?; // clear
                            // 1.52 ms at 270 kHz, up to about 2.2 ms at the slowest oscillator (190 kHz).
        block_for(Duration::from_millis(CLEAR_MS));
        lcd.command(0x06)?; // entry mode: increment, no shift
        lcd.command(0x0C)?; // display on, cursor off
        Ok(lcd)
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
        self.write_raw(&[hi, hi | E, hi, lo, lo | E, lo])?;
        Ok(())
    }

    fn command(&mut self, c: u8) -> Result<(), LcdError> {
        self.byte(c, 0)
    }

    fn goto(&mut self, row: u8, col: u8) -> Result<(), LcdError> {
        if self.at != Some((row, col)) {
            let base = ROW_ADDR.get(usize::from(row)).copied().unwrap_or(0);
            self.command(0x80 | base.wrapping_add(col))?;
            self.at = Some((row, col));
        }
        Ok(())
    }

    /// Sends up to [`CELLS_PER_REFRESH`] changed cells of `screen`, then the cursor.
    /// Returns whether the LCD now shows `screen` completely.
    pub fn refresh(&mut self, screen: &Screen) -> Result<bool, LcdError> {
        let rows = screen.rows().min(ROWS);
        let cols = screen.cols().min(COLS);
        let mut budget = CELLS_PER_REFRESH;
        for r in 0..rows {
            let line = screen.row_bytes(r);
            for c in 0..cols {
                let want = line.get(usize::from(c)).copied().unwrap_or(b' ');
                let have = self
                    .shown
                    .get(usize::from(r))
                    .and_then(|row| row.get(usize::from(c)))
                    .copied();
                if have.is_none_or(|h| h == want) {
                    continue;
                }
                if budget == 0 {
                    return Ok(false);
                }
                budget -= 1;
                self.goto(r, c)?;
                self.byte(want, RS)?;
                if let Some(cell) = self
                    .shown
                    .get_mut(usize::from(r))
                    .and_then(|row| row.get_mut(usize::from(c)))
                {
                    *cell = want;
                }
                // The address counter advances by one; past a row's end it jumps rows.
                self.at = if c + 1 < cols { Some((r, c + 1)) } else { None };
            }
        }
        if self.cursor != screen.cursor || self.blink != screen.blink {
            match screen.cursor {
                Some((r, c)) => {
                    self.goto(r, c)?;
                    self.command(if screen.blink { 0x0D } else { 0x0E })?;
                }
                None => self.command(0x0C)?,
            }
            self.cursor = screen.cursor;
            self.blink = screen.blink;
        } else if let Some((r, c)) = screen.cursor {
            // Writing cells moved the controller's cursor: put it back.
            self.goto(r, c)?;
        }
        Ok(true)
    }
}
