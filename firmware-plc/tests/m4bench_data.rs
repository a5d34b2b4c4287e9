//! The m4bench binary (plc-image, target only) scans `lift.plc` from
//! `plc-image/src/bin/data/lift.slots`: every program line's 4 stored bytes (`encode_slot`),
//! 1000 lines. This test keeps the file equal to the program; `BLESS=1 cargo test -p
//! firmware-plc --test m4bench_data` rewrites it.

use shared_protocol::program::{assemble, encode_slot, LINES, LINE_BYTES};

#[test]
fn m4bench_lift_slots_are_lift_plc() {
    let dir = env!("CARGO_MANIFEST_DIR");
    let text = std::fs::read_to_string(format!("{dir}/../shared-protocol/programs/lift.plc"))
        .expect("lift.plc");
    let program = assemble(&text).expect("lift.plc assembles");
    let mut bytes = Vec::with_capacity(LINES * LINE_BYTES);
    for line in &program.lines {
        bytes.extend_from_slice(&encode_slot(line.as_ref()));
    }
    let path = format!("{dir}/../plc-image/src/bin/data/lift.slots");
    if std::env::var_os("BLESS").is_some() {
        std::fs::write(&path, &bytes).expect("write lift.slots");
    }
    let stored =
        std::fs::read(&path).expect("plc-image/src/bin/data/lift.slots (BLESS=1 writes it)");
    assert!(
        stored == bytes,
        "plc-image/src/bin/data/lift.slots differs from lift.plc: run with BLESS=1"
    );
}
