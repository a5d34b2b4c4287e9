//! One copy of a stored program: header + sparse payload, streamed page by page.
//!
//! Streaming (never a whole-copy buffer) keeps the RAM cost at two pages, so the same
//! code runs on the MCU and builds the off-board image in hil-sim.
//!
//! Payload: runs of consecutive used lines, each `[first line: u16 BE][count: u8 1..=255]`
//! followed by `count` lines in the 4-byte [`encode_line`] form, runs in ascending line
//! order. Header (16 bytes): magic `"PG"`, format version, slot number, generation `u32`,
//! payload length `u16`, used-line count `u16`, CRC-32 (ISO-HDLC) over header bytes 0..12
//! and the payload — all big-endian.

use super::eeprom::{Eeprom, EepromError, PAGE_BYTES};
use super::layout::{COPY_HEADER_BYTES, PAYLOAD_MAX};
use crc::{Crc, Digest, CRC_32_ISO_HDLC};
use shared_protocol::program::{decode_line, encode_line, Instruction, Program, LINES, LINE_BYTES};

pub(crate) const CRC32: Crc<u32> = Crc::<u32>::new(&CRC_32_ISO_HDLC);
const MAGIC: [u8; 2] = *b"PG";
const VERSION: u8 = 1;
const RUN_MAX: usize = 255;

/// What a valid copy header says.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct CopyHeader {
    pub slot: u8,
    pub generation: u32,
    pub payload_len: u16,
    pub lines: u16,
    pub crc: u32,
}

impl CopyHeader {
    fn to_bytes(self) -> [u8; COPY_HEADER_BYTES] {
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

    fn parse(h: &[u8; COPY_HEADER_BYTES]) -> Option<CopyHeader> {
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
#[cfg_attr(target_os = "none", derive(defmt::Format))]
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

impl From<EepromError> for CopyError {
    fn from(e: EepromError) -> Self {
        CopyError::Eeprom(e)
    }
}

/// Calls `emit` with every payload byte of `program`, in order.
fn for_each_payload_byte(program: &Program, mut emit: impl FnMut(u8)) {
    let mut line = 0usize;
    while line < LINES {
        if program.lines.get(line).is_some_and(|l| l.is_none()) {
            line += 1;
            continue;
        }
        let mut count = 0usize;
        while count < RUN_MAX && program.lines.get(line + count).is_some_and(|l| l.is_some()) {
            count += 1;
        }
        let [a, b] = (line as u16).to_be_bytes();
        emit(a);
        emit(b);
        emit(count as u8);
        for i in program.lines.iter().skip(line).take(count).flatten() {
            for byte in encode_line(i) {
                emit(byte);
            }
        }
        line += count;
    }
}

/// Payload length and used lines of `program` in the stored form.
pub fn payload_size(program: &Program) -> (usize, u16) {
    let mut len = 0usize;
    for_each_payload_byte(program, |_| len += 1);
    let lines = program.lines.iter().filter(|l| l.is_some()).count() as u16;
    (len, lines)
}

/// Incremental payload decoder: fed byte by byte, reports each decoded line.
struct PayloadParser {
    state: ParseState,
    next_line: u16,
    run_left: u8,
    first_hi: u8,
    line_buf: [u8; LINE_BYTES],
    line_pos: usize,
    lines: u16,
    failed: bool,
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum ParseState {
    FirstHi,
    FirstLo,
    Count,
    Line,
}

impl PayloadParser {
    fn new() -> Self {
        PayloadParser {
            state: ParseState::FirstHi,
            next_line: 0,
            run_left: 0,
            first_hi: 0,
            line_buf: [0; LINE_BYTES],
            line_pos: 0,
            lines: 0,
            failed: false,
        }
    }

    fn feed(&mut self, byte: u8, mut apply: impl FnMut(u16, Instruction)) {
        if self.failed {
            return;
        }
        match self.state {
            ParseState::FirstHi => {
                self.first_hi = byte;
                self.state = ParseState::FirstLo;
            }
            ParseState::FirstLo => {
                let first = u16::from_be_bytes([self.first_hi, byte]);
                // Runs ascend and never overlap; that also makes every line unique.
                if first < self.next_line || usize::from(first) >= LINES {
                    self.failed = true;
                }
                self.next_line = first;
                self.state = ParseState::Count;
            }
            ParseState::Count => {
                if byte == 0 || usize::from(self.next_line) + usize::from(byte) > LINES {
                    self.failed = true;
                }
                self.run_left = byte;
                self.line_pos = 0;
                self.state = ParseState::Line;
            }
            ParseState::Line => {
                if let Some(slot) = self.line_buf.get_mut(self.line_pos) {
                    *slot = byte;
                }
                self.line_pos += 1;
                if self.line_pos == LINE_BYTES {
                    self.line_pos = 0;
                    match decode_line(&self.line_buf) {
                        Ok(i) => apply(self.next_line, i),
                        Err(_) => self.failed = true,
                    }
                    self.lines = self.lines.saturating_add(1);
                    self.next_line = self.next_line.saturating_add(1);
                    self.run_left = self.run_left.saturating_sub(1);
                    if self.run_left == 0 {
                        self.state = ParseState::FirstHi;
                    }
                }
            }
        }
    }

    fn finished_ok(&self, lines: u16) -> bool {
        !self.failed && self.state == ParseState::FirstHi && self.lines == lines
    }
}

/// Read the header of the copy at `addr` (no CRC check).
pub fn read_header<E: Eeprom>(e: &mut E, addr: u16) -> Result<CopyHeader, CopyError> {
    let mut h = [0u8; COPY_HEADER_BYTES];
    e.read(addr, &mut h)?;
    CopyHeader::parse(&h).ok_or(CopyError::NoHeader)
}

/// Stream the payload of a copy through `f`, 64 bytes at a time.
fn stream_payload<E: Eeprom>(
    e: &mut E,
    addr: u16,
    len: usize,
    mut f: impl FnMut(&[u8]),
) -> Result<(), CopyError> {
    let mut buf = [0u8; PAGE_BYTES];
    let mut done = 0usize;
    while done < len {
        let n = (len - done).min(PAGE_BYTES);
        let at = usize::from(addr) + COPY_HEADER_BYTES + done;
        let at = u16::try_from(at).map_err(|_| EepromError::OutOfRange)?;
        let chunk = buf.get_mut(..n).ok_or(CopyError::Format)?;
        e.read(at, chunk)?;
        f(chunk);
        done += n;
    }
    Ok(())
}

/// Check a copy completely (header, CRC, decodability) without touching any program.
pub fn check_copy<E: Eeprom>(e: &mut E, addr: u16, slot: u8) -> Result<CopyHeader, CopyError> {
    let h = read_header(e, addr)?;
    if h.slot != slot {
        return Err(CopyError::WrongSlot);
    }
    let header_bytes = h.to_bytes();
    let mut digest: Digest<'_, u32> = CRC32.digest();
    digest.update(header_bytes.get(..12).unwrap_or(&[]));
    let mut parser = PayloadParser::new();
    stream_payload(e, addr, usize::from(h.payload_len), |chunk| {
        digest.update(chunk);
        for &b in chunk {
            parser.feed(b, |_, _| {});
        }
    })?;
    if digest.finalize() != h.crc {
        return Err(CopyError::Crc);
    }
    if !parser.finished_ok(h.lines) {
        return Err(CopyError::Format);
    }
    Ok(h)
}

/// Read a copy already accepted by [`check_copy`] into `program` (cleared first). On a
/// read error the program is left empty, never mixed.
pub fn read_copy<E: Eeprom>(
    e: &mut E,
    addr: u16,
    h: &CopyHeader,
    program: &mut Program,
) -> Result<(), CopyError> {
    program.lines.fill(None);
    let mut parser = PayloadParser::new();
    let r = stream_payload(e, addr, usize::from(h.payload_len), |chunk| {
        for &b in chunk {
            parser.feed(b, |n, i| {
                if let Some(l) = program.lines.get_mut(usize::from(n)) {
                    *l = Some(i);
                }
            });
        }
    });
    if r.is_err() || !parser.finished_ok(h.lines) {
        program.lines.fill(None);
        return Err(r.err().unwrap_or(CopyError::Format));
    }
    Ok(())
}

/// Write `program` as one copy of `slot` with `generation` at `addr`.
///
/// Pages after the first go first and the header page last, so a copy torn by a power
/// cut usually still has its old header, and in any case fails its CRC.
pub fn write_copy<E: Eeprom>(
    e: &mut E,
    addr: u16,
    slot: u8,
    generation: u32,
    program: &Program,
) -> Result<CopyHeader, CopyError> {
    let (len, lines) = payload_size(program);
    if len > PAYLOAD_MAX {
        return Err(CopyError::Format);
    }
    let mut h = CopyHeader {
        slot,
        generation,
        payload_len: len as u16,
        lines,
        crc: 0,
    };
    let mut digest = CRC32.digest();
    digest.update(h.to_bytes().get(..12).unwrap_or(&[]));
    for_each_payload_byte(program, |b| digest.update(&[b]));
    h.crc = digest.finalize();

    let mut first_page = [0xFFu8; PAGE_BYTES];
    let mut page = [0xFFu8; PAGE_BYTES];
    let total = COPY_HEADER_BYTES + len;
    let mut pos = 0usize;
    let mut result: Result<(), EepromError> = Ok(());
    let mut put = |b: u8, pos: &mut usize| {
        let in_page = *pos % PAGE_BYTES;
        if *pos < PAGE_BYTES {
            if let Some(d) = first_page.get_mut(in_page) {
                *d = b;
            }
        } else if let Some(d) = page.get_mut(in_page) {
            *d = b;
        }
        *pos += 1;
        let page_full = pos.is_multiple_of(PAGE_BYTES) || *pos == total;
        if *pos > PAGE_BYTES && page_full && result.is_ok() {
            let used = (*pos - 1) % PAGE_BYTES + 1;
            let page_start = *pos - used;
            result = u16::try_from(usize::from(addr) + page_start)
                .map_err(|_| EepromError::OutOfRange)
                .and_then(|a| e.write_page(a, page.get(..used).unwrap_or(&[])));
        }
    };
    for b in h.to_bytes() {
        put(b, &mut pos);
    }
    for_each_payload_byte(program, |b| put(b, &mut pos));
    result?;
    let used = total.min(PAGE_BYTES);
    e.write_page(addr, first_page.get(..used).unwrap_or(&[]))?;
    Ok(h)
}

#[cfg(test)]
mod tests {
    use super::super::eeprom::MemEeprom;
    use super::*;
    use shared_protocol::program::{Mnemonic, Operand};

    fn sample() -> Program {
        let mut p = Program::default();
        for n in [0usize, 1, 2, 150, 151, 400, 999] {
            p.lines[n] = Some(Instruction {
                mnemonic: Mnemonic::Ld,
                operand: Some(Operand::K((n % 100) as u8)),
                constant: n as u16,
            });
        }
        p
    }

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
        read_copy(&mut e, 1024, &h, &mut q).unwrap();
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
        read_copy(&mut e, 384, &h, &mut q).unwrap();
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
