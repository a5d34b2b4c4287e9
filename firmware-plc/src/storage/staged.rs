//! A program written into a slot over the service port, staged in the payload area of
//! the copy a load does not use (the "spare" copy) and sealed there by a
//! [`super::Job::Commit`].
//!
//! The service writes the chunks straight into the spare copy's payload area (copy bytes
//! 16 onwards, [`payload_addr`]); the spare copy's header is left alone, so until the
//! commit the copy fails its CRC (or still holds its old, older program) and a load uses
//! the other copy: the slot's previous program. The commit reads the staged bytes back
//! twice, one page per step (`StagedCheck`): first for the CRC-32C the PC announced,
//! the layout of the runs and the whole-program verification (`program.md`, as RUN does);
//! then for the copy's own CRC-32 with the header that follows from the first pass. Only
//! then is the header written, after which the copy is the slot's newest, and the save
//! goes on as a keypad save does (read back, then the other copy; see `job`).
//!
//! No RAM holds the program meanwhile: the PLC has no room for a second 4 KiB payload
//! beside the program in RAM (`docs/eeprom-image.md`).

use shared_protocol::crc32::Digest;
use shared_protocol::link::frame::CRC as C32;
use shared_protocol::link::message::verify_kind_code;
use shared_protocol::program::ProgramVerifier;
use shared_protocol::service::{InvalidReason, WriteResult};

use super::eeprom::{Eeprom, EepromError, PAGE_BYTES};
use super::layout::COPY_HEADER_BYTES;
use super::slot::{CopyHeader, CRC32};
use shared_protocol::program::payload::PayloadParser;

/// EEPROM address of payload byte `offset` of the copy at `copy_addr`.
pub fn payload_addr(copy_addr: u16, offset: u16) -> Option<u16> {
    copy_addr
        .checked_add(COPY_HEADER_BYTES as u16)?
        .checked_add(offset)
}

/// Reading a staged payload back: the two passes of a commit.
#[derive(Clone)]
pub(crate) struct StagedCheck {
    copy_addr: u16,
    len: u16,
    /// Payload bytes read in this pass.
    pos: u16,
    pass: Pass,
}

#[derive(Clone)]
enum Pass {
    /// CRC-32C, layout, decoding and verification.
    Check {
        crc: shared_protocol::crc32::CastagnoliDigest,
        parser: PayloadParser,
        verifier: ProgramVerifier,
        /// The first line the verifier refused, and its reason code.
        refused: Option<(u16, u8)>,
    },
    /// The copy's CRC-32 (ISO-HDLC) over the header that will be written and the
    /// payload.
    Seal {
        header: CopyHeader,
        digest: Digest<16>,
    },
}

/// What a [`StagedCheck::step`] found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Checked {
    /// More pages to read.
    More,
    /// The staged bytes are not the program the PC announced, or not a valid one.
    Refused(WriteResult),
    /// Both passes done: write this header at the copy's start to make it valid.
    Header(CopyHeader),
}

impl StagedCheck {
    /// The check of `len` staged bytes in the copy at `copy_addr`.
    pub(crate) fn new(copy_addr: u16, len: u16) -> Self {
        StagedCheck {
            copy_addr,
            len,
            pos: 0,
            pass: Pass::Check {
                crc: C32.digest(),
                parser: PayloadParser::new(),
                verifier: ProgramVerifier::new(),
                refused: None,
            },
        }
    }

    /// Reads the next piece (up to the end of its EEPROM page) and takes it in; `crc` is
    /// the CRC-32C the PC announced, `slot` and `generation` go into the header.
    pub(crate) fn step<E: Eeprom>(
        &mut self,
        e: &mut E,
        slot: u8,
        generation: u32,
        crc: u32,
    ) -> Result<Checked, EepromError> {
        let mut buf = [0u8; PAGE_BYTES];
        if self.pos < self.len {
            let addr = payload_addr(self.copy_addr, self.pos).ok_or(EepromError::OutOfRange)?;
            let to_page_end = PAGE_BYTES - usize::from(addr) % PAGE_BYTES;
            let n = to_page_end.min(usize::from(self.len - self.pos));
            let chunk = buf.get_mut(..n).ok_or(EepromError::OutOfRange)?;
            e.read(addr, chunk)?;
            self.pos += n as u16;
            match &mut self.pass {
                Pass::Check {
                    crc,
                    parser,
                    verifier,
                    refused,
                } => {
                    crc.update(chunk);
                    for &b in chunk.iter() {
                        parser.feed(b, |line, i| {
                            if refused.is_none() {
                                if let Err(err) = verifier.line(line, &i) {
                                    *refused = Some((err.line, verify_kind_code(&err.kind)));
                                }
                            }
                        });
                    }
                }
                Pass::Seal { digest, .. } => digest.update(chunk),
            }
            if self.pos < self.len {
                return Ok(Checked::More);
            }
        }
        // The pass is over.
        match core::mem::replace(
            &mut self.pass,
            Pass::Seal {
                header: CopyHeader {
                    slot,
                    generation,
                    payload_len: self.len,
                    lines: 0,
                    crc: 0,
                },
                digest: CRC32.digest(),
            },
        ) {
            Pass::Check {
                crc: got,
                parser,
                refused,
                ..
            } => {
                if got.finalize() != crc {
                    return Ok(Checked::Refused(WriteResult::Crc));
                }
                if let Some((line, undecodable)) = parser.failure() {
                    let reason = if undecodable {
                        InvalidReason::Decode
                    } else {
                        InvalidReason::Layout
                    };
                    return Ok(Checked::Refused(WriteResult::Invalid { line, reason }));
                }
                if !parser.finished_ok(parser.lines()) {
                    // Bytes left over after the last whole run.
                    let line = parser.at_line();
                    return Ok(Checked::Refused(WriteResult::Invalid {
                        line,
                        reason: InvalidReason::Layout,
                    }));
                }
                if let Some((line, code)) = refused {
                    return Ok(Checked::Refused(WriteResult::Invalid {
                        line,
                        reason: InvalidReason::Verify(code),
                    }));
                }
                let header = CopyHeader {
                    slot,
                    generation,
                    payload_len: self.len,
                    lines: parser.lines(),
                    crc: 0,
                };
                let mut digest = CRC32.digest();
                digest.update(header.to_bytes().get(..12).unwrap_or(&[]));
                self.pass = Pass::Seal { header, digest };
                self.pos = 0;
                Ok(Checked::More)
            }
            Pass::Seal { mut header, digest } => {
                header.crc = digest.finalize();
                Ok(Checked::Header(header))
            }
        }
    }
}
