//! The 20 x 4 character LCD: an HD44780's display RAM and address counter as the
//! firmware's LCD sync drives them ([`CharLcd`]), or filled row by row from the emulated
//! board's bus traffic (`crate::emu`).

use firmware_plc::editor::Screen;
use firmware_plc::task::{CharLcd, Cursor};

pub const COLS: usize = 20;
pub const ROWS: usize = 4;

/// DDRAM address of each row's first cell on a 20 x 4 HD44780 (its datasheet's display
/// layout: rows 0 and 2 share the first line of its RAM, rows 1 and 3 the second).
const ROW_ADDR: [u8; ROWS] = [0x00, 0x40, 0x14, 0x54];
/// The second RAM line starts at 0x40; each line is 40 cells.
const LINE_CELLS: u8 = 40;

/// What the LCD shows.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SimLcd {
    rows: [[u8; COLS]; ROWS],
    /// The controller's address counter (DDRAM address).
    addr: u8,
    cursor: Cursor,
}

impl Default for SimLcd {
    fn default() -> Self {
        SimLcd {
            rows: [[b' '; COLS]; ROWS],
            addr: 0,
            cursor: Cursor::Hidden,
        }
    }
}

impl SimLcd {
    /// Writes `text` on `row` from column 0, padded with spaces (extra characters are cut,
    /// non-ASCII shown as `?`).
    pub fn set_row(&mut self, row: usize, text: &str) {
        if let Some(r) = self.rows.get_mut(row) {
            *r = [b' '; COLS];
            for (slot, c) in r.iter_mut().zip(text.chars()) {
                *slot = if c.is_ascii() && !c.is_ascii_control() {
                    c as u8
                } else {
                    b'?'
                };
            }
        }
    }

    /// One row as text (trailing spaces kept).
    pub fn row(&self, row: usize) -> String {
        self.rows
            .get(row)
            .map(|r| r.iter().map(|&b| b as char).collect())
            .unwrap_or_default()
    }

    /// The cursor as the controller shows it: its cell (row, column) when shown.
    pub fn cursor(&self) -> Option<(u8, u8, Cursor)> {
        if self.cursor == Cursor::Hidden {
            return None;
        }
        let (r, c) = self.cell(self.addr)?;
        Some((r as u8, c as u8, self.cursor))
    }

    /// What the display shows as a [`Screen`] (the panel draws it), cursor included.
    pub fn to_screen(&self) -> Screen {
        let mut s = Screen::new(COLS as u8, ROWS as u8);
        for r in 0..ROWS {
            s.put(r as u8, 0, &self.row(r));
        }
        if let Some((r, c, look)) = self.cursor() {
            s.cursor = Some((r, c));
            s.blink = look == Cursor::Blink;
        }
        s
    }

    /// All rows framed, for summaries and terminals.
    pub fn framed(&self) -> String {
        let mut s = String::new();
        s.push('+');
        s.push_str(&"-".repeat(COLS));
        s.push_str("+\n");
        for r in 0..ROWS {
            s.push('|');
            s.push_str(&self.row(r));
            s.push_str("|\n");
        }
        s.push('+');
        s.push_str(&"-".repeat(COLS));
        s.push('+');
        s
    }

    /// The visible cell at DDRAM address `addr`, if any.
    fn cell(&self, addr: u8) -> Option<(usize, usize)> {
        ROW_ADDR.iter().enumerate().find_map(|(r, &base)| {
            let c = addr.checked_sub(base)?;
            (usize::from(c) < COLS).then_some((r, usize::from(c)))
        })
    }
}

impl CharLcd for SimLcd {
    /// The simulated bus always takes the bytes.
    type Error = core::convert::Infallible;

    fn init(&mut self) -> Result<(), Self::Error> {
        *self = SimLcd::default();
        Ok(())
    }

    fn set_address(&mut self, row: u8, col: u8) -> Result<(), Self::Error> {
        let base = ROW_ADDR.get(usize::from(row)).copied().unwrap_or(0);
        self.addr = base.wrapping_add(col) & 0x7F;
        Ok(())
    }

    fn write_char(&mut self, c: u8) -> Result<(), Self::Error> {
        if let Some((r, col)) = self.cell(self.addr) {
            self.rows[r][col] = c;
        }
        // The counter runs through each 40-cell RAM line, then on to the other line.
        self.addr = match self.addr {
            a if a == LINE_CELLS - 1 => 0x40,
            a if a == 0x40 + LINE_CELLS - 1 => 0x00,
            a => a + 1,
        };
        Ok(())
    }

    fn set_cursor(&mut self, cursor: Cursor) -> Result<(), Self::Error> {
        self.cursor = cursor;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_are_padded_and_cut() {
        let mut l = SimLcd::default();
        l.set_row(1, "hello");
        l.set_row(2, "0123456789012345678901234");
        assert_eq!(l.row(1), format!("{:<20}", "hello"));
        assert_eq!(l.row(2), "01234567890123456789");
        assert_eq!(l.framed().lines().count(), 6);
    }

    #[test]
    fn the_address_counter_runs_from_row_0_into_row_2() {
        let mut l = SimLcd::default();
        l.set_address(0, 19).unwrap();
        l.write_char(b'A').unwrap();
        l.write_char(b'B').unwrap();
        assert_eq!(l.row(0).as_bytes()[19], b'A');
        assert_eq!(l.row(2).as_bytes()[0], b'B');
        l.set_cursor(Cursor::Blink).unwrap();
        assert_eq!(l.cursor(), Some((2, 1, Cursor::Blink)));
    }
}
