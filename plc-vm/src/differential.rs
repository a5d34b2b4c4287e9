//! Differential test of the compiled form: random programs run side by side on
//! [`PlcVm`] (compiled at RUN) and on [`ReferenceVm`] (the direct interpreter the VM used
//! before, kept as the oracle), scan after scan with random inputs and scan times
//! (including 0, jumps of days and clock wraps), and everything a scan produces is
//! compared after every scan: the output image, every Q, every B, the LCD fields, the Q
//! writes, the direction and acknowledge requests, the warning and the first-scan flag.

use proptest::prelude::*;
use shared_protocol::program::testing::{any_instruction, instruction, instruction_from};
use shared_protocol::program::{verify, Instruction, Mnemonic, Operand, Program, Section};
use shared_protocol::units::{CentiAmps, Decihertz, Decivolts, Millis};

use super::reference::ReferenceVm;
use super::{DriveView, PlcVm, ScanInputs, ScanOutputs, B_COUNT, OUTPUTS, Q_COUNT};

/// One scan: time since the previous scan (ms), inputs, and whether RUN restarts first.
#[derive(Debug, Clone)]
struct Scan {
    dt_ms: u32,
    inputs: ScanInputs,
    restart: bool,
}

fn drive_view() -> impl Strategy<Value = DriveView> {
    (
        (any::<u16>(), any::<i16>(), any::<i16>(), any::<i16>()),
        (any::<u8>(), any::<bool>(), any::<bool>(), any::<bool>()),
        (any::<i16>(), any::<i16>()),
        (any::<u16>(), any::<bool>(), any::<u16>(), any::<i16>()),
    )
        .prop_map(
            |(
                (com, frq, udc, imx),
                (flt, dir_reverse, ready, fault_latched),
                (ihw, uhw),
                (sf_status, sf_sdc, sf_elapsed_ds, sf_turns),
            )| {
                DriveView {
                    com,
                    frq: Decihertz(frq),
                    udc: Decivolts(udc),
                    imx: CentiAmps(imx),
                    flt,
                    dir_reverse,
                    ready,
                    fault_latched,
                    ihw: CentiAmps(ihw),
                    uhw: shared_protocol::units::Volts(uhw),
                    sf_status,
                    sf_sdc,
                    sf_elapsed_ds,
                    sf_turns,
                }
            },
        )
}

fn inputs() -> impl Strategy<Value = ScanInputs> {
    // Analog values around the interesting ranges: 0, the 10-bit limit and beyond.
    let analog = prop_oneof![0u16..=1023, 1000u16..=1100, any::<u16>()];
    (
        any::<u16>(),
        [analog.clone(), analog.clone(), analog.clone(), analog],
        drive_view(),
    )
        .prop_map(|(digital, analog, drive)| ScanInputs {
            digital,
            analog,
            drive,
        })
}

/// Scans with times that exercise the timers: equal times, steps around typical presets
/// (0.1 s units), long pauses and arbitrary jumps (wrapping the u32 clock). Inputs change
/// at random, or stay for a few scans so that delays can elapse.
fn scans(max: usize) -> impl Strategy<Value = Vec<Scan>> {
    let dt = prop_oneof![
        3 => 0u32..=20,
        3 => 0u32..=2_000,
        1 => 0u32..=200_000,
        1 => any::<u32>(),
    ];
    let step = (dt, inputs(), 1usize..=4, prop::bool::weighted(0.03));
    prop::collection::vec(step, 1..=max).prop_map(|steps| {
        let mut scans = Vec::new();
        for (dt_ms, inputs, hold, restart) in steps {
            scans.push(Scan {
                dt_ms,
                inputs,
                restart,
            });
            // The same inputs for a few more scans, 1-120 ms apart.
            for k in 1..hold {
                scans.push(Scan {
                    dt_ms: 1 + (dt_ms % 40) * k as u32 % 120,
                    inputs,
                    restart: false,
                });
            }
        }
        scans
    })
}

/// A program with `ins` on random lines `first..1000` (sparse) or on consecutive lines
/// from a random start (dense: long runs of logic and deep stacks).
fn program_from(
    first: usize,
    ins: impl Strategy<Value = Instruction> + Clone,
    max_lines: usize,
) -> impl Strategy<Value = Program> {
    let sparse = prop::collection::vec((first..1000, ins.clone()), 0..=max_lines);
    let dense = (first..1000, prop::collection::vec(ins, 0..=max_lines));
    prop_oneof![
        sparse.prop_map(|lines| {
            let mut p = Program::default();
            for (n, i) in lines {
                p.lines[n] = Some(i);
            }
            shared_protocol::program::testing::fix_safety(&mut p.lines);
            p
        }),
        dense.prop_map(|(first, lines)| {
            let mut p = Program::default();
            for (slot, i) in p.lines[first..].iter_mut().zip(lines) {
                *slot = Some(i);
            }
            shared_protocol::program::testing::fix_safety(&mut p.lines);
            p
        }),
    ]
}

/// Bit logic, stack-depth sensitive instructions and timers only: long push chains (bit
/// 15 dropped), `LD`+`AND`-style pairs (fused by the compiler), counters with one or two
/// bits loaded, edges and the first-scan rules.
fn logic_instruction() -> BoxedStrategy<Instruction> {
    use Mnemonic as M;
    instruction_from(
        Section::Plc,
        vec![
            M::Ld,
            M::Ldc,
            M::Ld,
            M::Ldc,
            M::And,
            M::Or,
            M::Xor,
            M::Anc,
            M::Orc,
            M::Not,
            M::Wr,
            M::Wrc,
            M::Let,
            M::Io,
            M::Set,
            M::Res,
            M::Ctu,
            M::Ctd,
            M::Ton,
            M::Tof,
            M::Imp,
            M::Ack,
            M::Alm,
            M::Rev,
            M::Sfr,
            M::Eq,
            M::Lcd,
        ],
    )
    .boxed()
}

/// Blocks that fill S to around 16 bits and pop it again: a bit pushed more than 16
/// pushes ago is dropped (S is 16 bits), so popping back down must read 0 there. Each
/// block: an optional S0-setting op on a possibly empty stack, 12-20 bit loads, 12-20
/// pops (binary logic, counters), each followed now and then by a write of S0.
fn stack_block() -> impl Strategy<Value = Vec<Instruction>> {
    use Mnemonic as M;
    let bit = prop_oneof![
        (0u8..8).prop_map(Operand::D),
        (0u8..6).prop_map(Operand::O),
        (0u8..100).prop_map(Operand::B),
        Just(Operand::Rdy),
        Just(Operand::Flb),
        Just(Operand::Sdc),
        (0u8..12).prop_map(|n| Operand::Sf(
            shared_protocol::safety::SafetyFunction::from_bit_saturating(n)
        )),
    ];
    let load = (prop::sample::select(vec![M::Ld, M::Ldc]), bit).prop_map(|(m, x)| ins(m, Some(x)));
    let pop = prop_oneof![
        prop::sample::select(vec![M::And, M::Or, M::Xor, M::Anc, M::Orc])
            .prop_map(|m| ins(m, None)),
        (prop::sample::select(vec![M::Ctu, M::Ctd]), 0u8..64)
            .prop_map(|(m, n)| ins(m, Some(Operand::Q(n)))),
    ];
    let write = prop_oneof![
        (0u8..100).prop_map(|n| ins(M::Wr, Some(Operand::B(n)))),
        (0u8..6).prop_map(|n| ins(M::Wrc, Some(Operand::O(n)))),
    ];
    let set_s0 = prop::option::of(prop::sample::select(vec![
        ins(M::Not, None),
        Instruction {
            mnemonic: M::Eq,
            operand: Some(Operand::K(0)),
            constant: 0,
        },
    ]));
    (
        set_s0,
        prop::collection::vec(load, 12..=20),
        prop::collection::vec((pop, prop::option::weighted(0.3, write)), 12..=20),
    )
        .prop_map(|(first, loads, pops)| {
            let mut v: Vec<Instruction> = first.into_iter().collect();
            v.extend(loads);
            for (pop, write) in pops {
                v.push(pop);
                v.extend(write);
            }
            v
        })
}

fn ins(mnemonic: Mnemonic, operand: Option<Operand>) -> Instruction {
    Instruction {
        mnemonic,
        operand,
        constant: 0,
    }
}

/// A PLC section of [`stack_block`]s on consecutive lines from a random start.
fn stack_program() -> impl Strategy<Value = Program> {
    (150usize..600, prop::collection::vec(stack_block(), 1..=4)).prop_map(|(first, blocks)| {
        let mut p = Program::default();
        let lines = blocks.into_iter().flatten();
        for (slot, i) in p.lines[first..].iter_mut().zip(lines) {
            *slot = Some(i);
        }
        p
    })
}

/// Compares the two VMs' state and outputs after a scan.
fn same(
    scan: usize,
    vm: &PlcVm,
    out: &ScanOutputs,
    oracle: &ReferenceVm,
    expected: &ScanOutputs,
) -> Result<(), TestCaseError> {
    prop_assert_eq!(out, expected, "scan {}: outputs", scan);
    for n in 0..Q_COUNT as u8 {
        prop_assert_eq!(vm.q(n), oracle.q(n), "scan {}: Q{:02}", scan, n);
    }
    for n in 0..B_COUNT as u8 {
        prop_assert_eq!(vm.b(n), oracle.b(n), "scan {}: B{:02}", scan, n);
    }
    for n in 0..OUTPUTS {
        prop_assert_eq!(vm.output(n), oracle.output(n), "scan {}: O{:02}", scan, n);
    }
    prop_assert_eq!(vm.is_first_scan(), oracle.is_first_scan());
    Ok(())
}

/// Runs `program` on both VMs from RUN at `t0` and compares after every scan. The VM
/// under test compiles at RUN (`start_program`) or at its first scan (`start`).
fn run_both(
    program: &Program,
    t0: u32,
    scans: &[Scan],
    compile_at_start: bool,
) -> Result<(), TestCaseError> {
    let mut vm = PlcVm::new();
    let mut oracle = ReferenceVm::new();
    let start = |vm: &mut PlcVm, oracle: &mut ReferenceVm, t: u32| {
        if compile_at_start {
            vm.start_program(program, Millis(t));
        } else {
            vm.start(Millis(t));
        }
        oracle.start(Millis(t));
    };
    start(&mut vm, &mut oracle, t0);
    let mut t = t0;
    let mut out = ScanOutputs::default();
    let mut expected = ScanOutputs::default();
    for (k, s) in scans.iter().enumerate() {
        t = t.wrapping_add(s.dt_ms);
        if s.restart {
            start(&mut vm, &mut oracle, t);
        }
        vm.scan(program, &s.inputs, Millis(t), &mut out);
        oracle.scan(program, &s.inputs, Millis(t), &mut expected);
        same(k, &vm, &out, &oracle, &expected)?;
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(600))]

    /// Verified programs over both sections, as the editor and the assembler make them.
    #[test]
    fn verified_programs_match_the_interpreter(
        program in shared_protocol::program::testing::program(700),
        t0 in any::<u32>(),
        scans in scans(10),
        compile_at_start in any::<bool>(),
    ) {
        prop_assert!(verify(&program).is_ok());
        run_both(&program, t0, &scans, compile_at_start)?;
    }

    /// Verified PLC sections, sparse or as one block of consecutive lines.
    #[test]
    fn verified_plc_sections_match_the_interpreter(
        program in program_from(150, instruction(Section::Plc).boxed(), 850),
        t0 in any::<u32>(),
        scans in scans(10),
        compile_at_start in any::<bool>(),
    ) {
        prop_assert!(verify(&program).is_ok());
        run_both(&program, t0, &scans, compile_at_start)?;
    }

    /// Verified bit logic, counters and timers in dense blocks: deep stacks, fused
    /// `LD`/`AND` pairs, one- and two-input counters, edges over many scans.
    #[test]
    fn verified_logic_and_timers_match_the_interpreter(
        program in program_from(150, logic_instruction(), 120),
        t0 in any::<u32>(),
        scans in scans(25),
        compile_at_start in any::<bool>(),
    ) {
        prop_assert!(verify(&program).is_ok());
        run_both(&program, t0, &scans, compile_at_start)?;
    }

    /// Deep stacks: bits dropped at the 17th push and popped again, counters with many
    /// bits loaded.
    #[test]
    fn deep_stacks_match_the_interpreter(
        program in stack_program(),
        t0 in any::<u32>(),
        scans in scans(8),
    ) {
        prop_assert!(verify(&program).is_ok());
        run_both(&program, t0, &scans, true)?;
    }

    /// Anything the `Program` type can hold, mostly rejected by the verifier: the
    /// compiled form drops exactly what the interpreter ignored.
    #[test]
    fn unverified_programs_match_the_interpreter(
        program in program_from(0, any_instruction(), 300),
        t0 in any::<u32>(),
        scans in scans(6),
    ) {
        run_both(&program, t0, &scans, false)?;
    }
}
