//! The VM never panics: on any program (valid or not), any inputs and any times; and on
//! verified programs its outputs only report what the program can produce.

use plc_vm::{DriveView, PlcVm, ScanInputs, ScanOutputs, Warning};
use proptest::prelude::*;
use shared_protocol::program::testing::any_instruction;
use shared_protocol::program::{
    constant_range, mnemonics_for, operands_for, verify, Instruction, Mnemonic, Operand, Program,
    Section, PLC_FIRST_LINE,
};
use shared_protocol::units::{CentiAmps, Decihertz, Decivolts, Millis};

/// Every valid PLC (mnemonic, operand) pair, from the verifier's own tables.
fn valid_pairs() -> Vec<(Mnemonic, Option<Operand>)> {
    mnemonics_for(Section::Plc)
        .flat_map(|m| operands_for(m, Section::Plc).map(move |o| (m, o)))
        .collect()
}

fn valid_instruction() -> impl Strategy<Value = Instruction> + Clone {
    (prop::sample::select(valid_pairs()), any::<u16>()).prop_map(|((mnemonic, operand), c)| {
        let constant = match constant_range(mnemonic, Section::Plc, operand) {
            Some(r) => r.start() + c % (r.end() - r.start() + 1),
            None => 0,
        };
        Instruction {
            mnemonic,
            operand,
            constant,
        }
    })
}

/// Sparse or full programs on the lines `first..1000`.
fn program(
    first: usize,
    ins: impl Strategy<Value = Instruction> + Clone,
) -> impl Strategy<Value = Program> {
    let sparse = prop::collection::vec((first..1000, ins.clone()), 0..200);
    let dense = prop::collection::vec(ins, 850);
    prop_oneof![
        sparse.prop_map(|lines| {
            let mut p = Program::default();
            for (n, i) in lines {
                p.lines[n] = Some(i);
            }
            shared_protocol::program::testing::fix_safety(&mut p.lines);
            p
        }),
        dense.prop_map(|lines| {
            let mut p = Program::default();
            for (n, i) in lines.into_iter().enumerate() {
                p.lines[150 + n] = Some(i);
            }
            shared_protocol::program::testing::fix_safety(&mut p.lines);
            p
        }),
    ]
}

fn inputs() -> impl Strategy<Value = ScanInputs> {
    (
        any::<u16>(),
        any::<[u16; 4]>(),
        (any::<u16>(), any::<i16>(), any::<i16>(), any::<i16>()),
        (any::<u8>(), any::<bool>(), any::<bool>(), any::<bool>()),
    )
        .prop_map(
            |(digital, analog, (com, frq, udc, imx), (flt, dir_reverse, ready, fault_latched))| {
                ScanInputs {
                    digital,
                    analog,
                    drive: DriveView {
                        com,
                        frq: Decihertz(frq),
                        udc: Decivolts(udc),
                        imx: CentiAmps(imx),
                        flt,
                        dir_reverse,
                        ready,
                        fault_latched,
                        ihw: CentiAmps(imx.wrapping_add(7)),
                        uhw: shared_protocol::units::Volts(udc / 10),
                        sf_status: com,
                        sf_sdc: ready,
                        sf_elapsed_ds: frq as u16,
                        sf_turns: udc.wrapping_neg(),
                    },
                }
            },
        )
}

/// Scans: time step (any, including huge jumps and 0) and inputs.
fn scans() -> impl Strategy<Value = Vec<(u32, ScanInputs)>> {
    prop::collection::vec(
        (prop_oneof![0u32..50, 0u32..20_000, any::<u32>()], inputs()),
        1..12,
    )
}

fn run(prog: &Program, t0: u32, scans: &[(u32, ScanInputs)]) -> Vec<ScanOutputs> {
    let mut vm = PlcVm::new();
    vm.start(Millis(t0));
    let mut t = t0;
    let mut out = ScanOutputs::default();
    scans
        .iter()
        .map(|(dt, inputs)| {
            t = t.wrapping_add(*dt);
            vm.scan(prog, inputs, Millis(t), &mut out);
            out
        })
        .collect()
}

/// The outputs O00-O07 the program's PLC section names at all (bit n = On): no other
/// output can ever be on.
fn named_outputs(prog: &Program) -> u8 {
    prog.lines
        .iter()
        .skip(usize::from(PLC_FIRST_LINE))
        .flatten()
        .fold(0, |m, i| match i.operand {
            Some(Operand::O(n)) if n < plc_vm::OUTPUTS => m | 1 << n,
            _ => m,
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    #[test]
    fn never_panics_on_any_program(
        prog in program(0, any_instruction()),
        t0 in any::<u32>(),
        scans in scans(),
    ) {
        for out in run(&prog, t0, &scans) {
            prop_assert_eq!(out.outputs & !named_outputs(&prog), 0);
        }
    }

    #[test]
    fn never_panics_on_shared_protocol_valid_programs(
        prog in shared_protocol::program::testing::program(600),
        t0 in any::<u32>(),
        scans in scans(),
    ) {
        prop_assert!(verify(&prog).is_ok());
        for out in run(&prog, t0, &scans) {
            prop_assert_eq!(out.outputs & !named_outputs(&prog), 0);
        }
    }

    #[test]
    fn verified_programs_report_only_what_they_contain(
        prog in program(150, valid_instruction()),
        t0 in any::<u32>(),
        scans in scans(),
    ) {
        prop_assert!(verify(&prog).is_ok(), "generator makes valid programs");
        let plc = || prog.lines.iter().enumerate().skip(usize::from(PLC_FIRST_LINE))
            .filter_map(|(n, l)| l.map(|i| (n, i)));
        let has = |m: Mnemonic| plc().any(|(_, i)| i.mnemonic == m);
        let lcd_lines = plc().filter(|(_, i)| i.mnemonic == Mnemonic::Lcd).count();
        let mut writable_q = 0u64;
        for (_, i) in plc() {
            if let (Mnemonic::Wr | Mnemonic::Wrc, Some(Operand::Q(n))) = (i.mnemonic, i.operand) {
                writable_q |= 1 << n;
            }
        }
        for out in run(&prog, t0, &scans) {
            prop_assert_eq!(out.outputs & !named_outputs(&prog), 0);
            prop_assert_eq!(out.q_dirty & !writable_q, 0, "only WR/WRC Q lines report");
            let filled = out.lcd.iter().take_while(|f| f.is_some()).count();
            prop_assert!(out.lcd[filled..].iter().all(|f| f.is_none()), "LCD fields in order");
            prop_assert_eq!(filled, lcd_lines.min(4), "every LCD line fills a field");
            prop_assert!(out.rev_request.is_none() || has(Mnemonic::Rev));
            prop_assert!(!out.ack_request || has(Mnemonic::Ack));
            if let Some(Warning::Div0 { line }) = out.warning {
                let i = prog.get(line);
                prop_assert!(
                    matches!(i, Some(i) if i.mnemonic == Mnemonic::Div && i.operand.is_some_and(|o| matches!(o, Operand::Q(_)))),
                    "DIV0 only on a DIV by Q line (K 0000 is rejected by the verifier)"
                );
            }
        }
    }
}
