//! The PLC board's character LCD: a PCF8574 I2C I/O expander ("backpack") driving an
//! HD44780 controller in 4-bit mode, from the PCF8574 (NXP/TI) and HD44780U (Hitachi)
//! datasheets.
//!
//! # PCF8574
//! Address 0b0100_A2A1A0 (0x27 with A2..A0 high; a PCF8574A would be 0x38..0x3F). Each byte
//! written sets the eight quasi-bidirectional pins (after its ACK, when the bus delivers it);
//! a read returns the pin levels: a pin whose latch is 1 is only pulled up weakly, so the
//! HD44780 can drive it low while it outputs data. Power-on latch: 0xFF (all high).
//! Wiring (the common backpack): P0 = RS, P1 = R/W, P2 = E, P3 = backlight, P4..P7 = D4..D7.
//!
//! # HD44780
//! * Powers up in 8-bit mode (DB0..DB3 unconnected read as 1: the chip's pull-ups), 1 line,
//!   display off, increment, DDRAM cleared to spaces by the internal reset, busy for
//!   [`POWER_ON_BUSY`] (the datasheet's "wait for more than 15 ms after VCC rises to
//!   4.5 V" before initialising by instruction).
//! * Latches on the falling edge of E; in 4-bit mode two transfers (high nibble first) make
//!   one byte. Reads (R/W = 1) drive D7..D4 while E is high: busy flag + address counter
//!   (RS = 0) or RAM data (RS = 1).
//! * Initialising by instruction: the first function set after power-on keeps the chip busy
//!   4.1 ms, the second 100 us (the datasheet's required waits); 0x3, 0x3, 0x3, 0x2 then
//!   puts it in 4-bit mode from any state.
//! * Execution times at fosc = 270 kHz, scaled by 270 kHz / fosc ([`Hd44780::with_fosc_hz`]):
//!   clear display and return home 1.52 ms, every other instruction and data write 37 us
//!   (tADD, the 4 us until the address counter moves, is not modelled).
//! * An instruction or data byte completed while the chip is busy is ignored and counted
//!   ([`Hd44780::busy_violations`]). The 4-bit nibble phase still advances (the interface
//!   latches every E pulse).
//! * DDRAM address map of the datasheet: 2-line mode 0x00..0x27 and 0x40..0x67, the address
//!   counter going 0x27 -> 0x40 and 0x67 -> 0x00; 1-line mode 0x00..0x4F. A 20 x 4 module
//!   shows line 1 on rows 1 and 3 and line 2 on rows 2 and 4, so its rows start at 0x00,
//!   0x40, 0x14, 0x54 and writing past 0x13 continues on the third row (0x14), not the
//!   second. Display shift moves the 40-character window of both lines.
//!
//! # Timing checks
//! * [`setup_violations`]: a PCF8574 write that raises E and, in the same write, changes RS,
//!   R/W or D4..D7 (tAS, the set-up before E rises, cannot be met: the pins change together).
//!   The fixed driver's `[b, b | E, b]` per nibble makes none.
//! * [`hold_violations`]: a write that lowers E and changes RS, R/W or D4..D7 in a write
//!   cycle (tAH/tH). The values latched are those before the write.
//! * [`busy_violations`]: see above (e.g. the next command sent too soon after a clear).
//!
//! [`setup_violations`]: LcdBackpack::setup_violations
//! [`hold_violations`]: LcdBackpack::hold_violations
//! [`busy_violations`]: LcdBackpack::busy_violations

use crate::periph::i2c::I2cDevice;
use crate::time::{ns_to_cycles, Cycles};

/// PCF8574 pins.
pub const RS: u8 = 1 << 0;
pub const RW: u8 = 1 << 1;
pub const E: u8 = 1 << 2;
pub const BACKLIGHT: u8 = 1 << 3;
const DATA: u8 = 0xF0;

/// Address of a PCF8574 backpack with A2..A0 high.
pub const DEFAULT_ADDRESS: u8 = 0x27;
/// The module's geometry.
pub const COLS: usize = 20;
pub const ROWS: usize = 4;
/// Busy after power-on (datasheet: wait more than 15 ms after VCC reaches 4.5 V).
pub const POWER_ON_BUSY: Cycles = 15_000 * crate::time::CYCLES_PER_US;
/// Oscillator frequency the datasheet's execution times are given for.
pub const FOSC_NOMINAL_HZ: u64 = 270_000;

const CLEAR_NS: u64 = 1_520_000;
const HOME_NS: u64 = 1_520_000;
const INSTRUCTION_NS: u64 = 37_000;
const FIRST_FUNCTION_SET_NS: u64 = 4_100_000;
const SECOND_FUNCTION_SET_NS: u64 = 100_000;
/// Characters per DDRAM line in 2-line mode.
const LINE: usize = 40;

/// The HD44780 controller.
#[derive(Debug, Clone)]
pub struct Hd44780 {
    ddram: [u8; 80],
    cgram: [u8; 64],
    ac: u8,
    /// The address counter points into CGRAM.
    cg: bool,
    eight_bit: bool,
    two_lines: bool,
    font_5x10: bool,
    display_on: bool,
    cursor_on: bool,
    blink_on: bool,
    increment: bool,
    shift_on_write: bool,
    /// First DDRAM position of the visible window (display shift).
    shift: u8,
    /// 4-bit mode: the high nibble of the byte in transfer.
    high_nibble: Option<u8>,
    /// 4-bit read: the byte being read and whether its high nibble was output.
    read_byte: u8,
    /// D7..D4 this chip drives (during a read with E high).
    driving: Option<u8>,
    busy_until: Cycles,
    function_sets: u32,
    fosc_hz: u64,
    power_on_busy: Cycles,
    busy_violations: u64,
    instructions: u64,
    data_writes: u64,
}

impl Hd44780 {
    /// A chip powered on at `now`.
    pub fn new(now: Cycles) -> Self {
        Self::powered(now, FOSC_NOMINAL_HZ, POWER_ON_BUSY)
    }

    /// The state after the internal reset at `now`, busy for `wait`.
    fn powered(now: Cycles, fosc_hz: u64, wait: Cycles) -> Self {
        Hd44780 {
            ddram: [b' '; 80],
            cgram: [0; 64],
            ac: 0,
            cg: false,
            eight_bit: true,
            two_lines: false,
            font_5x10: false,
            display_on: false,
            cursor_on: false,
            blink_on: false,
            increment: true,
            shift_on_write: false,
            shift: 0,
            high_nibble: None,
            read_byte: 0,
            driving: None,
            busy_until: now + wait,
            function_sets: 0,
            fosc_hz,
            power_on_busy: wait,
            busy_violations: 0,
            instructions: 0,
            data_writes: 0,
        }
    }

    /// The oscillator frequency (190..350 kHz over supply and temperature): execution
    /// times scale with 270 kHz / fosc.
    pub fn with_fosc_hz(mut self, hz: u64) -> Self {
        self.fosc_hz = hz.max(1);
        self
    }

    /// Power-up state (internal reset) at `now`, busy for the power-on time. The
    /// violation counters keep counting across power cycles.
    pub fn power_on(&mut self, now: Cycles) {
        let mut fresh = Self::powered(now, self.fosc_hz, self.power_on_busy);
        fresh.busy_violations = self.busy_violations;
        fresh.instructions = self.instructions;
        fresh.data_writes = self.data_writes;
        *self = fresh;
    }

    /// Whether the chip is busy at `now` (the busy flag).
    pub fn busy(&self, now: Cycles) -> bool {
        now < self.busy_until
    }

    /// End of the current busy time.
    pub fn busy_until(&self) -> Cycles {
        self.busy_until
    }

    /// Instructions and data arriving while busy (ignored).
    pub fn busy_violations(&self) -> u64 {
        self.busy_violations
    }

    /// Instructions executed.
    pub fn instructions(&self) -> u64 {
        self.instructions
    }

    /// Data bytes written to DDRAM/CGRAM.
    pub fn data_writes(&self) -> u64 {
        self.data_writes
    }

    pub fn four_bit(&self) -> bool {
        !self.eight_bit
    }

    pub fn two_lines(&self) -> bool {
        self.two_lines
    }

    pub fn font_5x10(&self) -> bool {
        self.font_5x10
    }

    pub fn display_on(&self) -> bool {
        self.display_on
    }

    /// Underline cursor on (and display on: what a user sees).
    pub fn cursor_visible(&self) -> bool {
        self.display_on && self.cursor_on
    }

    /// Blinking block cursor on (and display on).
    pub fn blink(&self) -> bool {
        self.display_on && self.blink_on
    }

    /// Entry mode: (increment, shift display on write).
    pub fn entry_mode(&self) -> (bool, bool) {
        (self.increment, self.shift_on_write)
    }

    /// The address counter (DDRAM or CGRAM address) and whether it points into CGRAM.
    pub fn address_counter(&self) -> (u8, bool) {
        (self.ac, self.cg)
    }

    /// The 80 DDRAM bytes (2-line mode: 0x00..0x27 then 0x40..0x67).
    pub fn ddram(&self) -> &[u8; 80] {
        &self.ddram
    }

    pub fn cgram(&self) -> &[u8; 64] {
        &self.cgram
    }

    /// The DDRAM position shown at (row, col) of the 20 x 4 module.
    fn cell_index(&self, row: usize, col: usize) -> Option<usize> {
        if self.two_lines {
            let line = row % 2;
            let pos = ((row / 2) * COLS + col + usize::from(self.shift)) % LINE;
            Some(line * LINE + pos)
        } else if row.is_multiple_of(2) {
            // 1-line mode: only the first line's common drivers run.
            Some(((row / 2) * COLS + col + usize::from(self.shift)) % 80)
        } else {
            None
        }
    }

    /// What a user sees: the character codes of the 4 x 20 cells (spaces when the display
    /// is off or a row is not driven).
    pub fn rows(&self) -> [[u8; COLS]; ROWS] {
        let mut out = [[b' '; COLS]; ROWS];
        if !self.display_on {
            return out;
        }
        for (r, row) in out.iter_mut().enumerate() {
            for (c, cell) in row.iter_mut().enumerate() {
                if let Some(i) = self.cell_index(r, c) {
                    *cell = self.ddram.get(i).copied().unwrap_or(b' ');
                }
            }
        }
        out
    }

    /// Row `row` as text (character ROM A00: ASCII 0x20..0x7D with 0x5C = '¥', 0x7E = '→',
    /// 0x7F = '←'; CGRAM characters 0x00..0x0F and the rest shown as '?').
    pub fn row_text(&self, row: usize) -> String {
        let rows = self.rows();
        rows.get(row)
            .map(|r| r.iter().map(|b| rom_a00(*b)).collect())
            .unwrap_or_default()
    }

    /// Where the cursor is on the screen (row, col), if the address counter points at a
    /// visible DDRAM cell.
    pub fn cursor(&self) -> Option<(u8, u8)> {
        if self.cg {
            return None;
        }
        let want = self.ddram_index(self.ac)?;
        for r in 0..ROWS {
            for c in 0..COLS {
                if self.cell_index(r, c) == Some(want) {
                    return Some((r as u8, c as u8));
                }
            }
        }
        None
    }

    fn ddram_index(&self, ac: u8) -> Option<usize> {
        let ac = usize::from(ac);
        if self.two_lines {
            let off = ac & 0x3F;
            (off < LINE).then_some(if ac & 0x40 != 0 { LINE + off } else { off })
        } else {
            (ac < 80).then_some(ac)
        }
    }

    fn step_ac(&mut self, up: bool) {
        if self.cg {
            self.ac = if up {
                self.ac + 1
            } else {
                self.ac.wrapping_sub(1)
            } & 0x3F;
            return;
        }
        self.ac = match (self.two_lines, up, self.ac) {
            (true, true, 0x27) => 0x40,
            (true, true, 0x67) => 0x00,
            (true, false, 0x40) => 0x27,
            (true, false, 0x00) => 0x67,
            (false, true, 0x4F) => 0x00,
            (false, false, 0x00) => 0x4F,
            (_, true, a) => (a + 1) & 0x7F,
            (_, false, a) => a.wrapping_sub(1) & 0x7F,
        };
    }

    fn shift_window(&mut self, left: bool) {
        let n = if self.two_lines { LINE as u8 } else { 80 };
        self.shift = if left {
            (self.shift + 1) % n
        } else {
            (self.shift + n - 1) % n
        };
    }

    fn scaled(&self, ns: u64) -> Cycles {
        ns_to_cycles(ns * FOSC_NOMINAL_HZ / self.fosc_hz)
    }

    /// E rises: on a read, the chip drives D7..D4.
    fn e_rise(&mut self, rs: bool, rw: bool, now: Cycles) {
        if !rw {
            return;
        }
        let first = self.eight_bit || self.high_nibble.is_none();
        if first {
            self.read_byte = if rs {
                self.read_ram()
            } else {
                (u8::from(self.busy(now)) << 7) | (self.ac & 0x7F)
            };
        }
        let nibble = if first {
            self.read_byte >> 4
        } else {
            self.read_byte & 0x0F
        };
        self.driving = Some(nibble);
    }

    fn read_ram(&self) -> u8 {
        if self.cg {
            self.cgram
                .get(usize::from(self.ac & 0x3F))
                .copied()
                .unwrap_or(0)
        } else {
            self.ddram_index(self.ac)
                .and_then(|i| self.ddram.get(i).copied())
                .unwrap_or(b' ')
        }
    }

    /// E falls: the chip latches D7..D4 (a write) or ends a read.
    fn e_fall(&mut self, rs: bool, rw: bool, d: u8, now: Cycles) {
        self.driving = None;
        let complete = if self.eight_bit {
            // DB3..DB0 are not connected: the chip's pull-ups read them as 1.
            Some((d << 4) | 0x0F)
        } else {
            match self.high_nibble.take() {
                None => {
                    self.high_nibble = Some(d);
                    None
                }
                Some(h) => Some((h << 4) | d),
            }
        };
        let Some(byte) = complete else {
            return;
        };
        if rw {
            if rs {
                // A data read moves the address counter.
                self.step_ac(self.increment);
            }
            return;
        }
        if self.busy(now) {
            self.busy_violations += 1;
            return;
        }
        let ns = if rs {
            self.write_data(byte);
            INSTRUCTION_NS
        } else {
            self.instruction(byte)
        };
        self.busy_until = now + self.scaled_or_fixed(byte, rs, ns);
    }

    /// The init-by-instruction waits are datasheet requirements, not oscillator periods.
    fn scaled_or_fixed(&self, byte: u8, rs: bool, ns: u64) -> Cycles {
        if !rs && byte & 0xE0 == 0x20 && ns != INSTRUCTION_NS {
            ns_to_cycles(ns)
        } else {
            self.scaled(ns)
        }
    }

    fn write_data(&mut self, byte: u8) {
        self.data_writes += 1;
        if self.cg {
            if let Some(c) = self.cgram.get_mut(usize::from(self.ac & 0x3F)) {
                *c = byte;
            }
        } else if let Some(i) = self.ddram_index(self.ac) {
            if let Some(c) = self.ddram.get_mut(i) {
                *c = byte;
            }
        }
        self.step_ac(self.increment);
        if self.shift_on_write {
            self.shift_window(self.increment);
        }
    }

    /// Executes an instruction; returns its execution time in ns at 270 kHz.
    fn instruction(&mut self, b: u8) -> u64 {
        self.instructions += 1;
        if b & 0x80 != 0 {
            self.ac = b & 0x7F;
            self.cg = false;
        } else if b & 0x40 != 0 {
            self.ac = b & 0x3F;
            self.cg = true;
        } else if b & 0x20 != 0 {
            self.eight_bit = b & 0x10 != 0;
            self.two_lines = b & 0x08 != 0;
            self.font_5x10 = b & 0x04 != 0;
            self.high_nibble = None;
            self.function_sets += 1;
            return match self.function_sets {
                1 => FIRST_FUNCTION_SET_NS,
                2 => SECOND_FUNCTION_SET_NS,
                _ => INSTRUCTION_NS,
            };
        } else if b & 0x10 != 0 {
            let right = b & 0x04 != 0;
            if b & 0x08 != 0 {
                // Display shift: "right" moves the text right, the window left.
                self.shift_window(!right);
            } else {
                self.step_ac(right);
            }
        } else if b & 0x08 != 0 {
            self.display_on = b & 0x04 != 0;
            self.cursor_on = b & 0x02 != 0;
            self.blink_on = b & 0x01 != 0;
        } else if b & 0x04 != 0 {
            self.increment = b & 0x02 != 0;
            self.shift_on_write = b & 0x01 != 0;
        } else if b & 0x02 != 0 {
            self.ac = 0;
            self.cg = false;
            self.shift = 0;
            return HOME_NS;
        } else if b & 0x01 != 0 {
            self.ddram = [b' '; 80];
            self.ac = 0;
            self.cg = false;
            self.shift = 0;
            self.increment = true;
            return CLEAR_NS;
        }
        INSTRUCTION_NS
    }
}

fn rom_a00(b: u8) -> char {
    match b {
        0x5C => '¥',
        0x7E => '→',
        0x7F => '←',
        0x20..=0x7D => char::from(b),
        _ => '?',
    }
}

/// A PCF8574 backpack with its HD44780.
#[derive(Debug, Clone)]
pub struct LcdBackpack {
    address: u8,
    latch: u8,
    hd: Hd44780,
    epoch: u32,
    writes: u64,
    setup_violations: u64,
    hold_violations: u64,
}

impl Default for LcdBackpack {
    fn default() -> Self {
        Self::new(DEFAULT_ADDRESS)
    }
}

impl LcdBackpack {
    /// A backpack at `address`, both chips powered on at cycle 0.
    pub fn new(address: u8) -> Self {
        LcdBackpack {
            address,
            latch: 0xFF,
            hd: Hd44780::new(0),
            epoch: 0,
            writes: 0,
            setup_violations: 0,
            hold_violations: 0,
        }
    }

    /// The HD44780's oscillator (see [`Hd44780::with_fosc_hz`]).
    pub fn with_fosc_hz(mut self, hz: u64) -> Self {
        self.hd = self.hd.with_fosc_hz(hz);
        self
    }

    /// Power cycle of the module at `now`: latch 0xFF, the HD44780 reset and busy.
    pub fn power_on(&mut self, now: Cycles) {
        self.latch = 0xFF;
        self.hd.power_on(now);
        self.epoch = self.epoch.wrapping_add(1);
    }

    /// The controller (screen contents, cursor, modes, busy violations).
    pub fn lcd(&self) -> &Hd44780 {
        &self.hd
    }

    /// The PCF8574 output latch.
    pub fn latch(&self) -> u8 {
        self.latch
    }

    /// Pin levels as a PCF8574 read returns them.
    pub fn pins(&self) -> u8 {
        match self.hd.driving {
            Some(n) if self.latch & (E | RW) == (E | RW) => self.latch & ((n << 4) | 0x0F),
            _ => self.latch,
        }
    }

    /// Backlight on (P3).
    pub fn backlight(&self) -> bool {
        self.latch & BACKLIGHT != 0
    }

    /// The four rows as text.
    pub fn text(&self) -> [String; ROWS] {
        std::array::from_fn(|r| self.hd.row_text(r))
    }

    /// Bytes written to the PCF8574.
    pub fn writes(&self) -> u64 {
        self.writes
    }

    /// E raised in the same write that changed RS, R/W or D4..D7 (tAS not met).
    pub fn setup_violations(&self) -> u64 {
        self.setup_violations
    }

    /// E lowered in the same write that changed RS, R/W or D4..D7 of a write cycle.
    pub fn hold_violations(&self) -> u64 {
        self.hold_violations
    }

    /// Instructions/data ignored because the HD44780 was busy.
    pub fn busy_violations(&self) -> u64 {
        self.hd.busy_violations()
    }

    /// The pins change to `new` at `now`.
    fn set_pins(&mut self, new: u8, now: Cycles) {
        let old = self.latch;
        self.latch = new;
        self.writes += 1;
        let changed = (old ^ new) & (RS | RW | DATA);
        let (e_old, e_new) = (old & E != 0, new & E != 0);
        if !e_old && e_new {
            if changed != 0 {
                self.setup_violations += 1;
            }
            self.hd.e_rise(new & RS != 0, new & RW != 0, now);
        } else if e_old && !e_new {
            if old & RW == 0 && changed != 0 {
                self.hold_violations += 1;
            }
            // The chip latches what was on its inputs while E was high.
            self.hd.e_fall(old & RS != 0, old & RW != 0, old >> 4, now);
        }
    }
}

impl I2cDevice for LcdBackpack {
    fn address(&self) -> u8 {
        self.address
    }

    fn start(&mut self, address: u8, _read: bool, _now: Cycles) -> bool {
        address == self.address
    }

    fn write(&mut self, byte: u8, now: Cycles) -> bool {
        self.set_pins(byte, now);
        true
    }

    fn read(&mut self, _now: Cycles) -> u8 {
        self.pins()
    }

    fn stop(&mut self, _now: Cycles) {}

    fn power_epoch(&self) -> u32 {
        self.epoch
    }
}

#[cfg(test)]
mod tests;
