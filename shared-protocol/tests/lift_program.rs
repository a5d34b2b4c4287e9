//! `programs/lift.plc` (lift.md 3): assembles, passes the verifier as a runnable program,
//! and uses only the registers and I/O lift.md 3.2-3.3 give it.

use shared_protocol::program::{assemble_runnable, verify, Mnemonic, Operand, Section};

const LIFT: &str = include_str!("../programs/lift.plc");

#[test]
fn lift_assembles_and_verifies() {
    let p = assemble_runnable(LIFT).expect("lift.plc assembles and is runnable");
    assert!(verify(&p).is_ok());
    let plc: Vec<_> = p.section(Section::Plc).collect();
    let drive: Vec<_> = p.section(Section::Drive).collect();
    assert!(drive.len() >= 20 && !plc.is_empty());
    // No frv line: the lift relies on the reversal at standstill (lift.md 3.4).
    assert!(drive.iter().all(|(_, i)| i.mnemonic != Mnemonic::Frv));
    // Outputs O00-O06 only (O07 is the spare); Q01 is written by the drive section only.
    for (_, i) in &plc {
        assert_ne!(i.operand, Some(Operand::O(7)), "{i:?}");
        if matches!(i.mnemonic, Mnemonic::Wr | Mnemonic::Wrc) {
            assert_ne!(i.operand, Some(Operand::Q(1)), "{i:?}");
        }
    }
    // The four LCD fields: floor, target, state, load.
    assert_eq!(
        plc.iter()
            .filter(|(_, i)| i.mnemonic == Mnemonic::Lcd)
            .count(),
        4
    );
}
