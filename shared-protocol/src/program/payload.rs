//! The stored form of a program's lines (the payload): what an EEPROM copy holds after its
//! header and what the service port transfers (`ReadProgram`, `WriteChunk`). The PLC
//! writes and checks its copies with it, `plcctl` pushes and pulls programs with it.
//!
//! Runs of consecutive used lines, each `[first line: u16 BE][count: u8 1..=255]` followed
//! by `count` lines in the 4-byte [`encode_line`] form, runs in ascending line order. Both
//! directions stream (a byte at a time, resumable), so the PLC never holds a whole copy.

use super::{decode_line, encode_line, Instruction, Program, LINES, LINE_BYTES};

/// Most lines in one run (the count is one byte).
const RUN_MAX: usize = 255;

/// The payload bytes of a program, produced one at a time and resumable, so that a page
/// of the payload can be produced in one step and the next page in a later one.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PayloadCursor {
    /// Line the next byte belongs to (or where the next run is looked for).
    line: u16,
    /// One past the last line of the current run.
    run_end: u16,
    /// Next byte of the run header (0..3; 3 = header done).
    header: u8,
    /// Next byte of the current line (0..LINE_BYTES).
    byte: u8,
}

impl Default for PayloadCursor {
    fn default() -> Self {
        Self::new()
    }
}

impl PayloadCursor {
    /// A cursor at the first byte of the payload.
    pub const fn new() -> Self {
        PayloadCursor {
            line: 0,
            run_end: 0,
            header: 3,
            byte: 0,
        }
    }

    fn used(program: &Program, line: usize) -> bool {
        program.lines.get(line).is_some_and(|l| l.is_some())
    }

    /// The next payload byte, `None` after the last one.
    pub fn next(&mut self, program: &Program) -> Option<u8> {
        if self.line >= self.run_end && self.header >= 3 {
            // Start the next run of used lines.
            let mut first = usize::from(self.line);
            while first < LINES && !Self::used(program, first) {
                first += 1;
            }
            if first >= LINES {
                self.line = LINES as u16;
                return None;
            }
            let mut count = 0usize;
            while count < RUN_MAX && Self::used(program, first + count) {
                count += 1;
            }
            self.line = first as u16;
            self.run_end = (first + count) as u16;
            self.header = 0;
            self.byte = 0;
        }
        if self.header < 3 {
            let [hi, lo] = self.line.to_be_bytes();
            let b = match self.header {
                0 => hi,
                1 => lo,
                _ => self.run_end.wrapping_sub(self.line) as u8,
            };
            self.header += 1;
            return Some(b);
        }
        let encoded = program
            .lines
            .get(usize::from(self.line))
            .copied()
            .flatten()
            .map(|i| encode_line(&i))?;
        let b = encoded.get(usize::from(self.byte)).copied()?;
        self.byte += 1;
        if usize::from(self.byte) == LINE_BYTES {
            self.byte = 0;
            self.line += 1;
        }
        Some(b)
    }
}

/// Calls `emit` with every payload byte of `program`, in order: the bytes a copy stores
/// after its header, which the service port transfers (`ReadProgram` of slot 0).
pub fn for_each_payload_byte(program: &Program, mut emit: impl FnMut(u8)) {
    let mut c = PayloadCursor::new();
    while let Some(b) = c.next(program) {
        emit(b);
    }
}

/// Payload length and used lines of `program` in the stored form.
pub fn payload_size(program: &Program) -> (usize, u16) {
    let mut len = 0usize;
    for_each_payload_byte(program, |_| len += 1);
    let lines = program.lines.iter().filter(|l| l.is_some()).count() as u16;
    (len, lines)
}

/// Decodes a whole payload (the bytes [`for_each_payload_byte`] emits, which the service
/// port transfers) into `program`, cleared first. `false` (and an empty program) when the
/// bytes are not whole ascending runs of decodable lines: a program is never half read.
pub fn program_from_payload(bytes: &[u8], program: &mut Program) -> bool {
    *program = Program::default();
    let mut parser = PayloadParser::new();
    for &b in bytes {
        parser.feed(b, |line, i| {
            if let Some(slot) = program.lines.get_mut(usize::from(line)) {
                *slot = Some(i);
            }
        });
    }
    let ok = parser.finished_ok(parser.lines);
    if !ok {
        *program = Program::default();
    }
    ok
}

/// Incremental payload decoder: fed byte by byte, reports each decoded line.
#[derive(Debug, Clone, Copy)]
pub struct PayloadParser {
    state: ParseState,
    next_line: u16,
    run_left: u8,
    first_hi: u8,
    line_buf: [u8; LINE_BYTES],
    line_pos: usize,
    lines: u16,
    failed: bool,
    /// The failure was a line that does not decode (else the runs' layout).
    undecodable: bool,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum ParseState {
    FirstHi,
    FirstLo,
    Count,
    Line,
}

impl Default for PayloadParser {
    fn default() -> Self {
        Self::new()
    }
}

impl PayloadParser {
    /// A parser before the first byte of a payload.
    pub fn new() -> Self {
        PayloadParser {
            state: ParseState::FirstHi,
            next_line: 0,
            run_left: 0,
            first_hi: 0,
            line_buf: [0; LINE_BYTES],
            line_pos: 0,
            lines: 0,
            failed: false,
            undecodable: false,
        }
    }

    /// Where and why the bytes stopped being a payload: the line being decoded (or the
    /// run's first line) and whether its bytes were no instruction (else the runs'
    /// layout was wrong). `None` while everything decoded.
    pub fn failure(&self) -> Option<(u16, bool)> {
        self.failed.then_some((self.next_line, self.undecodable))
    }

    /// The line being decoded, or the first line of the run being read.
    pub fn at_line(&self) -> u16 {
        self.next_line
    }

    /// Used lines decoded so far.
    pub fn lines(&self) -> u16 {
        self.lines
    }

    /// Takes the next payload byte; `apply` gets each line (number, instruction) as soon
    /// as its last byte is in. After the first error the bytes are ignored ([`Self::failure`]).
    pub fn feed(&mut self, byte: u8, mut apply: impl FnMut(u16, Instruction)) {
        if self.failed {
            return;
        }
        match self.state {
            ParseState::FirstHi => {
                self.first_hi = byte;
                self.state = ParseState::FirstLo;
            }
            ParseState::FirstLo => {
                let first = u16::from_be_bytes([self.first_hi, byte]);
                // Runs ascend and never overlap; that also makes every line unique.
                if first < self.next_line || usize::from(first) >= LINES {
                    self.failed = true;
                }
                self.next_line = first;
                self.state = ParseState::Count;
            }
            ParseState::Count => {
                if byte == 0 || usize::from(self.next_line) + usize::from(byte) > LINES {
                    self.failed = true;
                }
                self.run_left = byte;
                self.line_pos = 0;
                self.state = ParseState::Line;
            }
            ParseState::Line => {
                if let Some(slot) = self.line_buf.get_mut(self.line_pos) {
                    *slot = byte;
                }
                self.line_pos += 1;
                if self.line_pos == LINE_BYTES {
                    self.line_pos = 0;
                    match decode_line(&self.line_buf) {
                        Ok(i) => apply(self.next_line, i),
                        Err(_) => {
                            self.failed = true;
                            self.undecodable = true;
                            return;
                        }
                    }
                    self.lines = self.lines.saturating_add(1);
                    self.next_line = self.next_line.saturating_add(1);
                    self.run_left = self.run_left.saturating_sub(1);
                    if self.run_left == 0 {
                        self.state = ParseState::FirstHi;
                    }
                }
            }
        }
    }

    /// After the last byte: whether the bytes were whole runs of `lines` decodable lines.
    pub fn finished_ok(&self, lines: u16) -> bool {
        !self.failed && self.state == ParseState::FirstHi && self.lines == lines
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::program::testing::sparse_program as sample;

    #[test]
    fn runs_give_the_size() {
        let (len, lines) = payload_size(&sample());
        // Runs: 0..=2, 150..=151, 400, 999.
        assert_eq!(len, 4 * 3 + 7 * 4);
        assert_eq!(lines, 7);
        assert_eq!(payload_size(&Program::default()), (0, 0));
    }

    #[test]
    fn a_payload_decodes_to_its_program_and_a_cut_one_to_nothing() {
        let p = sample();
        let mut bytes = Vec::new();
        for_each_payload_byte(&p, |b| bytes.push(b));
        let mut q = Program::default();
        assert!(program_from_payload(&bytes, &mut q));
        assert_eq!(q, p);
        for cut in [1, 3, 5, bytes.len() - 1] {
            assert!(!program_from_payload(&bytes[..cut], &mut q), "{cut}");
            assert_eq!(q, Program::default(), "{cut}");
        }
        let mut bad = bytes.clone();
        bad[2] = 0; // a run of 0 lines
        assert!(!program_from_payload(&bad, &mut q));
        assert!(program_from_payload(&[], &mut q));
        assert_eq!(q, Program::default());
    }
}
