//! The `.plc` assembler (text from the service port, plcctl and files) and the verifier
//! behind it.
//!
//! Asserts: no panic on any text; a text that assembles disassembles to a text that
//! assembles to the same program; `assemble_runnable` accepts exactly the programs that
//! assemble and verify; a verifier error is located without panic.
#![no_main]

use libfuzzer_sys::fuzz_target;
use shared_protocol::program::{assemble, assemble_runnable, disassemble, locate, verify};

fuzz_target!(|data: &[u8]| {
    let Ok(text) = core::str::from_utf8(data) else {
        return;
    };
    let runnable = assemble_runnable(text);
    match assemble(text) {
        Ok(p) => {
            let mut again = String::new();
            disassemble(&p, &mut again).expect("disassembles");
            let q = assemble(&again).expect("the disassembly assembles");
            assert!(q == p, "disassembly does not assemble to the same program");
            match verify(&p) {
                Ok(()) => assert!(runnable.is_ok_and(|r| r == p)),
                Err(e) => {
                    let _ = locate(text, &e);
                    assert!(runnable.is_err());
                }
            }
        }
        Err(_) => assert!(runnable.is_err()),
    }
});
