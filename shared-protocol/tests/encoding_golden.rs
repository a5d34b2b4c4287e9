//! The 4-byte line encoding of every instruction, against a golden table made from the
//! encoder before the mnemonic table was introduced: the program byte format (EEPROM
//! images, link download) must never change under a refactor. For each mnemonic in each
//! section it exists in: no operand, or the first and last index of every accepted operand
//! class, with the smallest and largest accepted constant for `K`.
//!
//! A new instruction adds lines to the table: regenerate it with
//! `GOLDEN_BLESS=1 cargo test -p shared-protocol --release --test encoding_golden` and check
//! in the diff that only the new mnemonic's lines were added.

use shared_protocol::program::{
    constant_range, decode_line, encode_line, mnemonics_for, operands_for, Instruction, Section,
};

const GOLDEN: &str = "tests/encoding_golden.txt";

fn table() -> String {
    let mut out = String::new();
    for (section, name) in [(Section::Plc, "plc"), (Section::Drive, "drive")] {
        for m in mnemonics_for(section) {
            let ops: Vec<_> = operands_for(m, section).collect();
            // First and last operand of each class (operands come class by class).
            let mut picked = Vec::new();
            for (n, op) in ops.iter().enumerate() {
                let class = op.map(|o| o.class());
                let prev = n.checked_sub(1).map(|p| ops[p].map(|o| o.class()));
                let next = ops.get(n + 1).map(|o| o.map(|o| o.class()));
                if prev != Some(class) || next != Some(class) {
                    picked.push(*op);
                }
            }
            for op in picked {
                let constants = match constant_range(m, section, op) {
                    Some(r) => vec![*r.start(), *r.end()],
                    None => vec![0],
                };
                for constant in constants {
                    let i = Instruction {
                        mnemonic: m,
                        operand: op,
                        constant,
                    };
                    let bytes = encode_line(&i);
                    assert_eq!(decode_line(&bytes), Ok(i), "{i:?} does not decode back");
                    let op_text = op.map_or("-".to_string(), |o| o.to_string());
                    out.push_str(&format!(
                        "{name} {} {op_text} {constant:04} {:02X}{:02X}{:02X}{:02X}\n",
                        m.text(),
                        bytes[0],
                        bytes[1],
                        bytes[2],
                        bytes[3]
                    ));
                }
            }
        }
    }
    out
}

#[test]
fn every_instruction_encodes_as_before() {
    let now = table();
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(GOLDEN);
    if std::env::var_os("GOLDEN_BLESS").is_some() {
        std::fs::write(&path, &now).unwrap();
    }
    let golden = std::fs::read_to_string(&path).unwrap();
    let now_lines: Vec<&str> = now.lines().collect();
    // Every golden line is still encoded the same; new lines may only be added.
    for line in golden.lines() {
        assert!(
            now_lines.contains(&line),
            "golden encoding changed or instruction lost: {line}"
        );
    }
    assert!(golden.lines().count() > 300, "golden table too small");
    assert_eq!(
        now_lines.len(),
        golden.lines().count(),
        "instructions added: regenerate the table (GOLDEN_BLESS=1) and review its diff"
    );
}
