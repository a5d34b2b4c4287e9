//! The 20 x 4 character LCD as a text buffer.

pub const COLS: usize = 20;
pub const ROWS: usize = 4;

/// What the LCD shows.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Lcd {
    rows: [[u8; COLS]; ROWS],
}

impl Default for Lcd {
    fn default() -> Self {
        Lcd {
            rows: [[b' '; COLS]; ROWS],
        }
    }
}

impl Lcd {
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
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_are_padded_and_cut() {
        let mut l = Lcd::default();
        l.set_row(1, "hello");
        l.set_row(2, "0123456789012345678901234");
        assert_eq!(l.row(1), format!("{:<20}", "hello"));
        assert_eq!(l.row(2), "01234567890123456789");
        assert_eq!(l.framed().lines().count(), 6);
    }
}
