//! The LCD sync: which cell of a character LCD to write next so that it comes to show the
//! core's [`Screen`], over a [`CharLcd`] port (the board's HD44780 behind a PCF8574, or
//! hil-sim's model of it).
//!
//! One pass of the application task writes at most [`CELLS_PER_PASS`] changed cells, then
//! puts the controller's cursor back where the screen has it: a full 20 x 4 redraw takes
//! 80 passes, and no pass blocks the task for longer than one cell's I2C writes (about
//! 1.9 ms at 100 kHz with a goto and the cursor's restore, `docs/board.md`).

use crate::editor::{Screen, MAX_COLS, MAX_ROWS};

/// Changed cells written per [`LcdSync::sync`].
pub const CELLS_PER_PASS: usize = 1;

/// How the controller shows its cursor.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Cursor {
    Hidden,
    /// Steady underline.
    Underline,
    /// Blinking block.
    Blink,
}

/// A character LCD controller (HD44780 instruction set): its address counter, one
/// character at a time, the cursor's look. The port binds these to the bus; the policy of
/// what to write is [`LcdSync`]'s.
pub trait CharLcd {
    /// Why the controller did not take a write (the bus's error).
    type Error;
    /// Initialises the controller again after a failure: cleared, display on, cursor off.
    fn init(&mut self) -> Result<(), Self::Error>;
    /// Moves the address counter to (`row`, `col`).
    fn set_address(&mut self, row: u8, col: u8) -> Result<(), Self::Error>;
    /// Writes `c` at the address counter, which then advances by one.
    fn write_char(&mut self, c: u8) -> Result<(), Self::Error>;
    /// Shows the cursor at the address counter, or hides it.
    fn set_cursor(&mut self, cursor: Cursor) -> Result<(), Self::Error>;
}

/// What the controller shows, as the sync wrote it, and where its address counter is.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LcdSync {
    cols: u8,
    rows: u8,
    shown: [[u8; MAX_COLS]; MAX_ROWS],
    cursor: Cursor,
    /// The controller's address counter, when known (after a write the sync made).
    at: Option<(u8, u8)>,
}

impl LcdSync {
    /// A freshly initialised `cols` x `rows` display: blank, cursor hidden.
    pub fn new(cols: u8, rows: u8) -> Self {
        LcdSync {
            cols: cols.min(MAX_COLS as u8),
            rows: rows.min(MAX_ROWS as u8),
            shown: [[b' '; MAX_COLS]; MAX_ROWS],
            cursor: Cursor::Hidden,
            at: None,
        }
    }

    /// The controller was initialised again (cleared, cursor off).
    pub fn reset(&mut self) {
        *self = LcdSync::new(self.cols, self.rows);
    }

    /// What the display shows, row by row (`cols` bytes each).
    pub fn shown(&self, row: u8) -> &[u8] {
        self.shown
            .get(usize::from(row))
            .and_then(|r| r.get(..usize::from(self.cols)))
            .unwrap_or(&[])
    }

    fn goto<L: CharLcd>(&mut self, lcd: &mut L, row: u8, col: u8) -> Result<(), L::Error> {
        if self.at != Some((row, col)) {
            lcd.set_address(row, col)?;
            self.at = Some((row, col));
        }
        Ok(())
    }

    /// Writes up to [`CELLS_PER_PASS`] cells of `screen` that differ from what the display
    /// shows (row by row, left to right), then the cursor: its look when it changed, else
    /// its position again (writing moved the address counter). Returns whether the
    /// display now shows `screen` completely.
    pub fn sync<L: CharLcd>(&mut self, screen: &Screen, lcd: &mut L) -> Result<bool, L::Error> {
        let rows = screen.rows().min(self.rows);
        let cols = screen.cols().min(self.cols);
        let mut budget = CELLS_PER_PASS;
        for r in 0..rows {
            let line = screen.row_bytes(r);
            for c in 0..cols {
                let want = line.get(usize::from(c)).copied().unwrap_or(b' ');
                let Some(cell) = self
                    .shown
                    .get_mut(usize::from(r))
                    .and_then(|row| row.get_mut(usize::from(c)))
                else {
                    continue;
                };
                if *cell == want {
                    continue;
                }
                if budget == 0 {
                    return Ok(false);
                }
                budget -= 1;
                if self.at != Some((r, c)) {
                    lcd.set_address(r, c)?;
                }
                // Unknown until the write is taken: a failed write leaves the counter
                // wherever the controller has it.
                self.at = None;
                lcd.write_char(want)?;
                *cell = want;
                // The address counter advances by one; past a row's end it jumps rows.
                self.at = (c + 1 < cols).then_some((r, c + 1));
            }
        }
        let want = match screen.cursor {
            None => Cursor::Hidden,
            Some(_) if screen.blink => Cursor::Blink,
            Some(_) => Cursor::Underline,
        };
        if let Some((r, c)) = screen.cursor {
            // Writing cells moved the controller's cursor: put it back.
            self.goto(lcd, r, c)?;
        }
        if self.cursor != want {
            lcd.set_cursor(want)?;
            self.cursor = want;
        }
        Ok(true)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An HD44780 as far as the sync sees it, with every call recorded.
    #[derive(Default)]
    struct Model {
        ddram: [[u8; 20]; 4],
        at: (u8, u8),
        cursor: Option<Cursor>,
        calls: Vec<String>,
        fail_next: bool,
    }

    impl Model {
        fn new() -> Self {
            Model {
                ddram: [[b' '; 20]; 4],
                ..Model::default()
            }
        }
        fn fail(&mut self) -> Result<(), ()> {
            if core::mem::take(&mut self.fail_next) {
                return Err(());
            }
            Ok(())
        }
        fn row(&self, r: usize) -> String {
            self.ddram[r].iter().map(|&b| b as char).collect()
        }
    }

    impl CharLcd for Model {
        type Error = ();
        fn init(&mut self) -> Result<(), ()> {
            self.fail()?;
            *self = Model::new();
            Ok(())
        }
        fn set_address(&mut self, row: u8, col: u8) -> Result<(), ()> {
            self.fail()?;
            self.calls.push(format!("goto {row},{col}"));
            self.at = (row, col);
            Ok(())
        }
        fn write_char(&mut self, c: u8) -> Result<(), ()> {
            self.fail()?;
            self.calls.push(format!("char {}", c as char));
            self.ddram[usize::from(self.at.0)][usize::from(self.at.1)] = c;
            self.at.1 += 1;
            Ok(())
        }
        fn set_cursor(&mut self, cursor: Cursor) -> Result<(), ()> {
            self.fail()?;
            self.calls.push(format!("cursor {cursor:?}"));
            self.cursor = Some(cursor);
            Ok(())
        }
    }

    #[test]
    fn one_changed_cell_per_pass_in_reading_order() {
        let mut lcd = Model::new();
        let mut sync = LcdSync::new(20, 4);
        let mut screen = Screen::new(20, 4);
        screen.put(0, 0, "AB");
        screen.put(2, 5, "C");
        assert_eq!(sync.sync(&screen, &mut lcd), Ok(false));
        assert_eq!(lcd.calls, ["goto 0,0", "char A"]);
        assert_eq!(lcd.row(0).trim_end(), "A");
        lcd.calls.clear();
        // The next cell follows the address counter: no goto.
        assert_eq!(sync.sync(&screen, &mut lcd), Ok(false));
        assert_eq!(lcd.calls, ["char B"]);
        lcd.calls.clear();
        assert_eq!(sync.sync(&screen, &mut lcd), Ok(true));
        assert_eq!(lcd.calls, ["goto 2,5", "char C"]);
        lcd.calls.clear();
        // Nothing left to write: nothing sent.
        assert_eq!(sync.sync(&screen, &mut lcd), Ok(true));
        assert!(lcd.calls.is_empty(), "{:?}", lcd.calls);
        assert_eq!(lcd.row(2), format!("{:<20}", "     C"));
    }

    #[test]
    fn a_full_redraw_takes_one_pass_per_cell() {
        let mut lcd = Model::new();
        let mut sync = LcdSync::new(20, 4);
        let mut screen = Screen::new(20, 4);
        for r in 0..4 {
            screen.put(r, 0, "01234567890123456789");
        }
        let passes = (1..)
            .find(|_| sync.sync(&screen, &mut lcd) == Ok(true))
            .unwrap();
        assert_eq!(passes, 80);
        for r in 0..4 {
            assert_eq!(lcd.row(r), "01234567890123456789");
        }
        // A row's end does not carry the address counter to the next row's start.
        assert_eq!(
            lcd.calls.iter().filter(|c| c.starts_with("goto")).count(),
            4
        );
    }

    #[test]
    fn the_cursor_goes_back_after_each_write_and_its_look_is_sent_once() {
        let mut lcd = Model::new();
        let mut sync = LcdSync::new(20, 4);
        let mut screen = Screen::new(20, 4);
        screen.put(1, 0, "X");
        screen.cursor = Some((3, 7));
        screen.blink = true;
        assert_eq!(sync.sync(&screen, &mut lcd), Ok(true));
        assert_eq!(
            lcd.calls,
            ["goto 1,0", "char X", "goto 3,7", "cursor Blink"]
        );
        lcd.calls.clear();
        screen.put(1, 1, "Y");
        assert_eq!(sync.sync(&screen, &mut lcd), Ok(true));
        assert_eq!(lcd.calls, ["goto 1,1", "char Y", "goto 3,7"]);
        lcd.calls.clear();
        screen.cursor = None;
        assert_eq!(sync.sync(&screen, &mut lcd), Ok(true));
        assert_eq!(lcd.calls, ["cursor Hidden"]);
    }

    #[test]
    fn a_failed_write_is_written_again_after_the_reset() {
        let mut lcd = Model::new();
        let mut sync = LcdSync::new(20, 4);
        let mut screen = Screen::new(20, 4);
        screen.put(0, 3, "Z");
        lcd.fail_next = true;
        assert_eq!(sync.sync(&screen, &mut lcd), Err(()));
        assert_eq!(lcd.init(), Ok(()));
        sync.reset();
        assert_eq!(sync.sync(&screen, &mut lcd), Ok(true));
        assert_eq!(lcd.row(0).trim_end(), "   Z");
        assert_eq!(sync.shown(0), lcd.row(0).as_bytes());
    }
}
