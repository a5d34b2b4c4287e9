//! A character LCD's content: what the HD44780 driver copies to the display.

use core::fmt::Write as _;

/// Widest supported display.
pub const MAX_COLS: usize = 20;
/// Tallest supported display.
pub const MAX_ROWS: usize = 4;

/// The characters of a 20x4 (or smaller) LCD, plus the hardware cursor.
///
/// Only printable ASCII is stored (anything else becomes `?`), and never `\` or `~`,
/// which the HD44780's ROM A00 shows as other glyphs.
#[derive(Clone, PartialEq, Eq)]
pub struct Screen {
    cols: u8,
    rows: u8,
    cells: [[u8; MAX_COLS]; MAX_ROWS],
    /// Cursor position (row, column), `None` when hidden.
    pub cursor: Option<(u8, u8)>,
    /// Blinking block cursor (true) or steady underline (false).
    pub blink: bool,
}

impl Screen {
    /// A blank screen of `cols` x `rows` (clamped to 1..=20 x 1..=4).
    pub fn new(cols: u8, rows: u8) -> Screen {
        Screen {
            cols: cols.clamp(1, MAX_COLS as u8),
            rows: rows.clamp(1, MAX_ROWS as u8),
            cells: [[b' '; MAX_COLS]; MAX_ROWS],
            cursor: None,
            blink: false,
        }
    }

    pub fn cols(&self) -> u8 {
        self.cols
    }

    pub fn rows(&self) -> u8 {
        self.rows
    }

    /// Blank every cell and hide the cursor.
    pub fn clear(&mut self) {
        self.cells = [[b' '; MAX_COLS]; MAX_ROWS];
        self.cursor = None;
        self.blink = false;
    }

    /// Write `text` at (`row`, `col`), clipped at the right edge; rows outside are ignored.
    pub fn put(&mut self, row: u8, col: u8, text: &str) {
        if row >= self.rows {
            return;
        }
        let width = usize::from(self.cols);
        let Some(cells) = self.cells.get_mut(usize::from(row)) else {
            return;
        };
        for (i, ch) in text.chars().enumerate() {
            let c = usize::from(col) + i;
            if c >= width {
                break;
            }
            let b = if ch.is_ascii_graphic() && ch != '\\' && ch != '~' || ch == ' ' {
                ch as u8
            } else {
                b'?'
            };
            if let Some(cell) = cells.get_mut(c) {
                *cell = b;
            }
        }
    }

    /// One row's text, exactly `cols` characters (empty for rows outside).
    pub fn row(&self, row: u8) -> &str {
        if row >= self.rows {
            return "";
        }
        self.cells
            .get(usize::from(row))
            .and_then(|r| r.get(..usize::from(self.cols)))
            .and_then(|r| core::str::from_utf8(r).ok())
            .unwrap_or("")
    }

    /// Raw bytes of one row (for the HD44780 driver).
    pub fn row_bytes(&self, row: u8) -> &[u8] {
        self.row(row).as_bytes()
    }
}

/// The rows separated by newlines (what `hil-sim run` prints as "the LCD screen").
impl core::fmt::Display for Screen {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        for r in 0..self.rows {
            if r > 0 {
                f.write_char('\n')?;
            }
            f.write_str(self.row(r))?;
        }
        Ok(())
    }
}

impl core::fmt::Debug for Screen {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        for r in 0..self.rows {
            writeln!(f, "|{}|", self.row(r))?;
        }
        write!(f, "cursor {:?} blink {}", self.cursor, self.blink)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clips_and_filters() {
        let mut s = Screen::new(16, 2);
        s.put(0, 10, "ABCDEFGH");
        s.put(1, 0, "a\\b~cé");
        s.put(2, 0, "ignored");
        assert_eq!(s.row(0), "          ABCDEF");
        assert_eq!(s.row(1), "a?b?c?          ");
        assert_eq!(s.row(2), "");
        assert_eq!(s.to_string().lines().count(), 2);
    }
}
