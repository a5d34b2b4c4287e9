//! The PLC's program storage on the real image, with the 24C256 model.

use g431_emu::cpu::CpuEvent;

use crate::common::{assert_stack_headroom, emu, ns};

/// A 600-line program (lines 150-749), half a slot.
fn big_program() -> String {
    let mut t = String::new();
    for k in 0..600u32 {
        let line = 150 + k;
        if k % 2 == 0 {
            t.push_str(&format!("{line:03} LD  D{:02}\n", k % 8));
        } else {
            t.push_str(&format!("{line:03} WR  B{:02}\n", k % 100));
        }
    }
    t
}

/// RUN is left to the keys; at 1 s `C` `2` saves the program into slot 2.
const SAVE_TO_2: &str =
    "[[event]]\nat_s = 30.0\nkeys = \"A\"\n\n[[event]]\nat_s = 1.0\nkeys = \"C2\"\n";

#[test]
fn saving_a_600_line_program_survives_and_reloads_after_a_power_cycle() {
    let text = big_program();
    let mut sim = emu(&text, SAVE_TO_2);
    sim.run_until(ns(6.0), |_| {});
    assert!(
        sim.plc()
            .events()
            .iter()
            .all(|e| matches!(e, CpuEvent::Reset { at: 0, .. })),
        "the PLC reset during or after the save: {:?}",
        sim.plc().events()
    );
    let lcd: Vec<String> = (0..4).map(|r| sim.lcd().row(r)).collect();
    let log: Vec<&str> = sim.plc().log().iter().map(|l| l.message.as_str()).collect();
    assert!(
        lcd.iter().any(|r| r.contains("SAVED")),
        "LCD {lcd:#?}\nPLC log {log:#?}"
    );
    let gap_ms = g431_emu::time::cycles_to_ns(sim.plc().soc().iwdg().longest_gap) as f64 * 1e-6;
    eprintln!("longest watchdog feed gap over boot and save: {gap_ms:.1} ms");
    assert!(
        gap_ms < 50.0,
        "watchdog feed gap {gap_ms} ms during the save"
    );

    // Power cycle, then load slot 2 from the keypad.
    sim.power_cycle_plc();
    sim.set_key('D', true);
    sim.run_until(ns(7.5), |_| {});
    sim.set_key('D', false);
    sim.run_until(ns(7.6), |_| {});
    sim.set_key('2', true);
    sim.run_until(ns(7.7), |_| {});
    sim.set_key('2', false);
    sim.run_until(ns(10.0), |_| {});
    let lcd: Vec<String> = (0..4).map(|r| sim.lcd().row(r)).collect();
    assert!(
        lcd.iter().any(|r| r.contains("LOADED SLOT 2")),
        "LCD {lcd:#?}"
    );
}

/// The motor program with 600 more lines (200-799) that only copy D07 into B90-B99.
fn motor_with_600_more_lines() -> String {
    let mut t = crate::common::MOTOR_PLC.to_string();
    for k in 0..600u32 {
        let line = 200 + k;
        if k % 2 == 0 {
            t.push_str(&format!("{line:03} LD  D07\n"));
        } else {
            t.push_str(&format!("{line:03} WR  B{:02}\n", 90 + k % 10));
        }
    }
    t
}

/// RUN from the keys at 2 s (power-up reads the 660-line program synchronously, about
/// 1.3 s), the motor started at 2.5 s, a save into slot 2 at 3 s.
const SAVE_IN_RUN: &str = r#"
[[event]]
at_s = 0.0
set = { A00 = 980, A01 = 500 }

[[event]]
at_s = 2.0
keys = "A"

[[event]]
at_s = 2.5
press = "D00"

[[event]]
at_s = 3.0
keys = "C2"
"#;

#[test]
fn a_large_save_in_run_keeps_the_link_and_the_motor_running() {
    let text = motor_with_600_more_lines();
    // No allowance for the co-simulation's "RX character pushed after IDLE" any more: with
    // the PLC image of size-plc2 the images' blocks no longer end that way in this run (an
    // allowance that matches nothing fails the test).
    let mut sim = emu(&text, SAVE_IN_RUN);
    let mut samples = Vec::new();
    sim.run_until(ns(7.0), |s| samples.push(s.clone()));
    let log: Vec<&str> = sim.plc().log().iter().map(|l| l.message.as_str()).collect();
    let lcd: Vec<String> = (0..4).map(|r| sim.lcd().row(r)).collect();
    assert!(
        sim.plc()
            .events()
            .iter()
            .all(|e| matches!(e, CpuEvent::Reset { at: 0, .. })),
        "the PLC reset: {:?}",
        sim.plc().events()
    );
    // No LINK (or any other) trip: the link kept its frames flowing during the save.
    assert!(sim.faults().is_empty(), "faults {:?}", sim.faults());
    let saved = log
        .iter()
        .position(|l| l.contains("storage: Saved") && l.contains("Ok"))
        .unwrap_or_else(|| panic!("no save in the log {log:#?}\nLCD {lcd:#?}"));
    assert!(
        !log[..saved]
            .iter()
            .any(|l| l.contains("link: down") || l.contains("lost")),
        "{log:#?}"
    );
    // The motor ran through the save and still runs.
    let running: Vec<_> = samples
        .iter()
        .filter(|s| s.t_ns > ns(3.0) && s.t_ns < ns(7.0))
        .collect();
    assert!(!running.is_empty());
    let off: Vec<f64> = running
        .iter()
        .filter(|s| !s.pwm_on)
        .map(|s| s.t_ns as f64 * 1e-9)
        .collect();
    assert!(
        off.is_empty(),
        "PWM off during the save at {:?}.. {:?} ({} samples); f_cmd at 3 s {:?}; log {log:#?}",
        off.first(),
        off.last(),
        off.len(),
        running.first().map(|s| s.f_cmd_hz)
    );
    let gap_ms = g431_emu::time::cycles_to_ns(sim.plc().soc().iwdg().longest_gap) as f64 * 1e-6;
    eprintln!("save in RUN: longest PLC watchdog feed gap {gap_ms:.1} ms; log {log:#?}");
    assert!(gap_ms < 50.0, "watchdog feed gap {gap_ms} ms");
    assert_stack_headroom(&sim);
}
