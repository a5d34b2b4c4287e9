//! Every assembler error kind, with the text line and column the user sees
//! (`seed.plc:12:9: ...` once the CLI adds the file name).

use shared_protocol::program::{assemble, assemble_into, AsmErrorKind, Program, VerifyErrorKind};

type SyntaxCase = (&'static str, u32, u32, fn(&AsmErrorKind) -> bool);
type VerifyCase = (&'static str, u32, fn(&VerifyErrorKind) -> bool);

fn at(text: &str) -> (u32, u32, AsmErrorKind, String) {
    let e = assemble(text).unwrap_err();
    (e.line, e.col, e.kind.clone(), format!("seed.plc:{e}"))
}

#[test]
fn spec_message_example() {
    let text = "; header\n\n\n\n\n\n\n\n\n\n\n150 LD  D16\n";
    assert_eq!(
        at(text).3,
        "seed.plc:12:9: operand D16 out of range (D00-D15)"
    );
}

#[test]
fn syntax_errors() {
    let cases: &[SyntaxCase] = &[
        ("1500 LD D00", 1, 1, |k| {
            matches!(k, AsmErrorKind::LineNumber { .. })
        }),
        ("x", 1, 1, |k| matches!(k, AsmErrorKind::LineNumber { .. })),
        ("  150   ; nothing", 1, 7, |k| {
            matches!(k, AsmErrorKind::MissingMnemonic)
        }),
        ("150 JMP D00", 1, 5, |k| {
            matches!(k, AsmErrorKind::UnknownMnemonic { .. })
        }),
        ("150 LD\tD100", 1, 8, |k| {
            matches!(k, AsmErrorKind::UnknownOperand { .. })
        }),
        ("150 LD COMX", 1, 8, |k| {
            matches!(k, AsmErrorKind::UnknownOperand { .. })
        }),
        ("150 EQ K05", 1, 12, |k| {
            matches!(k, AsmErrorKind::ConstantMissing { .. })
        }),
        ("150 EQ K05 12345", 1, 12, |k| {
            matches!(k, AsmErrorKind::BadConstant { .. })
        }),
        ("150 EQ K05 01x0", 1, 12, |k| {
            matches!(k, AsmErrorKind::BadConstant { .. })
        }),
        ("150 WR O00 0001", 1, 12, |k| {
            matches!(k, AsmErrorKind::UnexpectedConstant { .. })
        }),
        ("150 AND 0001", 1, 9, |k| {
            matches!(k, AsmErrorKind::UnexpectedConstant { .. })
        }),
        ("150 WR O00 junk", 1, 12, |k| {
            matches!(k, AsmErrorKind::TrailingText { .. })
        }),
        ("150 EQ K05 0100 0200", 1, 17, |k| {
            matches!(k, AsmErrorKind::TrailingText { .. })
        }),
        ("150 LD D00\n151 LD D01\n150 LD D02", 3, 1, |k| {
            matches!(
                k,
                AsmErrorKind::DuplicateLine {
                    number: 150,
                    first_text_line: 1
                }
            )
        }),
    ];
    for (text, line, col, kind) in cases {
        let (l, c, k, msg) = at(text);
        assert_eq!((l, c), (*line, *col), "{text:?}: {msg}");
        assert!(kind(&k), "{text:?}: {msg}");
    }
}

#[test]
fn verifier_errors_point_at_the_field() {
    use VerifyErrorKind as V;
    let cases: &[VerifyCase] = &[
        ("150 PWF K00 1000", 5, |k| {
            matches!(k, V::WrongSection { .. })
        }),
        ("000 LCD", 5, |k| matches!(k, V::WrongSection { .. })),
        ("150 CTU", 9, |k| matches!(k, V::OperandMissing { .. })),
        ("020 SN1 Q00", 9, |k| {
            matches!(k, V::OperandNotAllowed { .. })
        }),
        ("150 LET O00", 9, |k| {
            matches!(k, V::OperandWrongKind { .. })
        }),
        ("001 LD A00", 8, |k| matches!(k, V::OperandWrongKind { .. })),
        ("150 EQ FRQ", 8, |k| matches!(k, V::OperandWrongKind { .. })),
        ("150 WR FRQ", 8, |k| matches!(k, V::OperandWrongKind { .. })),
        ("150 LDC Q00", 9, |k| matches!(k, V::LdcOnInt { .. })),
        ("150 WR O08", 8, |k| {
            matches!(k, V::OperandOutOfRange { .. })
        }),
        ("150 LD A04", 8, |k| {
            matches!(k, V::OperandOutOfRange { .. })
        }),
        ("000 LD Q64", 8, |k| {
            matches!(k, V::OperandOutOfRange { .. })
        }),
        ("000 dU= K00 1024", 13, |k| {
            matches!(k, V::ConstantOutOfRange { .. })
        }),
        ("000 PWF K00 0100", 13, |k| {
            matches!(k, V::ConstantOutOfRange { .. })
        }),
        ("150 DIV K00 0000", 13, |k| {
            matches!(k, V::ConstantOutOfRange { .. })
        }),
    ];
    for (text, col, kind) in cases {
        let (l, c, k, msg) = at(text);
        assert_eq!((l, c), (1, *col), "{text:?}: {msg}");
        match k {
            AsmErrorKind::Verify(v) => assert!(kind(&v), "{text:?}: {msg}"),
            other => panic!("{text:?}: expected a verifier error, got {other:?}"),
        }
    }
}

#[test]
fn messages_say_what_was_expected() {
    assert_eq!(
        at("150 WR A00").3,
        "seed.plc:1:8: operand A00 not allowed with WR here (expected O, B, Q)"
    );
    assert_eq!(
        at("001 WR D00").3,
        "seed.plc:1:8: operand D00 not allowed with WR here (expected Q, PW1, PW3, PW5)"
    );
    assert_eq!(
        at("000 dU= K00 1024").3,
        "seed.plc:1:13: constant 1024 out of range for dU= (0000-1023)"
    );
}

#[test]
fn nothing_half_loaded() {
    let mut p = assemble("150 LD D00\n151 WR O00").unwrap();
    let before = p.clone();
    assert!(assemble_into("150 LD D01\n151 WR O01\n152 WR O09\n", &mut p).is_err());
    assert_eq!(p, before);
    assert!(assemble_into("999 LD D01\n000 PWF K00 0100\n", &mut p).is_err());
    assert_eq!(p, before);
    assemble_into("999 LD D01", &mut p).unwrap();
    let mut expected = Program::default();
    expected.lines[999] = assemble("999 LD D01").unwrap().lines[999];
    assert_eq!(p, expected);
}
