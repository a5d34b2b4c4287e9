//! Differential: the compiled scan (`plc_vm::PlcVm`, what the PLC runs) against the
//! reference interpreter (`plc_vm::reference::ReferenceVm`, the oracle), the fuzz form of
//! `plc-vm/src/differential.rs`. Input layout (docs/fuzzing.md): a flags byte (bit 0:
//! compile at RUN, else at the first scan), a line count, that many `[line hi, line lo,
//! 4 code bytes]` (line modulo 1000, the 4-byte line encoding; undecodable lines are left
//! empty), then scans until the bytes run out: a time step, inputs and a RUN restart bit.
//! Programs are not required to verify: the compiled form must drop exactly what the
//! interpreter ignores.
//!
//! Asserts: after every scan, equal outputs (output image, LCD fields, Q writes, direction
//! and acknowledge requests, warning), every Q, every B, every output bit and the
//! first-scan flag.
#![no_main]

use libfuzzer_sys::arbitrary::{Result, Unstructured};
use libfuzzer_sys::fuzz_target;
use plc_vm::reference::ReferenceVm;
use plc_vm::{DriveView, PlcVm, ScanInputs, ScanOutputs, B_COUNT, OUTPUTS, Q_COUNT};
use shared_protocol::program::{decode_slot, Program, LINES, LINE_BYTES};
use shared_protocol::units::{CentiAmps, Decihertz, Decivolts, Millis, Volts};

fn program(u: &mut Unstructured<'_>) -> Result<Program> {
    let mut p = Program::default();
    let n: u8 = u.arbitrary()?;
    for _ in 0..n {
        let line = usize::from(u16::from_be_bytes(u.arbitrary()?)) % LINES;
        let code: [u8; LINE_BYTES] = u.arbitrary()?;
        if let Ok(i) = decode_slot(&code) {
            p.lines[line] = i;
        }
    }
    Ok(p)
}

fn inputs(u: &mut Unstructured<'_>) -> Result<ScanInputs> {
    Ok(ScanInputs {
        digital: u.arbitrary()?,
        analog: u.arbitrary()?,
        drive: DriveView {
            com: u.arbitrary()?,
            frq: Decihertz(u.arbitrary()?),
            udc: Decivolts(u.arbitrary()?),
            imx: CentiAmps(u.arbitrary()?),
            flt: u.arbitrary()?,
            dir_reverse: u.arbitrary()?,
            ready: u.arbitrary()?,
            fault_latched: u.arbitrary()?,
            ihw: CentiAmps(u.arbitrary()?),
            uhw: Volts(u.arbitrary()?),
            sf_status: u.arbitrary()?,
            sf_sdc: u.arbitrary()?,
            sf_elapsed_ds: u.arbitrary()?,
            sf_turns: u.arbitrary()?,
        },
    })
}

/// Time to the next scan: small steps mostly, some long pauses and clock wraps.
fn dt_ms(u: &mut Unstructured<'_>) -> Result<u32> {
    let kind: u8 = u.arbitrary()?;
    Ok(match kind % 8 {
        0..=3 => u32::from(u.arbitrary::<u8>()? % 21),
        4 | 5 => u32::from(u.arbitrary::<u16>()? % 2001),
        6 => u32::from(u.arbitrary::<u16>()?) * 4,
        _ => u.arbitrary()?,
    })
}

fn same(k: usize, vm: &PlcVm, out: &ScanOutputs, oracle: &ReferenceVm, expected: &ScanOutputs) {
    assert_eq!(out, expected, "scan {k}: outputs");
    for n in 0..Q_COUNT as u8 {
        assert_eq!(vm.q(n), oracle.q(n), "scan {k}: Q{n:02}");
    }
    for n in 0..B_COUNT as u8 {
        assert_eq!(vm.b(n), oracle.b(n), "scan {k}: B{n:02}");
    }
    for n in 0..OUTPUTS {
        assert_eq!(vm.output(n), oracle.output(n), "scan {k}: O{n:02}");
    }
    assert_eq!(
        vm.is_first_scan(),
        oracle.is_first_scan(),
        "scan {k}: first scan"
    );
}

fn run(data: &[u8]) -> Result<()> {
    let mut u = Unstructured::new(data);
    let flags: u8 = u.arbitrary()?;
    let compile_at_start = flags & 1 == 1;
    let p = program(&mut u)?;
    let mut t: u32 = u.arbitrary()?;
    let mut vm = PlcVm::new();
    let mut oracle = ReferenceVm::new();
    let start = |vm: &mut PlcVm, oracle: &mut ReferenceVm, t: u32| {
        if compile_at_start {
            vm.start_program(&p, Millis(t));
        } else {
            vm.start(Millis(t));
        }
        oracle.start(Millis(t));
    };
    start(&mut vm, &mut oracle, t);
    let mut out = ScanOutputs::default();
    let mut expected = ScanOutputs::default();
    let mut k = 0;
    while !u.is_empty() && k < 64 {
        t = t.wrapping_add(dt_ms(&mut u)?);
        let ins = inputs(&mut u)?;
        if u.ratio(1u8, 32u8)? {
            start(&mut vm, &mut oracle, t);
        }
        vm.scan(&p, &ins, Millis(t), &mut out);
        oracle.scan(&p, &ins, Millis(t), &mut expected);
        same(k, &vm, &out, &oracle, &expected);
        k += 1;
    }
    Ok(())
}

fuzz_target!(|data: &[u8]| {
    let _ = run(data);
});
