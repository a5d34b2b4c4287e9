//! The service port: one frame body as a request and as an answer, and the PLC's service
//! port fed records of `[kind, len, bytes...]` (bit 0 of `kind`: raw bytes or the body of a
//! valid wire frame; bits 1-7: milliseconds that pass first), answering over a fresh PLC
//! application with an erased EEPROM.
//!
//! Asserts: no panic; a body that decodes re-encodes to one that decodes to the same
//! message, and that encoding is a fixed point; the service reader gives the same message
//! from the whole wire frame; every answer the PLC sends decodes as an `Answer`.
#![no_main]

use firmware_plc::app::{BuildInfo, PlcApp};
use firmware_plc::service::Service;
use firmware_plc::storage::MemEeprom;
use fuzz::wire_frame;
use libfuzzer_sys::fuzz_target;
use shared_protocol::link::frame::{decode_body, Frame, MAX_RAW_FRAME, MAX_WIRE_FRAME};
use shared_protocol::link::{wire, LinkConfig};
use shared_protocol::service::{Answer, Request, ServiceReader};
use shared_protocol::units::Micros;

fn message<M>(body: &[u8])
where
    M: serde::Serialize + serde::de::DeserializeOwned + PartialEq + core::fmt::Debug,
{
    let decoded: Option<Frame<M>> = decode_body(body);
    if let Some(f) = &decoded {
        let mut out = [0u8; MAX_RAW_FRAME];
        let n = wire::to_slice(f, &mut out).expect("a decoded frame fits its buffer");
        let again: Frame<M> = decode_body(&out[..n]).expect("a re-encoded frame decodes");
        assert_eq!(&again, f);
        let mut out2 = [0u8; MAX_RAW_FRAME];
        let n2 = wire::to_slice(&again, &mut out2).expect("fits");
        assert_eq!(&out[..n], &out2[..n2], "encoding is not a fixed point");
    }
    let Some(w) = wire_frame(body) else { return };
    let mut reader = ServiceReader::new();
    let mut got = None;
    for &b in &w {
        if let Some(r) = reader.push::<M>(b) {
            got = Some(r);
        }
    }
    match (got.expect("a delimited frame gives a result"), decoded) {
        (Ok((id, m)), Some(f)) => {
            assert_eq!(f.ack, 0);
            assert_eq!((id, m), (f.seq, f.msg));
        }
        (Err(_), None) => {}
        (Err(_), Some(f)) => assert_ne!(f.ack, 0, "the reader refused a service frame"),
        (Ok(g), None) => panic!("the reader gave {g:?}, the body decoder nothing"),
    }
}

fuzz_target!(|data: &[u8]| {
    message::<Request>(data);
    message::<Answer>(data);

    let mut app = PlcApp::new(MemEeprom::new(), LinkConfig::default(), 20, 4, Micros(0));
    let mut service = Service::new(BuildInfo {
        firmware: "fuzz",
        git: "0",
        uid: [0; 12],
    });
    let mut out = [0u8; MAX_WIRE_FRAME];
    let mut answers = ServiceReader::new();
    let mut now = 0u64;
    let mut rest = data;
    while let [kind, len, tail @ ..] = rest {
        let n = usize::from(*len).min(tail.len());
        let (bytes, next) = tail.split_at(n);
        rest = next;
        now += u64::from(kind >> 1) * 1000;
        let framed;
        let stream: &[u8] = match (kind & 1 == 1).then(|| wire_frame(bytes)).flatten() {
            Some(w) => {
                framed = w;
                &framed
            }
            None => bytes,
        };
        service.on_rx(stream, Micros(now));
        for _ in 0..8 {
            for _ in 0..64 {
                if !service.eeprom_step(&mut app) {
                    break;
                }
            }
            let n = service.poll_tx(&mut app, Micros(now), &mut out);
            if n == 0 {
                break;
            }
            assert!(n <= out.len());
            for &b in &out[..n] {
                if let Some(r) = answers.push::<Answer>(b) {
                    assert!(
                        r.is_ok(),
                        "the PLC sent an answer that does not decode: {r:?}"
                    );
                }
            }
        }
    }
});
