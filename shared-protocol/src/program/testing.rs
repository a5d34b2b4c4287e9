//! proptest strategies for programs (feature `testing`; host only, uses std).
//!
//! Built from the verifier's own choice tables ([`mnemonics_for`], [`operands_for`],
//! [`constant_range`]), so every generated instruction is one the verifier accepts and the
//! keypad editor could enter. The PLC VM, the drive and hil-sim reuse them:
//!
//! ```toml
//! [dev-dependencies]
//! shared-protocol = { workspace = true, features = ["testing"] }
//! ```

extern crate std;

use std::vec::Vec;

use proptest::prelude::*;

use super::model::{
    DriveSection, Instruction, Mnemonic, Operand, Program, Section, DRIVE_LINES, LINES,
    PLC_FIRST_LINE,
};
use super::operand::OperandClass;
use super::verify::{constant_range, drive_stack_step, mnemonics_for, operands_for};

/// A program with four runs of used lines (0..=2, 150..=151, 400, 999: seven `LD K`
/// lines), for tests of the stored form: its payload is 4 * 3 + 7 * 4 = 40 bytes.
pub fn sparse_program() -> Program {
    let mut p = Program::default();
    for n in [0usize, 1, 2, 150, 151, 400, 999] {
        if let Some(line) = p.lines.get_mut(n) {
            *line = Some(Instruction {
                mnemonic: Mnemonic::Ld,
                operand: Some(Operand::K((n % 100) as u8)),
                constant: n as u16,
            });
        }
    }
    p
}

/// Makes a drive section's stack use valid: every line that would need more values than
/// the cycle has loaded before it (program.md 4.1, the verifier's stack check) becomes
/// `LD K00 0000`. Generated programs stay otherwise random.
pub fn fix_drive_stack(lines: &mut [Option<Instruction>]) {
    let mut depth = 0u8;
    for slot in lines.iter_mut().take(DRIVE_LINES) {
        let Some(i) = slot else { continue };
        depth = match drive_stack_step(depth, i.mnemonic) {
            Ok(d) => d,
            Err(_) => {
                *i = Instruction {
                    mnemonic: Mnemonic::Ld,
                    operand: Some(Operand::K(0)),
                    constant: 0,
                };
                drive_stack_step(depth, Mnemonic::Ld).unwrap_or(depth)
            }
        };
    }
}

/// Makes the settings rules hold (safety.md 4, docs/program-format.md "Settings once per
/// section"): a drive parameter set again is removed, and an `SFR x` whose function lacks
/// a needed setting (or any but `STO` with a direct-mode `WR PWx` in the drive section)
/// becomes `SFR STO`. Settings take no stack values, so the stack check stays valid.
pub fn fix_safety(lines: &mut [Option<Instruction>]) {
    use crate::safety::{SafetyFunction, SafetySettings};
    let mut settings = SafetySettings::default();
    let mut present = std::vec::Vec::new();
    let mut direct = false;
    for (n, slot) in lines.iter_mut().enumerate() {
        let Some(i) = slot else { continue };
        if n < DRIVE_LINES {
            if let Some(p) = i.mnemonic.drive_setting() {
                if present.contains(&p) {
                    *slot = None;
                    continue;
                }
                present.push(p);
            }
            if let Some(s) = i.mnemonic.safety_setting() {
                settings.set(s, Some(i.constant));
            }
            direct |= i.mnemonic == Mnemonic::Wr
                && matches!(i.operand, Some(Operand::Pw1 | Operand::Pw3 | Operand::Pw5));
        } else if let (Mnemonic::Sfr, Some(Operand::Sf(f))) = (i.mnemonic, i.operand) {
            if (direct && f != SafetyFunction::Sto) || settings.missing_for(f).is_some() {
                i.operand = Some(Operand::Sf(SafetyFunction::Sto));
            }
        }
    }
}

/// A valid instruction for `section`, with a constant when the operand is `K`.
pub fn instruction(section: Section) -> impl Strategy<Value = Instruction> {
    let mnemonics: Vec<Mnemonic> = mnemonics_for(section).collect();
    instruction_from(section, mnemonics)
}

/// A valid instruction for `section` using one of `mnemonics` (those not in the section
/// are ignored; an empty list means all of the section's).
pub fn instruction_from(
    section: Section,
    mnemonics: Vec<Mnemonic>,
) -> impl Strategy<Value = Instruction> {
    let mut mnemonics: Vec<Mnemonic> = mnemonics
        .into_iter()
        .filter(|m| mnemonics_for(section).any(|x| x == *m))
        .collect();
    if mnemonics.is_empty() {
        mnemonics = mnemonics_for(section).collect();
    }
    proptest::sample::select(mnemonics)
        .prop_flat_map(move |m| {
            let ops: Vec<Option<Operand>> = operands_for(m, section).collect();
            (Just(m), proptest::sample::select(ops))
        })
        .prop_flat_map(move |(m, op)| {
            let constant = match constant_range(m, section, op) {
                Some(r) => r.boxed(),
                None => Just(0u16).boxed(),
            };
            (Just(m), Just(op), constant)
        })
        .prop_map(|(mnemonic, operand, constant)| Instruction {
            mnemonic,
            operand,
            constant,
        })
}

/// A line number of `section` and a valid instruction for it.
pub fn line_in(section: Section) -> impl Strategy<Value = (u16, Instruction)> {
    let lines = match section {
        Section::Drive => 0..PLC_FIRST_LINE,
        Section::Plc => PLC_FIRST_LINE..LINES as u16,
    };
    (lines, instruction(section))
}

/// Any line number 000-999 and a valid instruction for its section.
pub fn line() -> impl Strategy<Value = (u16, Instruction)> {
    prop_oneof![line_in(Section::Drive), line_in(Section::Plc)]
}

/// A valid program with up to `max_lines` non-empty lines in both sections.
pub fn program(max_lines: usize) -> impl Strategy<Value = Program> {
    proptest::collection::vec(line(), 0..=max_lines).prop_map(|lines| {
        let mut p = Program::default();
        for (n, i) in lines {
            if let Some(slot) = p.lines.get_mut(usize::from(n)) {
                *slot = Some(i);
            }
        }
        fix_drive_stack(&mut p.lines);
        fix_safety(&mut p.lines);
        p
    })
}

/// A valid program with lines only in `section`.
pub fn program_in(section: Section, max_lines: usize) -> impl Strategy<Value = Program> {
    proptest::collection::vec(line_in(section), 0..=max_lines).prop_map(|lines| {
        let mut p = Program::default();
        for (n, i) in lines {
            if let Some(slot) = p.lines.get_mut(usize::from(n)) {
                *slot = Some(i);
            }
        }
        fix_drive_stack(&mut p.lines);
        fix_safety(&mut p.lines);
        p
    })
}

/// A valid drive section with up to `max_lines` non-empty lines.
pub fn drive_section(max_lines: usize) -> impl Strategy<Value = DriveSection> {
    proptest::collection::vec(line_in(Section::Drive), 0..=max_lines.min(DRIVE_LINES)).prop_map(
        |lines| {
            let mut d = DriveSection::default();
            for (n, i) in lines {
                if let Some(slot) = d.lines.get_mut(usize::from(n)) {
                    *slot = Some(i);
                }
            }
            fix_drive_stack(&mut d.lines);
            fix_safety(&mut d.lines);
            d
        },
    )
}

/// Any operand the type can hold, including indices outside the areas (up to 127).
pub fn any_operand() -> impl Strategy<Value = Operand> + Clone {
    (
        proptest::sample::select(OperandClass::ALL.to_vec()),
        any::<u8>(),
    )
        .prop_map(|(c, i)| c.operand_unchecked_range(i))
}

/// Any instruction the type can hold, mostly invalid: for "rejects, never panics" tests.
pub fn any_instruction() -> impl Strategy<Value = Instruction> + Clone {
    (
        proptest::sample::select(Mnemonic::ALL.to_vec()),
        proptest::option::of(any_operand()),
        prop_oneof![0u16..=9999, any::<u16>()],
    )
        .prop_map(|(mnemonic, operand, constant)| Instruction {
            mnemonic,
            operand,
            constant,
        })
}
