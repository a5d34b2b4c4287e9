//! Canonical text of a program (program.md section 2): upper case, one space between
//! fields, constants as 4 digits, ascending lines, no comments. `assemble` of the output
//! gives back the identical program.
//!
//! Decision: canonical form is upper case for every mnemonic, including the drive
//! mnemonics the spec's tables write mixed-case (`RS=`, `=DU`, `FMN`, `FRV`...), because
//! program.md section 2 says "canonical form uses upper case" and the assembler is
//! case-insensitive anyway. [`Mnemonic::text`] keeps the spec's spelling for anyone who
//! prefers it (e.g. an LCD listing).

use core::fmt::Write;

use super::model::{Instruction, Mnemonic, Operand, Program};

/// Writes the canonical (upper-case) text of a mnemonic: [`Mnemonic::text`] in upper
/// case, so the table in `mnemonic.rs` is the only list of mnemonic texts.
pub fn write_mnemonic<W: Write>(m: Mnemonic, w: &mut W) -> core::fmt::Result {
    m.text()
        .chars()
        .try_for_each(|c| w.write_char(c.to_ascii_uppercase()))
}

/// The text of an operand: `D09`, `K17`, `COM` (at most 3 characters).
pub fn operand_text(op: &Operand) -> heapless::String<4> {
    let mut s = heapless::String::new();
    // At most 3 characters for any operand with an index below 100; a larger index
    // (never valid) is cut rather than failing.
    let _ = write!(s, "{op}");
    s
}

/// One line without a line end: `150 LD D00`, `001 LD K00 0000`, `151 NOT`.
pub fn write_line<W: Write>(line: u16, i: &Instruction, w: &mut W) -> core::fmt::Result {
    write!(w, "{line:03} ")?;
    write_mnemonic(i.mnemonic, w)?;
    if let Some(op) = &i.operand {
        write!(w, " {op}")?;
        if op.is_k() {
            write!(w, " {:04}", i.constant)?;
        }
    }
    Ok(())
}

/// One line as a fixed-capacity string (at most 16 characters, `NNN MNEM OPR CCCC`).
pub fn line_string(line: u16, i: &Instruction) -> heapless::String<20> {
    let mut s = heapless::String::new();
    let _ = write_line(line, i, &mut s);
    s
}

/// The whole program, one `\n`-terminated line per non-empty program line, ascending.
pub fn disassemble<W: Write>(p: &Program, w: &mut W) -> core::fmt::Result {
    for (n, slot) in (0u16..).zip(p.lines.iter()) {
        if let Some(i) = slot {
            write_line(n, i, w)?;
            w.write_char('\n')?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::super::asm::assemble;
    use super::*;

    #[test]
    fn canonical_text() {
        let p = assemble(
            "151 let b00 ; edge\n150 ld   d00\n007 Rs= K03 0195\n010 =dU\n016 I> K11 0200\n025 frv K20 0200\n",
        )
        .unwrap();
        let mut s = std::string::String::new();
        disassemble(&p, &mut s).unwrap();
        assert_eq!(
            s,
            "007 RS= K03 0195\n010 =DU\n016 I> K11 0200\n025 FRV K20 0200\n150 LD D00\n151 LET B00\n"
        );
        assert_eq!(assemble(&s).unwrap(), p);
    }

    #[test]
    fn helpers() {
        assert_eq!(operand_text(&Operand::D(9)).as_str(), "D09");
        assert_eq!(operand_text(&Operand::Pw5).as_str(), "PW5");
        let i = Instruction {
            mnemonic: Mnemonic::Ton,
            operand: Some(Operand::K(1)),
            constant: 100,
        };
        assert_eq!(line_string(152, &i).as_str(), "152 TON K01 0100");
    }

    #[test]
    fn every_mnemonic_text_reassembles() {
        for m in Mnemonic::ALL {
            let mut text = String::new();
            write_mnemonic(m, &mut text).unwrap();
            assert_eq!(super::super::asm::parse_mnemonic(&text), Some(m));
            assert_eq!(text, m.text().to_ascii_uppercase());
        }
    }
}
