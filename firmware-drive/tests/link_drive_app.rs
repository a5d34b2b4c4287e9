//! DriveApp (drive core + link endpoint) driven by a bare PLC link endpoint on the
//! co-simulation rig (`shared_protocol::link::pair::Pair`: each side served by its pump,
//! as on the boards): what the drive does with downloads, rejects, RUN/STOP, a lost link
//! and a PLC of another protocol version.

use firmware_drive::app::{AppEvent, DriveApp};
use firmware_drive::link::{DriveEvent as LinkEvent, DriveLinkState};
use firmware_drive::{AdcSample, DriveConfig, DriveState, FaultCode, ResetCause};
use shared_protocol::link::channel::Impairments;
use shared_protocol::link::frame::{encode_frame, Frame};
use shared_protocol::link::line::{Line, Pumped};
use shared_protocol::link::pair::Pair;
use shared_protocol::link::pump::LinkEndpoint;
use shared_protocol::link::{
    DownloadResult, LinkConfig, PlcEvent, PlcLink, PlcMsg, RejectReason, MAX_WIRE_FRAME,
    PROTOCOL_VERSION,
};
use shared_protocol::program::{assemble, Instruction, Mnemonic, Operand};
use shared_protocol::units::Micros;

/// The drive application, recording each `poll_tx` call the pump makes.
struct Recorded {
    app: DriveApp,
    /// Every `poll_tx` call: (bytes returned, section loaded before, loaded after, the
    /// link accepted a section in this call).
    tx_calls: Vec<(usize, bool, bool, bool)>,
    events: Vec<AppEvent>,
}

impl LinkEndpoint for Recorded {
    fn on_rx(&mut self, bytes: &[u8], now: Micros) {
        self.app.on_rx(bytes, now);
    }
    fn poll_tx(&mut self, now: Micros, out: &mut [u8]) -> usize {
        let loaded = self.app.status().program_loaded;
        let n = self.app.poll_tx(now, out);
        let seen = self.events.len();
        self.events
            .extend(std::iter::from_fn(|| self.app.poll_event()));
        let accepted = self.events[seen..].contains(&AppEvent::Link(LinkEvent::ProgramAccepted));
        let after = self.app.status().program_loaded;
        self.tx_calls.push((n, loaded, after, accepted));
        n
    }
    fn poll_timeout(&self) -> Option<Micros> {
        self.app.poll_timeout()
    }
    fn line_error(&mut self) {
        self.app.on_line_error();
    }
}

/// A bare PLC endpoint and the drive application on the co-simulation rig, with the
/// drive's PWM period every 100 us and its 1 ms tick.
struct Rig {
    pair: Pair<Pumped<PlcLink>, Pumped<Recorded>>,
    plc_events: Vec<PlcEvent>,
    pwm_on: bool,
}

impl Rig {
    fn new() -> Rig {
        let cfg = LinkConfig::default();
        let drive = Recorded {
            app: DriveApp::new(DriveConfig::default(), ResetCause::PowerOn, cfg),
            tx_calls: Vec::new(),
            events: Vec::new(),
        };
        Rig {
            pair: Pair::pumped(
                PlcLink::new(cfg),
                drive,
                Line::new(cfg.baud, Impairments::default(), 1),
            ),
            plc_events: Vec::new(),
            pwm_on: false,
        }
    }

    fn run_for(&mut self, us: u64) {
        let end = self.pair.now.0 + us;
        let adc = AdcSample {
            u_dc: 2800,
            ..AdcSample::default()
        };
        let events = &mut self.plc_events;
        while self.pair.now.0 < end {
            // The drive's next PWM period (every 100 us).
            let next = ((self.pair.now.0 / 100 + 1) * 100).min(end);
            self.pair.run_until(Micros(next), |p| {
                events.extend(std::iter::from_fn(|| p.plc.poll_event()));
            });
            let now = self.pair.now;
            if now.0.is_multiple_of(100) {
                self.pwm_on = self.pair.drive.app.pwm_period(&adc).enable;
            }
            if now.0.is_multiple_of(1000) {
                self.pair.drive.app.tick_1ms(now);
            }
            self.pair.kick();
        }
    }

    fn download(&mut self, program: &str, patch: Option<(usize, Instruction)>) -> DownloadResult {
        let mut section = assemble(program).unwrap().drive_section();
        if let Some((line, i)) = patch {
            section.lines[line] = Some(i);
        }
        self.pair.plc.start_download(&section).unwrap();
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
    assert!(r.pair.plc.is_up());
    assert_eq!(r.pair.drive.app.core().state(), DriveState::Idle);
    r
}

#[test]
fn accepted_section_runs_and_stops() {
    let mut r = connected();
    assert_eq!(r.download(SPIN, None), DownloadResult::Accepted);
    r.pair.plc.write_q(0, 100).unwrap();
    r.pair.plc.run().unwrap();
    r.run_for(20_000);
    assert_eq!(r.pair.drive.app.core().state(), DriveState::Run);
    assert!(r.pwm_on, "outputs switching at 10 Hz");
    r.pair.plc.stop().unwrap();
    r.run_for(5_000);
    assert_eq!(r.pair.drive.app.core().state(), DriveState::Idle);
    assert!(!r.pwm_on);
}

/// The core's load (~6 900 instructions) is neither in the critical section
/// of the pass that sends the result nor in one of its own: it runs in four passes of its
/// own (`load_begin`, the VM's settings, the safety settings, the limits), each due at
/// once and sending no frame.
#[test]
fn an_accepted_section_is_loaded_in_passes_of_its_own() {
    let mut r = connected();
    r.pair.drive.tx_calls.clear();
    assert_eq!(r.download(SPIN, None), DownloadResult::Accepted);
    let accepted = r
        .pair
        .drive
        .tx_calls
        .iter()
        .position(|&(_, _, _, accepted_here)| accepted_here)
        .expect("a poll_tx call accepted the section");
    let loaded = r
        .pair
        .drive
        .tx_calls
        .iter()
        .position(|&(_, before, after, _)| !before && after)
        .expect("the section was loaded in a poll_tx call");
    assert_eq!(
        loaded - accepted,
        4,
        "four load passes after the accepting one"
    );
    for &(n, _, _, accepted_here) in &r.pair.drive.tx_calls[accepted + 1..=loaded] {
        assert_eq!(n, 0, "a loading pass sends no frame");
        assert!(!accepted_here);
    }
    assert!(r.pair.drive.app.status().program_loaded);
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
    assert_eq!(r.pair.drive.app.core().fault(), Some(FaultCode::Prog));
    // RUN is refused until the fault is acknowledged and a good section arrives.
    r.pair.plc.run().unwrap();
    r.run_for(10_000);
    assert_eq!(r.pair.drive.app.core().state(), DriveState::Fault);
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
    r.pair.plc.write_q(0, 100).unwrap();
    r.pair.plc.run().unwrap();
    r.run_for(20_000);
    assert!(r.pwm_on);
    r.pair.cut(true);
    let cut = r.pair.now;
    while r.pair.drive.app.core().fault().is_none() && r.pair.now.0 < cut.0 + 100_000 {
        r.run_for(100);
    }
    assert_eq!(r.pair.drive.app.core().fault(), Some(FaultCode::Link));
    assert!(r.pair.now.0 - cut.0 <= 51_000);
    r.run_for(200);
    assert!(!r.pwm_on);
    assert!(r
        .pair
        .drive
        .events
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
    let now = r.pair.now;
    r.pair.drive.app.on_rx(&out[..n], now);
    assert_eq!(
        r.pair.drive.app.link_state(),
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
    r.pair.drive.app.on_rx(&out[..n], now);
    let adc = AdcSample::default();
    r.pair.drive.app.tick_1ms(now);
    assert!(!r.pair.drive.app.pwm_period(&adc).enable);
    assert_ne!(r.pair.drive.app.core().state(), DriveState::Run);
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
    let before = r.pair.drive.app.pwm_timing();
    let changes = r.pair.drive.app.core().timing_changes();
    assert_eq!(r.download(SPIN_PWF, None), DownloadResult::Accepted);
    r.pair.plc.write_q(0, 100).unwrap();
    r.pair.plc.write_q(1, 12_000).unwrap();
    r.pair.plc.run().unwrap();
    r.run_for(20_000);
    assert_eq!(r.pair.drive.app.core().state(), DriveState::Run);
    assert_ne!(
        r.pair.drive.app.core().timing_changes(),
        changes,
        "PWF recomputed the timing"
    );
    assert_ne!(
        r.pair.drive.app.core().pwm_timing(),
        before,
        "12 kHz is not the default"
    );
    assert_eq!(
        r.pair.drive.app.pwm_timing(),
        r.pair.drive.app.core().pwm_timing()
    );
    let adc = AdcSample {
        u_dc: 2800,
        ..AdcSample::default()
    };
    let action = r.pair.drive.app.pwm_period(&adc);
    assert!(action.timing.is_none(), "programmed once, not every period");
    assert!(action.enable, "switching at the new frequency");
}
