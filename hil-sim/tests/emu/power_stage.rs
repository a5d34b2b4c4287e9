//! The drive's power stage under the real image: what TIM1's
//! outputs do when the core halts, locks up or faults, and when the switching frequency
//! changes in RUN.

use g431_emu::cpu::CpuEvent;
use g431_emu::cpu::RegisterARM;
use g431_emu::periph::rcc::ResetKind;
use g431_emu::time::cycles_to_ns;

use crate::common::{emu, ns, outputs_enabled, MOTOR_PLC, START_50HZ};

/// Largest phase current of the rig now.
fn i_max(sim: &hil_sim::emu::sim::EmuSim) -> f64 {
    let o = sim.rig().plant.outputs();
    o.i_abc_a.iter().fold(0.0f64, |m, i| m.max(i.abs()))
}

#[test]
fn a_halted_drive_core_stops_tim1_with_its_outputs_disabled() {
    let mut sim = emu(MOTOR_PLC, START_50HZ);
    sim.run_until(ns(1.5), |_| {});
    assert!(outputs_enabled(&sim), "the motor runs before the halt");
    assert!(i_max(&sim) > 0.3);
    // A debugger halts the core (a breakpoint, probe-rs "halt").
    sim.drive_mut().cpu_mut().set_debugger(true);
    sim.drive_mut().cpu_mut().halt();
    sim.run_until(ns(1.5) + ns(0.0001), |_| {});
    let g = sim.drive().soc().tim1().expect("TIM1").gate();
    assert!(g.frozen && !g.outputs_enabled, "{g:?}");
    // Nothing drives the windings while the core stays halted: the current dies out
    // through the diodes instead of building up from a frozen voltage vector.
    sim.run_until(ns(1.55), |_| {});
    assert!(i_max(&sim) < 0.05, "{} A while halted", i_max(&sim));
}

#[test]
fn a_stack_overflow_lockup_opens_the_switches_in_hardware() {
    let mut sim = emu(
        MOTOR_PLC,
        &format!("[emu]\nexpect = [\"hard_fault\", \"lockup\", \"watchdog_reset\"]\n{START_50HZ}"),
    );
    sim.run_until(ns(1.5), |_| {});
    assert!(outputs_enabled(&sim));
    // The stack has run past the bottom of RAM (flip-link's layout): the next access
    // through SP faults, and stacking the HardFault frame faults again: lockup, no
    // handler runs. SP is put below RAM rather than at its bottom edge (0x2000_0000):
    // from the edge, a pop or an epilogue that the halted code happens to run next
    // would read valid RAM, return into garbage and fault with a usable stack, so
    // whether the test saw a lockup depended on the instruction it halted at.
    let cpu = sim.drive_mut().cpu_mut();
    cpu.halt();
    cpu.write_reg(RegisterARM::SP, 0x1FFF_FFF0);
    cpu.resume();
    // Watch every 10 us: the first look after the lockup already finds the switches open.
    let mut t = ns(1.5);
    let lockup = loop {
        t += 10_000;
        assert!(t < ns(1.51), "no lockup: {:?}", sim.drive().events());
        sim.run_until(t, |_| {});
        let locked = sim
            .drive()
            .events()
            .iter()
            .any(|e| matches!(e, CpuEvent::Lockup { .. }));
        if locked {
            break t;
        }
    };
    // SYSCFG_CFGR2.CLL routes LOCKUP to TIM1's system break: MOE is cleared at once.
    let g = sim.drive().soc().tim1().expect("TIM1").gate();
    assert!(!g.moe && !g.outputs_enabled, "at {lockup} ns: {g:?}");
    // Later the watchdog restarts the drive, which reports WDG.
    sim.run_until(ns(2.5), |_| {});
    assert!(sim.drive().events().iter().any(|e| matches!(
        e,
        CpuEvent::Reset {
            why: ResetKind::Watchdog,
            ..
        }
    )));
    assert!(
        sim.faults().iter().any(|f| f.code == 7),
        "{:?}",
        sim.faults()
    );
}

#[test]
fn a_hard_fault_turns_the_outputs_off_and_resets_at_once() {
    let mut sim = emu(
        MOTOR_PLC,
        &format!("[emu]\nexpect = [\"hard_fault\", \"software_reset\"]\n{START_50HZ}"),
    );
    sim.run_until(ns(1.5), |_| {});
    assert!(outputs_enabled(&sim));
    // A jump into unmapped memory: a bus fault, escalated to HardFault.
    let cpu = sim.drive_mut().cpu_mut();
    cpu.halt();
    cpu.write_reg(RegisterARM::PC, 0x1000_0000);
    cpu.resume();
    sim.run_until(ns(1.5) + ns(0.002), |_| {});
    let events = sim.drive().events();
    let fault_at = events
        .iter()
        .find_map(|e| match e {
            CpuEvent::HardFault { at, .. } => Some(*at),
            _ => None,
        })
        .expect("HardFault taken");
    // No debugger: the handler resets the MCU (a software reset), it does not wait for
    // the watchdog.
    let reset_at = events
        .iter()
        .find_map(|e| match e {
            CpuEvent::Reset {
                at,
                why: ResetKind::Software,
            } => Some(*at),
            _ => None,
        })
        .expect("software reset after the HardFault");
    assert!(
        cycles_to_ns(reset_at - fault_at) < 1_000_000,
        "reset {} ns after the fault",
        cycles_to_ns(reset_at - fault_at)
    );
    // The image starts again and says why.
    assert!(sim
        .drive()
        .log()
        .iter()
        .any(|l| l.at > reset_at && l.message.contains("reset cause Other")));
}

#[test]
fn under_a_debugger_a_hard_fault_turns_the_outputs_off_then_logs_and_stops() {
    let mut sim = emu(
        MOTOR_PLC,
        &format!("[emu]\nexpect = [\"hard_fault\"]\n{START_50HZ}"),
    );
    sim.run_until(ns(1.5), |_| {});
    assert!(outputs_enabled(&sim));
    let log_before = sim.drive().log().len();
    let cpu = sim.drive_mut().cpu_mut();
    cpu.set_debugger(true);
    cpu.halt();
    cpu.write_reg(RegisterARM::PC, 0x1000_0000);
    cpu.resume();
    sim.run_until(ns(1.5) + ns(0.002), |_| {});
    let fault_at = sim
        .drive()
        .events()
        .iter()
        .find_map(|e| match e {
            CpuEvent::HardFault { at, .. } => Some(*at),
            _ => None,
        })
        .expect("HardFault taken");
    // The handler's log line comes after the fault, with the switches already open; the
    // core then waits on its BKPT for the debugger, TIM1 frozen with its outputs disabled.
    let line = sim.drive().log()[log_before..]
        .iter()
        .find(|l| l.message.contains("HardFault"))
        .expect("HardFault logged");
    assert!(line.at > fault_at);
    let g = sim.drive().soc().tim1().expect("TIM1").gate();
    assert!(!g.moe && !g.outputs_enabled && g.frozen, "{g:?}");
    assert_eq!(sim.drive().state(), g431_emu::cpu::CpuState::Halted);
    assert!(!sim.drive().events().iter().any(|e| matches!(
        e,
        CpuEvent::Reset {
            why: ResetKind::Software,
            ..
        }
    )));
}

#[test]
fn a_switching_frequency_change_in_run_pauses_the_outputs_for_one_period() {
    let scen = format!("{START_50HZ}\n[[event]]\nat_s = 1.5\nset = {{ A00 = 500 }}\n");
    let mut sim = emu(MOTOR_PLC, &scen);
    sim.run_until(ns(1.45), |_| {});
    let arr_before = sim.drive().soc().tim1().expect("TIM1").gate().arr;
    // Watch the timer every 10 us across the change.
    let mut off_ns = Vec::new();
    let mut t = ns(1.45);
    while t < ns(1.7) {
        t += 10_000;
        sim.run_until(t, |_| {});
        let g = sim.drive().soc().tim1().expect("TIM1").gate();
        // The dead time never drops below the power stage's minimum (500 ns = 85 counts).
        assert!(g.dead_time_rising >= 85, "{g:?}");
        for ch in &g.channels[..3] {
            assert!(ch.oc.ccr <= g.arr + 1, "compare above ARR + 1: {g:?}");
        }
        if !g.outputs_enabled {
            off_ns.push(t);
        }
    }
    let g = sim.drive().soc().tim1().expect("TIM1").gate();
    // 5 kHz now (PWF = A00 x 10 Hz): twice the ARR of 9.8 kHz, within rounding.
    assert!(
        (f64::from(g.arr) / f64::from(arr_before) - 1.96).abs() < 0.01,
        "ARR {} -> {}",
        arr_before,
        g.arr
    );
    // Off for one period (at most 200 us at 5 kHz) around the change, then on again.
    assert!(!off_ns.is_empty(), "the outputs never paused");
    let span = off_ns.last().copied().unwrap_or(0) - off_ns.first().copied().unwrap_or(0);
    assert!(span <= 250_000, "outputs off for {span} ns: {off_ns:?}");
    assert!(g.outputs_enabled);
    assert!(sim.faults().is_empty(), "{:?}", sim.faults());
}

/// The real image: once the drive runs, TIM1_BDTR is never read, so never
/// read-modify-written. A read-modify-write that straddles a break pulse writes back the
/// MOE = 1 it read after the break cleared it (the g431-emu TIM1 test
/// `bdtr_read_modify_write_across_a_break_pulse_re_sets_moe`); the image writes the
/// register whole from the configuration it recorded at start-up. The breaks stay armed
/// through the run (BKE, BK2E), so the whole writes carry the configuration.
#[test]
fn while_the_motor_runs_tim1_bdtr_is_written_whole_never_read() {
    let mut sim = emu(MOTOR_PLC, START_50HZ);
    sim.run_until(ns(1.0), |_| {});
    let reads_before = sim.drive().soc().tim1().expect("TIM1").bdtr_reads();
    let entries_before = sim.drive().cpu().irq_entries("TIM1_UP_TIM16");
    sim.run_until(ns(1.5), |_| {});
    assert!(outputs_enabled(&sim), "the motor runs");
    let t = sim.drive().soc().tim1().expect("TIM1");
    let reads = t.bdtr_reads() - reads_before;
    let periods = sim.drive().cpu().irq_entries("TIM1_UP_TIM16") - entries_before;
    assert!(periods > 1_000, "{periods} PWM periods");
    assert_eq!(
        reads, 0,
        "BDTR read {reads} times in {periods} PWM periods of running: read-modify-written"
    );
    // RM0440 TIMx_BDTR: BKE bit 12, BK2E bit 24, MOE bit 15.
    let bdtr = t.bdtr();
    assert_eq!(
        bdtr & (1 << 12 | 1 << 24 | 1 << 15),
        1 << 12 | 1 << 24 | 1 << 15,
        "BDTR {bdtr:#010x}: both breaks armed, MOE on"
    );
}
