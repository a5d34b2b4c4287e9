//! One link frame body (header and message, before the CRC), both directions.
//!
//! Asserts: no decoder panics; the drive's written-out decoder of the PLC's frames
//! (`plc_decode::plc_frame`) agrees with the postcard-format decoder on every body; a body
//! that decodes re-encodes to a body that decodes to the same frame, and that re-encoding is
//! a fixed point (postcard's varints are not canonical: `80 00` also reads as 0); the same
//! body sent as a whole wire frame (CRC, COBS, delimiters) comes out of the frame reader as
//! the same frame.
#![no_main]

use fuzz::wire_frame;
use libfuzzer_sys::fuzz_target;
use shared_protocol::link::frame::{decode_body, Frame, FrameReader, MAX_RAW_FRAME};
use shared_protocol::link::{plc_decode, wire, DriveMsg, PlcMsg};

/// A decoded frame re-encoded: the bytes, which must decode to the same frame and encode
/// to themselves again.
fn reencodes<M>(frame: &Frame<M>)
where
    M: serde::Serialize + serde::de::DeserializeOwned + PartialEq + core::fmt::Debug,
{
    let mut out = [0u8; MAX_RAW_FRAME];
    let n = wire::to_slice(frame, &mut out).expect("a decoded frame fits its buffer");
    let again: Frame<M> = decode_body(&out[..n]).expect("a re-encoded frame decodes");
    assert_eq!(&again, frame, "decode(encode(frame)) != frame");
    let mut out2 = [0u8; MAX_RAW_FRAME];
    let n2 = wire::to_slice(&again, &mut out2).expect("fits");
    assert_eq!(&out[..n], &out2[..n2], "encoding is not a fixed point");
}

fn through_reader<M>(
    body: &[u8],
    expected: &Option<Frame<M>>,
    decode: fn(&[u8]) -> Option<Frame<M>>,
) where
    M: PartialEq + core::fmt::Debug,
{
    let Some(wire) = wire_frame(body) else { return };
    let mut reader = FrameReader::new();
    let mut got = None;
    for &b in &wire {
        if let Some(r) = reader.push_with(b, decode) {
            assert!(got.is_none(), "one frame gave two results");
            got = Some(r);
        }
    }
    let got = got.expect("a delimited frame gives a result");
    match (got, expected) {
        (Ok(f), Some(e)) => assert_eq!(&f, e),
        (Err(_), None) => {}
        (g, e) => panic!("frame reader {g:?}, body decoder {e:?}"),
    }
}

fuzz_target!(|body: &[u8]| {
    let postcard: Option<Frame<PlcMsg>> = decode_body(body);
    let written_out = plc_decode::plc_frame(body);
    assert_eq!(
        postcard, written_out,
        "plc_frame differs from the postcard decoder"
    );
    if let Some(f) = &postcard {
        reencodes(f);
    }
    through_reader(body, &written_out, plc_decode::plc_frame);

    let status: Option<Frame<DriveMsg>> = decode_body(body);
    if let Some(f) = &status {
        reencodes(f);
    }
    through_reader(body, &status, decode_body::<DriveMsg>);
});
