//! Exceptions without a job on the real images: the NMI and every
//! exception without a handler of its own turn the outputs off before anything else, on
//! both images, and then reset (no spinning in cortex-m-rt's default `loop {}` until the
//! watchdog); a fault while the defmt logger is taken still reaches the reset.

use g431_emu::cpu::{CpuEvent, CpuState, RegisterARM};
use g431_emu::mcu::Mcu;
use g431_emu::periph::gpio::Drive;
use g431_emu::periph::rcc::ResetKind;
use g431_emu::scs::exc;
use g431_emu::time::cycles_to_ns;
use hil_sim::emu::boards::plc_pins;

use crate::common::{emu, ns, outputs_enabled, MOTOR_PLC, START_50HZ};

/// The drive's six gate pins (firmware-drive `pins.rs`): U, V, W high and low.
const GATES: [(u8, u8); 6] = [(0, 8), (2, 13), (0, 9), (0, 12), (0, 10), (1, 15)];

/// The motor program plus O06 = D08 on the PLC, D08 on from 0.5 s.
fn program() -> String {
    format!("{MOTOR_PLC}\n990 LD  D08\n991 WR  O06\n")
}

fn scenario(expect: &str) -> String {
    format!(
        "[emu]\nexpect = [{expect}]\n{START_50HZ}\n[[event]]\nat_s = 0.5\nset = {{ D08 = 1 }}\n"
    )
}

/// The first software reset of `mcu` after `after` (cycles).
fn software_reset_after(mcu: &Mcu, after: u64) -> Option<u64> {
    mcu.events().iter().find_map(|e| match e {
        CpuEvent::Reset {
            at,
            why: ResetKind::Software,
        } if *at > after => Some(*at),
        _ => None,
    })
}

/// Exception `n` pended on `mcu` now (NMIPENDSET / PENDSVSET, as a debugger could).
fn pend(mcu: &mut Mcu, n: u16) -> u64 {
    let at = mcu.now();
    mcu.soc_mut().pend_exception(n);
    at
}

/// Without a debugger: the outputs off, then a software reset within 1 ms of the
/// exception (not the watchdog ~100 ms later, not a hang).
fn assert_resets_soon(mcu: &Mcu, pended: u64, what: &str) {
    let reset = software_reset_after(mcu, pended);
    let resets: Vec<_> = mcu
        .events()
        .iter()
        .filter(|e| matches!(e, CpuEvent::Reset { .. }))
        .collect();
    let reset = reset.unwrap_or_else(|| {
        panic!(
            "{}: {what} at {} ns: no software reset; core {:?} at {}, resets {resets:?}",
            mcu.name,
            cycles_to_ns(pended),
            mcu.state(),
            mcu.where_()
        )
    });
    assert!(
        cycles_to_ns(reset - pended) < 1_000_000,
        "{}: {what}: software reset {} ns after it",
        mcu.name,
        cycles_to_ns(reset - pended)
    );
}

/// Under a debugger: the handler stops on its `bkpt` with the outputs already off and
/// its log line written after the exception.
fn assert_stopped_with(mcu: &Mcu, pended: u64, line: &str) {
    assert_eq!(
        mcu.state(),
        CpuState::Halted,
        "{}: {}",
        mcu.name,
        mcu.where_()
    );
    let logged = mcu
        .log()
        .iter()
        .find(|l| l.at >= pended && l.message.contains(line));
    assert!(
        logged.is_some(),
        "{}: no {line:?} after the exception: {:?}",
        mcu.name,
        mcu.log()
            .iter()
            .rev()
            .take(5)
            .map(|l| l.message.clone())
            .collect::<Vec<_>>()
    );
}

/// N10, drive: an NMI with no flash-ECC or parity flag behind it (nothing on this image
/// raises one) turns the gates off and resets at once.
#[test]
fn an_unexplained_nmi_turns_the_drive_outputs_off_and_resets() {
    let mut sim = emu(&program(), &scenario("\"software_reset\""));
    sim.run_until(ns(1.5), |_| {});
    assert!(outputs_enabled(&sim), "running before the NMI");
    let at = pend(sim.drive_mut(), exc::NMI);
    sim.run_until(ns(1.502), |_| {});
    assert_resets_soon(sim.drive(), at, "NMI");
    assert!(!outputs_enabled(&sim));
}

/// N10, drive: an exception without a handler (PendSV: nothing on the image uses it) under
/// a debugger: the six gates forced low, the log line, the `bkpt`.
#[test]
fn an_unused_exception_turns_the_drive_outputs_off_then_logs_and_stops() {
    let mut sim = emu(&program(), &scenario(""));
    sim.run_until(ns(1.5), |_| {});
    assert!(outputs_enabled(&sim));
    sim.drive_mut().cpu_mut().set_debugger(true);
    let at = pend(sim.drive_mut(), exc::PENDSV);
    sim.run_until(ns(1.502), |_| {});
    assert_stopped_with(sim.drive(), at, "unexpected exception");
    let soc = sim.drive().soc();
    let gates: Vec<Drive> = GATES.iter().map(|&(p, n)| soc.pin_drive(p, n)).collect();
    assert!(
        gates.iter().all(|d| *d == Drive::Low),
        "gate pins {gates:?}"
    );
    assert!(!outputs_enabled(&sim));
}

/// The PLC's O06 (PB9) pin.
fn o06(mcu: &Mcu) -> Drive {
    let (p, n) = plc_pins::OUTPUTS[6];
    mcu.soc().pin_drive(p, n)
}

/// N10, PLC: a flash double-ECC error (the NMI) under a debugger: O06, on before, forced
/// low, the log line, the `bkpt`.
#[test]
fn an_nmi_turns_the_plc_outputs_off_then_logs_and_stops() {
    let mut sim = emu(&program(), &scenario(""));
    sim.run_until(ns(1.0), |_| {});
    assert_eq!(o06(sim.plc()), Drive::High, "O06 follows D08");
    sim.plc_mut().cpu_mut().set_debugger(true);
    let at = sim.plc().now();
    hil_sim::emu::silicon::apply(
        sim.plc_mut(),
        hil_sim::scenario::silicon::SiliconEvent::FlashEccError,
    );
    sim.run_until(ns(1.002), |_| {});
    assert_stopped_with(sim.plc(), at, "NMI");
    assert_eq!(o06(sim.plc()), Drive::Low);
}

/// N10, PLC: an exception without a handler (PendSV) resets at once.
#[test]
fn an_unused_exception_on_the_plc_resets_at_once() {
    let mut sim = emu(&program(), &scenario("\"software_reset\""));
    sim.run_until(ns(1.0), |_| {});
    assert_eq!(o06(sim.plc()), Drive::High);
    let at = pend(sim.plc_mut(), exc::PENDSV);
    sim.run_until(ns(1.002), |_| {});
    assert_resets_soon(sim.plc(), at, "PendSV");
}

/// N11: a fault while the defmt logger is taken (the drive enters `_defmt_acquire` and
/// faults on its return, a jump into unmapped memory): the HardFault handler's own log
/// line finds the logger taken and panics ("defmt logger taken reentrantly"); that nested
/// panic must still reach the reset, not recurse until the core locks up.
#[test]
fn a_fault_inside_a_defmt_frame_still_resets() {
    let mut sim = emu(&program(), &scenario("\"hard_fault\", \"software_reset\""));
    sim.run_until(ns(1.5), |_| {});
    assert!(outputs_enabled(&sim));
    let acquire = sim
        .drive()
        .image()
        .functions
        .iter()
        .find(|(_, _, name)| name == "_defmt_acquire")
        .map(|(a, _, _)| *a)
        .expect("the image has _defmt_acquire");
    let at = sim.drive().now();
    let cpu = sim.drive_mut().cpu_mut();
    cpu.halt();
    cpu.write_reg(RegisterARM::LR, 0x1000_0001);
    cpu.write_reg(RegisterARM::PC, acquire);
    cpu.resume();
    sim.run_until(ns(1.502), |_| {});
    let events = sim.drive().events();
    assert!(
        events
            .iter()
            .any(|e| matches!(e, CpuEvent::HardFault { at: t, .. } if *t > at)),
        "the return from _defmt_acquire faults: {events:?}"
    );
    assert!(
        !events.iter().any(|e| matches!(e, CpuEvent::Lockup { .. })),
        "locked up instead of resetting: {events:?}"
    );
    assert_resets_soon(sim.drive(), at, "a fault inside a defmt frame");
}
