//! Fuzzing both decoders with proptest: any byte sequence gives a frame or an error value,
//! never a panic; memory is bounded by construction (fixed buffers) and time by the input
//! length. Random bytes almost never pass the CRC, so the message parser is also fed
//! random bodies with a correct CRC appended.
//!
//! Debug builds run a few thousand cases per property; `cargo test --release` runs
//! 1 000 000 per property (3 million in total, both decoders and both endpoints).

use proptest::prelude::*;
use shared_protocol::link::channel::Impairments;
use shared_protocol::link::frame::{decode_raw, FrameReader, CRC, MAX_WIRE_FRAME};
use shared_protocol::link::pair::LinkPair;
use shared_protocol::link::{DriveLink, DriveMsg, LinkConfig, PlcLink, PlcMsg};
use shared_protocol::units::Micros;

fn cases() -> u32 {
    if cfg!(debug_assertions) {
        3_000
    } else {
        1_000_000
    }
}

fn with_crc(body: &[u8]) -> Vec<u8> {
    let mut v = body.to_vec();
    v.extend_from_slice(&CRC.checksum(body).to_le_bytes());
    v
}

/// COBS-encode and delimit `raw` as a sender would.
fn wire(raw: &[u8]) -> Vec<u8> {
    let mut out = vec![0u8; raw.len() + raw.len() / 254 + 2];
    let n = cobs::encode(raw, &mut out);
    out.truncate(n);
    out.push(0);
    out
}

proptest! {
    #![proptest_config(ProptestConfig { cases: cases(), failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn reader_never_panics_on_random_bytes(bytes in proptest::collection::vec(any::<u8>(), 0..400)) {
        let mut a = FrameReader::new();
        let mut b = FrameReader::new();
        for &x in &bytes {
            let _ = a.push::<PlcMsg>(x);
            let _ = b.push::<DriveMsg>(x);
        }
    }

    #[test]
    fn parser_never_panics_on_bodies_with_valid_crc(body in proptest::collection::vec(any::<u8>(), 0..100)) {
        let raw = with_crc(&body);
        let p = decode_raw::<PlcMsg>(&raw);
        let d = decode_raw::<DriveMsg>(&raw);
        // Through the whole reader too, in case COBS adds a path.
        let mut r = FrameReader::new();
        let mut last = None;
        for &x in &wire(&raw) {
            if let Some(res) = r.push::<PlcMsg>(x) {
                last = Some(res);
            }
        }
        if raw.len() + 2 <= MAX_WIRE_FRAME {
            prop_assert_eq!(last, Some(p));
        }
        let _ = d;
    }

    #[test]
    fn endpoints_never_panic_on_random_bytes(
        bytes in proptest::collection::vec(any::<u8>(), 0..300),
        body in proptest::collection::vec(any::<u8>(), 3..90),
    ) {
        let cfg = LinkConfig::default();
        let mut plc = PlcLink::new(cfg);
        let mut drive = DriveLink::new(cfg);
        let frame = wire(&with_crc(&body));
        plc.receive(&bytes, Micros(1));
        drive.receive(&bytes, Micros(1));
        plc.receive(&frame, Micros(2));
        drive.receive(&frame, Micros(2));
        let mut out = [0u8; MAX_WIRE_FRAME];
        let _ = plc.poll_transmit(Micros(3), &mut out);
        let _ = drive.poll_transmit(Micros(3), &mut out);
        while plc.poll_event().is_some() {}
        while drive.poll_event().is_some() {}
    }
}

/// Random frames with valid CRCs injected into connected endpoints (so the message
/// handlers, not only the parser, see arbitrary content).
#[test]
fn connected_endpoints_survive_valid_crc_garbage() {
    let n = if cfg!(debug_assertions) {
        2_000
    } else {
        200_000
    };
    let mut p = LinkPair::new(LinkConfig::default(), Impairments::default(), 3);
    p.run_until(Micros(20_000), |_| {});
    assert!(p.plc.is_up() && p.drive.is_up());
    let mut x: u64 = 0x2545_F491;
    let mut accepted = 0;
    for k in 0..n {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        let len = 3 + (x % 60) as usize;
        // Structured start (seq, ack, message type) so that parsing often succeeds.
        let body: Vec<u8> = (0..len)
            .map(|i| (x.rotate_left(i as u32 * 7) >> (i % 8)) as u8 % if i == 2 { 12 } else { 255 })
            .collect();
        let f = wire(&with_crc(&body));
        if decode_raw::<PlcMsg>(&with_crc(&body)).is_ok() {
            accepted += 1;
        }
        let now = Micros(p.now.0 + 1);
        p.now = now;
        if k % 2 == 0 {
            p.drive.receive(&f, now);
        } else {
            p.plc.receive(&f, now);
        }
        p.kick();
        while p.plc.poll_event().is_some() {}
        while p.drive.poll_event().is_some() {}
    }
    assert!(accepted > n / 100, "the parser was exercised: {accepted}");
}
