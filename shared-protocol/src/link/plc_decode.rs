//! The drive's decoder of [`Frame<PlcMsg>`], written out: the same bytes postcard's serde
//! decoder accepts, decoded to the same value, and every other input refused.
//!
//! Why by hand: on the drive the generic postcard/serde decoder of `PlcMsg` was ~2 KiB of the
//! link task (the serde visitors of eleven variants and two `heapless::Vec`s, each call
//! through postcard's flavor), for a message set of a few fixed layouts; this is a few
//! hundred bytes (docs/size.md, "Drive image: board side"). The wire format does not
//! change: the PLC still encodes with postcard, and the tests below check this decoder against
//! `postcard::take_from_bytes` on every message shape and on arbitrary and damaged bytes.
//!
//! Postcard's rules, as its deserializer (1.1) applies them: `u8` one raw byte; `bool` one
//! byte, 0 or 1; `u16`/`u32`/`usize` an LEB128 varint of at most 3/5/(5 or 10) bytes whose
//! last byte has no bits above the type's width (non-minimal encodings are accepted); `i16`
//! zigzag on the `u16` varint; an enum's variant index a `u32` varint; a sequence its
//! `usize` length then the elements (a `heapless::Vec` longer than its capacity is
//! refused); structs their fields in order. The whole body must be consumed.

use super::frame::Frame;
use super::message::{PlcMsg, QValue, CHUNK_BYTES, MAX_Q_PER_FRAME};

/// Reads the body of one frame.
struct Reader<'a> {
    rest: &'a [u8],
}

impl Reader<'_> {
    fn u8(&mut self) -> Option<u8> {
        let (&b, rest) = self.rest.split_first()?;
        self.rest = rest;
        Some(b)
    }

    fn bool(&mut self) -> Option<bool> {
        match self.u8()? {
            0 => Some(false),
            1 => Some(true),
            _ => None,
        }
    }

    /// A varint of a `bits`-wide unsigned type (postcard's `try_take_varint_*`). Out of
    /// line: one copy for every width and field (docs/size.md).
    #[inline(never)]
    fn varint(&mut self, bits: u32) -> Option<u64> {
        let max_bytes = bits.div_ceil(7);
        let last_max = (1u8 << (bits % 7)).wrapping_sub(1);
        let mut out = 0u64;
        for i in 0..max_bytes {
            let b = self.u8()?;
            out |= u64::from(b & 0x7F) << (7 * i);
            if b & 0x80 == 0 {
                return (i + 1 < max_bytes || b <= last_max).then_some(out);
            }
        }
        None
    }

    fn u16(&mut self) -> Option<u16> {
        self.varint(16).and_then(|v| u16::try_from(v).ok())
    }

    fn u32(&mut self) -> Option<u32> {
        self.varint(32).and_then(|v| u32::try_from(v).ok())
    }

    fn i16(&mut self) -> Option<i16> {
        let n = self.u16()?;
        Some(((n >> 1) as i16) ^ -((n & 1) as i16))
    }

    /// A sequence's length, refused above `capacity` (the `heapless::Vec` would be).
    fn len(&mut self, capacity: usize) -> Option<usize> {
        let n = self.varint(usize::BITS)?;
        usize::try_from(n).ok().filter(|&n| n <= capacity)
    }

    fn msg(&mut self) -> Option<PlcMsg> {
        Some(match self.u32()? {
            0 => PlcMsg::Hello {
                version: self.u16()?,
                session: self.u8()?,
            },
            1 => PlcMsg::Heartbeat,
            2 => {
                let mut writes = heapless::Vec::<QValue, MAX_Q_PER_FRAME>::new();
                for _ in 0..self.len(MAX_Q_PER_FRAME)? {
                    let q = QValue {
                        addr: self.u8()?,
                        value: self.i16()?,
                    };
                    writes.push(q).ok()?;
                }
                PlcMsg::QWrite(writes)
            }
            3 => PlcMsg::Run,
            4 => PlcMsg::Stop,
            5 => PlcMsg::Direction {
                reverse: self.bool()?,
            },
            6 => PlcMsg::AckFault,
            7 => PlcMsg::DownloadBegin { crc: self.u32()? },
            8 => {
                let first_line = self.u8()?;
                let n = self.len(CHUNK_BYTES)?;
                let bytes = self.rest.get(..n)?;
                self.rest = self.rest.get(n..)?;
                let mut data = heapless::Vec::new();
                data.extend_from_slice(bytes).ok()?;
                PlcMsg::DownloadChunk { first_line, data }
            }
            9 => PlcMsg::DownloadEnd,
            10 => PlcMsg::SafetyRequest {
                requested: self.u16()?,
            },
            _ => return None,
        })
    }
}

/// The frame whose body (header and message, without the CRC) is `body`, or `None` where
/// postcard's decoder would fail or leave bytes over.
pub fn plc_frame(body: &[u8]) -> Option<Frame<PlcMsg>> {
    let mut r = Reader { rest: body };
    let seq = r.u8()?;
    let ack = r.u8()?;
    let msg = r.msg()?;
    r.rest.is_empty().then_some(Frame { seq, ack, msg })
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::collection::vec;
    use proptest::prelude::*;

    /// What postcard's serde decoder makes of `body` (the frame decoder's rule: all of it).
    fn postcard(body: &[u8]) -> Option<Frame<PlcMsg>> {
        match postcard::take_from_bytes::<Frame<PlcMsg>>(body) {
            Ok((f, [])) => Some(f),
            _ => None,
        }
    }

    fn any_msg() -> impl Strategy<Value = PlcMsg> {
        prop_oneof![
            (any::<u16>(), any::<u8>())
                .prop_map(|(version, session)| PlcMsg::Hello { version, session }),
            Just(PlcMsg::Heartbeat),
            vec((any::<u8>(), any::<i16>()), 0..=MAX_Q_PER_FRAME).prop_map(|qs| {
                PlcMsg::QWrite(
                    qs.into_iter()
                        .map(|(addr, value)| QValue { addr, value })
                        .collect(),
                )
            }),
            Just(PlcMsg::Run),
            Just(PlcMsg::Stop),
            any::<bool>().prop_map(|reverse| PlcMsg::Direction { reverse }),
            Just(PlcMsg::AckFault),
            any::<u32>().prop_map(|crc| PlcMsg::DownloadBegin { crc }),
            (any::<u8>(), vec(any::<u8>(), 0..=CHUNK_BYTES)).prop_map(|(first_line, d)| {
                PlcMsg::DownloadChunk {
                    first_line,
                    data: heapless::Vec::from_slice(&d).unwrap_or_default(),
                }
            }),
            Just(PlcMsg::DownloadEnd),
            any::<u16>().prop_map(|requested| PlcMsg::SafetyRequest { requested }),
        ]
    }

    fn encode(seq: u8, ack: u8, msg: PlcMsg) -> std::vec::Vec<u8> {
        let mut buf = [0u8; 128];
        let n = postcard::to_slice(&Frame { seq, ack, msg }, &mut buf)
            .expect("encodes")
            .len();
        buf[..n].to_vec()
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(4000))]

        #[test]
        fn every_message_decodes_as_postcard_does(seq: u8, ack: u8, msg in any_msg()) {
            let body = encode(seq, ack, msg.clone());
            prop_assert_eq!(plc_frame(&body), Some(Frame { seq, ack, msg }));
        }

        #[test]
        fn damaged_messages_decode_as_postcard_does(
            seq: u8,
            ack: u8,
            msg in any_msg(),
            at: prop::sample::Index,
            byte: u8,
            cut: prop::sample::Index,
            extra in vec(any::<u8>(), 0..3),
        ) {
            let mut body = encode(seq, ack, msg);
            let i = at.index(body.len());
            body[i] = byte;
            body.truncate(cut.index(body.len() + 1).max(i));
            body.extend_from_slice(&extra);
            prop_assert_eq!(plc_frame(&body), postcard(&body));
        }

        #[test]
        fn arbitrary_bytes_decode_as_postcard_does(body in vec(any::<u8>(), 0..24)) {
            prop_assert_eq!(plc_frame(&body), postcard(&body));
        }

        #[test]
        fn small_variant_bodies_decode_as_postcard_does(
            variant in 0u8..13,
            rest in vec(prop_oneof![Just(0u8), Just(1), Just(2), Just(0x7f), Just(0x80), Just(0xff), any::<u8>()], 0..12),
        ) {
            let mut body = std::vec![1, 2, variant];
            body.extend_from_slice(&rest);
            prop_assert_eq!(plc_frame(&body), postcard(&body));
        }
    }

    /// Varints at the edges of their types: the longest accepted encodings, one bit over,
    /// and non-minimal zeros.
    #[test]
    fn varint_edges_decode_as_postcard_does() {
        let cases: &[&[u8]] = &[
            // Hello with version 0xFFFF (3 bytes, last byte 3) and one over (last byte 4).
            &[0, 0, 0, 0xff, 0xff, 0x03, 9],
            &[0, 0, 0, 0xff, 0xff, 0x04, 9],
            &[0, 0, 0, 0x80, 0x80, 0x00, 9],
            &[0, 0, 0, 0x80, 0x80, 0x80, 0x00, 9],
            // DownloadBegin with crc u32::MAX (5 bytes, last 15) and one over.
            &[0, 0, 7, 0xff, 0xff, 0xff, 0xff, 0x0f],
            &[0, 0, 7, 0xff, 0xff, 0xff, 0xff, 0x10],
            // A variant index written in 5 bytes, and one in 6.
            &[0, 0, 0x83, 0x80, 0x80, 0x80, 0x00],
            &[0, 0, 0x83, 0x80, 0x80, 0x80, 0x80, 0x00],
            // QWrite with 8 and with 9 entries; a chunk of 64 and of 65 bytes announced.
            &[0, 0, 2, 8, 1, 2, 1, 2, 1, 2, 1, 2, 1, 2, 1, 2, 1, 2, 1, 2],
            &[
                0, 0, 2, 9, 1, 2, 1, 2, 1, 2, 1, 2, 1, 2, 1, 2, 1, 2, 1, 2, 1, 2,
            ],
            &[0, 0, 8, 3, 0x41],
            &[
                0, 0, 8, 3, 0x80, 0x80, 0x80, 0x80, 0x80, 0x80, 0x80, 0x80, 0x80, 0x00,
            ],
            // Direction with a bool of 2.
            &[0, 0, 5, 2],
        ];
        for body in cases {
            assert_eq!(plc_frame(body), postcard(body), "{body:02x?}");
        }
        let mut chunk = std::vec![0, 0, 8, 3, 64];
        chunk.extend_from_slice(&[0x55; 64]);
        assert!(plc_frame(&chunk).is_some());
        assert_eq!(plc_frame(&chunk), postcard(&chunk));
        chunk[4] = 65;
        chunk.push(0x55);
        assert_eq!(plc_frame(&chunk), None);
        assert_eq!(plc_frame(&chunk), postcard(&chunk));
    }
}
