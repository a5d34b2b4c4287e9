//! Sizes, round trips and the decoders' fuzzing.

use super::*;
use crate::fault::FaultCode;
use crate::link::frame::{decode_raw, CRC, MAX_WIRE_FRAME};
use crate::link::DriveState;
use heapless::{String, Vec};
use proptest::prelude::*;

fn wire<M: Serialize>(id: u8, msg: M) -> std::vec::Vec<u8> {
    let mut out = [0u8; MAX_WIRE_FRAME];
    let n = encode(id, msg, &mut out).expect("every message fits a frame");
    out[..n].to_vec()
}

fn read_all<M: DeserializeOwned>(bytes: &[u8]) -> std::vec::Vec<Result<(u8, M), FrameError>> {
    let mut r = ServiceReader::new();
    bytes.iter().filter_map(|&b| r.push::<M>(b)).collect()
}

fn roundtrip_request(req: Request) {
    let w = wire(200, req.clone());
    assert_eq!(w[0], 0, "leading delimiter");
    assert_eq!(read_all::<Request>(&w), std::vec![Ok((200, req))]);
}

fn roundtrip_answer(a: Answer) {
    let w = wire(255, a.clone());
    assert_eq!(read_all::<Answer>(&w), std::vec![Ok((255, a))]);
}

fn full_vec<const N: usize>(v: u8) -> Vec<u8, N> {
    core::iter::repeat_n(v, N).collect()
}

fn big_entry() -> LogEntry {
    LogEntry {
        pos: 31,
        code: 255,
        power_up: u16::MAX,
        uptime_s: UPTIME_LIMIT_S,
        wall_s: Some(u32::MAX),
        values: [Some(i16::MIN); 2],
    }
}

/// Every message with every field at its largest encoding: each must fit a frame.
fn largest_answers() -> std::vec::Vec<Answer> {
    let drive = DriveInfo {
        state: DriveState::Fault,
        fault: 255,
        freq_dhz: i16::MIN,
        reverse: true,
        udc_dv: i16::MIN,
        imax_ca: i16::MIN,
        com: u16::MAX,
    };
    let mut rows = Vec::new();
    for _ in 0..4 {
        let mut s: String<20> = String::new();
        for _ in 0..20 {
            s.push('W').unwrap();
        }
        rows.push(s).unwrap();
    }
    let slot = SlotSummary {
        state: SlotState::Damaged,
        generation: u32::MAX,
        lines: u16::MAX,
        len: u16::MAX,
        crc: u32::MAX,
    };
    std::vec![
        Answer::HelloReply { version: u16::MAX },
        Answer::Identity(Identity {
            firmware: "0123456789abcdef".try_into().unwrap(),
            git: "0123456789ab".try_into().unwrap(),
            uid: [0xFF; 12],
            power_ups: u32::MAX,
            uptime_ms: u64::MAX,
        }),
        Answer::Status(Status {
            plc: PlcState::Starting,
            remote: true,
            link: LinkView::VersionMismatch {
                drive_version: u16::MAX
            },
            drive: Some(drive),
            d: u16::MAX,
            o: u8::MAX,
            a: [u16::MAX; 4],
            lcd: [Some(i16::MIN); 4],
            warning: Some(RunWarning::Div0 { line: u16::MAX }),
            newest_log: Some((255, 255)),
            scan_last_us: u32::MAX,
            scan_max_us: u32::MAX,
            uptime_ms: u64::MAX,
            slot: Some(255),
            unsaved: true,
        }),
        Answer::Screen(Screen { rows }),
        Answer::Subscribed {
            period_ms: u16::MAX
        },
        Answer::FaultLog(FaultLog {
            total: 255,
            newest: Some(255),
            entries: core::iter::repeat_n(big_entry(), LOG_ENTRIES_PER_ANSWER).collect(),
        }),
        Answer::Counters(Counters {
            run_starts: u32::MAX,
            run_minutes: u32::MAX,
            pwm_minutes: u32::MAX,
            link_errors: u32::MAX,
            program_saves: u16::MAX,
            trips: Trips([u16::MAX; FaultCode::COUNT]),
            app: [u32::MAX; 4],
            power_ups: u32::MAX,
            since_write_s: Some(u32::MAX),
        }),
        Answer::Slots(Slots {
            slots: [slot; 4],
            ram_slot: Some(255),
            unsaved: true,
            last_run: Some(255),
        }),
        Answer::ProgramChunk(ProgramChunk {
            slot: 255,
            generation: u32::MAX,
            len: u16::MAX,
            crc: u32::MAX,
            offset: u16::MAX,
            data: full_vec(0xFF),
        }),
        Answer::Done,
        Answer::Refused(RefuseReason::Transfer),
        Answer::WriteResult(WriteResult::Invalid {
            line: u16::MAX,
            reason: InvalidReason::Verify(255)
        }),
        Answer::WriteResult(WriteResult::Saved {
            generation: u32::MAX
        }),
        Answer::Clock {
            seconds: Some(u32::MAX),
        },
        Answer::Sample(Sample {
            uptime_ms: u64::MAX,
            plc: PlcState::Starting,
            drive: Some(DriveSample {
                freq_dhz: i16::MIN,
                reverse: true,
                udc_dv: i16::MIN,
                imax_ca: i16::MIN,
                fault: 255,
            }),
            d: u16::MAX,
            o: u8::MAX,
            a: [u16::MAX; 4],
            lcd: [Some(i16::MIN); 4],
            q: core::iter::repeat_n(i16::MIN, MAX_SUBSCRIBED_Q).collect(),
            dropped: u32::MAX,
        }),
    ]
}

fn largest_requests() -> std::vec::Vec<Request> {
    std::vec![
        Request::Hello { version: u16::MAX },
        Request::Identify,
        Request::GetStatus,
        Request::GetScreen,
        Request::Subscribe {
            period_ms: u16::MAX,
            q: full_vec(255),
        },
        Request::ReadFaultLog {
            from: 255,
            count: 255
        },
        Request::GetCounters,
        Request::ListSlots,
        Request::ReadProgram {
            slot: 255,
            offset: u16::MAX
        },
        Request::WriteBegin {
            slot: 255,
            len: u16::MAX,
            crc: u32::MAX
        },
        Request::WriteChunk {
            offset: u16::MAX,
            data: full_vec(0),
        },
        Request::WriteCommit,
        Request::Run { slot: 255 },
        Request::Stop,
        Request::Ack,
        Request::ClearFaultLog,
        Request::GetClock,
        Request::SetClock { seconds: u32::MAX },
    ]
}

#[test]
fn every_message_fits_a_frame_at_its_largest_and_round_trips() {
    for a in largest_answers() {
        roundtrip_answer(a);
    }
    for r in largest_requests() {
        roundtrip_request(r);
    }
}

#[test]
fn hello_is_variant_zero_in_both_directions() {
    // id, 0, variant 0, version 1: frozen forever (service.md 2).
    let w = wire(1, Request::Hello { version: 1 });
    let mut raw = w[1..w.len() - 1].to_vec();
    let n = cobs::decode_in_place(&mut raw).unwrap();
    assert_eq!(&raw[..n - 4], &[1, 0, 0, 1]);
    let w = wire(1, Answer::HelloReply { version: 1 });
    let mut raw = w[1..w.len() - 1].to_vec();
    let n = cobs::decode_in_place(&mut raw).unwrap();
    assert_eq!(&raw[..n - 4], &[1, 0, 0, 1]);
}

#[test]
fn a_frame_with_a_nonzero_second_byte_is_refused() {
    let mut out = [0u8; MAX_WIRE_FRAME];
    let n = encode_frame(
        &Frame {
            seq: 3,
            ack: 1,
            msg: Request::Stop,
        },
        false,
        &mut out,
    )
    .unwrap();
    assert_eq!(
        read_all::<Request>(&out[..n]),
        std::vec![Err(FrameError::Message)]
    );
}

#[test]
fn guarded_set_is_the_spec_table() {
    let guarded: std::vec::Vec<bool> = largest_requests().iter().map(|r| r.is_guarded()).collect();
    assert_eq!(
        guarded,
        [
            false, false, false, false, false, false, false, false, false, true, true, true, true,
            false, true, true, false, false
        ]
    );
}

#[test]
fn log_texts() {
    use std::string::ToString;
    assert_eq!(LogText(2).to_string(), "overcurrent (HW)");
    assert_eq!(LogText(240).to_string(), "fault log cleared");
    assert_eq!(LogText(112).to_string(), "application fault 12");
    assert_eq!(log_name(112), "ALM");
    assert_eq!(app_fault_code(12), 112);
    assert_eq!(app_fault_of(112), Some(12));
    assert_eq!(app_fault_of(100), None);
    assert_eq!(app_fault_of(200), None);
    assert!(!is_event(app_fault_code(99)));
    assert_eq!(
        LogText(241).to_string(),
        "program written over the service port"
    );
    assert_eq!(LogText(99).to_string(), "code 99");
    assert_eq!(LogText(0).to_string(), "code 0");
    assert_eq!(log_name(240), "LOGCLR");
    assert_eq!(log_name(241), "PGMSVC");
    assert!(is_event(240) && is_event(254) && !is_event(255) && !is_event(8));
}

#[test]
fn field_io_faults_sit_between_the_application_faults_and_the_events() {
    for code in [
        FIELD_FAULT_OVT,
        FIELD_FAULT_24V,
        FIELD_FAULT_INT,
        FIELD_FAULT_SPI,
    ] {
        assert!(app_fault_of(code).is_none() && !is_event(code));
        assert!(field_fault_name(code).is_some() && field_fault_text(code).is_some());
    }
    assert_eq!(field_fault_name(204), None);
    assert_eq!(field_fault_text(199), None);
    assert_eq!(LogText(201).to_string(), "field 24 V supply lost");
}

fn cases() -> u32 {
    if cfg!(debug_assertions) {
        2_000
    } else {
        50_000
    }
}

fn with_crc(body: &[u8]) -> std::vec::Vec<u8> {
    let mut v = body.to_vec();
    v.extend_from_slice(&CRC.checksum(body).to_le_bytes());
    v
}

proptest! {
    #![proptest_config(ProptestConfig { cases: cases(), failure_persistence: None, ..ProptestConfig::default() })]

    /// Any byte sequence gives frames or errors, never a panic, in fixed memory.
    #[test]
    fn reader_never_panics_on_random_bytes(bytes in proptest::collection::vec(any::<u8>(), 0..400)) {
        let mut a = ServiceReader::new();
        let mut b = ServiceReader::new();
        for &x in &bytes {
            let _ = a.push::<Request>(x);
            let _ = b.push::<Answer>(x);
        }
    }

    /// Random bodies with a correct CRC reach the message parsers (random bytes almost
    /// never pass the CRC), through the whole reader.
    #[test]
    fn parsers_never_panic_on_bodies_with_valid_crc(body in proptest::collection::vec(any::<u8>(), 0..92)) {
        let raw = with_crc(&body);
        let req = decode_raw::<Request>(&raw);
        let ans = decode_raw::<Answer>(&raw);
        let mut w = std::vec![0u8; raw.len() + 3];
        let n = cobs::encode(&raw, &mut w);
        w.truncate(n);
        w.push(0);
        let via_reader = read_all::<Request>(&w);
        prop_assert_eq!(via_reader.len(), 1);
        if let (Ok(f), Ok((id, m))) = (&req, &via_reader[0]) {
            prop_assert_eq!(f.seq, *id);
            prop_assert_eq!(&f.msg, m);
        }
        let _ = ans;
    }

    /// Round trip of arbitrary chunks and subscriptions.
    #[test]
    fn chunk_requests_round_trip(offset in any::<u16>(), data in proptest::collection::vec(any::<u8>(), 0..=64), id in any::<u8>()) {
        let req = Request::WriteChunk { offset, data: Vec::from_slice(&data).unwrap() };
        let w = wire(id, req.clone());
        prop_assert_eq!(read_all::<Request>(&w), std::vec![Ok((id, req))]);
    }
}

/// `Trips` carries one counter per fault code, so its size is part of the service
/// version: a new code (`docs/contributing/add-a-trip.md`) raises `SERVICE_VERSION` and
/// adds its line here. A host of another version is refused at `Hello`.
#[test]
fn the_service_version_names_its_trip_count() {
    const TRIPS_PER_VERSION: [(u16, usize); 3] = [(1, 16), (2, 17), (3, 17)];
    let known = TRIPS_PER_VERSION
        .iter()
        .find(|(v, _)| *v == SERVICE_VERSION);
    assert_eq!(
        known.map(|(_, n)| *n),
        Some(crate::fault::FaultCode::COUNT),
        "SERVICE_VERSION {SERVICE_VERSION} does not carry {} trip counters: raise it and \
         add (version, count) to TRIPS_PER_VERSION",
        crate::fault::FaultCode::COUNT
    );
    // Raw big-endian pairs whatever the values.
    let mut buf = [0u8; 2 * TRIPS_BYTES];
    for t in [Trips::default(), Trips([u16::MAX; FaultCode::COUNT])] {
        let b = postcard::to_slice(&t, &mut buf).expect("fits");
        assert_eq!(b.len(), TRIPS_BYTES);
    }
    let mut t = Trips::default();
    t.0[0] = 0x0102;
    let b = postcard::to_slice(&t, &mut buf).expect("fits");
    assert_eq!(&b[..3], &[1, 2, 0]);
    assert_eq!(postcard::from_bytes::<Trips>(b), Ok(t));
    assert!(postcard::from_bytes::<Trips>(&b[..TRIPS_BYTES - 1]).is_err());
}
