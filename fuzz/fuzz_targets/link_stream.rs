//! The link state machines of both MCUs fed a byte stream from the other side: records of
//! `[kind, len, bytes...]`, where `kind` bit 0 says whether `bytes` go out raw (garbage,
//! torn frames) or as the body of a valid wire frame (CRC and COBS computed here, so the
//! sessions, acknowledgements and downloads behind the CRC are reached), and bits 1-7 the
//! milliseconds that pass before them.
//!
//! Asserts: no panic in `receive`, `tick`, `poll_event` or `poll_transmit`; what the drive
//! accepts as a program verifies (`take_program` hands out only verified sections); every
//! transmitted frame fits the buffer and decodes as the sender's message type.
#![no_main]

use fuzz::wire_frame;
use libfuzzer_sys::fuzz_target;
use shared_protocol::link::frame::{FrameReader, MAX_WIRE_FRAME};
use shared_protocol::link::{DriveLink, DriveMsg, LinkConfig, PlcLink, PlcMsg};
use shared_protocol::program::verify_drive;
use shared_protocol::units::Micros;

fuzz_target!(|data: &[u8]| {
    let mut drive = DriveLink::new(LinkConfig::default());
    let mut plc = PlcLink::new(LinkConfig::default());
    let mut now = 0u64;
    let mut rest = data;
    let mut out = [0u8; MAX_WIRE_FRAME];
    let mut from_drive = FrameReader::new();
    let mut from_plc = FrameReader::new();
    while let [kind, len, tail @ ..] = rest {
        let n = usize::from(*len).min(tail.len());
        let (bytes, next) = tail.split_at(n);
        rest = next;
        now += u64::from(kind >> 1) * 1000;
        let framed;
        let stream: &[u8] = if kind & 1 == 1 {
            match wire_frame(bytes) {
                Some(w) => {
                    framed = w;
                    &framed
                }
                None => bytes,
            }
        } else {
            bytes
        };
        drive.receive(stream, Micros(now));
        plc.receive(stream, Micros(now));
        drive.tick(Micros(now));
        plc.tick(Micros(now));
        while drive.poll_event().is_some() {}
        while plc.poll_event().is_some() {}
        if let Some(section) = drive.take_program() {
            assert!(
                verify_drive(section.section()).is_ok(),
                "drive took an unverified section"
            );
        }
        for _ in 0..16 {
            let n = drive.poll_transmit(Micros(now), &mut out);
            if n == 0 {
                break;
            }
            assert!(n <= out.len());
            for &b in &out[..n] {
                if let Some(r) = from_drive.push::<DriveMsg>(b) {
                    assert!(
                        r.is_ok(),
                        "the drive sent a frame that does not decode: {r:?}"
                    );
                }
            }
        }
        for _ in 0..16 {
            let n = plc.poll_transmit(Micros(now), &mut out);
            if n == 0 {
                break;
            }
            assert!(n <= out.len());
            for &b in &out[..n] {
                if let Some(r) = from_plc.push::<PlcMsg>(b) {
                    assert!(
                        r.is_ok(),
                        "the PLC sent a frame that does not decode: {r:?}"
                    );
                }
            }
        }
    }
});
