//! The safety monitor inside the drive core (safety.md 3, 6, 7): where it sits in the
//! tick, what the outputs do, the ACK rules of codes 9-16, `STO_IN`, the status fields,
//! and a property test over random requests, inputs and commands.

use firmware_drive::{
    AdcSample, DriveCommand, DriveConfig, DriveCore, DriveEvent, DriveRefusal, DriveState,
    FaultCode, ResetCause,
};
use proptest::prelude::*;
use shared_protocol::program::{assemble, safety_settings};
use shared_protocol::safety::SafetyFunction as F;

/// A 3-phase sine on Q01 (f = A = Q01), fmn 1.0 Hz, plus the lab's settings.
const LAB: &str = "
000 LD  Q01
001 LD  Q01
002 LD  K00 0000
003 SN1
004 LD  K01 1200
005 SN2
006 LD  K02 2400
007 SN3
008 fmn K03 0010
030 fss K04 0040
031 pss K05 0200
032 trd K06 0050
033 tel K07 0050
034 ts1 K08 0100
035 ts2 K09 0100
036 fl1 K10 0160
037 fl2 K11 0100
038 tl1 K12 0100
039 tl2 K13 0100
040 pli K14 0100
041 tli K15 0100
042 tdi K16 0000
043 aap K17 2000
044 adp K18 2000
045 aan K19 2000
046 adn K20 2000
047 tla K21 0000
";

fn ok() -> AdcSample {
    AdcSample {
        u_dc: 2730,
        ..AdcSample::default()
    }
}

fn tick(core: &mut DriveCore) -> Vec<DriveEvent> {
    let mut v = Vec::new();
    core.tick_1ms(&mut |e| v.push(e));
    v
}

fn core_with(text: &str, f: i16) -> DriveCore {
    let mut core = DriveCore::new(DriveConfig::default(), ResetCause::PowerOn);
    let _ = core.pwm_period(&ok());
    tick(&mut core);
    core.load_program(&assemble(text).unwrap().drive_section())
        .unwrap();
    core.command(DriveCommand::SetQ { addr: 1, value: f })
        .unwrap();
    core.command(DriveCommand::Run).unwrap();
    tick(&mut core);
    core
}

fn request(core: &mut DriveCore, mask: u16) {
    core.command(DriveCommand::SafetyRequest { requested: mask })
        .unwrap();
}

#[test]
fn sto_opens_the_outputs_in_the_tick_of_the_request_and_needs_its_release_to_ack() {
    let mut core = core_with(LAB, 100);
    assert!(core.pwm_period(&ok()).enable);
    request(&mut core, F::Sto.mask());
    let ev = tick(&mut core);
    assert!(ev.contains(&DriveEvent::Fault(FaultCode::Sto)));
    assert!(!core.pwm_period(&ok()).enable);
    let s = core.status();
    assert_eq!(
        (s.state, s.fault),
        (DriveState::Fault, Some(FaultCode::Sto))
    );
    assert_eq!(s.sf_status, F::Sto.mask(), "FAULT: STO status = requested");
    // Cause present: refused even with the command below fmn.
    core.command(DriveCommand::SetQ { addr: 1, value: 0 })
        .unwrap();
    tick(&mut core);
    assert_eq!(
        core.command(DriveCommand::Ack),
        Err(DriveRefusal::CauseActive(FaultCode::Sto))
    );
    request(&mut core, 0);
    core.command(DriveCommand::Ack).unwrap();
    assert_eq!(core.state(), DriveState::Idle);
    // No automatic restart: the outputs stay off until a new RUN.
    core.command(DriveCommand::SetQ {
        addr: 1,
        value: 100,
    })
    .unwrap();
    for _ in 0..10 {
        tick(&mut core);
        assert!(!core.pwm_period(&ok()).enable);
    }
    core.command(DriveCommand::Run).unwrap();
    tick(&mut core);
    assert!(core.pwm_period(&ok()).enable);
}

#[test]
fn sto_in_refuses_run_latches_code_9_in_run_and_blocks_its_ack() {
    let mut core = core_with(LAB, 100);
    core.command(DriveCommand::Stop).unwrap();
    core.set_sto_input(true);
    assert_eq!(core.command(DriveCommand::Run), Err(DriveRefusal::StoInput));
    let s = core.status();
    assert!(s.sto_in_low);
    assert_eq!(s.sf_requested, 1);
    assert_eq!(s.sf_status, 1, "IDLE: status = requested");
    core.set_sto_input(false);
    core.command(DriveCommand::Run).unwrap();
    tick(&mut core);
    assert!(core.pwm_period(&ok()).enable);
    core.set_sto_input(true);
    tick(&mut core);
    assert_eq!(core.fault(), Some(FaultCode::Sto));
    assert!(!core.pwm_period(&ok()).enable);
    core.command(DriveCommand::SetQ { addr: 1, value: 0 })
        .unwrap();
    tick(&mut core);
    assert_eq!(
        core.command(DriveCommand::Ack),
        Err(DriveRefusal::CauseActive(FaultCode::Sto))
    );
    core.set_sto_input(false);
    core.command(DriveCommand::Ack).unwrap();
}

/// The `STO_IN` break seen by the break interrupt, with the input high again
/// by the next tick (a pulse shorter than the 1 ms read): code 9 at once, no PWM period
/// enables the outputs, ACK and a new RUN bring them back.
#[test]
fn an_sto_break_shorter_than_a_tick_latches_code_9_until_ack_and_run() {
    let mut core = core_with(LAB, 100);
    tick(&mut core);
    assert!(core.pwm_period(&ok()).enable);
    core.sto_break();
    assert_eq!(core.fault(), Some(FaultCode::Sto));
    assert!(!core.pwm_period(&ok()).enable, "no period after the break");
    assert_eq!(core.command(DriveCommand::Run), Err(DriveRefusal::Faulted));
    core.set_sto_input(false);
    for _ in 0..10 {
        tick(&mut core);
        assert!(!core.pwm_period(&ok()).enable, "not by itself");
    }
    core.command(DriveCommand::SetQ { addr: 1, value: 0 })
        .unwrap();
    tick(&mut core);
    core.command(DriveCommand::Ack).unwrap();
    core.command(DriveCommand::SetQ {
        addr: 1,
        value: 100,
    })
    .unwrap();
    core.command(DriveCommand::Run).unwrap();
    tick(&mut core);
    assert!(core.pwm_period(&ok()).enable, "after ACK and a new RUN");
}

/// In IDLE an `STO_IN` break latches nothing (code 9 is a RUN fault, safety.md 6) but
/// refuses RUN until the board reads the input high again.
#[test]
fn an_sto_break_in_idle_refuses_run_until_the_input_reads_high() {
    let mut core = core_with(LAB, 100);
    core.command(DriveCommand::Stop).unwrap();
    core.sto_break();
    assert_eq!(core.fault(), None);
    assert_eq!(core.command(DriveCommand::Run), Err(DriveRefusal::StoInput));
    core.set_sto_input(false);
    core.command(DriveCommand::Run).unwrap();
}

/// A system break latches `BOOT`, whose ACK is refused (a power cycle).
#[test]
fn a_system_break_latches_boot_for_good() {
    let mut core = core_with(LAB, 100);
    tick(&mut core);
    core.system_break();
    assert_eq!(core.fault(), Some(FaultCode::Boot));
    assert!(!core.pwm_period(&ok()).enable);
    assert_eq!(
        core.command(DriveCommand::Ack),
        Err(DriveRefusal::CauseActive(FaultCode::Boot))
    );
}

#[test]
fn the_lab_ss1_ends_15000_ticks_after_the_request_with_code_10() {
    let mut core = core_with(LAB, 100);
    for _ in 0..50 {
        tick(&mut core);
    }
    request(&mut core, F::Ss1.mask());
    for k in 0..15_000 {
        let ev = tick(&mut core);
        assert!(ev.iter().all(|e| !matches!(e, DriveEvent::Fault(_))), "{k}");
        assert!(core.status().sf_sdc);
        assert!(core.pwm_period(&ok()).enable);
    }
    tick(&mut core);
    let s = core.status();
    assert_eq!(s.fault, Some(FaultCode::Ss1));
    assert_eq!(s.sf_elapsed_ds, 150);
    // `SFP`: 10.0 Hz for 15.001 s since the request: 150 turns.
    assert_eq!(s.sf_turns, 150);
    assert!(!s.sf_sdc);
    assert_eq!(s.sf_status, F::Ss1.mask());
    assert!(!core.pwm_period(&ok()).enable);
    // Code 10: ACK needs the SS1 request released (and f below fmn). In FAULT the
    // stopwatch and `SFP` hold while SS1 is requested.
    core.command(DriveCommand::SetQ { addr: 1, value: 0 })
        .unwrap();
    tick(&mut core);
    assert_eq!(
        (core.status().sf_elapsed_ds, core.status().sf_turns),
        (150, 150)
    );
    assert_eq!(
        core.command(DriveCommand::Ack),
        Err(DriveRefusal::CauseActive(FaultCode::Ss1))
    );
    request(&mut core, 0);
    core.command(DriveCommand::Ack).unwrap();
    // Deselected: both read 0 from the next tick (001 4.2.4, A.3-A.8).
    tick(&mut core);
    assert_eq!(
        (core.status().sf_elapsed_ds, core.status().sf_turns),
        (0, 0)
    );
}

#[test]
fn asr_lowers_the_applied_frequency_and_the_amplitude_with_it() {
    let text = LAB.to_string() + "048 asr K22 0050\n";
    let mut core = core_with(&text, 100);
    tick(&mut core);
    let m0 = core.status().modulation_permille;
    request(&mut core, F::Ss2.mask());
    for _ in 0..1200 {
        tick(&mut core);
    }
    // cap = 100 - ⌊50·1200/1000⌋ = 40 after 1200 ticks (the request tick is n = 0).
    let s = core.status();
    assert_eq!(s.f_applied.0, 41);
    assert_eq!(s.f_command.0, 100, "the section's f is unchanged");
    assert!(s.modulation_permille * 100 / m0 <= 42, "V/f kept");
    for _ in 0..2000 {
        tick(&mut core);
    }
    // Below fmn: the outputs are off, no trip (SS2 reaches standstill later).
    assert!(!core.pwm_period(&ok()).enable);
    assert_eq!(core.fault(), None);
    // A release drops the cap at once.
    request(&mut core, 0);
    tick(&mut core);
    assert_eq!(core.status().f_applied.0, 100);
}

#[test]
fn the_status_carries_the_signature_of_the_accepted_section() {
    let core = core_with(LAB, 0);
    let p = assemble(LAB).unwrap();
    assert_eq!(
        core.status().sf_signature,
        safety_settings(p.lines.iter()).signature()
    );
    let other = core_with(&LAB.replace("0040", "0041"), 0);
    assert_ne!(other.status().sf_signature, core.status().sf_signature);
}

#[test]
fn a_download_with_a_setting_twice_is_rejected_with_prog() {
    let mut core = DriveCore::new(DriveConfig::default(), ResetCause::PowerOn);
    let _ = core.pwm_period(&ok());
    tick(&mut core);
    let text = LAB.to_string() + "060 fss K30 0041\n";
    let p = assemble(&text).unwrap().drive_section();
    let e = core.load_program(&p).unwrap_err();
    assert_eq!(e.line, 60);
    assert_eq!(core.fault(), Some(FaultCode::Prog));
}

// ---- property test ----------------------------------------------------------------

#[derive(Debug, Clone)]
enum Op {
    Ticks(u16),
    Request(u16),
    StoIn(bool),
    SetF(i16),
    Run,
    Stop,
    Ack,
    Reverse(bool),
}

fn op() -> impl Strategy<Value = Op> {
    prop_oneof![
        10 => (1u16..300).prop_map(Op::Ticks),
        4 => prop::bits::u16::masked(0x0FFE).prop_map(Op::Request),
        1 => prop::bits::u16::masked(0x0FFF).prop_map(Op::Request),
        1 => any::<bool>().prop_map(Op::StoIn),
        4 => (0i16..300).prop_map(Op::SetF),
        2 => Just(Op::Run),
        1 => Just(Op::Stop),
        2 => Just(Op::Ack),
        1 => any::<bool>().prop_map(Op::Reverse),
    ]
}

/// Small random values for some settings, so that every phase is reached quickly.
fn settings_text() -> impl Strategy<Value = String> {
    prop::collection::vec(0u16..40, 24).prop_map(|v| {
        shared_protocol::safety::SafetySetting::ALL
            .iter()
            .zip(v)
            .enumerate()
            .map(|(n, (s, val))| format!("{:03} {} K00 {:04}\n", 50 + n, s.text(), val))
            .collect()
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(120))]

    /// safety.md 14: the outputs are never enabled while STO is requested (by the PLC or
    /// `STO_IN`) or a code 9-16 is latched, and stay off after one until ACK and a new
    /// RUN; the applied frequency never exceeds the section's.
    #[test]
    fn outputs_never_on_while_sto_is_requested_or_a_safety_code_is_latched(
        settings in settings_text(),
        ops in prop::collection::vec(op(), 1..60),
    ) {
        let text = LAB.lines().take(10).collect::<Vec<_>>().join("\n") + "\n" + &settings;
        let mut core = core_with(&text, 50);
        let mut requested = 0u16;
        let mut sto_in = false;
        // A safety code latched, and no ACK + RUN since.
        let mut off_until_run = false;
        for op in ops {
            match op {
                Op::Ticks(n) => {
                    for _ in 0..n {
                        tick(&mut core);
                        let c = core.pwm_period(&ok());
                        let s = core.status();
                        if matches!(s.fault.map(|f| f.code()), Some(9..=16)) {
                            off_until_run = true;
                        }
                        if requested & 1 != 0 || sto_in || off_until_run {
                            prop_assert!(!c.enable, "{s:?}");
                        }
                        prop_assert!(s.f_applied.0 <= s.f_command.0.max(0));
                        prop_assert_eq!(s.sf_requested, requested | u16::from(sto_in));
                    }
                }
                Op::Request(m) => {
                    requested = m;
                    request(&mut core, m);
                }
                Op::StoIn(low) => {
                    sto_in = low;
                    core.set_sto_input(low);
                }
                Op::SetF(f) => {
                    core.command(DriveCommand::SetQ { addr: 1, value: f }).unwrap();
                }
                Op::Run => {
                    let r = core.command(DriveCommand::Run);
                    if r.is_ok() && core.state() == DriveState::Run {
                        off_until_run = false;
                    }
                    if sto_in && core.state() != DriveState::Run {
                        prop_assert!(r.is_err());
                    }
                }
                Op::Stop => {
                    core.command(DriveCommand::Stop).unwrap();
                }
                Op::Ack => {
                    let before = core.fault();
                    let r = core.command(DriveCommand::Ack);
                    if r.is_ok() && before == Some(FaultCode::Sto) {
                        prop_assert!(requested & 1 == 0 && !sto_in);
                    }
                    if r.is_ok() && before == Some(FaultCode::Ss1) {
                        prop_assert!(requested & 2 == 0);
                    }
                }
                Op::Reverse(r) => {
                    core.command(DriveCommand::Direction { reverse: r }).unwrap();
                }
            }
        }
    }
}
