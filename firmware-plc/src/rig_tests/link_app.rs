//! The two applications (PlcApp, DriveApp) on the co-simulation rig
//! (`shared_protocol::link::pair::Pair`: each served by its pump over the byte-timed line,
//! as the boards join them): RUN handshake/download/start, Q writes reaching the drive core,
//! a cut link tripping LINK and showing on the PLC, no automatic restart after a fault.

use crate::app::{PlcApp, RunState};
use crate::editor::{Key, Screen};
use crate::storage::MemEeprom;
use firmware_drive::app::DriveApp;
use firmware_drive::{AdcSample, DriveConfig, DriveState as CoreState, FaultCode, ResetCause};
use shared_protocol::link::channel::Impairments;
use shared_protocol::link::line::{Line, Pumped};
use shared_protocol::link::pair::Pair;
use shared_protocol::link::pump::MAX_IDLE_US;
use shared_protocol::link::{LinkConfig, PlcLinkState};
use shared_protocol::program::{assemble, Instruction, Mnemonic, Operand};
use shared_protocol::units::Micros;

const PROGRAM: &str = "
000 fmn K00 0010      ; f stays 0: PWM off, nothing else needed from the plant
001 LD  Q00
002 WR  Q01
150 LD  D00
151 LD  A00
152 WR  Q00           ; Q00 = A00 while D00
153 LD  D01
154 ACK
155 LD  A00
156 LCD
";

/// The two applications on the co-simulation rig, with the PLC's 1 ms tasks (scan,
/// storage, tick) and the drive's PWM period every 100 us and 1 ms tick.
struct Rig {
    pair: Pair<Pumped<PlcApp<MemEeprom>>, Pumped<DriveApp>>,
    digital: u16,
    analog: [u16; 4],
    next_ms: u64,
}

impl Rig {
    fn new(program: &str) -> Rig {
        let cfg = LinkConfig::default();
        let mut plc = PlcApp::new(MemEeprom::new(), cfg, 20, 4, Micros(0));
        *plc.program_mut() = assemble(program).unwrap();
        Rig {
            pair: Pair::pumped(
                plc,
                DriveApp::new(DriveConfig::default(), ResetCause::PowerOn, cfg),
                Line::new(cfg.baud, Impairments::default(), 1),
            ),
            digital: 0,
            analog: [0; 4],
            next_ms: 0,
        }
    }

    /// Advance: the line's events as they come, a PWM period every 100 us (the ADC reads
    /// zero current, 30 V), and every 1 ms the PLC's scan, storage step and tick and the
    /// drive's tick; the applications then kick their link tasks.
    fn run_for(&mut self, us: u64) {
        let end = self.pair.now.0 + us;
        let adc = AdcSample {
            u_dc: 2800,
            ..AdcSample::default()
        };
        while self.pair.now.0 < end {
            let next = ((self.pair.now.0 / 100 + 1) * 100)
                .min(self.next_ms * 1000)
                .min(end)
                .max(self.pair.now.0);
            self.pair.run_until(Micros(next), |_| {});
            let now = self.pair.now;
            if now.0.is_multiple_of(100) {
                // No power stage in this rig: only the core's trips matter.
                let _ = self.pair.drive.pwm_period(&adc);
            }
            if now.0 >= self.next_ms * 1000 {
                self.next_ms += 1;
                // No pins in this rig: the outputs are read from the app.
                let plc = &mut self.pair.plc.ep;
                let _ = plc.scan(self.digital, self.analog, now);
                let _ = plc.step_storage(now);
                self.pair.drive.tick_1ms(now);
            }
            self.pair.kick();
        }
    }

    fn cut(&mut self, cut: bool) {
        self.pair.cut(cut);
    }

    fn screen(&self) -> String {
        let mut s = Screen::new(20, 4);
        self.pair.plc.render(self.pair.now, &mut s);
        (0..4).map(|r| s.row(r).to_string() + "\n").collect()
    }
}

fn running_rig() -> Rig {
    let mut r = Rig::new(PROGRAM);
    r.run_for(20_000);
    assert_eq!(r.pair.plc.link().state(), PlcLinkState::Up);
    r.pair.plc.run(None, r.pair.now);
    r.run_for(100_000);
    assert_eq!(r.pair.plc.run_state(), RunState::Running);
    assert_eq!(r.pair.drive.core().state(), CoreState::Run);
    r
}

#[test]
fn run_verifies_downloads_and_starts_both() {
    let mut r = Rig::new(PROGRAM);
    // RUN before the link is up: waits for it, then downloads.
    r.pair.plc.run(None, Micros(0));
    assert_eq!(r.pair.plc.run_state(), RunState::WaitLink);
    r.run_for(5_000);
    assert_eq!(r.pair.plc.run_state(), RunState::Downloading);
    assert_eq!(r.pair.drive.core().state(), CoreState::Idle);
    let mut started = None;
    for _ in 0..200 {
        r.run_for(1_000);
        if r.pair.plc.run_state() == RunState::Running {
            started = Some(r.pair.now);
            break;
        }
    }
    let started = started.expect("RUN completes");
    assert!(
        started.0 < 120_000,
        "download + start took {} us",
        started.0
    );
    r.run_for(5_000);
    assert_eq!(r.pair.drive.core().state(), CoreState::Run);
    assert!(r.pair.drive.status().program_loaded);
    let st = r.pair.plc.status();
    assert_eq!(
        st.drive.map(|d| d.state),
        Some(shared_protocol::link::DriveState::Run)
    );
    assert!(r.screen().contains("RUN"), "{}", r.screen());
}

#[test]
fn an_invalid_program_never_runs() {
    let mut r = Rig::new(PROGRAM);
    // A PLC operand in the drive section (the keypad cannot enter it, a corrupt image could).
    r.pair.plc.program_mut().lines[0] = Some(Instruction {
        mnemonic: Mnemonic::Ld,
        operand: Some(Operand::D(0)),
        constant: 0,
    });
    r.run_for(20_000);
    r.pair.plc.run(None, r.pair.now);
    r.run_for(50_000);
    assert_eq!(r.pair.plc.run_state(), RunState::Stopped);
    assert_eq!(r.pair.drive.core().state(), CoreState::Idle);
    assert!(r.screen().contains("000:"), "{}", r.screen());
}

#[test]
fn q_write_in_a_scan_reaches_the_drive_core_within_2ms() {
    let mut r = running_rig();
    r.analog[0] = 321;
    r.digital = 1;
    // The scan that writes Q00 runs at the next ms boundary.
    let scan_at = r.next_ms * 1000;
    let mut applied = None;
    while r.pair.now.0 < scan_at + 10_000 {
        r.run_for(10);
        if applied.is_none() && r.pair.drive.core().vm().q(0) == 321 {
            applied = Some(r.pair.now.0);
        }
    }
    let latency = applied.expect("applied") - scan_at;
    eprintln!("scan -> drive core Q00: {latency} us");
    assert!(latency <= 2_000, "latency {latency} us");
    assert_eq!(r.pair.plc.q(0), 321);
    // The drive section copies it (drive's own WR) every 1 ms.
    assert_eq!(r.pair.drive.core().vm().q(1), 321);
}

#[test]
fn cut_link_trips_link_on_the_drive_and_shows_on_the_plc_without_restart() {
    let mut r = running_rig();
    let cut = r.pair.now;
    r.cut(true);
    let mut drive_tripped = None;
    let mut plc_saw = None;
    while r.pair.now.0 < cut.0 + 150_000 {
        r.run_for(100);
        if drive_tripped.is_none() && r.pair.drive.core().fault() == Some(FaultCode::Link) {
            drive_tripped = Some(r.pair.now.0 - cut.0);
        }
        if plc_saw.is_none() && r.pair.plc.status().link != PlcLinkState::Up {
            plc_saw = Some(r.pair.now.0 - cut.0);
        }
    }
    let tripped = drive_tripped.expect("drive trips LINK");
    assert!(
        (40_000..=52_000).contains(&tripped),
        "LINK after {tripped} us"
    );
    assert!(plc_saw.expect("PLC shows it") <= 100_000);
    assert_eq!(r.pair.drive.core().state(), CoreState::Fault);
    eprintln!("link cut:\n{}", r.screen());

    // Wires back: the link comes up again, the fault reaches the PLC's log and screen,
    // and the drive stays in FAULT.
    r.cut(false);
    r.run_for(1_000_000);
    assert_eq!(r.pair.plc.link().state(), PlcLinkState::Up);
    assert_eq!(r.pair.drive.core().state(), CoreState::Fault);
    assert_eq!(r.pair.plc.status().newest_fault, Some((5, "link lost")));
    assert_eq!(r.pair.plc.fault_log().first().map(|e| e.code), Some(5));
    eprintln!("after reconnection:\n{}", r.screen());
    assert!(r.screen().to_uppercase().contains("LINK"), "{}", r.screen());

    // ACK (D01 rising): the fault clears to IDLE, not RUN.
    r.digital = 0b10;
    r.run_for(20_000);
    r.digital = 0;
    r.run_for(500_000);
    assert_eq!(r.pair.drive.core().fault(), None);
    assert_eq!(r.pair.drive.core().state(), CoreState::Idle);
    // Only a new RUN starts it again.
    r.pair.plc.key(Key::A, r.pair.now); // running -> STOP
    r.run_for(10_000);
    assert_eq!(r.pair.plc.run_state(), RunState::Stopped);
    r.pair.plc.key(Key::A, r.pair.now); // RUN
    r.run_for(150_000);
    assert_eq!(r.pair.plc.run_state(), RunState::Running);
    assert_eq!(r.pair.drive.core().state(), CoreState::Run);
}

#[test]
fn stop_turns_the_drive_off() {
    let mut r = running_rig();
    r.pair.plc.stop();
    r.run_for(10_000);
    assert_eq!(r.pair.plc.run_state(), RunState::Stopped);
    assert_eq!(r.pair.drive.core().state(), CoreState::Idle);
}

#[test]
fn stop_is_never_dropped_even_with_the_link_queue_full() {
    let mut r = running_rig();
    // Fill the link's command queue.
    let mut queued = 0;
    while r.pair.plc.ack_fault().is_ok() {
        queued += 1;
        assert!(queued < 1000);
    }
    assert!(queued > 0);
    // The link takes STOP at once, ahead of the waiting ACKs: the drive is IDLE long
    // before they have all gone (each is a frame).
    r.pair.plc.stop();
    assert_eq!(r.pair.plc.run_state(), RunState::Stopped);
    r.run_for(5_000);
    assert_eq!(r.pair.drive.core().state(), CoreState::Idle);
    r.run_for(200_000);
    assert_eq!(r.pair.plc.run_state(), RunState::Stopped);
    assert_eq!(r.pair.drive.core().state(), CoreState::Idle);
}

#[test]
fn div0_warning_shows_on_the_run_screen() {
    let mut r = Rig::new(&format!("{PROGRAM}157 LD K00 0005\n158 DIV Q05\n"));
    r.run_for(20_000);
    r.pair.plc.run(None, r.pair.now);
    r.run_for(100_000);
    assert_eq!(r.pair.plc.run_state(), RunState::Running);
    assert_eq!(
        r.pair.plc.status().warning,
        Some(crate::vm::Warning::Div0 { line: 158 })
    );
    let screen = r.screen();
    assert!(
        screen.contains("DIV0") && screen.contains("158"),
        "{screen}"
    );
}

/// `ALM K00 0012` logs application fault 12 (code 112) in the PLC's fault log on each
/// rising edge of its input, and nothing while the input stays on; the entry holds the
/// scan's first two `LCD` fields (A00 and 7 here) and no time of day (clock unset).
#[test]
fn alm_logs_an_application_fault_in_the_fault_log() {
    let mut r = Rig::new(&format!(
        "{PROGRAM}157 LD D02\n158 ALM K00 0012\n159 LD K00 0007\n160 LCD\n"
    ));
    r.analog[0] = 321;
    r.run_for(20_000);
    r.pair.plc.run(None, r.pair.now);
    r.run_for(100_000);
    assert_eq!(r.pair.plc.run_state(), RunState::Running);
    assert!(r.pair.plc.fault_log().is_empty());
    r.digital |= 1 << 2;
    r.run_for(50_000);
    let codes: Vec<u8> = r.pair.plc.fault_log().iter().map(|e| e.code).collect();
    assert_eq!(codes, vec![112]);
    let e = r.pair.plc.fault_log()[0];
    assert_eq!(
        (e.value(0), e.value(1), e.wall()),
        (Some(321), Some(7), None)
    );
    assert_eq!(
        shared_protocol::service::LogText(codes[0]).to_string(),
        "application fault 12"
    );
    r.digital &= !(1 << 2);
    r.run_for(20_000);
    r.digital |= 1 << 2;
    r.run_for(50_000);
    assert_eq!(r.pair.plc.fault_log().len(), 2);
    assert_eq!(
        r.pair.plc.run_state(),
        RunState::Running,
        "the program goes on"
    );
}

#[test]
fn the_slot_last_run_runs_again_at_power_up() {
    let mut r = Rig::new(PROGRAM);
    let program = r.pair.plc.program().clone();
    r.pair.plc.storage().save(2, &program).unwrap();
    r.run_for(20_000);
    r.pair.plc.run(Some(2), r.pair.now);
    r.run_for(100_000);
    assert_eq!(r.pair.plc.run_state(), RunState::Running);

    // Power cycle of both boards with the same EEPROM.
    let image = r.pair.plc.storage().eeprom().image().to_vec();
    let cfg = LinkConfig::default();
    let mut r2 = Rig::new(PROGRAM);
    r2.pair.restart_plc(Pumped::new(
        PlcApp::new(MemEeprom::from_image(&image), cfg, 20, 4, Micros(0)),
        MAX_IDLE_US,
    ));
    assert_eq!(r2.pair.plc.program(), &program);
    assert_eq!(r2.pair.plc.run_state(), RunState::WaitLink);
    r2.run_for(150_000);
    assert_eq!(r2.pair.plc.run_state(), RunState::Running);
    assert_eq!(r2.pair.drive.core().state(), CoreState::Run);

    // STOP is remembered too: the next power-up does not run.
    r2.pair.plc.stop();
    // The boot record is written by the storage queue, a page per millisecond.
    r2.run_for(50_000);
    let image = r2.pair.plc.storage().eeprom().image().to_vec();
    let p3 = PlcApp::new(MemEeprom::from_image(&image), cfg, 20, 4, Micros(0));
    assert_eq!(p3.run_state(), RunState::Stopped);
}

#[test]
fn run_and_q_writes_on_a_noisy_link() {
    let mut r = Rig::new(PROGRAM);
    let imp = Impairments {
        bit_error_rate: 1e-4,
        byte_drop: 1e-4,
        frame_drop: 1e-3,
        ..Default::default()
    };
    r.pair.line.set_impairments(imp);
    r.run_for(50_000);
    r.pair.plc.run(None, r.pair.now);
    r.run_for(300_000);
    assert_eq!(r.pair.plc.run_state(), RunState::Running);
    r.digital = 1;
    // Every scan writes Q00 (D00 stays on): at 115200 the PLC-to-drive direction is
    // saturated, so a lost frame costs a retransmission timeout plus the window.
    for v in (0..1024).step_by(37) {
        r.analog[0] = v;
        r.run_for(100_000);
        assert_eq!(r.pair.drive.core().vm().q(0), v as i16);
    }
    assert_eq!(r.pair.drive.core().state(), CoreState::Run);
    assert!(r.pair.plc.link().stats().frames_bad + r.pair.drive.link().stats().frames_bad > 0);
}

#[test]
fn memory_footprint() {
    use std::mem::size_of;
    let sizes = [
        ("PlcLink", size_of::<shared_protocol::link::PlcLink>()),
        ("DriveLink", size_of::<shared_protocol::link::DriveLink>()),
        (
            "PlcApp<MemEeprom> without the EEPROM model",
            size_of::<PlcApp<MemEeprom>>() - size_of::<MemEeprom>(),
        ),
        ("DriveApp", size_of::<DriveApp>()),
    ];
    for (name, bytes) in sizes {
        eprintln!("{name}: {bytes} bytes");
    }
    // The drive's static RAM budget is 16 KiB, the PLC's 24 KiB (CI checks the images).
    // The PLC application holds the PLC section compiled at RUN (6.8 KiB for
    // 850 lines with their timer start times, 3 KiB more than the interpreter's state;
    // plc-vm/docs/vm.md, "RAM").
    assert!(size_of::<DriveApp>() < 8 * 1024);
    // 17.5 KiB since the safety functions (the status's safety fields, the
    // `S:` items' request times); the image's static RAM is what CI budgets.
    assert!(size_of::<PlcApp<MemEeprom>>() - size_of::<MemEeprom>() < 17 * 1024 + 512);
}

#[test]
fn q_changes_reach_the_drive_core_within_2ms_every_time() {
    let mut r = running_rig();
    r.digital = 1;
    let mut worst = 0;
    for k in 0..150u64 {
        // Let heartbeats and statuses fall at every phase.
        r.run_for(1_000 + (k * 1_370) % 9_000);
        let v = 100 + k as u16;
        r.analog[0] = v;
        let scan_at = r.next_ms * 1000;
        let mut applied = None;
        while r.pair.now.0 < scan_at + 10_000 {
            r.run_for(10);
            if r.pair.drive.core().vm().q(0) == v as i16 {
                applied = Some(r.pair.now.0 - scan_at);
                break;
            }
        }
        worst = worst.max(applied.expect("applied"));
    }
    eprintln!("worst scan -> drive core latency over 150 changes: {worst} us");
    assert!(worst <= 2_000, "{worst} us");
}

#[test]
fn a_fault_is_acknowledged_from_the_panel_then_run_again() {
    let mut r = running_rig();
    r.cut(true);
    r.run_for(100_000);
    r.cut(false);
    r.run_for(300_000);
    assert_eq!(r.pair.drive.core().fault(), Some(FaultCode::Link));
    r.pair.plc.ack_fault().unwrap();
    r.run_for(20_000);
    assert_eq!(r.pair.drive.core().state(), CoreState::Idle);
    // Still no restart by itself.
    r.run_for(500_000);
    assert_eq!(r.pair.drive.core().state(), CoreState::Idle);
    r.pair.plc.run(None, r.pair.now);
    r.run_for(150_000);
    assert_eq!(r.pair.drive.core().state(), CoreState::Run);
}

#[test]
fn keypad_star_9_acknowledges_a_trip_and_a_run_is_still_needed() {
    let mut r = running_rig();
    r.cut(true);
    r.run_for(100_000);
    r.cut(false);
    r.run_for(300_000);
    assert_eq!(r.pair.drive.core().fault(), Some(FaultCode::Link));
    assert!(r.screen().contains("F5 "), "{}", r.screen());
    // STOP the PLC (A), acknowledge on the keypad (* 9): the drive goes to IDLE.
    r.pair.plc.key(Key::A, r.pair.now);
    r.pair.plc.key(Key::Star, r.pair.now);
    r.pair.plc.key(Key::Digit(9), r.pair.now);
    assert!(r.screen().contains("FAULT ACK SENT"), "{}", r.screen());
    r.run_for(20_000);
    assert_eq!(r.pair.drive.core().fault(), None);
    assert_eq!(r.pair.drive.core().state(), CoreState::Idle);
    r.run_for(500_000);
    assert_eq!(
        r.pair.drive.core().state(),
        CoreState::Idle,
        "no restart by itself"
    );
    // RUN (A) starts both again.
    r.pair.plc.key(Key::A, r.pair.now);
    r.run_for(150_000);
    assert_eq!(r.pair.plc.run_state(), RunState::Running);
    assert_eq!(r.pair.drive.core().state(), CoreState::Run);
}

// ---- safety functions (safety.md 5, 6, 8, 10) --------------------------------------

/// A sine on Q01 = A00 (f = A), the lab's SOS settings; D00 is the curtain (1 = clear).
const SAFETY: &str = "
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
149 fmx K06 0500
150 LDC B99
151 LD  A00
152 WR  Q01
153 LD  D00
154 SFR SOS
155 LD  SOS
156 WR  O00
157 LD  D01
158 ACK
";

fn safety_rig() -> Rig {
    let mut r = Rig::new(SAFETY);
    r.digital = 1;
    r.analog[0] = 20;
    r.run_for(20_000);
    r.pair.plc.run(None, r.pair.now);
    r.run_for(100_000);
    assert_eq!(r.pair.plc.run_state(), RunState::Running);
    assert_eq!(r.pair.drive.core().state(), CoreState::Run);
    // Drawn as the board does: the RUN hint's 3 s count from here.
    r.screen();
    r
}

#[test]
fn sfr_reaches_the_drive_and_its_status_comes_back_to_ld() {
    let mut r = safety_rig();
    assert!(r.screen().contains("NOT RATED SIG"), "{}", r.screen());
    let sig = r.pair.drive.status().sf_signature;
    assert!(r.screen().contains(&format!("{sig:04X}")), "{}", r.screen());
    assert_eq!(r.pair.drive.core().safety_requested(), 0);
    assert_eq!(r.pair.drive.status().f_applied.0, 20);
    // The curtain opens (D00 = 0): SOS requested; at 2.0 Hz it is in its safe state.
    r.digital = 0;
    r.run_for(20_000);
    assert_eq!(r.pair.drive.core().safety_requested(), 1 << 3);
    assert_eq!(r.pair.drive.status().sf_status, 1 << 3);
    assert!(r.pair.plc.outputs() & 1 == 1, "LD SOS sees the status");
    assert_eq!(r.pair.drive.core().fault(), None);
    // Released: the mask goes back to 0.
    r.digital = 1;
    r.run_for(20_000);
    assert_eq!(r.pair.drive.core().safety_requested(), 0);
    assert!(r.pair.plc.outputs() & 1 == 0);
}

#[test]
fn a_violation_latches_its_code_and_stop_resets_the_mask() {
    let mut r = safety_rig();
    r.digital = 0;
    r.run_for(20_000);
    // 6.0 Hz > fss 4.0 Hz: code 12, logged with its text.
    r.analog[0] = 60;
    r.run_for(20_000);
    assert_eq!(r.pair.drive.core().fault(), Some(FaultCode::Sos));
    r.run_for(50_000);
    assert!(r.screen().contains("F12 standstill lost"), "{}", r.screen());
    assert_eq!(r.pair.plc.fault_log().first().map(|e| e.code), Some(12));
    // STOP: every control bit back to 1, the drive's mask follows.
    r.pair.plc.stop();
    r.run_for(20_000);
    assert_eq!(r.pair.drive.core().safety_requested(), 0);
}

#[test]
fn run_is_refused_while_sto_in_is_low() {
    let mut r = Rig::new(SAFETY);
    r.digital = 1;
    r.pair.drive.set_sto_input(true);
    r.run_for(30_000);
    r.pair.plc.run(None, r.pair.now);
    r.run_for(30_000);
    assert_eq!(r.pair.plc.run_state(), RunState::Stopped);
    assert_eq!(r.pair.drive.core().state(), CoreState::Idle);
    assert!(r.screen().contains("RUN REFUSED:STO_IN"), "{}", r.screen());
    r.pair.drive.set_sto_input(false);
    r.run_for(30_000);
    r.pair.plc.run(None, r.pair.now);
    r.run_for(100_000);
    assert_eq!(r.pair.drive.core().state(), CoreState::Run);
}

/// safety.md 8: the drive reports the signature of the section it accepted; when it is
/// not the one of the program RUN started, RUN stops with `SIG MISMATCH`. (The PLC's copy
/// is changed after the section went out: the drive holds the old settings.)
#[test]
fn a_signature_mismatch_stops_run() {
    let mut r = Rig::new(SAFETY);
    r.digital = 1;
    r.run_for(20_000);
    r.pair.plc.run(None, r.pair.now);
    while r.pair.plc.run_state() != RunState::Downloading {
        r.run_for(100);
    }
    // fss 4.0 -> 4.1 Hz in the PLC's copy only.
    r.pair.plc.program_mut().lines[30] = Some(Instruction {
        mnemonic: Mnemonic::Fss,
        operand: Some(Operand::K(4)),
        constant: 41,
    });
    r.run_for(150_000);
    assert_eq!(r.pair.plc.run_state(), RunState::Stopped);
    assert!(r.screen().contains("SIG MISMATCH"), "{}", r.screen());
    assert_eq!(r.pair.drive.core().state(), CoreState::Idle);
}

/// A drive that restarts while the PLC runs comes back without its drive section: RUN
/// stops (outputs off) with `DRIVE RESTARTED` on the LCD, nothing restarts by itself, and
/// one RUN downloads again and runs both. A link cut and restore (the drive keeps its
/// section, trips LINK) does not stop RUN.
#[test]
fn a_drive_restart_in_run_stops_run_and_says_so() {
    let mut r = running_rig();
    // Link cut and restored: LINK on the drive, RUN stays.
    r.cut(true);
    r.run_for(100_000);
    r.cut(false);
    r.run_for(100_000);
    assert_eq!(r.pair.plc.run_state(), RunState::Running, "{}", r.screen());
    assert!(!r.screen().contains("DRIVE RESTARTED"), "{}", r.screen());
    // The drive's supply cycles: a new DriveApp, as after its reset.
    r.pair.restart_drive(Pumped::new(
        DriveApp::new(
            DriveConfig::default(),
            ResetCause::PowerOn,
            LinkConfig::default(),
        ),
        MAX_IDLE_US,
    ));
    r.run_for(200_000);
    assert_eq!(r.pair.plc.run_state(), RunState::Stopped, "{}", r.screen());
    assert!(r.screen().contains("DRIVE RESTARTED"), "{}", r.screen());
    assert_eq!(r.pair.drive.core().state(), CoreState::Idle);
    r.run_for(500_000);
    assert_eq!(
        r.pair.drive.core().state(),
        CoreState::Idle,
        "no automatic restart"
    );
    r.pair.plc.run(None, r.pair.now);
    r.run_for(150_000);
    assert_eq!(r.pair.plc.run_state(), RunState::Running, "{}", r.screen());
    assert_eq!(r.pair.drive.core().state(), CoreState::Run);
}
