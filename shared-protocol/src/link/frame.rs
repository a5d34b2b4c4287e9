//! Frame layout, CRC and COBS framing (see `docs/link.md` in this crate).
//!
//! ```text
//! wire:  [0x00]? COBS( seq | ack | postcard(msg) | crc32c_le ) 0x00
//! ```
//!
//! The optional leading delimiter is sent before handshake frames only, so that a receiver
//! that saw a cut mid-frame never glues the garbage to the handshake.

use serde::{de::DeserializeOwned, Deserialize, Serialize};

/// CRC-32C (Castagnoli): Hamming distance 6 up to 5243 data bits, so every frame of this
/// protocol (< 800 bits) with up to 5 flipped bits is caught, and random garbage passes
/// with probability 2^-32. CRC-32 (ISO-HDLC) only gives HD 5 at these lengths.
/// One 1 KiB table in an image, whoever uses it (the service payload's CRC is the same
/// CRC-32C): [`crate::crc32::CASTAGNOLI`].
pub use crate::crc32::CASTAGNOLI as CRC;

/// Largest frame before COBS: header, message, CRC.
pub const MAX_RAW_FRAME: usize = 96;
/// Largest frame on the wire: COBS overhead plus the leading and trailing delimiter.
/// A `poll_transmit` buffer of this size always fits the next frame.
pub const MAX_WIRE_FRAME: usize = cobs::max_encoding_length(MAX_RAW_FRAME) + 2;

const CRC_BYTES: usize = 4;
const HEADER_BYTES: usize = 2;

/// A decoded frame. `seq` matters only for reliable messages; `ack` is the next sequence
/// number the sender of this frame expects (all below it were received).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Frame<M> {
    // One copy of the byte reads for every frame type (flash, `message::one_copy`).
    #[serde(deserialize_with = "super::message::one_copy::de_u8")]
    pub seq: u8,
    #[serde(deserialize_with = "super::message::one_copy::de_u8")]
    pub ack: u8,
    pub msg: M,
}

/// Why bytes did not make a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FrameError {
    /// More bytes than [`MAX_WIRE_FRAME`] before a delimiter.
    TooLong,
    /// The COBS code bytes are inconsistent.
    Cobs,
    /// Shorter than header + CRC.
    TooShort,
    /// The CRC does not match: corrupted.
    Crc,
    /// CRC fine but the message does not parse (other protocol version or a bug).
    Message,
    /// The output buffer is too small (encoding only).
    BufferTooSmall,
}

impl core::fmt::Display for FrameError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            FrameError::TooLong => "frame longer than the wire limit",
            FrameError::Cobs => "inconsistent COBS code bytes",
            FrameError::TooShort => "frame shorter than header and CRC",
            FrameError::Crc => "frame CRC mismatch",
            FrameError::Message => "the frame's message does not parse",
            FrameError::BufferTooSmall => "output buffer too small for the frame",
        })
    }
}

impl core::error::Error for FrameError {}

/// Encode one frame into `out`; returns the number of wire bytes.
pub fn encode_frame<M: Serialize>(
    frame: &Frame<M>,
    leading_delimiter: bool,
    out: &mut [u8],
) -> Result<usize, FrameError> {
    let mut raw = [0u8; MAX_RAW_FRAME];
    let body_len = super::wire::to_slice(frame, &mut raw[..MAX_RAW_FRAME - CRC_BYTES])
        .map_err(|_| FrameError::BufferTooSmall)?;
    let crc = CRC.checksum(raw.get(..body_len).unwrap_or(&[]));
    let raw_len = body_len + CRC_BYTES;
    raw.get_mut(body_len..raw_len)
        .ok_or(FrameError::BufferTooSmall)?
        .copy_from_slice(&crc.to_le_bytes());

    let start = usize::from(leading_delimiter);
    if leading_delimiter {
        *out.first_mut().ok_or(FrameError::BufferTooSmall)? = 0;
    }
    let dest = out.get_mut(start..).ok_or(FrameError::BufferTooSmall)?;
    let n = cobs::try_encode(raw.get(..raw_len).unwrap_or(&[]), dest)
        .map_err(|_| FrameError::BufferTooSmall)?;
    *out.get_mut(start + n).ok_or(FrameError::BufferTooSmall)? = 0;
    Ok(start + n + 1)
}

/// Decode the raw (already COBS-decoded) bytes of one frame.
pub fn decode_raw<M: DeserializeOwned>(raw: &[u8]) -> Result<Frame<M>, FrameError> {
    decode_raw_with(raw, decode_body::<M>)
}

/// [`decode_raw`] with the body decoder `body` (`None`: not a valid message).
pub fn decode_raw_with<M>(
    raw: &[u8],
    decode: impl FnOnce(&[u8]) -> Option<Frame<M>>,
) -> Result<Frame<M>, FrameError> {
    if raw.len() < HEADER_BYTES + 1 + CRC_BYTES {
        return Err(FrameError::TooShort);
    }
    let (body, crc) = raw.split_at(raw.len() - CRC_BYTES);
    let mut crc_bytes = [0u8; CRC_BYTES];
    crc_bytes.copy_from_slice(crc);
    if CRC.checksum(body) != u32::from_le_bytes(crc_bytes) {
        return Err(FrameError::Crc);
    }
    decode(body).ok_or(FrameError::Message)
}

/// A frame's body (header and message, without the CRC) by postcard's format ([`super::wire`]), `None`
/// unless it decodes and uses every byte: the body decoder of [`FrameReader::push`]
/// ([`FrameReader::push_with`] takes another one).
pub fn decode_body<M: DeserializeOwned>(body: &[u8]) -> Option<Frame<M>> {
    match super::wire::take_from_bytes::<Frame<M>>(body) {
        Ok((frame, [])) => Some(frame),
        _ => None,
    }
}

/// Cuts a received byte stream into frames. Holds at most [`MAX_WIRE_FRAME`] bytes;
/// each byte is handled in bounded time (a frame's decode happens at its delimiter).
#[derive(Debug, Clone)]
pub struct FrameReader {
    buf: heapless::Vec<u8, MAX_WIRE_FRAME>,
    overflow: bool,
}

impl Default for FrameReader {
    fn default() -> Self {
        Self::new()
    }
}

impl FrameReader {
    pub const fn new() -> Self {
        FrameReader {
            buf: heapless::Vec::new(),
            overflow: false,
        }
    }

    /// Forget a partial frame (e.g. after a UART framing error).
    pub fn reset(&mut self) {
        self.buf.clear();
        self.overflow = false;
    }

    /// Feed one byte; at a delimiter that ends a non-empty frame, returns its result.
    pub fn push<M: DeserializeOwned>(&mut self, byte: u8) -> Option<Result<Frame<M>, FrameError>> {
        self.push_with(byte, decode_body::<M>)
    }

    /// [`FrameReader::push`] with the body decoder `body` (the drive's written-out
    /// `plc_decode::plc_frame`).
    pub fn push_with<M>(
        &mut self,
        byte: u8,
        body: impl FnOnce(&[u8]) -> Option<Frame<M>>,
    ) -> Option<Result<Frame<M>, FrameError>> {
        if byte != 0 {
            if self.buf.push(byte).is_err() {
                self.overflow = true;
            }
            return None;
        }
        if self.overflow {
            self.reset();
            return Some(Err(FrameError::TooLong));
        }
        if self.buf.is_empty() {
            return None;
        }
        let result = match cobs::decode_in_place(&mut self.buf) {
            Ok(n) => decode_raw_with(self.buf.get(..n).unwrap_or(&[]), body),
            Err(_) => Err(FrameError::Cobs),
        };
        self.reset();
        Some(result)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::message::{DriveMsg, DriveStatus, PlcMsg, QValue};

    fn roundtrip<M: Serialize + DeserializeOwned + PartialEq + core::fmt::Debug + Clone>(
        msg: M,
    ) -> usize {
        let f = Frame {
            seq: 7,
            ack: 200,
            msg,
        };
        let mut out = [0u8; MAX_WIRE_FRAME];
        let n = encode_frame(&f, false, &mut out).unwrap();
        let mut r = FrameReader::new();
        let mut got = None;
        for &b in &out[..n] {
            if let Some(res) = r.push::<M>(b) {
                got = Some(res.unwrap());
            }
        }
        assert_eq!(got.unwrap(), f);
        n
    }

    #[test]
    fn frames_roundtrip_and_stay_small() {
        let mut w = heapless::Vec::new();
        w.push(QValue {
            addr: 63,
            value: -32768,
        })
        .unwrap();
        // The latency budget relies on a one-Q write being a dozen bytes on the wire.
        assert!(roundtrip(PlcMsg::QWrite(w)) <= 14);
        assert!(roundtrip(PlcMsg::Heartbeat) <= 10);
        let s = DriveStatus {
            freq_dhz: -500,
            udc_dv: 450,
            imax_ca: 999,
            com: 1023,
            oc_hw_ca: 999,
            ov_hw_v: 45,
            ..Default::default()
        };
        // The safety fields add 6 bytes at their idle values (protocol 4), `program_loaded`
        // one (protocol 5), `sf_turns` one (protocol 7).
        assert!(roundtrip(DriveMsg::Status(s)) <= 32);
        // With a warning and every safety field at its widest: the largest status. The
        // retransmission timeout's 160 byte times hold a largest PLC frame (99), this
        // status (50 with `sf_turns`, protocol 7) and an ack (9).
        let w = DriveStatus {
            warning: Some(crate::link::DriveWarning::PwfClamped {
                line: 149,
                requested: -32768,
                applied_hz: 20000,
            }),
            sf_requested: 0x0FFF,
            sf_status: 0x0FFF,
            sf_sdc: true,
            sf_elapsed_ds: 32767,
            sf_signature: 0xFFFF,
            sto_in_low: true,
            program_loaded: true,
            sf_turns: i16::MIN,
            ..s
        };
        let largest = roundtrip(DriveMsg::Status(w));
        assert!(largest <= 50, "{largest}");
        let data = heapless::Vec::from_slice(&[0xFF; 64]).unwrap();
        assert!(
            roundtrip(PlcMsg::DownloadChunk {
                first_line: 144,
                data
            }) <= MAX_WIRE_FRAME
        );
    }

    #[test]
    fn single_bit_flip_is_rejected() {
        let f = Frame {
            seq: 1,
            ack: 2,
            msg: PlcMsg::Run,
        };
        let mut raw = [0u8; MAX_RAW_FRAME];
        let body = postcard::to_slice(&f, &mut raw).unwrap().len();
        let crc = CRC.checksum(&raw[..body]);
        raw[body..body + 4].copy_from_slice(&crc.to_le_bytes());
        let len = body + 4;
        assert!(decode_raw::<PlcMsg>(&raw[..len]).is_ok());
        for bit in 0..len * 8 {
            let mut c = raw;
            c[bit / 8] ^= 1 << (bit % 8);
            assert!(decode_raw::<PlcMsg>(&c[..len]).is_err());
        }
    }

    #[test]
    fn reader_resynchronises_after_garbage_and_overflow() {
        let f = Frame {
            seq: 3,
            ack: 4,
            msg: PlcMsg::Stop,
        };
        let mut out = [0u8; MAX_WIRE_FRAME];
        let n = encode_frame(&f, false, &mut out).unwrap();
        let mut r = FrameReader::new();
        let mut results = Vec::new();
        let garbage = [0x55u8; 300];
        for &b in garbage
            .iter()
            .chain(&out[..n])
            .chain(&[1, 2, 3])
            .chain(&out[..n])
            .chain(&out[..n])
        {
            if let Some(x) = r.push::<PlcMsg>(b) {
                results.push(x);
            }
        }
        assert_eq!(results.len(), 3);
        assert_eq!(results[0], Err(FrameError::TooLong));
        assert!(results[1].is_err());
        assert_eq!(results[2], Ok(f));
    }
}
