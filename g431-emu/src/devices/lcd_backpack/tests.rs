//! Tests of the PCF8574 + HD44780 model: the PLC image's driver through the I2C model, and
//! the controller's documented behaviour at device level.

use std::cell::RefCell;
use std::rc::Rc;

use super::*;
use crate::periph::i2c::embassy_driver::{Embassy, TIMINGR_100K};
use crate::periph::i2c::{I2c, I2cInstance};
use crate::time::CYCLES_PER_US;

const US: Cycles = CYCLES_PER_US;
const MS: Cycles = 1000 * US;

/// `plc-image/src/board/lcd.rs` replayed through embassy's blocking driver: `fixed`
/// selects the D14 fix (`[b, b|E, b]` per nibble) instead of the image's `[b|E, b]`.
struct ImageLcd<'e, 'a> {
    e: &'e mut Embassy<'a>,
    fixed: bool,
}

impl ImageLcd<'_, '_> {
    fn write_raw(&mut self, bytes: &[u8]) {
        assert_eq!(self.e.blocking_write(DEFAULT_ADDRESS, bytes), Ok(()));
    }

    fn nibble(&mut self, value: u8, rs: u8) {
        let b = (value & 0xF0) | rs | BACKLIGHT;
        if self.fixed {
            self.write_raw(&[b, b | E, b]);
        } else {
            self.write_raw(&[b | E, b]);
        }
    }

    fn byte(&mut self, value: u8, rs: u8) {
        let hi = (value & 0xF0) | rs | BACKLIGHT;
        let lo = (value << 4) | rs | BACKLIGHT;
        if self.fixed {
            self.write_raw(&[hi, hi | E, hi, lo, lo | E, lo]);
        } else {
            self.write_raw(&[hi | E, hi, lo | E, lo]);
        }
    }

    fn command(&mut self, c: u8) {
        self.byte(c, 0);
    }

    /// `Lcd::new`: initialising by instruction, 4-bit, 2 lines, display off, clear (the
    /// image waits 2 ms, the fix 3 ms), entry mode, display on.
    fn init(&mut self, clear_wait: Cycles) {
        self.e.wait(50 * MS);
        for wait_us in [4500, 150, 150] {
            self.nibble(0x30, 0);
            self.e.wait(wait_us * US);
        }
        self.nibble(0x20, 0);
        self.command(0x28);
        self.command(0x08);
        self.command(0x01);
        self.e.wait(clear_wait);
        self.command(0x06);
        self.command(0x0C);
    }

    fn goto(&mut self, row: u8, col: u8) {
        const ROW_ADDR: [u8; 4] = [0x00, 0x40, 0x14, 0x54];
        self.command(0x80 | (ROW_ADDR[usize::from(row)] + col));
    }

    fn text(&mut self, s: &str) {
        for b in s.bytes() {
            self.byte(b, RS);
        }
    }
}

fn bus() -> (I2c, Rc<RefCell<LcdBackpack>>) {
    let mut i2c = I2c::new(I2cInstance::I2c1);
    let lcd = Rc::new(RefCell::new(LcdBackpack::default()));
    i2c.attach(lcd.clone());
    (i2c, lcd)
}

fn padded(s: &str) -> String {
    format!("{s:<20}")
}

#[test]
fn image_init_and_hello_on_row_1() {
    let (mut i2c, lcd) = bus();
    let mut e = Embassy::new(&mut i2c, 0);
    e.init(TIMINGR_100K);
    let mut d = ImageLcd {
        e: &mut e,
        fixed: false,
    };
    d.init(2 * MS);
    d.goto(1, 0);
    d.text("HELLO");
    let l = lcd.borrow();
    assert_eq!(
        l.text(),
        [padded(""), padded("HELLO"), padded(""), padded("")]
    );
    let c = l.lcd();
    assert!(c.four_bit() && c.two_lines() && !c.font_5x10() && c.display_on());
    assert!(!c.cursor_visible() && !c.blink());
    assert_eq!(c.cursor(), Some((1, 5)));
    assert!(l.backlight());
    // At 270 kHz the image's timing is enough...
    assert_eq!(l.busy_violations(), 0);
    assert_eq!(l.hold_violations(), 0);
    // ...but every nibble whose RS/D4-D7 differ from the previous write raises E in the
    // same PCF8574 write (D14): 1 in the init nibbles, 9 in the five commands, 1 in the
    // goto, 10 in "HELLO".
    assert_eq!(l.setup_violations(), 21);
}

#[test]
fn fixed_driver_pattern_makes_no_setup_violation() {
    let (mut i2c, lcd) = bus();
    let mut e = Embassy::new(&mut i2c, 0);
    e.init(TIMINGR_100K);
    let mut d = ImageLcd {
        e: &mut e,
        fixed: true,
    };
    d.init(3 * MS);
    d.goto(1, 0);
    d.text("HELLO");
    let l = lcd.borrow();
    assert_eq!(l.text()[1], padded("HELLO"));
    assert_eq!(l.setup_violations(), 0);
    assert_eq!(l.hold_violations(), 0);
    assert_eq!(l.busy_violations(), 0);
}

#[test]
fn data_sent_too_soon_after_clear_is_ignored_and_counted() {
    let (mut i2c, lcd) = bus();
    let mut e = Embassy::new(&mut i2c, 0);
    e.init(TIMINGR_100K);
    let mut d = ImageLcd {
        e: &mut e,
        fixed: true,
    };
    d.init(3 * MS);
    d.text("AB");
    assert_eq!(lcd.borrow().text()[0], padded("AB"));
    // Clear, then at once a character: the six-byte transaction (~0.6 ms) ends well
    // inside the 1.52 ms clear.
    d.command(0x01);
    d.text("X");
    assert_eq!(lcd.borrow().busy_violations(), 1);
    assert_eq!(lcd.borrow().text()[0], padded(""), "X was ignored");
    d.e.wait(2 * MS);
    d.text("Y");
    assert_eq!(lcd.borrow().text()[0], padded("Y"));
    assert_eq!(lcd.borrow().busy_violations(), 1);
}

/// D14: at fosc = 190 kHz a clear takes 1.52 ms x 270 / 190 = 2.16 ms. The image waits
/// 2 ms; the I2C transfer of the next command (START, address, four bytes) brings its
/// completion to about 2.5 ms, so it still gets through; an oscillator below the
/// datasheet's range (150 kHz: 2.74 ms) makes it fail.
#[test]
fn images_2_ms_clear_wait_is_covered_by_the_i2c_latency_down_to_190_khz() {
    for (hz, violations) in [(270_000, 0), (190_000, 0), (150_000, 1)] {
        let mut i2c = I2c::new(I2cInstance::I2c1);
        let lcd = Rc::new(RefCell::new(LcdBackpack::default().with_fosc_hz(hz)));
        i2c.attach(lcd.clone());
        let mut e = Embassy::new(&mut i2c, 0);
        e.init(TIMINGR_100K);
        let mut d = ImageLcd {
            e: &mut e,
            fixed: false,
        };
        d.init(2 * MS);
        assert_eq!(lcd.borrow().busy_violations(), violations, "{hz} Hz");
        assert!(
            lcd.borrow().lcd().display_on(),
            "0x0C arrives after the clear"
        );
    }
}

/// Device-level driver: one PCF8574 write every 100 us (an I2C byte takes ~95 us).
struct Raw {
    b: LcdBackpack,
    now: Cycles,
}

impl Raw {
    fn new() -> Self {
        Raw {
            b: LcdBackpack::default(),
            now: 0,
        }
    }

    fn put(&mut self, v: u8) {
        self.now += 100 * US;
        self.b.write(v, self.now);
    }

    fn nibble(&mut self, v: u8, rs: u8) {
        let b = (v & 0xF0) | rs | BACKLIGHT;
        self.put(b);
        self.put(b | E);
        self.put(b);
    }

    fn byte(&mut self, v: u8, rs: u8) {
        self.nibble(v, rs);
        self.nibble(v << 4, rs);
    }

    fn wait(&mut self, c: Cycles) {
        self.now += c;
    }

    fn init(&mut self) {
        self.wait(50 * MS);
        for w in [4500, 150, 150] {
            self.nibble(0x30, 0);
            self.wait(w * US);
        }
        self.nibble(0x20, 0);
        for c in [0x28, 0x08, 0x01] {
            self.byte(c, 0);
        }
        self.wait(3 * MS);
        self.byte(0x06, 0);
        self.byte(0x0C, 0);
    }

    fn text(&mut self, s: &[u8]) {
        for b in s {
            self.byte(*b, RS);
        }
    }
}

#[test]
fn power_up_state_and_low_nibble_pull_ups() {
    let mut r = Raw::new();
    assert_eq!(r.b.latch(), 0xFF, "PCF8574 outputs high at power-on");
    let c = r.b.lcd();
    assert!(!c.four_bit() && !c.two_lines() && !c.display_on());
    assert_eq!(c.rows(), [[b' '; COLS]; ROWS]);
    r.wait(50 * MS);
    for w in [4500, 150, 150] {
        r.nibble(0x30, 0);
        r.wait(w * US);
    }
    r.nibble(0x20, 0);
    // In 8-bit mode DB3..DB0 read 1: 0x2 latched as function set 0x2F (N=1, F=1).
    let c = r.b.lcd();
    assert!(c.four_bit() && c.two_lines() && c.font_5x10());
    assert_eq!(r.b.busy_violations(), 0);
    r.byte(0x28, 0);
    assert!(!r.b.lcd().font_5x10());
}

#[test]
fn instructions_during_power_up_and_init_waits_are_ignored() {
    let mut r = Raw::new();
    // 5 ms after power-on: still busy (15 ms).
    r.wait(5 * MS);
    r.nibble(0x30, 0);
    assert_eq!(r.b.busy_violations(), 1);
    r.wait(20 * MS);
    r.nibble(0x30, 0);
    // The second 0x3 only 1 ms after the first: inside the required 4.1 ms.
    r.wait(MS);
    r.nibble(0x30, 0);
    assert_eq!(r.b.busy_violations(), 2);
    r.wait(5 * MS);
    r.nibble(0x30, 0);
    r.wait(150 * US);
    r.nibble(0x30, 0);
    assert_eq!(r.b.busy_violations(), 2);
}

#[test]
fn ddram_address_map_of_a_20x4_module() {
    let mut r = Raw::new();
    r.init();
    r.text(b"ABCDEFGHIJKLMNOPQRST");
    // 0x13 -> 0x14: the 21st character goes to the third row.
    r.text(b"U");
    let rows = r.b.lcd().rows();
    assert_eq!(&rows[0], b"ABCDEFGHIJKLMNOPQRST");
    assert_eq!(rows[1], [b' '; COLS]);
    assert_eq!(rows[2][0], b'U');
    assert_eq!(r.b.lcd().cursor(), Some((2, 1)));
    // 0x27 (row 3, last column) -> 0x40 (row 2, first column).
    r.byte(0x80 | 0x27, 0);
    r.text(b"vw");
    let rows = r.b.lcd().rows();
    assert_eq!(rows[2][19], b'v');
    assert_eq!(rows[1][0], b'w');
    // 0x67 (row 4, last column) -> 0x00.
    r.byte(0x80 | 0x67, 0);
    r.text(b"yz");
    let rows = r.b.lcd().rows();
    assert_eq!(rows[3][19], b'y');
    assert_eq!(rows[0][0], b'z');
    assert_eq!(r.b.lcd().address_counter(), (0x01, false));
    // Decrement mode goes back across the same boundaries.
    r.byte(0x04, 0);
    r.byte(0x80 | 0x40, 0);
    r.text(b"12");
    assert_eq!(r.b.lcd().rows()[1][0], b'1');
    assert_eq!(r.b.lcd().rows()[2][19], b'2');
}

#[test]
fn cursor_blink_display_and_backlight_reports() {
    let mut r = Raw::new();
    r.init();
    r.byte(0x80 | 0x54 | 3, 0);
    assert_eq!(r.b.lcd().cursor(), Some((3, 3)));
    r.byte(0x0D, 0);
    assert!(r.b.lcd().blink() && !r.b.lcd().cursor_visible());
    r.byte(0x0E, 0);
    assert!(!r.b.lcd().blink() && r.b.lcd().cursor_visible());
    r.text(b"~");
    assert_eq!(r.b.text()[3].chars().nth(3), Some('→'));
    // Display off: the user sees nothing, DDRAM keeps the text.
    r.byte(0x08, 0);
    assert_eq!(r.b.lcd().rows(), [[b' '; COLS]; ROWS]);
    assert_eq!(r.b.lcd().ddram()[40 + 20 + 3], b'~');
    assert!(!r.b.lcd().cursor_visible());
    // Backlight is P3 of the PCF8574.
    assert!(r.b.backlight());
    r.put(0x00);
    assert!(!r.b.backlight());
    // CGRAM addressing: no cursor on screen.
    r.put(BACKLIGHT);
    r.byte(0x40, 0);
    assert_eq!(r.b.lcd().cursor(), None);
}

#[test]
fn display_shift_moves_the_visible_window() {
    let mut r = Raw::new();
    r.init();
    r.text(b"0123");
    r.byte(0x18, 0); // shift display left
    assert_eq!(&r.b.lcd().rows()[0][..3], b"123");
    assert_eq!(
        r.b.lcd().cursor(),
        Some((0, 3)),
        "the cursor moves with the text"
    );
    r.byte(0x1C, 0); // shift right
    assert_eq!(&r.b.lcd().rows()[0][..4], b"0123");
    r.byte(0x10, 0); // cursor left
    assert_eq!(r.b.lcd().cursor(), Some((0, 3)));
    r.byte(0x02, 0); // return home
    assert_eq!(r.b.lcd().cursor(), Some((0, 0)));
}

#[test]
fn busy_flag_and_address_are_read_through_the_pcf8574() {
    let mut r = Raw::new();
    r.init();
    r.byte(0x80 | 0x45, 0);
    // Read BF/AC: RW=1, data pins high (quasi-bidirectional inputs).
    let base = 0xF0 | RW | BACKLIGHT;
    r.put(base);
    r.put(base | E);
    let hi = r.b.read(r.now) >> 4;
    r.put(base);
    r.put(base | E);
    let lo = r.b.read(r.now) >> 4;
    r.put(base);
    assert_eq!((hi << 4) | lo, 0x45, "BF = 0, AC = 0x45");
    // Right after an instruction the busy flag is 1.
    r.byte(0x01, 0);
    r.b.write(base, r.now + 1);
    r.b.write(base | E, r.now + 2);
    assert_eq!(r.b.read(r.now + 3) & 0x80, 0x80);
    // A read is not an instruction: nothing counted.
    assert_eq!(r.b.busy_violations(), 0);
}

#[test]
fn data_read_returns_ddram_and_moves_the_counter() {
    let mut r = Raw::new();
    r.init();
    r.text(b"Q");
    r.byte(0x80, 0);
    let base = 0xF0 | RW | RS | BACKLIGHT;
    r.put(base);
    r.put(base | E);
    let hi = r.b.read(r.now) >> 4;
    r.put(base);
    r.put(base | E);
    let lo = r.b.read(r.now) >> 4;
    r.put(base);
    assert_eq!((hi << 4) | lo, b'Q');
    assert_eq!(r.b.lcd().address_counter(), (1, false));
}

#[test]
fn hold_violation_when_e_falls_with_new_data() {
    let mut r = Raw::new();
    r.init();
    let before = r.b.lcd().data_writes();
    // E falls in the write that changes D7..D4: the chip latches the old nibble.
    r.put(0x40 | RS | BACKLIGHT);
    r.put(0x40 | RS | BACKLIGHT | E);
    r.put(0x10 | RS | BACKLIGHT);
    r.put(0x10 | RS | BACKLIGHT | E);
    r.put(0x10 | RS | BACKLIGHT);
    assert_eq!(r.b.hold_violations(), 1);
    assert_eq!(r.b.setup_violations(), 0);
    assert_eq!(r.b.lcd().data_writes(), before + 1);
    assert_eq!(r.b.lcd().rows()[0][0], 0x41);
}

#[test]
fn execution_times_scale_with_the_oscillator() {
    for (hz, clear_us) in [(270_000, 1520), (190_000, 2160)] {
        let mut r = Raw {
            b: LcdBackpack::default().with_fosc_hz(hz),
            now: 0,
        };
        r.init();
        r.byte(0x01, 0);
        // The byte completes at the E fall of its low nibble, the last write.
        let e_fall = r.now;
        let busy = r.b.lcd().busy_until() - e_fall;
        assert!(busy.abs_diff(clear_us * US) <= US, "{hz} Hz: {busy}");
    }
}

#[test]
fn power_cycle_resets_the_module() {
    let mut r = Raw::new();
    r.init();
    r.text(b"HI");
    r.b.power_on(r.now);
    assert_eq!(r.b.latch(), 0xFF);
    assert!(!r.b.lcd().display_on() && !r.b.lcd().four_bit());
    assert!(r.b.lcd().busy(r.now + 14 * MS));
    assert_eq!(r.b.lcd().ddram()[0], b' ');
}
