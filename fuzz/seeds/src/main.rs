//! Writes the seed corpora of the fuzz targets (docs/fuzzing.md) into `fuzz/corpus/`:
//! a few small valid inputs per target, made with the project's encoders from its example
//! programs and scenarios, so that the fuzzer starts past the checksums and formats.

use std::fs;
use std::path::{Path, PathBuf};

use shared_protocol::link::frame::{Frame, MAX_RAW_FRAME};
use shared_protocol::link::{wire, DriveMsg, DriveStatus, PlcMsg, QValue, PROTOCOL_VERSION};
use shared_protocol::program::payload::for_each_payload_byte;
use shared_protocol::program::{assemble_runnable, encode_slot, Program, LINES};
use shared_protocol::service::{Request, SERVICE_VERSION};

/// The example programs the seeds are made from (small and varied; the lift is the
/// largest shipped program).
const PROGRAMS: [&str; 6] = [
    "and_or",
    "counter100",
    "on_delay_10s",
    "arithmetic",
    "three_phase_sine",
    "lift",
];

fn body<M: serde::Serialize>(seq: u8, ack: u8, msg: M) -> Vec<u8> {
    let mut out = [0u8; MAX_RAW_FRAME];
    let n = wire::to_slice(&Frame { seq, ack, msg }, &mut out).expect("a seed frame fits");
    out[..n].to_vec()
}

/// Stream records `[kind, len, bytes...]` of the link and service targets: each body as
/// a valid frame (bit 0) after `dt_ms` (bits 1-7).
fn records(bodies: &[Vec<u8>], dt_ms: u8) -> Vec<u8> {
    let mut out = Vec::new();
    for b in bodies {
        out.push(1 | dt_ms << 1);
        out.push(b.len() as u8);
        out.extend_from_slice(b);
    }
    out
}

fn program(root: &Path, name: &str) -> (String, Program) {
    let path = root.join(format!("shared-protocol/programs/{name}.plc"));
    let text = fs::read_to_string(&path).expect("an example program");
    let p = assemble_runnable(&text).expect("an example program assembles");
    (text, p)
}

fn write(dir: &Path, name: &str, bytes: &[u8]) {
    fs::create_dir_all(dir).expect("corpus directory");
    fs::write(dir.join(name), bytes).expect("seed written");
}

fn main() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..");
    let corpus = root.join("fuzz/corpus");

    let plc = [
        body(
            0,
            0,
            PlcMsg::Hello {
                version: PROTOCOL_VERSION,
                session: 5,
            },
        ),
        body(1, 0, PlcMsg::Heartbeat),
        body(
            2,
            1,
            PlcMsg::QWrite(
                [
                    QValue {
                        addr: 3,
                        value: -250,
                    },
                    QValue {
                        addr: 63,
                        value: 1000,
                    },
                ]
                .into_iter()
                .collect(),
            ),
        ),
        body(3, 1, PlcMsg::Run),
        body(4, 2, PlcMsg::Direction { reverse: true }),
        body(5, 2, PlcMsg::DownloadBegin { crc: 0x1234_5678 }),
        body(
            6,
            2,
            PlcMsg::DownloadChunk {
                first_line: 0,
                data: encode_slot(None).iter().copied().collect(),
            },
        ),
        body(7, 3, PlcMsg::SafetyRequest { requested: 0x0003 }),
    ];
    let drive = [
        body(
            0,
            0,
            DriveMsg::HelloReply {
                version: PROTOCOL_VERSION,
                session: 5,
            },
        ),
        body(1, 1, DriveMsg::Ack),
        body(2, 1, DriveMsg::Status(DriveStatus::default())),
    ];
    let dir = corpus.join("link_frame");
    for (k, b) in plc.iter().chain(&drive).enumerate() {
        write(&dir, &format!("frame_{k:02}"), b);
    }
    let dir = corpus.join("link_stream");
    write(&dir, "plc_session", &records(&plc, 2));
    write(&dir, "drive_session", &records(&drive, 2));

    let requests = [
        body(
            1,
            0,
            Request::Hello {
                version: SERVICE_VERSION,
            },
        ),
        body(2, 0, Request::Identify),
        body(3, 0, Request::GetStatus),
        body(4, 0, Request::ListSlots),
        body(5, 0, Request::ReadProgram { slot: 1, offset: 0 }),
        body(6, 0, Request::ReadFaultLog { from: 0, count: 4 }),
        body(7, 0, Request::GetCounters),
        body(
            8,
            0,
            Request::WriteBegin {
                slot: 2,
                len: 8,
                crc: 0,
            },
        ),
        body(
            9,
            0,
            Request::WriteChunk {
                offset: 0,
                data: [0u8; 8].into_iter().collect(),
            },
        ),
        body(10, 0, Request::WriteCommit),
    ];
    let dir = corpus.join("service_msg");
    for (k, b) in requests.iter().enumerate() {
        write(&dir, &format!("request_{k:02}"), b);
    }
    write(&dir, "session", &records(&requests, 5));

    let dir_asm = corpus.join("assembler");
    let dir_codec = corpus.join("program_codec");
    let dir_vm = corpus.join("vm_diff");
    for name in PROGRAMS {
        let (text, p) = program(&root, name);
        write(&dir_asm, name, text.as_bytes());
        let mut payload = Vec::new();
        for_each_payload_byte(&p, |b| payload.push(b));
        write(&dir_codec, name, &payload);

        // vm_diff: flags, line count, [line, code] per line, t0, then scans.
        let lines: Vec<(usize, [u8; 4])> = (0..LINES)
            .filter_map(|n| p.lines[n].as_ref().map(|i| (n, encode_slot(Some(i)))))
            .take(255)
            .collect();
        let mut v = vec![1u8, lines.len() as u8];
        for (n, code) in &lines {
            v.extend_from_slice(&(*n as u16).to_be_bytes());
            v.extend_from_slice(code);
        }
        v.extend_from_slice(&1000u32.to_le_bytes());
        for k in 0..8u8 {
            // A 10 ms step, digital inputs, four analog inputs and the drive's view.
            v.extend_from_slice(&[0, 10]);
            v.extend_from_slice(&[k, 0xA5 ^ k]);
            v.extend_from_slice(&[0x10, 0x02, 0, 0, 0xFF, 0x03, 0, 1]);
            v.extend_from_slice(&[0u8; 24]);
            v.push(0);
        }
        write(&dir_vm, name, &v);
    }

    // eeprom: region byte, then XOR bytes (zeros: the valid image; one set bit: a flip).
    let dir = corpus.join("eeprom");
    write(&dir, "valid", &[5]);
    write(&dir, "boot_flip", &[0, 0, 0, 0, 0x01]);
    write(
        &dir,
        "log_flip",
        &[1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0x80],
    );
    write(&dir, "slot_header_flip", &[2, 0, 0, 0, 0, 0, 0, 0, 0x02]);
    write(
        &dir,
        "slot_payload_flip",
        &[
            3, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0x10,
        ],
    );
    write(&dir, "counters_flip", &[4, 0, 0, 0, 0, 0, 0, 0x04]);

    let dir = corpus.join("scenario_toml");
    for name in [
        "motor",
        "link_cut",
        "locked_rotor",
        "regen_brake",
        "lab_5_2_reversal",
    ] {
        let path = root.join(format!("hil-sim/scenarios/{name}.toml"));
        let text = fs::read(&path).expect("a scenario");
        write(&dir, name, &text);
    }
    println!("seeds written to {}", corpus.display());
}
