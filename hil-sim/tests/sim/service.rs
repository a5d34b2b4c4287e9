//! The service port in the simulation (service.md 9, 10): `run --service-pty` through a
//! real pty, and the flood leaving the record unchanged.

use std::io::{BufRead, BufReader, Read, Write};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use hil_sim::record;
use hil_sim::run::{parse_program, run_with};
use hil_sim::scenario::Scenario;
use hil_sim::service::{line, Attached, ServiceLine};
use hil_sim::sim::RunOptions;
use shared_protocol::link::MAX_WIRE_FRAME;
use shared_protocol::service::{
    encode, Answer, PlcState, Request, ServiceReader, SERVICE_BAUD, SERVICE_VERSION,
};

const MOTOR: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../shared-protocol/programs/motor.plc"
);

/// Sends `req` with `id` on `port` and reads until its answer (samples skipped).
fn ask(port: &mut std::fs::File, reader: &mut ServiceReader, id: u8, req: Request) -> Answer {
    let mut out = [0u8; MAX_WIRE_FRAME];
    let n = encode(id, req, &mut out).unwrap();
    port.write_all(&out[..n]).unwrap();
    let deadline = Instant::now() + Duration::from_secs(5);
    let mut buf = [0u8; 256];
    while Instant::now() < deadline {
        let got = port.read(&mut buf).unwrap();
        for &b in &buf[..got] {
            if let Some(Ok((i, a))) = reader.push::<Answer>(b) {
                if i == id {
                    return a;
                }
            }
        }
    }
    panic!("no answer to request {id}");
}

#[test]
fn run_with_service_pty_answers_hello_and_status_through_a_real_pty() {
    let mut child = Command::new(env!("CARGO_BIN_EXE_hil-sim"))
        .args(["run", MOTOR, "--duration", "2", "--service-pty"])
        .args(["--service-linger", "0.5"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut err = BufReader::new(child.stderr.take().unwrap());
    let mut first = String::new();
    err.read_line(&mut first).unwrap();
    let path = first
        .trim_end()
        .strip_prefix("service: ")
        .unwrap_or_else(|| panic!("first stderr line: {first:?}"))
        .to_string();
    // Opened as a plain file: the simulation set raw mode, bytes pass unchanged.
    let mut port = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .open(&path)
        .unwrap();
    let mut reader = ServiceReader::new();
    let before_hello = ask(&mut port, &mut reader, 1, Request::GetStatus);
    assert_eq!(
        before_hello,
        Answer::Refused(shared_protocol::service::RefuseReason::Hello)
    );
    assert_eq!(
        ask(
            &mut port,
            &mut reader,
            2,
            Request::Hello {
                version: SERVICE_VERSION
            }
        ),
        Answer::HelloReply {
            version: SERVICE_VERSION
        }
    );
    let Answer::Identity(id) = ask(&mut port, &mut reader, 3, Request::Identify) else {
        panic!("Identify");
    };
    assert_eq!(&id.uid[..8], &1u64.to_le_bytes(), "uid from --seed 1");
    assert_eq!(id.firmware.as_str(), env!("CARGO_PKG_VERSION"));
    // motor.plc starts at power-up: RUN once the drive has its section.
    let mut status = None;
    for k in 0..40u8 {
        let Answer::Status(s) = ask(&mut port, &mut reader, 4 + k, Request::GetStatus) else {
            panic!("GetStatus");
        };
        if s.plc == PlcState::Run {
            status = Some(s);
            break;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let s = status.expect("RUN within a second of real time");
    assert!(s.uptime_ms > 0 && s.uptime_ms < 2_000, "{}", s.uptime_ms);
    drop(port);
    let mut summary = String::new();
    child
        .stdout
        .take()
        .unwrap()
        .read_to_string(&mut summary)
        .unwrap();
    assert!(child.wait().unwrap().success());
    assert!(summary.contains("final state: PLC RUN"), "{summary}");
}

fn record_csv(scenario: &Scenario, service: Option<&mut Attached>) -> String {
    let prog = parse_program(&std::fs::read_to_string(MOTOR).unwrap(), "motor.plc").unwrap();
    let mut csv = record::header() + "\n";
    run_with(
        &prog,
        scenario.clone(),
        1.5,
        RunOptions::default(),
        hil_sim::decimate::KeepSamples::for_plot(false),
        |s| {
            csv.push_str(&record::row(s));
            csv.push('\n');
        },
        |_| {},
        service,
    )
    .unwrap();
    csv
}

#[test]
fn a_flooded_service_port_leaves_the_record_byte_identical() {
    let text = "duration_s = 1.5\n[[event]]\nat_s = 0.0\nset = { A00 = 980, A01 = 500 }\n\
                [[event]]\nat_s = 0.2\npress = \"D00\"\nhold_s = 0.2\n";
    let plain = Scenario::parse(text).unwrap();
    let flooded = Scenario::parse(&format!("{text}[service]\nflood = true\n")).unwrap();
    assert!(flooded.service_flood);
    let mut line = Attached::detached(ServiceLine::new(
        line::build_info(1),
        SERVICE_BAUD,
        SERVICE_VERSION,
        Some(7),
    ));
    let with_flood = record_csv(&flooded, Some(&mut line));
    let without = record_csv(&plain, None);
    // The line was kept full: ~11.5 bytes per ms for 1.5 s.
    let sent = line.line().flooded_bytes();
    assert!(sent > 15_000, "{sent} flood bytes");
    assert!(line.line().port_stats().frames_bad > 0);
    assert!(without.lines().count() > 1000);
    assert!(with_flood == without, "the flood changed the record");
}

#[test]
fn the_panel_serves_the_service_port_on_a_pty_and_shows_its_path() {
    use hil_sim::service::{pty::Pty, PtyOptions};
    let pty = Pty::open().unwrap();
    let path = pty.path().display().to_string();
    let line = ServiceLine::new(line::build_info(3), SERVICE_BAUD, SERVICE_VERSION, None);
    let opts = PtyOptions {
        wait_for_client: false,
        linger: Duration::ZERO,
        pace_virtual_per_wall: None,
    };
    let mut app = hil_sim::panel::open_with(
        Some(std::path::Path::new(MOTOR)),
        None,
        false,
        Some((Attached::on_pty(line, pty, opts), path.clone())),
    )
    .unwrap();
    assert_eq!(
        app.notice.as_deref(),
        Some(format!("service: {path}").as_str())
    );
    let mut port = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .open(&path)
        .unwrap();
    let mut out = [0u8; MAX_WIRE_FRAME];
    let n = encode(
        9,
        Request::Hello {
            version: SERVICE_VERSION,
        },
        &mut out,
    )
    .unwrap();
    port.write_all(&out[..n]).unwrap();
    // The panel's own clock: 50 ms of simulated time carry the frame both ways.
    app.advance(50);
    let mut reader = ServiceReader::new();
    let mut buf = [0u8; 64];
    let got = port.read(&mut buf).unwrap();
    let answers: Vec<(u8, Answer)> = buf[..got]
        .iter()
        .filter_map(|&b| reader.push::<Answer>(b).and_then(Result::ok))
        .collect();
    assert_eq!(
        answers,
        vec![(
            9,
            Answer::HelloReply {
                version: SERVICE_VERSION
            }
        )]
    );
}
