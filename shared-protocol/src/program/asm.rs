//! The `.plc` text assembler (program.md section 2).
//!
//! A successful assemble is a runnable program: every line goes through
//! [`super::verify_line`] with the columns of its text at hand, so verifier errors name the
//! text line and column of the offending field.
//!
//! Rules beyond the spec's text (also in `docs/program-format.md`):
//! * Columns are 1-based and count characters; a tab counts as one column.
//! * A UTF-8 byte-order mark at the start of the text is ignored; `\r\n` line ends work.
//! * The line number is exactly three digits, a constant exactly four.
//! * Errors are reported in text order, the first one only. Within a line the fields are
//!   checked left to right: line number, mnemonic (known? in this section?), operand,
//!   constant, then the verifier's operand/constant rules.
//! * [`assemble_into`] leaves `out` **unchanged** on error: the whole text is checked
//!   first, and `out` is only cleared and filled once nothing can fail.
//! * [`assemble`] checks what a line alone can break (the text format, program.md 2, whose
//!   own example is a fragment). [`assemble_runnable`] also runs the whole-program
//!   verifier ([`super::verify`], e.g. the drive section's stack depth) and places its
//!   error at the text line of the offending program line, column of its mnemonic: what
//!   `hil-sim run`/`asm` use, so that a program the PLC would refuse at RUN is refused
//!   when it is read.

use super::model::{Instruction, Mnemonic, Operand, Program, Section, LINES};
use super::operand::OperandClass;
use super::verify::{operand_set, verify, verify_line, VerifyError, VerifyErrorKind};

/// A piece of the offending text, cut to fit (no allocation).
pub type Token = heapless::String<16>;

/// What is wrong at an [`AsmError`]'s position.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum AsmErrorKind {
    /// Not a three-digit line number.
    LineNumber {
        found: Token,
    },
    /// A line number with nothing after it.
    MissingMnemonic,
    UnknownMnemonic {
        found: Token,
    },
    /// Not an area letter with two digits, nor a named operand.
    UnknownOperand {
        found: Token,
    },
    /// A `K` operand without its constant.
    ConstantMissing {
        operand: Operand,
    },
    /// The constant is not four digits.
    BadConstant {
        found: Token,
    },
    /// A constant after something that is not a `K` operand.
    UnexpectedConstant {
        found: Token,
    },
    /// Anything after the last field.
    TrailingText {
        found: Token,
    },
    /// A program line number used a second time.
    DuplicateLine {
        number: u16,
        first_text_line: u32,
    },
    /// The verifier's rules (wrong section, operand kind or range, constant range...).
    Verify(VerifyErrorKind),
}

impl core::fmt::Display for AsmErrorKind {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            AsmErrorKind::LineNumber { found } => write!(
                f,
                "expected a 3-digit line number (000-999), found `{found}`"
            ),
            AsmErrorKind::MissingMnemonic => {
                f.write_str("expected a mnemonic after the line number")
            }
            AsmErrorKind::UnknownMnemonic { found } => write!(f, "unknown mnemonic `{found}`"),
            AsmErrorKind::UnknownOperand { found } => write!(
                f,
                "unknown operand `{found}` (expected an area letter with two digits like D00, or a name like COM)"
            ),
            AsmErrorKind::ConstantMissing { operand } => write!(
                f,
                "operand {operand} needs a 4-digit constant (0000-9999)"
            ),
            AsmErrorKind::BadConstant { found } => write!(
                f,
                "expected a 4-digit constant (0000-9999), found `{found}`"
            ),
            AsmErrorKind::UnexpectedConstant { found } => write!(
                f,
                "constant `{found}` not allowed: only a K operand takes a constant"
            ),
            AsmErrorKind::TrailingText { found } => {
                write!(f, "unexpected `{found}` at the end of the instruction")
            }
            AsmErrorKind::DuplicateLine {
                number,
                first_text_line,
            } => write!(
                f,
                "line {number:03} used twice (first on text line {first_text_line})"
            ),
            AsmErrorKind::Verify(k) => write!(f, "{k}"),
        }
    }
}

/// An assembly error at a 1-based text line and column. `Display` gives
/// `12:9: operand D16 out of range (D00-D15)`; the caller prefixes the file name.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct AsmError {
    pub line: u32,
    pub col: u32,
    pub kind: AsmErrorKind,
}

impl core::error::Error for AsmError {}

impl core::fmt::Display for AsmError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "{}:{}: {}", self.line, self.col, self.kind)
    }
}

fn token(s: &str) -> Token {
    let mut t = Token::new();
    let cap = t.capacity();
    let mut chars = s.chars();
    for c in chars.by_ref() {
        if t.len() + c.len_utf8() > cap - 3 {
            // Room for "..." or the rest of a short token.
            let rest_len = c.len_utf8() + chars.as_str().len();
            if t.len() + rest_len <= cap {
                let _ = t.push(c);
                let _ = t.push_str(chars.as_str());
            } else {
                let _ = t.push_str("...");
            }
            return t;
        }
        let _ = t.push(c);
    }
    t
}

/// A field of a text line: its 1-based column and its text.
#[derive(Clone, Copy)]
struct Field<'a> {
    col: u32,
    text: &'a str,
}

impl Field<'_> {
    /// Where a following field would start (after one space): the column named when a
    /// field is missing.
    fn next_col(&self) -> u32 {
        self.col
            .saturating_add(self.text.chars().count() as u32)
            .saturating_add(1)
    }
}

/// Splits one text line (comment already removed) into whitespace-separated fields.
struct Fields<'a> {
    rest: &'a str,
    col: u32,
}

impl<'a> Iterator for Fields<'a> {
    type Item = Field<'a>;

    fn next(&mut self) -> Option<Field<'a>> {
        let mut chars = self.rest.char_indices();
        let start = loop {
            let (i, c) = chars.next()?;
            if !c.is_whitespace() {
                break i;
            }
            self.col = self.col.saturating_add(1);
        };
        let after = self.rest.get(start..).unwrap_or("");
        let len = after.find(char::is_whitespace).unwrap_or(after.len());
        let text = after.get(..len).unwrap_or("");
        let field = Field {
            col: self.col,
            text,
        };
        self.col = self.col.saturating_add(text.chars().count() as u32);
        self.rest = after.get(len..).unwrap_or("");
        Some(field)
    }
}

fn digits(s: &str, n: usize) -> Option<u16> {
    if s.len() != n || !s.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    s.parse().ok()
}

/// The mnemonic a text spells (case-insensitive, `I/O`, `Rs=`, `=dU`, `U>` as written).
pub fn parse_mnemonic(s: &str) -> Option<Mnemonic> {
    Mnemonic::ALL
        .into_iter()
        .find(|m| m.text().eq_ignore_ascii_case(s))
}

/// The operand a text spells (case-insensitive): an area letter with exactly two digits
/// (the index may be outside the area: range checks are the verifier's), or a name.
pub fn parse_operand(s: &str) -> Option<Operand> {
    if let Some(f) = crate::safety::SafetyFunction::ALL
        .into_iter()
        .find(|f| f.name().eq_ignore_ascii_case(s))
    {
        return Some(Operand::Sf(f));
    }
    if let Some(c) = OperandClass::ALL
        .into_iter()
        .find(|c| !c.is_area() && c.name().eq_ignore_ascii_case(s))
    {
        return Some(c.operand_unchecked_range(0));
    }
    let letter = s.get(..1)?;
    let index = digits(s.get(1..)?, 2)?;
    OperandClass::ALL
        .into_iter()
        .find(|c| c.is_area() && c.name().eq_ignore_ascii_case(letter))
        .map(|c| c.operand_unchecked_range(index as u8))
}

/// One parsed text line.
struct Parsed {
    number: u16,
    number_col: u32,
    mnemonic_col: u32,
    instruction: Instruction,
}

fn err(line: u32, col: u32, kind: AsmErrorKind) -> AsmError {
    AsmError { line, col, kind }
}

/// Parse and verify one text line; `Ok(None)` for blank and comment lines.
fn parse_line(text: &str, line: u32) -> Result<Option<Parsed>, AsmError> {
    let code = text.split(';').next().unwrap_or("");
    let mut fields = Fields { rest: code, col: 1 };
    let Some(num) = fields.next() else {
        return Ok(None);
    };
    let number = digits(num.text, 3).ok_or_else(|| {
        err(
            line,
            num.col,
            AsmErrorKind::LineNumber {
                found: token(num.text),
            },
        )
    })?;
    // Three digits are always 000-999.
    let section = Section::of_line(number).unwrap_or(Section::Plc);

    let mn = fields
        .next()
        .ok_or_else(|| err(line, num.next_col(), AsmErrorKind::MissingMnemonic))?;
    let mnemonic = parse_mnemonic(mn.text).ok_or_else(|| {
        err(
            line,
            mn.col,
            AsmErrorKind::UnknownMnemonic {
                found: token(mn.text),
            },
        )
    })?;
    if operand_set(mnemonic, section).is_none() {
        return Err(err(
            line,
            mn.col,
            AsmErrorKind::Verify(VerifyErrorKind::WrongSection { mnemonic, section }),
        ));
    }

    let op_field = fields.next();
    let operand = match op_field {
        None => None,
        Some(f) if digits(f.text, 4).is_some() => {
            return Err(err(
                line,
                f.col,
                AsmErrorKind::UnexpectedConstant {
                    found: token(f.text),
                },
            ))
        }
        Some(f) => Some(parse_operand(f.text).ok_or_else(|| {
            err(
                line,
                f.col,
                AsmErrorKind::UnknownOperand {
                    found: token(f.text),
                },
            )
        })?),
    };

    let const_field = fields.next();
    let constant = match (operand, op_field, const_field) {
        (Some(op @ Operand::K(_)), Some(of), None) => {
            return Err(err(
                line,
                of.next_col(),
                AsmErrorKind::ConstantMissing { operand: op },
            ))
        }
        (Some(Operand::K(_)), _, Some(cf)) => digits(cf.text, 4).ok_or_else(|| {
            err(
                line,
                cf.col,
                AsmErrorKind::BadConstant {
                    found: token(cf.text),
                },
            )
        })?,
        (_, _, Some(cf)) => {
            let kind = if cf.text.bytes().all(|b| b.is_ascii_digit()) {
                AsmErrorKind::UnexpectedConstant {
                    found: token(cf.text),
                }
            } else {
                AsmErrorKind::TrailingText {
                    found: token(cf.text),
                }
            };
            return Err(err(line, cf.col, kind));
        }
        _ => 0,
    };
    if let Some(extra) = fields.next() {
        return Err(err(
            line,
            extra.col,
            AsmErrorKind::TrailingText {
                found: token(extra.text),
            },
        ));
    }

    let instruction = Instruction {
        mnemonic,
        operand,
        constant,
    };
    verify_line(number, &instruction).map_err(|kind| {
        let col = match kind {
            VerifyErrorKind::LineOutOfRange => num.col,
            VerifyErrorKind::WrongSection { .. } => mn.col,
            VerifyErrorKind::OperandMissing { .. } => mn.next_col(),
            VerifyErrorKind::ConstantOutOfRange { .. }
            | VerifyErrorKind::ConstantWithoutK { .. } => {
                const_field.or(op_field).map_or(mn.next_col(), |f| f.col)
            }
            _ => op_field.map_or(mn.next_col(), |f| f.col),
        };
        err(line, col, AsmErrorKind::Verify(kind))
    })?;
    Ok(Some(Parsed {
        number,
        number_col: num.col,
        mnemonic_col: mn.col,
        instruction,
    }))
}

fn text_lines(text: &str) -> impl Iterator<Item = (u32, &str)> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    (1u32..).zip(text.split('\n'))
}

/// The text line that first defines program line `number` (for the duplicate message),
/// and the column of its mnemonic.
fn definition(text: &str, number: u16) -> (u32, u32) {
    text_lines(text)
        .find_map(|(n, l)| match parse_line(l, n) {
            Ok(Some(p)) if p.number == number => Some((n, p.mnemonic_col)),
            _ => None,
        })
        .unwrap_or((0, 0))
}

fn first_definition(text: &str, number: u16) -> u32 {
    definition(text, number).0
}

/// Assemble a whole `.plc` text into a new program.
pub fn assemble(text: &str) -> Result<Program, AsmError> {
    let mut p = Program::default();
    assemble_into(text, &mut p)?;
    Ok(p)
}

/// Assemble a whole `.plc` text and run the whole-program verifier on it: `Ok` is a
/// program the PLC starts. The verifier's error is placed at the text line of the
/// offending program line ([`locate`]).
pub fn assemble_runnable(text: &str) -> Result<Program, AsmError> {
    let p = assemble(text)?;
    verify(&p).map_err(|e| locate(text, &e))?;
    Ok(p)
}

/// A verifier error of the program assembled from `text`, at the text line that defines
/// the program line and the column of its mnemonic (line 0, column 0 when no text line
/// defines it).
pub fn locate(text: &str, e: &VerifyError) -> AsmError {
    let (line, col) = definition(text, e.line);
    err(line, col, AsmErrorKind::Verify(e.kind))
}

/// Assemble into an existing program (no 6 KB temporary on the stack). On error `out` is
/// left unchanged; on success it holds exactly the text's lines (all others empty).
pub fn assemble_into(text: &str, out: &mut Program) -> Result<(), AsmError> {
    let mut seen = [0u32; LINES.div_ceil(32)];
    for (n, l) in text_lines(text) {
        let Some(p) = parse_line(l, n)? else {
            continue;
        };
        let word = seen.get_mut(usize::from(p.number / 32));
        let bit = 1u32 << (p.number % 32);
        if let Some(word) = word {
            if *word & bit != 0 {
                return Err(err(
                    n,
                    p.number_col,
                    AsmErrorKind::DuplicateLine {
                        number: p.number,
                        first_text_line: first_definition(text, p.number),
                    },
                ));
            }
            *word |= bit;
        }
    }
    // Nothing can fail from here on.
    *out = Program::default();
    for (n, l) in text_lines(text) {
        if let Ok(Some(p)) = parse_line(l, n) {
            if let Some(slot) = out.lines.get_mut(usize::from(p.number)) {
                *slot = Some(p.instruction);
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::string::ToString;

    fn e(text: &str) -> std::string::String {
        assemble(text).unwrap_err().to_string()
    }

    #[test]
    fn spec_example() {
        let p = assemble(
            "; comment\n000 PWF Q00\n001 LD  K00 0000\n005 PI  K02 1000      ; limiter 0..1000\n150 LD  D00\n151 LET B00\n",
        )
        .unwrap();
        assert_eq!(p.section(Section::Drive).count(), 3);
        assert_eq!(
            p.get(5),
            Some(&Instruction {
                mnemonic: Mnemonic::Pi,
                operand: Some(Operand::K(2)),
                constant: 1000
            })
        );
        assert_eq!(p.get(151).map(|i| i.operand), Some(Some(Operand::B(0))));
    }

    #[test]
    fn case_tabs_crlf_any_order() {
        let a = assemble("151\tlet\tb00\r\n150 ld d00\r\n007 rs= k03 0195\n010 =DU\n014 u> K09 0035\n152 i/o b01").unwrap();
        let b = assemble(
            "007 Rs= K03 0195\n010 =dU\n014 U> K09 0035\n150 LD D00\n151 LET B00\n152 I/O B01",
        )
        .unwrap();
        assert_eq!(a, b);
    }

    #[test]
    fn error_positions() {
        assert_eq!(e("150 LD  D16"), "1:9: operand D16 out of range (D00-D15)");
        assert_eq!(e("150 WR  O08"), "1:9: operand O08 out of range (O00-O07)");
        assert!(assemble("150 LD  D15\n151 WR  O07").is_ok());
        assert_eq!(
            e("\n\n150 LD D00\n150 LD D01"),
            "4:1: line 150 used twice (first on text line 3)"
        );
        assert_eq!(
            e("15 LD D00"),
            "1:1: expected a 3-digit line number (000-999), found `15`"
        );
        assert_eq!(e("150"), "1:5: expected a mnemonic after the line number");
        assert_eq!(e("150 LOAD D00"), "1:5: unknown mnemonic `LOAD`");
        assert!(e("150 LD X00").starts_with("1:8: unknown operand `X00`"));
        assert!(e("150 LD D1").starts_with("1:8: unknown operand `D1`"));
        assert_eq!(
            e("150 LD K01"),
            "1:12: operand K01 needs a 4-digit constant (0000-9999)"
        );
        assert_eq!(
            e("150 LD K01 100"),
            "1:12: expected a 4-digit constant (0000-9999), found `100`"
        );
        assert_eq!(
            e("150 LD D00 0100"),
            "1:12: constant `0100` not allowed: only a K operand takes a constant"
        );
        assert_eq!(
            e("150 LCD 0100"),
            "1:9: constant `0100` not allowed: only a K operand takes a constant"
        );
        assert_eq!(
            e("150 LD K01 0100 x"),
            "1:17: unexpected `x` at the end of the instruction"
        );
        assert_eq!(
            e("150 PWF K00 1000"),
            "1:5: PWF is not allowed in the PLC section (lines 150-999), only in the drive section (lines 000-149)"
        );
        assert_eq!(e("150 WR"), "1:8: WR needs an operand (O, B, Q)");
        assert_eq!(e("150 NOT B00"), "1:9: NOT takes no operand, found B00");
        assert_eq!(
            e("150 WR A00"),
            "1:8: operand A00 not allowed with WR here (expected O, B, Q)"
        );
        assert_eq!(
            e("150 LDC K00 0001"),
            "1:9: LDC needs a bit operand (D, O, B, RDY, FLB, STO..SLA, SDC), K00 is an int"
        );
        assert_eq!(
            e("003 PWF K00 0487"),
            "1:13: constant 0487 out of range for PWF (0488-9999)"
        );
        assert_eq!(
            e("150 DIV K00 0000"),
            "1:13: constant 0000 out of range for DIV (0001-9999)"
        );
    }

    #[test]
    fn first_error_in_text_order_and_out_unchanged() {
        let mut p = assemble("150 LD D00").unwrap();
        let before = p.clone();
        let r = assemble_into("151 LD D01\n152 WR D00\n153 LD D16", &mut p);
        assert_eq!(r.unwrap_err().line, 2);
        assert_eq!(p, before);
        assemble_into("151 LD D01", &mut p).unwrap();
        assert_eq!(p.get(150), None);
        assert!(p.get(151).is_some());
    }

    #[test]
    fn empty_and_comment_only() {
        assert_eq!(assemble("").unwrap(), Program::default());
        assert_eq!(
            assemble("\u{feff}; only a comment\n   \n\t; another\n").unwrap(),
            Program::default()
        );
    }

    #[test]
    fn long_tokens_are_cut() {
        let msg = e("150 ABCDEFGHIJKLMNOPQRSTUVWXYZ");
        assert_eq!(msg, "1:5: unknown mnemonic `ABCDEFGHIJKLM...`");
        assert_eq!(e("150 ÄÖÜ"), "1:5: unknown mnemonic `ÄÖÜ`");
        assert_eq!(
            e("ü 150 LD D00"),
            "1:1: expected a 3-digit line number (000-999), found `ü`"
        );
    }
}
