//! What the fuzz targets share: the wire form of a frame whose body the fuzzer chose (the
//! CRC and COBS are computed here, so the fuzzer's bytes reach the decoders behind them).
//! The targets and what each asserts: docs/fuzzing.md.

use shared_protocol::link::frame::{CRC, MAX_RAW_FRAME};

/// `body` (header and message) as it travels: CRC-32C appended, COBS-encoded, between two
/// delimiters. `None` when the body does not fit a frame.
pub fn wire_frame(body: &[u8]) -> Option<Vec<u8>> {
    if body.len() + 4 > MAX_RAW_FRAME {
        return None;
    }
    let mut raw = body.to_vec();
    raw.extend_from_slice(&CRC.checksum(body).to_le_bytes());
    let mut out = vec![0u8; raw.len() + raw.len() / 254 + 4];
    let n = cobs::encode(&raw, &mut out[1..]);
    out.truncate(n + 2);
    out[0] = 0;
    out[n + 1] = 0;
    Some(out)
}
