//! The source's example programs (program.md section 5) in `programs/`: each assembles,
//! verifies, sits in the right section and survives the canonical text and binary forms.
//! (`lift.plc` is tested in `tests/lift_program.rs` and by hil-sim's L1-L10.)

use shared_protocol::program::{
    assemble, assemble_runnable, decode_slot, disassemble, encode_slot, verify, Instruction,
    Mnemonic, Operand, Program, Section,
};

const PLC_EXAMPLES: &[(&str, &str)] = &[
    ("rs_flipflop", include_str!("../programs/rs_flipflop.plc")),
    ("t_flipflop", include_str!("../programs/t_flipflop.plc")),
    ("and_or", include_str!("../programs/and_or.plc")),
    ("counter100", include_str!("../programs/counter100.plc")),
    ("on_delay_10s", include_str!("../programs/on_delay_10s.plc")),
    ("arithmetic", include_str!("../programs/arithmetic.plc")),
    ("lcd", include_str!("../programs/lcd.plc")),
    ("rev_buttons", include_str!("../programs/rev_buttons.plc")),
    (
        "conditional_write",
        include_str!("../programs/conditional_write.plc"),
    ),
];

/// Examples with both sections (besides the motor program).
const MIXED_EXAMPLES: &[(&str, &str)] = &[
    ("com_monitor", include_str!("../programs/com_monitor.plc")),
    // The source's lab chapter (Obr 5.1-5.7), hil-sim/docs/lab.md.
    (
        "lab_5_1_runup",
        include_str!("../programs/lab_5_1_runup.plc"),
    ),
    (
        "lab_5_3_rundown_runup",
        include_str!("../programs/lab_5_3_rundown_runup.plc"),
    ),
    (
        "lab_5_4_switching",
        include_str!("../programs/lab_5_4_switching.plc"),
    ),
];

const DRIVE_EXAMPLES: &[(&str, &str)] = &[
    ("pi_ramp", include_str!("../programs/pi_ramp.plc")),
    (
        "three_phase_sine",
        include_str!("../programs/three_phase_sine.plc"),
    ),
    ("protections", include_str!("../programs/protections.plc")),
    ("direct_pwm", include_str!("../programs/direct_pwm.plc")),
    ("ir_boost", include_str!("../programs/ir_boost.plc")),
];

const MOTOR: &str = include_str!("../programs/motor.plc");
const SAFETY_LAB: &str = include_str!("../programs/safety_lab.plc");

fn checked(name: &str, text: &str) -> Program {
    let p = assemble(text).unwrap_or_else(|e| panic!("{name}.plc:{e}"));
    assert_eq!(verify(&p), Ok(()), "{name}");
    let mut canonical = String::new();
    disassemble(&p, &mut canonical).unwrap();
    assert_eq!(assemble(&canonical).as_ref(), Ok(&p), "{name} round trip");
    for slot in &p.lines {
        assert_eq!(
            decode_slot(&encode_slot(slot.as_ref())),
            Ok(*slot),
            "{name}"
        );
    }
    p
}

fn ins(mnemonic: Mnemonic, operand: Option<Operand>, constant: u16) -> Instruction {
    Instruction {
        mnemonic,
        operand,
        constant,
    }
}

#[test]
fn plc_examples_are_plc_only_from_line_150() {
    for (name, text) in PLC_EXAMPLES {
        let p = checked(name, text);
        assert_eq!(p.section(Section::Drive).count(), 0, "{name}");
        let first = p.section(Section::Plc).next().map(|(n, _)| n);
        assert_eq!(first, Some(150), "{name}");
    }
}

#[test]
fn drive_examples_are_drive_only_from_line_000() {
    for (name, text) in DRIVE_EXAMPLES {
        let p = checked(name, text);
        assert_eq!(p.section(Section::Plc).count(), 0, "{name}");
        let first = p.section(Section::Drive).next().map(|(n, _)| n);
        assert_eq!(first, Some(0), "{name}");
    }
}

#[test]
fn mixed_examples_verify_in_both_sections() {
    for (name, text) in MIXED_EXAMPLES {
        let p = checked(name, text);
        assert!(p.section(Section::Drive).count() > 0, "{name}");
        assert!(p.section(Section::Plc).count() > 0, "{name}");
    }
    // com_monitor: the trimmers are I>> and U>>, shown with IHW and UHW.
    let p = checked("com_monitor", MIXED_EXAMPLES[0].1);
    assert_eq!(
        p.get(0),
        Some(&ins(Mnemonic::IMaxHw, Some(Operand::K(0)), 250))
    );
    assert_eq!(
        p.get(1),
        Some(&ins(Mnemonic::UMaxHw, Some(Operand::K(1)), 38))
    );
    let shown: Vec<_> = p
        .section(Section::Plc)
        .filter(|(_, i)| i.mnemonic == Mnemonic::Ld)
        .filter_map(|(_, i)| i.operand)
        .collect();
    assert!(shown.contains(&Operand::Ihw) && shown.contains(&Operand::Uhw));
}

#[test]
fn every_file_in_programs_is_covered() {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/programs");
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .filter(|n| n.ends_with(".plc"))
        .collect();
    names.sort();
    let mut known: Vec<String> = PLC_EXAMPLES
        .iter()
        .chain(DRIVE_EXAMPLES)
        .chain(MIXED_EXAMPLES)
        .map(|(n, _)| format!("{n}.plc"))
        .chain(["motor.plc", "safety_lab.plc", "lift.plc"].map(String::from))
        .collect();
    known.sort();
    assert_eq!(names, known);
}

#[test]
fn motor_example_is_the_listing_with_the_frv_correction() {
    let p = checked("motor", MOTOR);
    let drive: Vec<u16> = p.section(Section::Drive).map(|(n, _)| n).collect();
    let plc: Vec<u16> = p.section(Section::Plc).map(|(n, _)| n).collect();
    assert_eq!(drive, (0..=25).collect::<Vec<_>>());
    assert_eq!(plc, (150..=175).collect::<Vec<_>>());
    assert_eq!(
        p.get(25),
        Some(&ins(Mnemonic::Frv, Some(Operand::K(20)), 200))
    );
    assert_eq!(
        p.get(5),
        Some(&ins(Mnemonic::Pi, Some(Operand::K(2)), 1000))
    );
    assert_eq!(
        p.get(2),
        Some(&ins(Mnemonic::Ld, Some(Operand::K(1)), 2333))
    );
    assert_eq!(p.get(0), Some(&ins(Mnemonic::Pwf, Some(Operand::Q(0)), 0)));
    assert_eq!(
        p.get(167),
        Some(&ins(Mnemonic::Imp, Some(Operand::K(16)), 70))
    );
    assert_eq!(
        p.get(169),
        Some(&ins(Mnemonic::Let, Some(Operand::B(4)), 0))
    );
    assert_eq!(p.get(175), Some(&ins(Mnemonic::Wr, Some(Operand::Q(0)), 0)));
    // Exactly two LCD fields: A01 and the switching frequency.
    let lcd = p
        .section(Section::Plc)
        .filter(|(_, i)| i.mnemonic == Mnemonic::Lcd)
        .count();
    assert_eq!(lcd, 2);
}

#[test]
fn arithmetic_follows_the_prose_add_10_multiply_by_3() {
    let p = checked("arithmetic", PLC_EXAMPLES[5].1);
    assert_eq!(
        p.get(151),
        Some(&ins(Mnemonic::Add, Some(Operand::K(3)), 10))
    );
    assert_eq!(
        p.get(152),
        Some(&ins(Mnemonic::Mul, Some(Operand::K(4)), 3))
    );
}

#[test]
fn counters_follow_the_two_bit_and_the_single_bit_rule() {
    let ctu = |p: &shared_protocol::program::Program| {
        p.section(Section::Plc)
            .find(|(_, i)| i.mnemonic == Mnemonic::Ctu)
            .unwrap()
            .0
    };
    // counter100: the line before CTU pushes the reset bit (an LD of a B bit) and the line
    // before that is the LET producing the count edge.
    let p = checked("counter100", PLC_EXAMPLES[3].1);
    let n = ctu(&p);
    assert_eq!(p.get(n - 1).map(|i| i.mnemonic), Some(Mnemonic::Ld));
    assert_eq!(p.get(n - 2).map(|i| i.mnemonic), Some(Mnemonic::Let));
    // lcd: the source's listing, only the edge loaded before CTU (program.md 3.2, the
    // single-bit rule: it is the count input).
    let p = checked("lcd", PLC_EXAMPLES[6].1);
    let n = ctu(&p);
    assert_eq!(p.get(n - 1).map(|i| i.mnemonic), Some(Mnemonic::Let));
    assert_eq!(p.get(n - 2).map(|i| i.mnemonic), Some(Mnemonic::Ld));
}

/// safety.md 12: the lab program. Its signature is documented (README, shared-protocol
/// docs) as 7C32; each function the lab configures has its selection switch (requested
/// while the request latch B21 holds and the switch is on), STO when no switch is on.
#[test]
fn safety_lab_has_the_lab_settings_its_documented_signature_and_a_switch_per_function() {
    use shared_protocol::program::{safety_settings, uses_safety};
    use shared_protocol::safety::{SafetyFunction as F, SafetySetting as S};
    let p = checked("safety_lab", SAFETY_LAB);
    assert!(SAFETY_LAB.contains("NOT RATED"));
    assert!(uses_safety(&p));
    let s = safety_settings(p.lines.iter());
    assert_eq!(s.signature(), 0x7C32);
    for (k, v) in [
        (S::Fss, Some(40)),
        (S::Pss, Some(200)),
        (S::Trd, Some(50)),
        (S::Tel, Some(50)),
        (S::Ts1, Some(100)),
        (S::Fl1, Some(160)),
        (S::Fl2, Some(100)),
        (S::Pli, Some(100)),
        (S::Tli, Some(100)),
        (S::Aap, Some(2000)),
        (S::Ard, None),
        (S::Asr, None),
        (S::Fl3, None),
        (S::Fl4, None),
    ] {
        assert_eq!(s.get(k), v, "{k:?}");
    }
    assert_eq!(
        p.get(11),
        Some(&ins(Mnemonic::Fmn, Some(Operand::K(6)), 10))
    );
    let sfr_line = |f: F| {
        (150..shared_protocol::program::LINES as u16)
            .find(|&n| p.get(n) == Some(&ins(Mnemonic::Sfr, Some(Operand::Sf(f)), 0)))
            .unwrap_or_else(|| panic!("no SFR {f:?}"))
    };
    // LDC B21, LDC <switch>, OR, SFR <function>.
    for (f, switch) in [
        (F::Ss1, 8),
        (F::Ss2, 9),
        (F::Sos, 10),
        (F::Sl1, 11),
        (F::Sl2, 12),
        (F::Sli, 13),
        (F::Sdp, 14),
        (F::Sdn, 15),
        (F::Sla, 4),
    ] {
        let n = sfr_line(f);
        assert_eq!(
            [p.get(n - 3), p.get(n - 2), p.get(n - 1)],
            [
                Some(&ins(Mnemonic::Ldc, Some(Operand::B(21)), 0)),
                Some(&ins(Mnemonic::Ldc, Some(Operand::D(switch)), 0)),
                Some(&ins(Mnemonic::Or, None, 0)),
            ],
            "{f:?}"
        );
    }
    // STO: the latch and no switch on (B25 = any switch).
    let n = sfr_line(F::Sto);
    assert_eq!(
        [p.get(n - 3), p.get(n - 2), p.get(n - 1)],
        [
            Some(&ins(Mnemonic::Ldc, Some(Operand::B(21)), 0)),
            Some(&ins(Mnemonic::Ld, Some(Operand::B(25)), 0)),
            Some(&ins(Mnemonic::Or, None, 0)),
        ]
    );
    // SL3/SL4 are not configured: a program requesting them does not verify.
    for f in [F::Sl3, F::Sl4] {
        let text = format!("{SAFETY_LAB}999 SFR {}\n", f.name());
        let e = assemble_runnable(&text).unwrap_err().to_string();
        assert!(
            e.ends_with(&format!("{} needs fl{}", f.name(), &f.name()[2..])),
            "{e}"
        );
    }
}
