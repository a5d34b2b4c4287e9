//! One copy of a stored program: header + sparse payload, streamed page by page.
//!
//! Streaming (never a whole-copy buffer) keeps the RAM cost at one page on the stack, so
//! the same code runs on the MCU and builds the off-board image in hil-sim. The work is
//! done by two steppers, `CopyReader` (check or load) and `CopyWriter`, which touch
//! at most one 64-byte page of the copy per call: the job queue (`storage::job`) calls
//! them once per pass of the application task; the synchronous functions below
//! ([`check_copy`], [`read_copy`], [`write_copy`]) run them to the end.
//!
//! Payload: the program's lines in the stored form of
//! [`shared_protocol::program::payload`] (which the service port transfers too). Header
//! (16 bytes): magic `"PG"`, format version, slot number, generation `u32`,
//! payload length `u16`, used-line count `u16`, CRC-32 (ISO-HDLC) over header bytes 0..12
//! and the payload — all big-endian.

use super::eeprom::{Eeprom, EepromError, PAGE_BYTES};
use super::layout::{COPY_HEADER_BYTES, PAYLOAD_MAX};
use shared_protocol::crc32::Digest;
use shared_protocol::program::payload::{
    for_each_payload_byte, payload_size, PayloadCursor, PayloadParser,
};
use shared_protocol::program::{Program, LINES};

/// CRC-32 (ISO-HDLC) of copies and boot records (shared-protocol's implementation, with a
/// 64-byte nibble table: storage steps are not time-critical).
pub(crate) use shared_protocol::crc32::ISO_HDLC as CRC32;
const MAGIC: [u8; 2] = *b"PG";
const VERSION: u8 = 1;

/// What a valid copy header says.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CopyHeader {
    pub slot: u8,
    pub generation: u32,
    pub payload_len: u16,
    pub lines: u16,
    pub crc: u32,
}

impl CopyHeader {
    pub(crate) fn to_bytes(self) -> [u8; COPY_HEADER_BYTES] {
        let mut h = [0u8; COPY_HEADER_BYTES];
        let g = self.generation.to_be_bytes();
        let l = self.payload_len.to_be_bytes();
        let n = self.lines.to_be_bytes();
        let c = self.crc.to_be_bytes();
        let fields: [u8; COPY_HEADER_BYTES] = [
            MAGIC[0], MAGIC[1], VERSION, self.slot, g[0], g[1], g[2], g[3], l[0], l[1], n[0], n[1],
            c[0], c[1], c[2], c[3],
        ];
        h.copy_from_slice(&fields);
        h
    }

    pub(crate) fn parse(h: &[u8; COPY_HEADER_BYTES]) -> Option<CopyHeader> {
        let [m0, m1, ver, slot, g0, g1, g2, g3, l0, l1, n0, n1, c0, c1, c2, c3] = *h;
        if [m0, m1] != MAGIC || ver != VERSION {
            return None;
        }
        let payload_len = u16::from_be_bytes([l0, l1]);
        let lines = u16::from_be_bytes([n0, n1]);
        if usize::from(payload_len) > PAYLOAD_MAX || usize::from(lines) > LINES {
            return None;
        }
        Some(CopyHeader {
            slot,
            generation: u32::from_be_bytes([g0, g1, g2, g3]),
            payload_len,
            lines,
            crc: u32::from_be_bytes([c0, c1, c2, c3]),
        })
    }
}

/// Why a copy is not a program.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum CopyError {
    /// Never written, or the header is damaged (erased EEPROM reads `FF`).
    NoHeader,
    /// The header belongs to another slot.
    WrongSlot,
    /// CRC mismatch: torn write or bit flips.
    Crc,
    /// CRC fine but the payload does not decode (written by a different format).
    Format,
    Eeprom(EepromError),
}

impl core::fmt::Display for CopyError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            CopyError::NoHeader => f.write_str("no program header (never written or damaged)"),
            CopyError::WrongSlot => f.write_str("the copy belongs to another slot"),
            CopyError::Crc => f.write_str("program copy CRC mismatch"),
            CopyError::Format => f.write_str("program payload does not decode"),
            CopyError::Eeprom(e) => write!(f, "{e}"),
        }
    }
}

impl core::error::Error for CopyError {}

impl From<EepromError> for CopyError {
    fn from(e: EepromError) -> Self {
        CopyError::Eeprom(e)
    }
}

/// Read the header of the copy at `addr` (no CRC check).
pub fn read_header<E: Eeprom>(e: &mut E, addr: u16) -> Result<CopyHeader, CopyError> {
    let mut h = [0u8; COPY_HEADER_BYTES];
    e.read(addr, &mut h)?;
    CopyHeader::parse(&h).ok_or(CopyError::NoHeader)
}

/// EEPROM address of byte `offset` of the copy at `addr`.
fn at(addr: u16, offset: usize) -> Result<u16, CopyError> {
    u16::try_from(usize::from(addr) + offset)
        .map_err(|_| CopyError::Eeprom(EepromError::OutOfRange))
}

/// Checks a copy (header, CRC, decodability), or loads it into a program, one page of
/// the copy per [`CopyReader::step`]. Page 0 holds the header and the first 48 payload
/// bytes, page k the copy's bytes 64k..64k+63, as [`CopyWriter`] writes them.
#[derive(Clone)]
pub(crate) struct CopyReader {
    addr: u16,
    slot: u8,
    /// The header, once page 0 has been read.
    header: Option<CopyHeader>,
    /// Next page of the copy to read.
    page: u16,
    digest: Digest<16>,
    parser: PayloadParser,
    /// Load: decoded lines go into the program (cleared before page 0).
    load: bool,
}

impl CopyReader {
    /// A check of the copy of `slot` at `addr`; the program is not touched.
    pub(crate) fn check(addr: u16, slot: u8) -> Self {
        CopyReader {
            addr,
            slot,
            header: None,
            page: 0,
            digest: CRC32.digest(),
            parser: PayloadParser::new(),
            load: false,
        }
    }

    /// A load of the copy of `slot` at `addr` into the program (cleared at the first step,
    /// left empty if the copy turns out bad or unreadable: never a mix).
    pub(crate) fn load(addr: u16, slot: u8) -> Self {
        CopyReader {
            load: true,
            ..Self::check(addr, slot)
        }
    }

    /// Reads one page. `Ok(None)`: more pages to read; `Ok(Some(header))`: the copy is
    /// complete and valid. With `load`, `program` must be given (else `CopyError::Format`).
    pub(crate) fn step<E: Eeprom>(
        &mut self,
        e: &mut E,
        mut program: Option<&mut Program>,
    ) -> Result<Option<CopyHeader>, CopyError> {
        let r = self.step_inner(e, program.as_deref_mut());
        if self.load && r.is_err() {
            if let Some(p) = program {
                p.lines.fill(None);
            }
        }
        r
    }

    fn step_inner<E: Eeprom>(
        &mut self,
        e: &mut E,
        mut program: Option<&mut Program>,
    ) -> Result<Option<CopyHeader>, CopyError> {
        if self.load && program.is_none() {
            return Err(CopyError::Format);
        }
        let mut buf = [0u8; PAGE_BYTES];
        let offset = usize::from(self.page) * PAGE_BYTES;
        let payload_from: usize;
        let chunk_len: usize;
        match self.header {
            None => {
                // Page 0 in one read: the header, and the first payload bytes behind it
                // (bytes past the payload are read and ignored).
                e.read(self.addr, &mut buf)?;
                let h = buf
                    .get(..COPY_HEADER_BYTES)
                    .and_then(|b| <[u8; COPY_HEADER_BYTES]>::try_from(b).ok())
                    .and_then(|h| CopyHeader::parse(&h))
                    .ok_or(CopyError::NoHeader)?;
                if h.slot != self.slot {
                    return Err(CopyError::WrongSlot);
                }
                self.digest.update(h.to_bytes().get(..12).unwrap_or(&[]));
                if let (true, Some(p)) = (self.load, program.as_deref_mut()) {
                    p.lines.fill(None);
                }
                self.header = Some(h);
                payload_from = COPY_HEADER_BYTES;
                chunk_len = usize::from(h.payload_len).min(PAGE_BYTES - COPY_HEADER_BYTES);
            }
            Some(h) => {
                let total = COPY_HEADER_BYTES + usize::from(h.payload_len);
                let n = total.saturating_sub(offset).min(PAGE_BYTES);
                let chunk = buf.get_mut(..n).ok_or(CopyError::Format)?;
                e.read(at(self.addr, offset)?, chunk)?;
                payload_from = 0;
                chunk_len = n;
            }
        }
        let chunk = buf
            .get(payload_from..payload_from + chunk_len)
            .ok_or(CopyError::Format)?;
        self.digest.update(chunk);
        for &b in chunk {
            self.parser.feed(b, |n, i| {
                if let Some(l) = program
                    .as_deref_mut()
                    .and_then(|p| p.lines.get_mut(usize::from(n)))
                {
                    *l = Some(i);
                }
            });
        }
        self.page += 1;
        let h = self.header.ok_or(CopyError::NoHeader)?;
        let total = COPY_HEADER_BYTES + usize::from(h.payload_len);
        if usize::from(self.page) * PAGE_BYTES < total {
            return Ok(None);
        }
        if self.digest.clone().finalize() != h.crc {
            return Err(CopyError::Crc);
        }
        if !self.parser.finished_ok(h.lines) {
            return Err(CopyError::Format);
        }
        Ok(Some(h))
    }
}

/// Writes one copy, one page per [`CopyWriter::step`]: the pages after the first go
/// first and the header page last, so a copy torn by a power cut usually still has its
/// old header, and in any case fails its CRC. The chip's write cycle after each page is
/// the caller's to wait for ([`Eeprom::ready`]) before the next step.
///
/// The bytes come from the program in RAM (a keypad save) or from the other copy of the
/// slot, already written and checked (the second copy of a program written over the
/// service port, which never was in RAM: [`CopyWriter::copy_of`]); the page order is the
/// same.
#[derive(Debug, Clone)]
pub(crate) struct CopyWriter {
    addr: u16,
    header: CopyHeader,
    /// Next page to write: 1, 2, ... up to the last, then 0.
    page: u16,
    pages: u16,
    source: Source,
}

/// Where a [`CopyWriter`] takes its bytes.
#[derive(Debug, Clone)]
enum Source {
    /// The payload bytes of the pages after the first, in order, from the program.
    Program(PayloadCursor),
    /// The copy at `from`, page for page; `page` holds the page read in the previous
    /// step (a step makes one transfer: the read, then the write).
    Copy {
        from: u16,
        page: Option<[u8; PAGE_BYTES]>,
    },
}

/// What one [`CopyWriter::step`] did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum WriterStep {
    /// Read a page of the source copy (no write cycle to wait for).
    Read,
    /// Wrote a page; more follow.
    Wrote,
    /// Wrote the header page: the copy is written (once its write cycle ends).
    Done,
}

impl CopyWriter {
    /// Prepares the copy of `program` (its CRC is computed here: CPU time only).
    pub(crate) fn new(
        addr: u16,
        slot: u8,
        generation: u32,
        program: &Program,
    ) -> Result<Self, CopyError> {
        let (len, lines) = payload_size(program);
        if len > PAYLOAD_MAX {
            return Err(CopyError::Format);
        }
        let mut header = CopyHeader {
            slot,
            generation,
            payload_len: len as u16,
            lines,
            crc: 0,
        };
        let mut digest = CRC32.digest();
        digest.update(header.to_bytes().get(..12).unwrap_or(&[]));
        for_each_payload_byte(program, |b| digest.update(&[b]));
        header.crc = digest.finalize();
        let mut cursor = PayloadCursor::new();
        for _ in 0..(PAGE_BYTES - COPY_HEADER_BYTES) {
            if cursor.next(program).is_none() {
                break;
            }
        }
        Ok(Self::with(addr, header, Source::Program(cursor)))
    }

    /// The copy at `to` made a page-for-page duplicate of the valid copy at `from`, whose
    /// header is `header` (both copies of a slot are identical after a save).
    pub(crate) fn copy_of(from: u16, to: u16, header: CopyHeader) -> Self {
        Self::with(to, header, Source::Copy { from, page: None })
    }

    fn with(addr: u16, header: CopyHeader, source: Source) -> Self {
        let total = COPY_HEADER_BYTES + usize::from(header.payload_len);
        let pages = total.div_ceil(PAGE_BYTES) as u16;
        CopyWriter {
            addr,
            header,
            page: if pages > 1 { 1 } else { 0 },
            pages,
            source,
        }
    }

    /// The header the copy gets.
    pub(crate) fn header(&self) -> CopyHeader {
        self.header
    }

    /// One transfer: writes one page (or, copying, first reads it).
    pub(crate) fn step<E: Eeprom>(
        &mut self,
        e: &mut E,
        program: &Program,
    ) -> Result<WriterStep, CopyError> {
        let mut page = [0xFFu8; PAGE_BYTES];
        let total = COPY_HEADER_BYTES + usize::from(self.header.payload_len);
        let offset = usize::from(self.page) * PAGE_BYTES;
        let used = total.saturating_sub(offset).min(PAGE_BYTES);
        match &mut self.source {
            Source::Program(_) if self.page == 0 => {
                let mut first = PayloadCursor::new();
                for (i, d) in page.iter_mut().enumerate().take(used) {
                    *d = match self.header.to_bytes().get(i) {
                        Some(&b) => b,
                        None => first.next(program).ok_or(CopyError::Format)?,
                    };
                }
            }
            Source::Program(cursor) => {
                for d in page.iter_mut().take(used) {
                    *d = cursor.next(program).ok_or(CopyError::Format)?;
                }
            }
            Source::Copy { from, page: held } => match held.take() {
                None => {
                    let mut read = [0xFFu8; PAGE_BYTES];
                    e.read(at(*from, offset)?, read.get_mut(..used).unwrap_or(&mut []))?;
                    *held = Some(read);
                    return Ok(WriterStep::Read);
                }
                Some(read) => page = read,
            },
        }
        e.start_write(at(self.addr, offset)?, page.get(..used).unwrap_or(&[]))?;
        if self.page == 0 {
            return Ok(WriterStep::Done);
        }
        self.page += 1;
        if self.page >= self.pages {
            self.page = 0;
        }
        Ok(WriterStep::Wrote)
    }
}

/// Polls `e` until its write cycle has ended (synchronous use on the RAM model and in
/// tools only; the firmware polls on later passes instead).
pub(crate) fn wait_ready<E: Eeprom>(e: &mut E) -> Result<(), EepromError> {
    for _ in 0..SYNC_POLL_LIMIT {
        if e.ready()? {
            return Ok(());
        }
    }
    Err(EepromError::Bus)
}

/// Polls [`wait_ready`] gives a write cycle before it reports a bus error.
const SYNC_POLL_LIMIT: u32 = 10_000;

/// Check a copy completely (header, CRC, decodability) without touching any program.
pub fn check_copy<E: Eeprom>(e: &mut E, addr: u16, slot: u8) -> Result<CopyHeader, CopyError> {
    let mut r = CopyReader::check(addr, slot);
    loop {
        if let Some(h) = r.step(e, None)? {
            return Ok(h);
        }
    }
}

/// Read the copy of `slot` at `addr` into `program` (cleared first), checking it again
/// on the way. On a read error or a bad copy the program is left empty, never mixed.
pub fn read_copy<E: Eeprom>(
    e: &mut E,
    addr: u16,
    slot: u8,
    program: &mut Program,
) -> Result<CopyHeader, CopyError> {
    let mut r = CopyReader::load(addr, slot);
    loop {
        if let Some(h) = r.step(e, Some(program))? {
            return Ok(h);
        }
    }
}

/// Write `program` as one copy of `slot` with `generation` at `addr`, waiting for each
/// write cycle (see `CopyWriter` for the page order).
pub fn write_copy<E: Eeprom>(
    e: &mut E,
    addr: u16,
    slot: u8,
    generation: u32,
    program: &Program,
) -> Result<CopyHeader, CopyError> {
    let mut w = CopyWriter::new(addr, slot, generation, program)?;
    loop {
        let step = w.step(e, program)?;
        wait_ready(e)?;
        if step == WriterStep::Done {
            return Ok(w.header());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::MemEeprom;
    use super::*;
    use shared_protocol::program::testing::sparse_program as sample;
    use shared_protocol::program::{Instruction, Mnemonic, Operand};

    #[test]
    fn round_trip_and_size() {
        let mut e = MemEeprom::new();
        let p = sample();
        let (len, lines) = payload_size(&p);
        // Runs: 0..=2, 150..=151, 400, 999.
        assert_eq!(len, 4 * 3 + 7 * 4);
        assert_eq!(lines, 7);
        let h = write_copy(&mut e, 1024, 2, 7, &p).unwrap();
        assert_eq!(check_copy(&mut e, 1024, 2), Ok(h));
        assert_eq!(check_copy(&mut e, 1024, 3), Err(CopyError::WrongSlot));
        let mut q = Program::default();
        assert_eq!(read_copy(&mut e, 1024, 2, &mut q), Ok(h));
        assert_eq!(p, q);
    }

    #[test]
    fn full_program_fits() {
        let mut p = Program::default();
        for l in p.lines.iter_mut() {
            *l = Some(Instruction {
                mnemonic: Mnemonic::Add,
                operand: Some(Operand::K(99)),
                constant: 9999,
            });
        }
        let (len, _) = payload_size(&p);
        assert!(len <= PAYLOAD_MAX, "{len}");
        let mut e = MemEeprom::new();
        let h = write_copy(&mut e, 384, 1, 1, &p).unwrap();
        let mut q = Program::default();
        assert_eq!(read_copy(&mut e, 384, 1, &mut q), Ok(h));
        assert_eq!(p, q);
    }

    #[test]
    fn empty_program_and_erased_copy() {
        let mut e = MemEeprom::new();
        assert_eq!(check_copy(&mut e, 384, 1), Err(CopyError::NoHeader));
        let h = write_copy(&mut e, 384, 1, 1, &Program::default()).unwrap();
        assert_eq!(h.payload_len, 0);
        assert_eq!(check_copy(&mut e, 384, 1), Ok(h));
    }

    #[test]
    fn every_single_bit_flip_is_detected() {
        let mut e = MemEeprom::new();
        let h = write_copy(&mut e, 384, 1, 5, &sample()).unwrap();
        let end = 384 + COPY_HEADER_BYTES as u16 + h.payload_len;
        for addr in 384..end {
            for bit in 0..8 {
                let mut f = e.clone();
                f.flip_bit(addr, bit);
                assert!(check_copy(&mut f, 384, 1).is_err(), "{addr}.{bit}");
            }
        }
    }
}
