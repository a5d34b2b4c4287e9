//! Screen text without `core::fmt`: a fixed-capacity string with the few number and
//! padding forms the LCD uses (`{n}`, `{n:03}`, `{n:04X}`, `{s:<5}`, `{s:>6}`).
//!
//! Formatting through `core::fmt` linked its machinery into the image (`Formatter::pad`,
//! `pad_integral`, the integer `Display`s and the argument tables of every `write!`,
//! docs/size.md); the LCD's text needs none of its generality. The tests compare every form
//! with `std::format!`.

use shared_protocol::link::DriveWarning;
use shared_protocol::program::{Operand, ShortText};

/// Longest text: any row or message before it is clipped to the display.
pub const CAPACITY: usize = 64;

/// Text of at most [`CAPACITY`] bytes; what does not fit is cut (a row is clipped at the
/// display's edge anyway). One capacity for every use, so that the image holds one copy
/// of each method (not one per capacity).
#[derive(Clone, Default, PartialEq, Eq)]
pub struct Text(heapless::String<CAPACITY>);

impl core::ops::Deref for Text {
    type Target = str;

    fn deref(&self) -> &str {
        &self.0
    }
}

impl core::fmt::Debug for Text {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        core::fmt::Debug::fmt(self.0.as_str(), f)
    }
}

impl Text {
    pub const fn new() -> Self {
        Text(heapless::String::new())
    }

    pub fn as_str(&self) -> &str {
        &self.0
    }

    /// Appends `s`, as far as it fits.
    pub fn str(&mut self, s: &str) -> &mut Self {
        if self.0.push_str(s).is_err() {
            for c in s.chars() {
                if self.0.push(c).is_err() {
                    break;
                }
            }
        }
        self
    }

    pub fn char(&mut self, c: char) -> &mut Self {
        let _ = self.0.push(c);
        self
    }

    /// `{n}`.
    pub fn dec(&mut self, n: u32) -> &mut Self {
        self.dec0(n, 0)
    }

    /// `{n:0width$}`: at least `width` digits, zeros in front.
    pub fn dec0(&mut self, n: u32, width: usize) -> &mut Self {
        let mut digits = [b'0'; 10];
        let mut start = digits.len();
        let mut rest = n;
        loop {
            start -= 1;
            if let Some(d) = digits.get_mut(start) {
                *d = b'0' + (rest % 10) as u8;
            }
            rest /= 10;
            if rest == 0 || start == 0 {
                break;
            }
        }
        for _ in (digits.len() - start)..width {
            self.char('0');
        }
        for &d in digits.get(start..).unwrap_or(&[]) {
            self.char(char::from(d));
        }
        self
    }

    /// `{n}` of a signed number.
    pub fn int(&mut self, n: i32) -> &mut Self {
        if n < 0 {
            self.char('-');
        }
        self.dec(n.unsigned_abs())
    }

    /// `{n:04X}`.
    pub fn hex4(&mut self, n: u16) -> &mut Self {
        for shift in [12, 8, 4, 0] {
            let nibble = ((n >> shift) & 0xF) as u8;
            let c = if nibble < 10 {
                b'0' + nibble
            } else {
                b'A' + nibble - 10
            };
            self.char(char::from(c));
        }
        self
    }

    /// `{s:<width}`: `s`, then spaces up to `width` characters. `s` is ASCII (what the
    /// LCD can show): its width is its length in bytes.
    pub fn left(&mut self, s: &str, width: usize) -> &mut Self {
        self.str(s);
        self.spaces(width.saturating_sub(s.len()))
    }

    /// `{s:>width}`: spaces up to `width` characters, then `s` (ASCII, as [`Text::left`]).
    pub fn right(&mut self, s: &str, width: usize) -> &mut Self {
        self.spaces(width.saturating_sub(s.len()));
        self.str(s)
    }

    fn spaces(&mut self, n: usize) -> &mut Self {
        for _ in 0..n {
            self.char(' ');
        }
        self
    }

    /// An operand as the listing shows it (`D09`, `COM`, `SS1`): [`Operand`]'s `Display`.
    pub fn operand(&mut self, op: &Operand) -> &mut Self {
        let class = op.class();
        if class.is_area() {
            self.str(class.name()).dec0(u32::from(op.index()), 2)
        } else if let Operand::Sf(func) = op {
            self.str(func.name())
        } else {
            self.str(class.name())
        }
    }

    /// A verifier error's LCD text (`fss twice`, `PRx twice`): [`ShortText`]'s `Display`.
    pub fn short_text(&mut self, t: ShortText) -> &mut Self {
        match t {
            ShortText::Fixed(s) => self.str(s),
            ShortText::Twice(m) => self.str(m.setting_name()).str(" twice"),
            ShortText::Needs(func, s) => self.str(func.name()).str(" needs ").str(s.text()),
            ShortText::NeedsSine(func) => self.str(func.name()).str(" needs sine"),
        }
    }

    /// A drive warning's LCD text (`PWF 488Hz @ 000`): [`DriveWarning::short`].
    pub fn drive_warning(&mut self, w: DriveWarning) -> &mut Self {
        match w {
            DriveWarning::PwfClamped {
                line, applied_hz, ..
            } => self
                .str("PWF ")
                .dec(u32::from(applied_hz))
                .str("Hz @ ")
                .dec0(u32::from(line), 3),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use shared_protocol::program::{Mnemonic, OperandClass};
    use shared_protocol::safety::{SafetyFunction, SafetySetting};
    use std::format;
    use std::string::ToString;

    type T = Text;

    fn text(f: impl FnOnce(&mut T)) -> std::string::String {
        let mut t = T::new();
        f(&mut t);
        t.to_string()
    }

    #[test]
    fn numbers_at_their_edges() {
        for n in [0, 1, 9, 10, 99, 100, 999, 1000, 9999, 65_535, u32::MAX] {
            assert_eq!(
                text(|t| {
                    t.dec(n);
                }),
                format!("{n}")
            );
            for w in 0..12 {
                assert_eq!(
                    text(|t| {
                        t.dec0(n, w);
                    }),
                    format!("{n:0w$}")
                );
            }
        }
        for n in [i32::MIN, -32_768, -10, -1, 0, 1, 32_767, i32::MAX] {
            assert_eq!(
                text(|t| {
                    t.int(n);
                }),
                format!("{n}")
            );
        }
        for n in [0, 9, 0xA, 0x3A7F, 0xFFFF] {
            assert_eq!(
                text(|t| {
                    t.hex4(n);
                }),
                format!("{n:04X}")
            );
        }
    }

    #[test]
    fn padding_as_format_pads() {
        for s in ["", "-", "RUN", "STOP", "42.3", "-32768", "LONGER THAN"] {
            for w in 0..8 {
                assert_eq!(
                    text(|t| {
                        t.left(s, w);
                    }),
                    format!("{s:<w$}")
                );
                assert_eq!(
                    text(|t| {
                        t.right(s, w);
                    }),
                    format!("{s:>w$}")
                );
            }
        }
    }

    #[test]
    fn text_past_the_capacity_is_cut() {
        let mut t = Text::new();
        t.str(&"A".repeat(CAPACITY - 2)).dec(12_345).char('x');
        assert_eq!(t.len(), CAPACITY);
        assert!(t.ends_with("AA12"), "{t:?}");
        let mut t = Text::new();
        t.str(&"B".repeat(CAPACITY + 3));
        assert_eq!(t.as_str(), "B".repeat(CAPACITY));
    }

    #[test]
    fn every_operand_as_its_display() {
        for class in OperandClass::ALL {
            for index in 0..=255u8 {
                let op = class.operand_unchecked_range(index);
                assert_eq!(
                    text(|t| {
                        t.operand(&op);
                    }),
                    op.to_string()
                );
                let mut short = Text::new();
                short.operand(&op);
                assert_eq!(
                    short.as_str(),
                    shared_protocol::program::operand_text(&op).as_str()
                );
            }
        }
    }

    #[test]
    fn every_short_text_as_its_display() {
        let mut all = std::vec![ShortText::Fixed("wrong section")];
        for m in Mnemonic::ALL {
            all.push(ShortText::Twice(m));
        }
        for f in SafetyFunction::ALL {
            all.push(ShortText::NeedsSine(f));
            for s in SafetySetting::ALL {
                all.push(ShortText::Needs(f, s));
            }
        }
        for st in all {
            assert_eq!(
                text(|t| {
                    t.short_text(st);
                }),
                st.to_string()
            );
        }
    }

    proptest! {
        #[test]
        fn numbers_as_format_writes_them(n in any::<u32>(), i in any::<i32>(), h in any::<u16>(), w in 0usize..12) {
            prop_assert_eq!(text(|t| {
                t.dec0(n, w);
            }), format!("{n:0w$}"));
            prop_assert_eq!(text(|t| {
                t.int(i);
            }), format!("{i}"));
            prop_assert_eq!(text(|t| {
                t.hex4(h);
            }), format!("{h:04X}"));
        }

        #[test]
        fn drive_warnings_as_their_short_text(line in any::<u8>(), requested in any::<i16>(), applied_hz in any::<u16>()) {
            let w = DriveWarning::PwfClamped { line, requested, applied_hz };
            let mut t = Text::new();
            t.drive_warning(w);
            let want = w.short();
            prop_assert_eq!(t.as_str(), want.as_str());
        }
    }
}
