//! Property tests over the whole program module (encoding, verifier, text format).

use proptest::prelude::*;
use std::string::String;

use super::testing;
use super::*;

fn text_of(p: &Program) -> String {
    let mut s = String::new();
    disassemble(p, &mut s).unwrap();
    s
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn disassembly_reassembles_to_the_same_program(p in testing::program(120)) {
        prop_assert_eq!(verify(&p), Ok(()));
        let text = text_of(&p);
        prop_assert_eq!(assemble(&text), Ok(p.clone()));
        // Canonical form is a fixed point.
        prop_assert_eq!(text_of(&assemble(&text).unwrap()), text);
    }

    #[test]
    fn valid_lines_encode_and_decode_exactly(
        (n, i) in testing::line(),
    ) {
        prop_assert_eq!(verify_line(n, &i), Ok(()));
        let bytes = encode_line(&i);
        prop_assert_eq!(decode_line(&bytes), Ok(i));
        prop_assert_eq!(decode_slot(&encode_slot(Some(&i))), Ok(Some(i)));
    }

    #[test]
    fn drive_sections_verify(d in testing::drive_section(60)) {
        prop_assert_eq!(verify_drive(&d), Ok(()));
    }

    #[test]
    fn verifier_never_panics_and_accepts_only_offered_choices(
        line in any::<u16>(),
        i in testing::any_instruction(),
    ) {
        match verify_line(line, &i) {
            Ok(()) => {
                let section = Section::of_line(line).unwrap();
                prop_assert!(operands_for(i.mnemonic, section).any(|o| o == i.operand));
                // Accepted lines survive the binary and the text form.
                prop_assert_eq!(decode_line(&encode_line(&i)), Ok(i));
                let text = line_string(line, &i);
                let p = assemble(&text).unwrap();
                prop_assert_eq!(p.get(line), Some(&i));
            }
            Err(kind) => {
                prop_assert!(kind.short().to_string().len() <= 16);
                let _ = std::format!("{kind}");
            }
        }
    }

    #[test]
    fn decoder_never_panics_on_any_bytes(bytes in proptest::collection::vec(any::<u8>(), 0..9)) {
        if let Ok(i) = decode_line(&bytes) {
            // Whatever decodes re-encodes to the same bytes (canonical form).
            prop_assert_eq!(&encode_line(&i)[..], &bytes[..]);
            let _ = verify_line(0, &i);
            let _ = verify_line(500, &i);
        }
        let _ = decode_slot(&bytes);
    }

    #[test]
    fn assembler_never_panics_on_any_text(text in "\\PC{0,200}") {
        let _ = assemble(&text).map_err(|e| std::format!("{e}"));
    }

    #[test]
    fn assembler_never_panics_on_near_miss_text(
        text in "([0-9]{1,4}[ \t]+[A-Za-z=/<>]{1,4}([ \t]+[A-Za-z]{1,3}[0-9]{0,3})?([ \t]+[0-9]{1,5})?[ \t]*(;.*)?\r?\n){0,8}",
    ) {
        if let Ok(p) = assemble(&text) {
            // Line rules hold; only a whole-section rule (the drive stack) can fail.
            match verify(&p) {
                Ok(()) => prop_assert!(assemble_runnable(&text).is_ok()),
                Err(e) => {
                    let underflow = matches!(e.kind, VerifyErrorKind::StackUnderflow { .. });
                    prop_assert!(underflow, "{:?}", e);
                    prop_assert!(assemble_runnable(&text).is_err());
                }
            }
        }
    }
}

/// "Decode 1000 random lines, verify": random words with a valid mnemonic code half of
/// the time, so that both the decoder's and the verifier's paths are exercised.
#[test]
fn decode_1000_random_lines_then_verify() {
    use proptest::strategy::ValueTree;
    let mut runner = proptest::test_runner::TestRunner::deterministic();
    let code = prop_oneof![
        proptest::sample::select(Mnemonic::ALL.map(|m| m.code()).to_vec()),
        any::<u8>()
    ];
    let strategy = (code, any::<[u8; 3]>());
    let (mut decoded, mut accepted) = (0, 0);
    for _ in 0..1000 {
        let (c, rest) = strategy.new_tree(&mut runner).unwrap().current();
        let bytes = [c, rest[0], rest[1], rest[2]];
        if let Ok(i) = decode_line(&bytes) {
            decoded += 1;
            assert_eq!(encode_line(&i), bytes);
            for line in [0u16, 149, 150, 999, 1000] {
                if verify_line(line, &i).is_ok() {
                    accepted += 1;
                }
            }
        }
    }
    std::println!("{decoded} of 1000 random lines decode, {accepted} line placements verify");
}
