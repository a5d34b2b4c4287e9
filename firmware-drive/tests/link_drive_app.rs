//! DriveApp (drive core + link endpoint) driven by a bare PLC link endpoint over the
//! byte-timed wire: what the drive does with downloads, rejects, RUN/STOP, a lost link
//! and a PLC of another protocol version.

use firmware_drive::app::{AppEvent, DriveApp};
use firmware_drive::link::{DriveEvent as LinkEvent, DriveLinkState};
use firmware_drive::{AdcSample, DriveConfig, DriveState, FaultCode, ResetCause};
use shared_protocol::link::channel::{Channel, Impairments};
use shared_protocol::link::frame::{encode_frame, Frame};
use shared_protocol::link::{
    DownloadResult, LinkConfig, PlcEvent, PlcLink, PlcMsg, RejectReason, MAX_WIRE_FRAME,
    PROTOCOL_VERSION,
};
use shared_protocol::program::{assemble, Instruction, Mnemonic, Operand};
use shared_protocol::units::Micros;

struct Rig {
    plc: PlcLink,
    drive: DriveApp,
    to_drive: Channel,
    to_plc: Channel,
    now: Micros,
    plc_events: Vec<PlcEvent>,
    pwm_on: bool,
    /// Every `poll_tx` call: (bytes returned, section loaded before, loaded after, the
    /// link accepted a section in this call).
    tx_calls: Vec<(usize, bool, bool, bool)>,
    drive_events: Vec<AppEvent>,
}

impl Rig {
    fn new() -> Rig {
        let cfg = LinkConfig::default();
        Rig {
            plc: PlcLink::new(cfg),
            drive: DriveApp::new(DriveConfig::default(), ResetCause::PowerOn, cfg),
            to_drive: Channel::new(cfg.baud, Impairments::default(), 1),
            to_plc: Channel::new(cfg.baud, Impairments::default(), 2),
            now: Micros(0),
            plc_events: Vec::new(),
            pwm_on: false,
            tx_calls: Vec::new(),
            drive_events: Vec::new(),
        }
    }

    fn run_for(&mut self, us: u64) {
        let end = self.now.0 + us;
        let mut buf = [0u8; 64];
        let mut out = [0u8; MAX_WIRE_FRAME];
        let adc = AdcSample {
            u_dc: 2800,
            ..AdcSample::default()
        };
        while self.now.0 < end {
            self.now = Micros(self.now.0 + 10);
            let now = self.now;
            let n = self.to_drive.receive(now, &mut buf);
            if n > 0 {
                self.drive.on_rx(&buf[..n], now);
            }
            let n = self.to_plc.receive(now, &mut buf);
            if n > 0 {
                self.plc.receive(&buf[..n], now);
            }
            if now.0.is_multiple_of(100) {
                self.pwm_on = self.drive.pwm_period(&adc).enable;
            }
            if now.0.is_multiple_of(1000) {
                self.drive.tick_1ms(now);
            }
            if self.to_drive.is_idle(now) {
                let n = self.plc.poll_transmit(now, &mut out);
                if n > 0 {
                    self.to_drive.send(&out[..n], now);
                }
            }
            // As the pump: a frame when the line is free, else the endpoint's timers only.
            let loaded = self.drive.status().program_loaded;
            let n = if self.to_plc.is_idle(now) {
                let n = self.drive.poll_tx(now, &mut out);
                if n > 0 {
                    self.to_plc.send(&out[..n], now);
                }
                n
            } else {
                self.drive.poll_tx(now, &mut [])
            };
            let seen = self.drive_events.len();
            self.drive_events
                .extend(std::iter::from_fn(|| self.drive.poll_event()));
            let accepted =
                self.drive_events[seen..].contains(&AppEvent::Link(LinkEvent::ProgramAccepted));
            let after = self.drive.status().program_loaded;
            self.tx_calls.push((n, loaded, after, accepted));
            self.plc_events
                .extend(std::iter::from_fn(|| self.plc.poll_event()));
        }
    }

    fn download(&mut self, program: &str, patch: Option<(usize, Instruction)>) -> DownloadResult {
        let mut section = assemble(program).unwrap().drive_section();
        if let Some((line, i)) = patch {
            section.lines[line] = Some(i);
        }
        self.plc.start_download(&section).unwrap();
        self.run_for(150_000);
        self.plc_events
            .iter()
            .find_map(|e| match e {
                PlcEvent::Download(r) => Some(*r),
                _ => None,
            })
            .expect("answer")
    }
}

/// A drive section that switches the PWM on: f = 10.0 Hz from Q00 (above fmn = 5.0 Hz).
const SPIN: &str = "
000 fmn K00 0050
001 LD  Q00
002 LD  Q00
003 LD  K01 0000
004 SN1
005 LD  K02 1200
006 SN2
007 LD  K03 2400
008 SN3
";

fn connected() -> Rig {
    let mut r = Rig::new();
    r.run_for(20_000);
    assert!(r.plc.is_up());
    assert_eq!(r.drive.core().state(), DriveState::Idle);
    r
}

#[test]
fn accepted_section_runs_and_stops() {
    let mut r = connected();
    assert_eq!(r.download(SPIN, None), DownloadResult::Accepted);
    r.plc.write_q(0, 100).unwrap();
    r.plc.run().unwrap();
    r.run_for(20_000);
    assert_eq!(r.drive.core().state(), DriveState::Run);
    assert!(r.pwm_on, "outputs switching at 10 Hz");
    r.plc.stop().unwrap();
    r.run_for(5_000);
    assert_eq!(r.drive.core().state(), DriveState::Idle);
    assert!(!r.pwm_on);
}

/// Review D13/N8: the core's load (~6 900 instructions) is neither in the critical section
/// of the pass that sends the result nor in one of its own: it runs in four passes of its
/// own (`load_begin`, the VM's settings, the safety settings, the limits), each due at
/// once and sending no frame.
#[test]
fn an_accepted_section_is_loaded_in_passes_of_its_own() {
    let mut r = connected();
    r.tx_calls.clear();
    assert_eq!(r.download(SPIN, None), DownloadResult::Accepted);
    let accepted = r
        .tx_calls
        .iter()
        .position(|&(_, _, _, accepted_here)| accepted_here)
        .expect("a poll_tx call accepted the section");
    let loaded = r
        .tx_calls
        .iter()
        .position(|&(_, before, after, _)| !before && after)
        .expect("the section was loaded in a poll_tx call");
    assert_eq!(
        loaded - accepted,
        4,
        "four load passes after the accepting one"
    );
    for &(n, _, _, accepted_here) in &r.tx_calls[accepted + 1..=loaded] {
        assert_eq!(n, 0, "a loading pass sends no frame");
        assert!(!accepted_here);
    }
    assert!(r.drive.status().program_loaded);
}

#[test]
fn rejected_section_trips_prog_and_names_the_line() {
    let mut r = connected();
    let bad = Instruction {
        mnemonic: Mnemonic::Ld,
        operand: Some(Operand::D(3)),
        constant: 0,
    };
    let result = r.download(SPIN, Some((7, bad)));
    assert!(
        matches!(
            result,
            DownloadResult::Rejected {
                line: 7,
                reason: RejectReason::Verify(_)
            }
        ),
        "{result:?}"
    );
    assert_eq!(r.drive.core().fault(), Some(FaultCode::Prog));
    // RUN is refused until the fault is acknowledged and a good section arrives.
    r.plc.run().unwrap();
    r.run_for(10_000);
    assert_eq!(r.drive.core().state(), DriveState::Fault);
    assert!(!r.pwm_on);
    // The PLC hears of the trip (for its fault log).
    assert!(r.plc_events.iter().any(|e| matches!(
        e,
        PlcEvent::DriveFault {
            code: FaultCode::Prog,
            ..
        }
    )));
}

#[test]
fn lost_link_in_run_trips_link_and_switches_off() {
    let mut r = connected();
    assert_eq!(r.download(SPIN, None), DownloadResult::Accepted);
    r.plc.write_q(0, 100).unwrap();
    r.plc.run().unwrap();
    r.run_for(20_000);
    assert!(r.pwm_on);
    r.to_drive.set_cut(true);
    r.to_plc.set_cut(true);
    let cut = r.now;
    while r.drive.core().fault().is_none() && r.now.0 < cut.0 + 100_000 {
        r.run_for(100);
    }
    assert_eq!(r.drive.core().fault(), Some(FaultCode::Link));
    assert!(r.now.0 - cut.0 <= 51_000);
    r.run_for(200);
    assert!(!r.pwm_on);
    assert!(r
        .drive_events
        .contains(&AppEvent::Link(LinkEvent::LinkLost)));
}

#[test]
fn a_plc_of_another_version_never_brings_the_outputs_on() {
    let mut r = Rig::new();
    r.run_for(5_000);
    let hello = Frame {
        seq: 0,
        ack: 0,
        msg: PlcMsg::Hello {
            version: PROTOCOL_VERSION + 1,
            session: 3,
        },
    };
    let mut out = [0u8; MAX_WIRE_FRAME];
    let n = encode_frame(&hello, true, &mut out).unwrap();
    let now = r.now;
    r.drive.on_rx(&out[..n], now);
    assert_eq!(
        r.drive.link_state(),
        DriveLinkState::Incompatible {
            plc_version: PROTOCOL_VERSION + 1
        }
    );
    // Frames of a running session (as a confused PLC would send) are ignored.
    let run = Frame {
        seq: 0,
        ack: 0,
        msg: PlcMsg::Run,
    };
    let n = encode_frame(&run, false, &mut out).unwrap();
    r.drive.on_rx(&out[..n], now);
    let adc = AdcSample::default();
    r.drive.tick_1ms(now);
    assert!(!r.drive.pwm_period(&adc).enable);
    assert_ne!(r.drive.core().state(), DriveState::Run);
}

/// SPIN with the switching frequency from Q01 (`PWF`, Hz).
const SPIN_PWF: &str = "
000 fmn K00 0050
001 LD  Q00
002 LD  Q00
003 LD  K01 0000
004 SN1
005 LD  K02 1200
006 SN2
007 LD  K03 2400
008 SN3
009 PWF Q01
";

/// A new `PWF` reaches TIM1: once the core recomputes its timing, the application's next
/// period carries it (`DriveApp::pwm_timing` follows the core), and the periods after it
/// switch again with no timing to program. The application compares the timings only when
/// the core's `timing_changes` count moved (the PWM interrupt's fast path).
#[test]
fn a_new_pwf_is_programmed_once_and_then_switches() {
    let mut r = connected();
    let before = r.drive.pwm_timing();
    let changes = r.drive.core().timing_changes();
    assert_eq!(r.download(SPIN_PWF, None), DownloadResult::Accepted);
    r.plc.write_q(0, 100).unwrap();
    r.plc.write_q(1, 12_000).unwrap();
    r.plc.run().unwrap();
    r.run_for(20_000);
    assert_eq!(r.drive.core().state(), DriveState::Run);
    assert_ne!(
        r.drive.core().timing_changes(),
        changes,
        "PWF recomputed the timing"
    );
    assert_ne!(
        r.drive.core().pwm_timing(),
        before,
        "12 kHz is not the default"
    );
    assert_eq!(r.drive.pwm_timing(), r.drive.core().pwm_timing());
    let adc = AdcSample {
        u_dc: 2800,
        ..AdcSample::default()
    };
    let action = r.drive.pwm_period(&adc);
    assert!(action.timing.is_none(), "programmed once, not every period");
    assert!(action.enable, "switching at the new frequency");
}
