//! The compiled form of the PLC section: at most one 4-byte [`Op`] per line that does
//! something, built once at RUN from the stored lines (docs/vm.md).
//!
//! What compiling decides once instead of every scan:
//! * empty lines, drive mnemonics and lines with invalid operands (no-ops in the VM) are
//!   dropped;
//! * every operand is resolved to a cell index (`cells.rs`) or, for `K`, to its value;
//!   the mnemonic and the operand class together pick one op kind;
//! * the bit-stack depth that `CTU`/`CTD` look at (docs/vm.md) depends only on the
//!   instructions before the line, never on data (the section is straight-line code and
//!   S starts every scan empty), so it is decided here: [`Op::CountUp`] or
//!   [`Op::CountUpReset`];
//! * the n-th `LCD` line fills field n, so it is bound to its field; a 5th and later `LCD`
//!   is dropped;
//! * only the last `REV` of the section matters (its direction is what the scan reports),
//!   so the others are dropped;
//! * S is a 32-bit register at run time; how many of its bits can be in use is known
//!   here too, so only a push that can drop bit 15 of the 16-bit stack masks
//!   ([`Op::PushDrop`]);
//! * a bit load followed by a binary logic op becomes one op ([`Op::AndBit`] ...);
//! * timer and `ACK` lines carry their flag byte inside the op, a timer's start time sits
//!   next to it ([`Slot`]).
//!
//! Semantics are those of the direct interpreter (kept as `reference.rs`, the test
//! oracle; `differential.rs` compares both).

use shared_protocol::program::{Instruction, Mnemonic, Operand, Program, PLC_FIRST_LINE};
use shared_protocol::units::Millis;

use super::cells::{bit_cell, int_cell, q_cell, sfr_cell, writable_bit_cell};
use super::io::LCD_FIELDS;
use super::PLC_LINES;

/// Depth of the 16-bit stack S.
const S_BITS: u8 = 16;

/// One pre-decoded PLC instruction. `u8` fields are cell indices (see `cells.rs`) unless
/// named otherwise; `i16` fields are `K` values.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Op {
    /// `LD` bit: push the cell.
    Push(u8),
    /// `LDC`: push the cell's complement.
    PushNot(u8),
    /// `LD`/`LDC` bit with 16 bits possibly in use: the push drops bit 15 (S is 16 bits).
    PushDrop(u8),
    PushNotDrop(u8),
    /// `LD` int: P = cell.
    Load(u8),
    /// `LD K`: P = constant.
    LoadK(i16),
    /// `LD VLT`, `LD AMP`: convert P.
    Vlt,
    Amp,
    /// `WR`/`WRC` to a bit: cell = S0 / !S0.
    Store(u8),
    StoreNot(u8),
    /// `WR`/`WRC` to Q (index = Q number): Q = P when S0 = 1 / 0, reported in `q_dirty`.
    WriteQ(u8),
    WriteQNot(u8),
    /// `LD`/`LDC` bit followed by a binary logic op (two lines): S0 = S0 op cell (or
    /// op !cell) without the push and pop. Used only where that push cannot drop a bit.
    AndBit(u8),
    AndNotBit(u8),
    OrBit(u8),
    OrNotBit(u8),
    XorBit(u8),
    XorNotBit(u8),
    Not,
    And,
    Or,
    Xor,
    Anc,
    Orc,
    /// `LET B`: edge of S0 against the cell, cell = S0.
    Let(u8),
    /// `I/O`, `SET`, `RES` on a bit, when S0 = 1.
    Toggle(u8),
    Set(u8),
    Reset(u8),
    /// Compares of P with a cell / a constant: S0 = result.
    Eq(u8),
    EqK(i16),
    Gt(u8),
    GtK(i16),
    Lt(u8),
    LtK(i16),
    /// `CTU`/`CTD` (Q cell) with fewer than two bits loaded: pops the count input.
    CountUp(u8),
    CountDown(u8),
    /// `CTU`/`CTD` with two or more bits loaded: pops the reset (S0), counts S1.
    CountUpReset(u8),
    CountDownReset(u8),
    /// Timers with the preset in a cell / a constant (0.1 s); `flags` = `timer` flags.
    Ton {
        flags: u8,
        cell: u8,
    },
    TonK {
        flags: u8,
        preset: i16,
    },
    Tof {
        flags: u8,
        cell: u8,
    },
    TofK {
        flags: u8,
        preset: i16,
    },
    Imp {
        flags: u8,
        cell: u8,
    },
    ImpK {
        flags: u8,
        preset: i16,
    },
    /// P arithmetic with a cell / a constant.
    Add(u8),
    AddK(i16),
    Sub(u8),
    SubK(i16),
    Mul(u8),
    MulK(i16),
    /// `DIV` by a cell; `line` is reported when the divisor is 0.
    Div {
        cell: u8,
        line: u16,
    },
    /// `DIV` by a constant other than 0.
    DivK(i16),
    /// `DIV K 0` (rejected by the verifier): P = 0 and the warning.
    DivZero {
        line: u16,
    },
    /// `LCD`: the run-screen field it fills (0..4).
    Lcd(u8),
    /// The section's last `REV`.
    Rev,
    /// `ACK` (`code` 0): rising edge of S0 requests a fault acknowledge. `ALM K` (`code`
    /// = K, 1..=255): rising edge of S0 reports application fault K. One op for both:
    /// a variant of its own made every line of the scan ~0.9 instructions slower.
    Ack {
        flags: u8,
        code: u8,
    },
    /// `SFR x`: the request cell of function x = !S0 (control bit 0 = requested).
    Sfr(u8),
}

// The RAM figure in docs/vm.md depends on it.
const _: () = assert!(core::mem::size_of::<Op>() == 4);

/// One compiled line: its op and, for a timer, when it started. Side by side, so that
/// the scan reaches a timer's start time without counting lines (the same RAM as a
/// separate array: every line may be a timer).
#[derive(Debug, Clone, Copy)]
pub struct Slot {
    pub op: Op,
    pub since: Millis,
}

/// The compiled PLC section.
#[derive(Clone)]
pub struct Code {
    slots: [Slot; PLC_LINES],
    len: u16,
}

impl Code {
    pub const fn new() -> Self {
        Code {
            // `Push(0)` (tag 0) makes an empty code all zero bytes (see `PlcVm::new`).
            slots: [Slot {
                op: Op::Push(0),
                since: Millis(0),
            }; PLC_LINES],
            len: 0,
        }
    }

    /// No program (RUN stopped or not compiled yet).
    pub fn clear(&mut self) {
        self.len = 0;
    }

    /// The compiled lines, for the scan.
    pub fn slots(&mut self) -> &mut [Slot] {
        let len = usize::from(self.len);
        self.slots.get_mut(..len).unwrap_or(&mut [])
    }

    /// The compiled ops (for tests).
    #[cfg(test)]
    pub fn ops(&self) -> impl Iterator<Item = Op> + '_ {
        self.slots.iter().take(usize::from(self.len)).map(|s| s.op)
    }

    /// Compiles lines 150-999 of `program` in place (no temporary on the stack), with
    /// every timer and edge cleared.
    pub fn compile(&mut self, program: &Program, now: Millis) {
        let plc = program
            .lines
            .get(usize::from(PLC_FIRST_LINE)..)
            .unwrap_or(&[]);
        let last_rev = plc
            .iter()
            .rposition(|l| l.is_some_and(|i| i.mnemonic == Mnemonic::Rev));
        let mut st = Lowering::default();
        let mut len = 0usize;
        for (idx, slot) in plc.iter().enumerate() {
            let Some(ins) = slot else { continue };
            let line = PLC_FIRST_LINE.saturating_add(idx as u16);
            let last_rev_line = last_rev == Some(idx);
            let Some(op) = st.lower(ins, line, last_rev_line) else {
                continue;
            };
            // `LD x` + `AND` (and the like) become one op in the slot of the `LD`.
            let prev = len.checked_sub(1).and_then(|n| self.slots.get_mut(n));
            if let Some(prev) = prev {
                if let Some(fused) = fuse(prev.op, op) {
                    prev.op = fused;
                    continue;
                }
            }
            if let Some(dst) = self.slots.get_mut(len) {
                *dst = Slot { op, since: now };
                len += 1;
            }
        }
        self.len = len as u16;
    }
}

/// The one op doing `first` then `second`, if there is one. A bit push followed by a
/// binary logic op pops the bit it pushed: S0 = S0 op bit. Only for [`Op::Push`] and
/// [`Op::PushNot`], which never drop a bit (a dropped bit 15 would come back as 0 after
/// the pop).
fn fuse(first: Op, second: Op) -> Option<Op> {
    let (cell, inverted) = match first {
        Op::Push(c) => (c, false),
        Op::PushNot(c) => (c, true),
        _ => return None,
    };
    // `ANC`/`ORC` combine with the complement of the popped bit.
    let op = match (second, inverted) {
        (Op::And, false) | (Op::Anc, true) => Op::AndBit(cell),
        (Op::And, true) | (Op::Anc, false) => Op::AndNotBit(cell),
        (Op::Or, false) | (Op::Orc, true) => Op::OrBit(cell),
        (Op::Or, true) | (Op::Orc, false) => Op::OrNotBit(cell),
        (Op::Xor, false) => Op::XorBit(cell),
        (Op::Xor, true) => Op::XorNotBit(cell),
        _ => return None,
    };
    Some(op)
}

/// What compiling tracks along the section, as the interpreter's state would be at each
/// line: both depend only on the instructions before it (straight-line code, S empty at
/// the start of every scan), never on data.
#[derive(Default)]
struct Lowering {
    /// Bits loaded in this scan still on S, 0..=16 (`CTU`/`CTD`, docs/vm.md).
    depth: u8,
    /// A bound on the bits in use: S < 2^width. A push at width 16 drops bit 15
    /// ([`Op::PushDrop`]); every other push is a plain shift.
    width: u8,
    /// `LCD` lines so far.
    lcd: u8,
}

impl Lowering {
    /// The op of one line, `None` when the line does nothing.
    fn lower(&mut self, ins: &Instruction, line: u16, last_rev: bool) -> Option<Op> {
        let op = self.select(ins, line, last_rev)?;
        let op = match op {
            Op::Push(c) if self.width >= S_BITS => Op::PushDrop(c),
            Op::PushNot(c) if self.width >= S_BITS => Op::PushNotDrop(c),
            op => op,
        };
        self.track(op);
        Some(op)
    }

    /// How `op` changes the depth and the width.
    fn track(&mut self, op: Op) {
        match op {
            Op::Push(_) | Op::PushNot(_) | Op::PushDrop(_) | Op::PushNotDrop(_) => {
                self.depth = (self.depth + 1).min(S_BITS);
                self.width = (self.width + 1).min(S_BITS);
            }
            Op::And | Op::Or | Op::Xor | Op::Anc | Op::Orc => {
                self.depth = self.depth.saturating_sub(1).max(1);
                self.width = self.width.saturating_sub(1).max(1);
            }
            Op::CountUp(_) | Op::CountDown(_) | Op::CountUpReset(_) | Op::CountDownReset(_) => {
                self.depth = self.depth.saturating_sub(1);
                self.width = self.width.saturating_sub(1);
            }
            // Only made by `fuse` after tracking.
            Op::AndBit(_)
            | Op::AndNotBit(_)
            | Op::OrBit(_)
            | Op::OrNotBit(_)
            | Op::XorBit(_)
            | Op::XorNotBit(_) => {}
            // Ops that set S0 (even on an empty stack).
            Op::Not
            | Op::Let(_)
            | Op::Eq(_)
            | Op::EqK(_)
            | Op::Gt(_)
            | Op::GtK(_)
            | Op::Lt(_)
            | Op::LtK(_)
            | Op::Ton { .. }
            | Op::TonK { .. }
            | Op::Tof { .. }
            | Op::TofK { .. }
            | Op::Imp { .. }
            | Op::ImpK { .. } => self.width = self.width.max(1),
            Op::Load(_)
            | Op::LoadK(_)
            | Op::Vlt
            | Op::Amp
            | Op::Store(_)
            | Op::StoreNot(_)
            | Op::WriteQ(_)
            | Op::WriteQNot(_)
            | Op::Toggle(_)
            | Op::Set(_)
            | Op::Reset(_)
            | Op::Add(_)
            | Op::AddK(_)
            | Op::Sub(_)
            | Op::SubK(_)
            | Op::Mul(_)
            | Op::MulK(_)
            | Op::Div { .. }
            | Op::DivK(_)
            | Op::DivZero { .. }
            | Op::Lcd(_)
            | Op::Rev
            | Op::Ack { .. }
            | Op::Sfr(_) => {}
        }
    }

    /// The op of one instruction as it stands (before [`Lowering::track`]).
    fn select(&mut self, ins: &Instruction, line: u16, last_rev: bool) -> Option<Op> {
        use Mnemonic as M;
        let x = ins.operand;
        // K's value; a constant above 9999 (verifier) saturates as the interpreter did.
        let k = i16::try_from(ins.constant).unwrap_or(i16::MAX);
        // Int operand: a cell, or K.
        let int = |cell: fn(u8) -> Op, konst: fn(i16) -> Op| match x? {
            Operand::K(_) => Some(konst(k)),
            op => int_cell(op).map(cell),
        };
        let op = match ins.mnemonic {
            M::Ld => match x? {
                Operand::Vlt => Op::Vlt,
                Operand::Amp => Op::Amp,
                op => match bit_cell(op) {
                    Some(c) => Op::Push(c),
                    None => int(Op::Load, Op::LoadK)?,
                },
            },
            M::Ldc => Op::PushNot(bit_cell(x?)?),
            M::Wr | M::Wrc => {
                let wr = ins.mnemonic == M::Wr;
                match x? {
                    Operand::Q(n) => {
                        let c = q_cell(n)?;
                        if wr {
                            Op::WriteQ(c)
                        } else {
                            Op::WriteQNot(c)
                        }
                    }
                    op => {
                        let c = writable_bit_cell(op)?;
                        if wr {
                            Op::Store(c)
                        } else {
                            Op::StoreNot(c)
                        }
                    }
                }
            }
            M::Not => Op::Not,
            M::And => Op::And,
            M::Or => Op::Or,
            M::Xor => Op::Xor,
            M::Anc => Op::Anc,
            M::Orc => Op::Orc,
            M::Let => match x? {
                Operand::B(_) => Op::Let(bit_cell(x?)?),
                _ => return None,
            },
            M::Io | M::Set | M::Res => {
                let c = writable_bit_cell(x?)?;
                match ins.mnemonic {
                    M::Io => Op::Toggle(c),
                    M::Set => Op::Set(c),
                    _ => Op::Reset(c),
                }
            }
            M::Eq => int(Op::Eq, Op::EqK)?,
            M::Gt => int(Op::Gt, Op::GtK)?,
            M::Lt => int(Op::Lt, Op::LtK)?,
            M::Ctu | M::Ctd => {
                let Operand::Q(n) = x? else { return None };
                let c = q_cell(n)?;
                // With fewer than two bits loaded there is no reset input (docs/vm.md).
                let pair = self.depth >= 2;
                match (ins.mnemonic == M::Ctu, pair) {
                    (true, false) => Op::CountUp(c),
                    (true, true) => Op::CountUpReset(c),
                    (false, false) => Op::CountDown(c),
                    (false, true) => Op::CountDownReset(c),
                }
            }
            M::Ton => int(
                |cell| Op::Ton { flags: 0, cell },
                |preset| Op::TonK { flags: 0, preset },
            )?,
            M::Tof => int(
                |cell| Op::Tof { flags: 0, cell },
                |preset| Op::TofK { flags: 0, preset },
            )?,
            M::Imp => int(
                |cell| Op::Imp { flags: 0, cell },
                |preset| Op::ImpK { flags: 0, preset },
            )?,
            M::Add => int(Op::Add, Op::AddK)?,
            M::Sub => int(Op::Sub, Op::SubK)?,
            M::Mul => int(Op::Mul, Op::MulK)?,
            M::Div => match x? {
                Operand::K(_) if k == 0 => Op::DivZero { line },
                Operand::K(_) => Op::DivK(k),
                op => Op::Div {
                    cell: int_cell(op)?,
                    line,
                },
            },
            M::Lcd => {
                let field = self.lcd;
                self.lcd = self.lcd.saturating_add(1);
                if usize::from(field) >= LCD_FIELDS {
                    return None;
                }
                Op::Lcd(field)
            }
            M::Rev if last_rev => Op::Rev,
            M::Rev => return None,
            M::Ack => Op::Ack { flags: 0, code: 0 },
            // A constant of 0 or above 255 (verifier: 1..=99) does nothing, as in the
            // interpreter.
            M::Alm => match x? {
                Operand::K(_) => Op::Ack {
                    flags: 0,
                    code: u8::try_from(ins.constant).ok().filter(|c| *c != 0)?,
                },
                _ => return None,
            },
            M::Sfr => match x? {
                Operand::Sf(f) => Op::Sfr(sfr_cell(f)),
                _ => return None,
            },
            // Drive-section mnemonics: the verifier keeps them out of lines 150-999.
            drive_mnemonics!() => return None,
        };
        Some(op)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sample::{mixed_program, timer_program};
    use Mnemonic as M;
    use Operand as X;

    fn program(lines: &[(u16, Mnemonic, Option<Operand>, u16)]) -> Program {
        let mut p = Program::default();
        for &(n, mnemonic, operand, constant) in lines {
            p.lines[usize::from(n)] = Some(Instruction {
                mnemonic,
                operand,
                constant,
            });
        }
        p
    }

    fn ops(p: &Program) -> Vec<Op> {
        let mut code = Code::new();
        code.compile(p, Millis(0));
        code.ops().collect()
    }

    #[test]
    fn empty_lines_and_no_ops_take_no_slot() {
        assert!(ops(&Program::default()).is_empty());
        let p = program(&[
            (10, M::Ld, Some(X::D(0)), 0), // drive section: not the PLC's
            (150, M::Pwf, Some(X::K(0)), 1000),
            (300, M::Ld, Some(X::D(16)), 0),
            (400, M::Wr, Some(X::D(1)), 0),
            (999, M::Ld, Some(X::D(7)), 0),
        ]);
        assert_eq!(
            ops(&p),
            vec![Op::Push(crate::cells::bit_cell(X::D(7)).unwrap())]
        );
    }

    #[test]
    fn constants_are_inline_and_div_by_k0_is_the_warning() {
        let p = program(&[
            (150, M::Ld, Some(X::K(1)), 9999),
            (151, M::Add, Some(X::K(2)), 40000),
            (152, M::Div, Some(X::K(3)), 0),
            (153, M::Div, Some(X::Q(5)), 0),
        ]);
        assert_eq!(
            ops(&p),
            vec![
                Op::LoadK(9999),
                Op::AddK(i16::MAX),
                Op::DivZero { line: 152 },
                Op::Div { cell: 5, line: 153 },
            ]
        );
    }

    #[test]
    fn lcd_lines_are_bound_to_fields_and_only_the_last_rev_runs() {
        let mut lines = vec![(150, M::Rev, None, 0)];
        lines.extend((0..6).map(|k| (151 + k, M::Lcd, None, 0)));
        lines.push((200, M::Rev, None, 0));
        let got = ops(&program(&lines));
        assert_eq!(
            got,
            vec![Op::Lcd(0), Op::Lcd(1), Op::Lcd(2), Op::Lcd(3), Op::Rev]
        );
    }

    #[test]
    fn counters_know_at_compile_time_whether_they_have_a_reset_input() {
        let q = X::Q(1);
        let one = program(&[(150, M::Ld, Some(X::D(0)), 0), (151, M::Ctu, Some(q), 0)]);
        assert_eq!(ops(&one)[1], Op::CountUp(1));
        let two = program(&[
            (150, M::Ld, Some(X::D(0)), 0),
            (151, M::Ld, Some(X::D(1)), 0),
            (152, M::Ctd, Some(q), 0),
            // One bit left after the pop: the next counter has no reset input.
            (153, M::Ctd, Some(q), 0),
        ]);
        assert_eq!(ops(&two)[2..], [Op::CountDownReset(1), Op::CountDown(1)]);
    }

    #[test]
    fn a_bit_load_and_a_logic_op_become_one_op() {
        let b = |n| crate::cells::bit_cell(X::B(n)).unwrap();
        let p = program(&[
            (150, M::Ld, Some(X::B(0)), 0),
            (151, M::Ld, Some(X::B(1)), 0),
            (152, M::And, None, 0),
            (153, M::Ldc, Some(X::B(2)), 0),
            (154, M::Anc, None, 0),
            (155, M::Ldc, Some(X::B(3)), 0),
            (156, M::Or, None, 0),
            (157, M::Xor, None, 0),
        ]);
        assert_eq!(
            ops(&p),
            vec![
                Op::Push(b(0)),
                Op::AndBit(b(1)),
                Op::AndBit(b(2)),
                Op::OrNotBit(b(3)),
                Op::Xor,
            ]
        );
    }

    #[test]
    fn the_seventeenth_bit_push_drops_bit_15_and_is_not_fused() {
        let mut lines: Vec<_> = (0..17)
            .map(|k| (150 + k, M::Ld, Some(X::D(0)), 0))
            .collect();
        lines.push((167, M::And, None, 0));
        let got = ops(&program(&lines));
        assert!(got[..16].iter().all(|op| matches!(op, Op::Push(_))));
        assert!(matches!(got[16], Op::PushDrop(_)));
        assert_eq!(got[17], Op::And);
    }

    #[test]
    fn a_full_section_takes_eight_bytes_per_line() {
        // docs/vm.md, "RAM": 850 x (op + timer start time).
        assert_eq!(size_of::<Slot>(), 8);
        assert!(size_of::<Code>() <= 850 * 8 + 4);
    }

    #[test]
    fn the_benchmark_programs_fit() {
        // Mixed: 50 blocks of 17 lines. Only 4 of the 50 `LCD` lines fill a field, and
        // `LD B`+`AND`, `LDC D`+`OR` fuse while their push cannot drop a bit (the stack
        // grows by 2 bits per block).
        let mixed = ops(&mixed_program());
        let fused = mixed
            .iter()
            .filter(|op| matches!(op, Op::AndBit(_) | Op::OrNotBit(_)))
            .count();
        assert!(fused > 0);
        assert_eq!(mixed.len(), 850 - 46 - fused);
        assert_eq!(ops(&timer_program()).len(), 850);
    }
}
