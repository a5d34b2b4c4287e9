//! The program's binary forms: the 4-byte line encoding (what a slot and the link's
//! download chunks carry), the stored payload (runs of lines, what the service port
//! transfers and an EEPROM copy holds) and the verifier of what they decode to.
//!
//! Asserts: no panic; a line that decodes re-encodes to a line that decodes to the same
//! instruction (and that re-encoding is a fixed point); a payload that decodes re-encodes to
//! one that decodes to the same program; the verifier never panics on a decoded program, and
//! a program it accepts is saved into an EEPROM image and read back from it unchanged
//! (`firmware_plc::storage::image`).
#![no_main]

use firmware_plc::storage::image::{program_from_image, program_image, ImageOptions};
use libfuzzer_sys::fuzz_target;
use shared_protocol::program::payload::{for_each_payload_byte, program_from_payload};
use shared_protocol::program::{
    decode_slot, encode_slot, verify, verify_drive, Program, LINE_BYTES,
};

fuzz_target!(|data: &[u8]| {
    for chunk in data.chunks_exact(LINE_BYTES) {
        if let Ok(line) = decode_slot(chunk) {
            let bytes = encode_slot(line.as_ref());
            let again = decode_slot(&bytes).expect("a re-encoded line decodes");
            assert_eq!(again, line);
            assert_eq!(encode_slot(again.as_ref()), bytes);
        }
    }

    let mut p = Program::default();
    if !program_from_payload(data, &mut p) {
        assert!(
            p == Program::default(),
            "a refused payload left lines behind"
        );
        return;
    }
    let mut bytes = Vec::new();
    for_each_payload_byte(&p, |b| bytes.push(b));
    let mut q = Program::default();
    assert!(
        program_from_payload(&bytes, &mut q),
        "a re-encoded payload does not decode"
    );
    assert!(q == p, "payload round trip changed the program");

    let _ = verify_drive(&p.drive_section());
    if verify(&p).is_ok() {
        let image = program_image(&p, &ImageOptions::default()).expect("a verified program saves");
        let back = program_from_image(&image).expect("a saved image loads");
        assert!(back == p, "the EEPROM image gave another program");
    }
});
