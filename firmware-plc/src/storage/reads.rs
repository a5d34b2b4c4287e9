//! EEPROM reads for the service port, done a few bytes at a time between scans
//! (service.md 5: the application never waits for the I2C bus).
//!
//! `ListSlots` and `ReadProgram` of slots 1-4 need to know which copy of a slot is valid
//! and the CRC-32C of its payload: that takes reading both copies completely. The result
//! is kept per slot ([`SlotReads::summary`]) until that slot is written (keypad save or
//! service write: the caller invalidates it), so afterwards a chunk is one read of at most
//! 64 bytes. Every read goes through [`SlotReads::step`], which reads at most the byte
//! budget it is given: the service endpoint calls it once per application pass, after
//! the scan. Part of the storage (the service uses it, not the other way), so that the
//! application's answers to service requests depend on nothing in `crate::service`.

use heapless::Vec;
use shared_protocol::crc32::Digest;
use shared_protocol::link::frame::CRC as C32;
use shared_protocol::service::{SlotState, SlotSummary, CHUNK_BYTES};

use crate::storage::eeprom::{Eeprom, EepromError};
use crate::storage::layout::{copy_addr, COPY_HEADER_BYTES, SLOTS};
use crate::storage::slot::{CopyError, CopyHeader, CRC32 as ISO};
use shared_protocol::program::payload::PayloadParser;

/// A slot as the service reports it, and the address of the copy a load would use.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SlotRecord {
    pub summary: SlotSummary,
    /// First byte of the copy a load uses (valid slots only).
    pub copy_addr: u16,
}

type CopyResult = Result<(CopyHeader, u32), CopyError>;

/// Checking both copies of one slot, byte range by byte range.
#[derive(Clone)]
struct Scan {
    slot: u8,
    copy: u8,
    /// Bytes of the current copy read so far (header first).
    pos: usize,
    head: [u8; COPY_HEADER_BYTES],
    header: Option<CopyHeader>,
    iso: Digest<16>,
    c32: shared_protocol::crc32::CastagnoliDigest,
    parser: PayloadParser,
    results: [Option<CopyResult>; 2],
}

impl Scan {
    fn new(slot: u8) -> Scan {
        Scan {
            slot,
            copy: 0,
            pos: 0,
            head: [0; COPY_HEADER_BYTES],
            header: None,
            iso: ISO.digest(),
            c32: C32.digest(),
            parser: PayloadParser::new(),
            results: [None, None],
        }
    }

    fn next_copy(&mut self, result: CopyResult) {
        if let Some(r) = self.results.get_mut(usize::from(self.copy)) {
            *r = Some(result);
        }
        self.copy += 1;
        self.pos = 0;
        self.header = None;
        self.iso = ISO.digest();
        self.c32 = C32.digest();
        self.parser = PayloadParser::new();
    }

    fn end(&self) -> usize {
        COPY_HEADER_BYTES + self.header.map_or(0, |h| usize::from(h.payload_len))
    }

    /// Bytes `self.pos..` of the current copy arrived.
    fn take(&mut self, bytes: &[u8]) {
        for &b in bytes {
            if self.pos < COPY_HEADER_BYTES {
                if let Some(d) = self.head.get_mut(self.pos) {
                    *d = b;
                }
            } else {
                self.iso.update(&[b]);
                self.c32.update(&[b]);
                self.parser.feed(b, |_, _| {});
            }
            self.pos += 1;
        }
        if self.pos == COPY_HEADER_BYTES && self.header.is_none() {
            match CopyHeader::parse(&self.head) {
                None => return self.next_copy(Err(CopyError::NoHeader)),
                Some(h) if h.slot != self.slot => return self.next_copy(Err(CopyError::WrongSlot)),
                Some(h) => {
                    self.iso.update(self.head.get(..12).unwrap_or(&[]));
                    self.header = Some(h);
                }
            }
        }
        if let Some(h) = self.header {
            if self.pos >= self.end() {
                let iso = core::mem::replace(&mut self.iso, ISO.digest()).finalize();
                let c32 = core::mem::replace(&mut self.c32, C32.digest()).finalize();
                let r = if iso != h.crc {
                    Err(CopyError::Crc)
                } else if !self.parser.finished_ok(h.lines) {
                    Err(CopyError::Format)
                } else {
                    Ok((h, c32))
                };
                self.next_copy(r);
            }
        }
    }

    /// Both copies checked: what a load would use (the same rules as `Storage::load`).
    fn record(&self) -> SlotRecord {
        let empty = SlotSummary {
            state: SlotState::Empty,
            generation: 0,
            lines: 0,
            len: 0,
            crc: 0,
        };
        let used = match (&self.results[0], &self.results[1]) {
            (Some(Ok(a)), Some(Ok(b))) => Some(if b.0.generation > a.0.generation {
                (1, *b)
            } else {
                (0, *a)
            }),
            (Some(Ok(a)), _) => Some((0, *a)),
            (_, Some(Ok(b))) => Some((1, *b)),
            _ => None,
        };
        let no_header = self
            .results
            .iter()
            .any(|r| matches!(r, Some(Err(CopyError::NoHeader))));
        match used {
            Some((copy, (h, crc))) => SlotRecord {
                summary: SlotSummary {
                    state: SlotState::Valid,
                    generation: h.generation,
                    lines: h.lines,
                    len: h.payload_len,
                    crc,
                },
                copy_addr: copy_addr(self.slot, copy).unwrap_or(0),
            },
            None => SlotRecord {
                summary: SlotSummary {
                    state: if no_header {
                        SlotState::Empty
                    } else {
                        SlotState::Damaged
                    },
                    ..empty
                },
                copy_addr: 0,
            },
        }
    }
}

/// Reading `len` bytes at `addr` for a `ProgramChunk`.
#[derive(Debug, Clone)]
struct Chunk {
    slot: u8,
    offset: u16,
    addr: u16,
    data: Vec<u8, CHUNK_BYTES>,
    len: usize,
}

#[derive(Clone, Default)]
enum Job {
    #[default]
    Idle,
    Scan(Scan),
    Chunk(Chunk),
    /// The last job's EEPROM read failed.
    Failed,
}

/// The service's EEPROM reads and what they found.
#[derive(Clone, Default)]
pub struct SlotReads {
    cache: [Option<SlotRecord>; SLOTS as usize],
    job: Job,
}

impl SlotReads {
    pub fn new() -> Self {
        Self::default()
    }

    /// What slot 1-4 holds, once checked.
    pub fn summary(&self, slot: u8) -> Option<SlotRecord> {
        let i = usize::from(slot).checked_sub(1)?;
        self.cache.get(i).copied().flatten()
    }

    /// The slot was written: check it again when next asked.
    pub fn invalidate(&mut self, slot: u8) {
        if let Some(c) = usize::from(slot)
            .checked_sub(1)
            .and_then(|i| self.cache.get_mut(i))
        {
            *c = None;
        }
        if matches!(&self.job, Job::Scan(s) if s.slot == slot)
            || matches!(&self.job, Job::Chunk(c) if c.slot == slot)
        {
            self.job = Job::Idle;
        }
    }

    /// No read under way.
    pub fn idle(&self) -> bool {
        matches!(self.job, Job::Idle)
    }

    /// The last read failed (taken: the next job starts afresh).
    pub fn take_failure(&mut self) -> bool {
        if matches!(self.job, Job::Failed) {
            self.job = Job::Idle;
            return true;
        }
        false
    }

    /// Start checking slot 1-4 unless known or another read is under way.
    /// A chunk read for an earlier request is dropped (only one request is worked on at
    /// a time: it was superseded).
    pub fn want(&mut self, slot: u8) {
        if matches!(self.job, Job::Chunk(_)) {
            self.job = Job::Idle;
        }
        if (1..=SLOTS).contains(&slot) && self.summary(slot).is_none() && self.idle() {
            self.job = Job::Scan(Scan::new(slot));
        }
    }

    /// Start reading payload bytes `offset..offset + len` of a checked, valid slot.
    pub fn start_chunk(&mut self, slot: u8, offset: u16, len: usize) {
        let Some(rec) = self.summary(slot) else {
            return;
        };
        if !self.idle() {
            return;
        }
        let addr = usize::from(rec.copy_addr) + COPY_HEADER_BYTES + usize::from(offset);
        if let Ok(addr) = u16::try_from(addr) {
            self.job = Job::Chunk(Chunk {
                slot,
                offset,
                addr,
                data: Vec::new(),
                len: len.min(CHUNK_BYTES),
            });
        }
    }

    /// A chunk read to the end: slot, offset and bytes (taken).
    pub fn take_chunk(&mut self, slot: u8, offset: u16) -> Option<Vec<u8, CHUNK_BYTES>> {
        match &mut self.job {
            Job::Chunk(c) if c.slot == slot && c.offset == offset && c.data.len() == c.len => {
                let data = core::mem::take(&mut c.data);
                self.job = Job::Idle;
                Some(data)
            }
            _ => None,
        }
    }

    /// Whether a chunk read for another place is under way or finished unclaimed (the
    /// request that wanted it was superseded).
    pub fn drop_stale_chunk(&mut self, slot: u8, offset: u16) {
        if matches!(&self.job, Job::Chunk(c) if c.slot != slot || c.offset != offset) {
            self.job = Job::Idle;
        }
    }

    /// Read at most `budget` bytes for the job under way; `Ok(true)` when the bus was used.
    pub fn step<E: Eeprom>(&mut self, e: &mut E, budget: usize) -> Result<bool, EepromError> {
        let budget = budget.clamp(1, CHUNK_BYTES);
        let mut buf = [0u8; CHUNK_BYTES];
        let r = match &mut self.job {
            Job::Idle | Job::Failed => return Ok(false),
            // Read to the end: waits for `take_chunk`.
            Job::Chunk(c) if c.data.len() >= c.len => return Ok(false),
            Job::Chunk(c) => {
                let got = c.data.len();
                let n = (c.len - got).min(budget);
                let piece = buf.get_mut(..n).unwrap_or(&mut []);
                let at = c.addr.wrapping_add(got as u16);
                let r = e.read(at, piece);
                if r.is_ok() {
                    // Never more than `len` <= the capacity.
                    let _ = c.data.extend_from_slice(piece);
                }
                r
            }
            Job::Scan(s) => {
                let base = copy_addr(s.slot, s.copy).unwrap_or(0);
                let n = (s.end() - s.pos).min(budget);
                let n = if s.pos < COPY_HEADER_BYTES {
                    n.min(COPY_HEADER_BYTES - s.pos)
                } else {
                    n
                };
                let piece = buf.get_mut(..n).unwrap_or(&mut []);
                let at = u16::try_from(usize::from(base) + s.pos).unwrap_or(u16::MAX);
                let r = e.read(at, piece);
                if r.is_ok() {
                    s.take(piece);
                    if s.copy >= 2 {
                        let rec = s.record();
                        if let Some(c) = usize::from(s.slot)
                            .checked_sub(1)
                            .and_then(|i| self.cache.get_mut(i))
                        {
                            *c = Some(rec);
                        }
                        self.job = Job::Idle;
                    }
                }
                r
            }
        };
        if r.is_err() {
            self.job = Job::Failed;
        }
        r.map(|_| true)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::storage::{MemEeprom, SlotCopy, Storage};
    use shared_protocol::program::assemble;

    fn run(reads: &mut SlotReads, e: &mut MemEeprom, budget: usize) -> usize {
        let mut steps = 0;
        while reads.step(e, budget).unwrap() {
            steps += 1;
        }
        steps
    }

    #[test]
    fn scan_agrees_with_the_storage_and_chunks_read_the_payload() {
        let p = assemble(include_str!("../../../shared-protocol/programs/motor.plc")).unwrap();
        let mut s = Storage::new(MemEeprom::new());
        s.save(2, &p).unwrap();
        s.save(2, &p).unwrap();
        let mut payload = std::vec::Vec::new();
        shared_protocol::program::payload::for_each_payload_byte(&p, |b| payload.push(b));
        let mut e = s.into_eeprom();
        let mut r = SlotReads::new();
        for budget in [4, 64] {
            r.invalidate(2);
            r.want(2);
            let steps = run(&mut r, &mut e, budget);
            // Two copies of 16 + 214 bytes.
            assert_eq!(
                steps,
                2 * (16usize.div_ceil(budget.min(16)) + 214usize.div_ceil(budget))
            );
            let rec = r.summary(2).unwrap();
            assert_eq!(rec.summary.state, SlotState::Valid);
            assert_eq!(rec.summary.generation, 2);
            assert_eq!(rec.summary.len as usize, payload.len());
            assert_eq!(
                rec.summary.crc,
                shared_protocol::link::frame::CRC.checksum(&payload)
            );
        }
        r.start_chunk(2, 64, 64);
        run(&mut r, &mut e, 4);
        assert_eq!(r.take_chunk(2, 0), None);
        assert_eq!(&r.take_chunk(2, 64).unwrap()[..], &payload[64..128]);
        // Empty and damaged slots.
        r.want(1);
        run(&mut r, &mut e, 64);
        assert_eq!(r.summary(1).unwrap().summary.state, SlotState::Empty);
        let a = copy_addr(2, 0).unwrap();
        let b = copy_addr(2, 1).unwrap();
        e.flip_bit(b + 20, 1);
        r.invalidate(2);
        r.want(2);
        run(&mut r, &mut e, 64);
        assert_eq!(r.summary(2).unwrap().copy_addr, a, "the good copy");
        e.flip_bit(a + 20, 1);
        r.invalidate(2);
        r.want(2);
        run(&mut r, &mut e, 64);
        assert_eq!(r.summary(2).unwrap().summary.state, SlotState::Damaged);
        let _ = SlotCopy::A;
    }
}
