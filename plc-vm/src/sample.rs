//! Reference programs for the scan benchmarks (`benches/scan.rs`, `src/bin/m4bench.rs`)
//! and for simulations: built in code so that the target bench needs no assembler.

use shared_protocol::program::{Instruction, Mnemonic, Operand, Program, LINES, PLC_FIRST_LINE};

/// One block of the mixed program: bit logic, edges, a timer, a counter, arithmetic, a
/// compare, outputs, a Q write and an `LCD` (17 lines; 50 blocks fill lines 150-999).
const BLOCK: [(Mnemonic, Operand, u16); 17] = [
    (Mnemonic::Ld, Operand::D(0), 0),
    (Mnemonic::Ld, Operand::B(10), 0),
    (Mnemonic::And, Operand::K(0), 0), // operand dropped below for no-operand mnemonics
    (Mnemonic::Ldc, Operand::D(1), 0),
    (Mnemonic::Or, Operand::K(0), 0),
    (Mnemonic::Let, Operand::B(20), 0),
    (Mnemonic::Io, Operand::B(10), 0),
    (Mnemonic::Ld, Operand::A(1), 0),
    (Mnemonic::Add, Operand::K(1), 10),
    (Mnemonic::Mul, Operand::Q(1), 0),
    (Mnemonic::Div, Operand::K(2), 3),
    (Mnemonic::Gt, Operand::K(3), 300),
    (Mnemonic::Ton, Operand::K(4), 50),
    (Mnemonic::Wr, Operand::O(0), 0),
    (Mnemonic::Ld, Operand::B(10), 0),
    (Mnemonic::Wr, Operand::Q(2), 0),
    (Mnemonic::Lcd, Operand::K(0), 0),
];

/// Spreads the block's addresses so that the 50 copies use different memory.
fn vary(op: Operand, block: u8) -> Operand {
    match op {
        Operand::D(n) => Operand::D((n + block) % 8),
        Operand::O(n) => Operand::O((n + block) % 6),
        Operand::B(n) => Operand::B((n + block) % 100),
        Operand::A(n) => Operand::A((n + block) % 4),
        Operand::Q(n) => Operand::Q((n + block) % 64),
        other => other,
    }
}

/// A full PLC section (all 850 lines, 150-999) of mixed instructions, valid for the
/// verifier. Every line executes in every scan.
pub fn mixed_program() -> Program {
    let mut p = Program::default();
    let plc = p.lines.iter_mut().skip(usize::from(PLC_FIRST_LINE));
    for (n, slot) in plc.enumerate() {
        let block = (n / BLOCK.len()) as u8;
        let Some(&(mnemonic, op, constant)) = BLOCK.get(n % BLOCK.len()) else {
            continue;
        };
        let takes_operand = !matches!(mnemonic, Mnemonic::And | Mnemonic::Or | Mnemonic::Lcd);
        *slot = Some(Instruction {
            mnemonic,
            operand: takes_operand.then(|| vary(op, block)),
            constant,
        });
    }
    p
}

/// A full PLC section of timers only (`LD Dn`, then `TON`/`TOF`/`IMP` in turn on the
/// remaining lines): the slowest instructions, for a worst-case figure.
pub fn timer_program() -> Program {
    let mut p = Program::default();
    let plc = p.lines.iter_mut().skip(usize::from(PLC_FIRST_LINE));
    for (n, slot) in plc.enumerate() {
        let mnemonic = match n % 4 {
            0 => Mnemonic::Ld,
            1 => Mnemonic::Ton,
            2 => Mnemonic::Tof,
            _ => Mnemonic::Imp,
        };
        let (operand, constant) = if mnemonic == Mnemonic::Ld {
            (Operand::D((n % 8) as u8), 0)
        } else {
            (Operand::K((n % 100) as u8), 1 + (n % 50) as u16)
        };
        *slot = Some(Instruction {
            mnemonic,
            operand: Some(operand),
            constant,
        });
    }
    p
}

/// Number of PLC lines that hold an instruction (what one scan executes).
pub fn plc_instructions(p: &Program) -> usize {
    p.lines
        .get(usize::from(PLC_FIRST_LINE)..LINES)
        .map_or(0, |l| l.iter().filter(|l| l.is_some()).count())
}

#[cfg(test)]
mod tests {
    use super::*;
    use shared_protocol::program::verify;

    #[test]
    fn sample_programs_are_full_and_valid() {
        for p in [mixed_program(), timer_program()] {
            assert_eq!(verify(&p), Ok(()));
            assert_eq!(plc_instructions(&p), 850);
        }
    }
}
