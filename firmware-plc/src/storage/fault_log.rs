//! The fault log: the newest 16 faults, surviving power cycles, each with its time of day,
//! its power-up and uptime, and two application values (004 §2.3.3: date, time, floor and
//! target).
//!
//! Format 2 (`docs/eeprom-image.md` "Fault log"): 16-byte entries written one at a time
//! round a ring of 16 slots in pages 2-5, each with its own CRC-16, so a power cut while
//! logging loses at most the entry being written. The ring has no head pointer to keep
//! consistent: the newest entry is found from (power cycle, uptime), power cycles compared
//! modulo 2^16. The time of day is stored but not used for the order: it may be unset, and
//! a clock set later may run backwards.
//!
//! Format 1 (firmware before format 2: 32 entries of 8 bytes in the same pages, no time of
//! day, no values) is still read, never rewritten: a slot that is not a format-2 entry is
//! read as two format-1 entries. A format-2 entry is a format-1 entry with 8 more bytes
//! before its CRC, which covers all 14: the length is the version. A slot of two valid
//! format-1 entries never passes as format 2: the CRC (CRC-16/IBM-3740) has no final XOR,
//! so after the first entry (6 bytes and their CRC) its register is 0, and the second
//! entry's CRC is that of its 6 bytes from the initial 0xFFFF, never the one from 0 (the
//! two differ by what the initial value adds to any 6-byte message, a constant other than
//! 0); nor does a valid entry followed by an erased one (test
//! `format_1_slots_never_pass_as_format_2`). The firmware that writes format 2 never
//! writes format 1, so every format-2 entry is newer than every format-1 entry: the log
//! lists format 2 newest first, then format 1 newest first, and the first format-2 entry
//! goes into the slot after the newest format-1 entry's, so that new entries replace the
//! oldest ones.

use super::eeprom::{Eeprom, EepromError, PAGE_BYTES};
use super::layout::{FAULT_ENTRY_BYTES, FAULT_LOG_ADDR, FAULT_LOG_ENTRIES};
/// The entries' CRC (and the counters record's): the safety signature's, one
/// definition in the image (`shared_protocol::crc16`).
pub(crate) use shared_protocol::crc16::IBM_3740 as CRC16;
/// Largest uptime an entry can hold (24 bits of seconds, about 194 days); longer saturates.
pub const UPTIME_MAX_S: u32 = 0x00FF_FFFF;
/// [`FaultEntry::wall_s`] of an entry made while the PLC's clock was not set.
pub const WALL_UNSET: u32 = u32::MAX;
/// [`FaultEntry::values`]: no value (the field was not written, or the PLC was stopped).
pub const NO_VALUE: i16 = i16::MIN;
/// Bytes of a format-1 entry.
const V1_ENTRY_BYTES: usize = 8;
/// Format-1 entries the area holds.
const V1_ENTRIES: usize = 2 * FAULT_LOG_ENTRIES;
/// Bytes of the log.
const LOG_BYTES: usize = FAULT_LOG_ENTRIES * FAULT_ENTRY_BYTES;

/// One logged fault.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FaultEntry {
    /// Fault code (drive.md; 1..=254).
    pub code: u8,
    /// Power-up count when it happened (low 16 bits of the boot record's count).
    pub power_cycle: u16,
    /// Seconds since that power-up.
    pub uptime_s: u32,
    /// The PLC's time of day: seconds since 2000-01-01 00:00:00 UTC, [`WALL_UNSET`] while
    /// the clock was not set (and in every format-1 entry).
    pub wall_s: u32,
    /// The two application values (the program's first two `LCD` fields), [`NO_VALUE`]
    /// for none.
    pub values: [i16; 2],
}

impl FaultEntry {
    /// An entry without time of day and values (as format 1's).
    pub const fn new(code: u8, power_cycle: u16, uptime_s: u32) -> FaultEntry {
        FaultEntry {
            code,
            power_cycle,
            uptime_s,
            wall_s: WALL_UNSET,
            values: [NO_VALUE; 2],
        }
    }

    /// The time of day, if the clock was set.
    pub fn wall(&self) -> Option<u32> {
        (self.wall_s != WALL_UNSET).then_some(self.wall_s)
    }

    /// Application value `n` (0 or 1), if there is one.
    pub fn value(&self, n: usize) -> Option<i16> {
        self.values.get(n).copied().filter(|v| *v != NO_VALUE)
    }

    pub(crate) fn to_bytes(self) -> [u8; FAULT_ENTRY_BYTES] {
        let [p0, p1] = self.power_cycle.to_be_bytes();
        let [_, u0, u1, u2] = self.uptime_s.min(UPTIME_MAX_S).to_be_bytes();
        let [w0, w1, w2, w3] = self.wall_s.to_be_bytes();
        let [a0, a1] = self.values[0].to_be_bytes();
        let [b0, b1] = self.values[1].to_be_bytes();
        let body = [
            self.code, p0, p1, u0, u1, u2, w0, w1, w2, w3, a0, a1, b0, b1,
        ];
        let [c0, c1] = CRC16.checksum(&body).to_be_bytes();
        [
            self.code, p0, p1, u0, u1, u2, w0, w1, w2, w3, a0, a1, b0, b1, c0, c1,
        ]
    }

    /// A format-2 entry (16 bytes) or a format-1 entry (8 bytes: code, power cycle,
    /// uptime, CRC-16 over those 6 bytes), told apart by the length only: format 2 is
    /// format 1 with the time of day and the values before the CRC.
    pub(crate) fn parse(b: &[u8]) -> Option<FaultEntry> {
        let (body, crc) = b.split_last_chunk::<2>()?;
        let [code, p0, p1, u0, u1, u2] = *body.first_chunk::<6>()?;
        if code == 0 || code == 0xFF || CRC16.checksum(body) != u16::from_be_bytes(*crc) {
            return None;
        }
        let mut e = FaultEntry::new(
            code,
            u16::from_be_bytes([p0, p1]),
            u32::from_be_bytes([0, u0, u1, u2]),
        );
        if let Some(&[w0, w1, w2, w3, a0, a1, b0, b1]) =
            body.get(6..).and_then(|x| x.first_chunk::<8>())
        {
            e.wall_s = u32::from_be_bytes([w0, w1, w2, w3]);
            e.values = [i16::from_be_bytes([a0, a1]), i16::from_be_bytes([b0, b1])];
        }
        Some(e)
    }

    fn stamp(&self) -> Stamp {
        Stamp {
            power_cycle: self.power_cycle,
            uptime_s: self.uptime_s,
        }
    }
}

/// What orders the entries of one format: when they happened since which power-up.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Stamp {
    power_cycle: u16,
    uptime_s: u32,
}

impl Stamp {
    /// Whether `self` happened after `other`.
    fn newer_than(self, other: Stamp) -> bool {
        let d = self.power_cycle.wrapping_sub(other.power_cycle) as i16;
        d > 0 || (d == 0 && self.uptime_s > other.uptime_s)
    }
}

/// Finds the newest entry of a ring while it is read in order, entry 0 first, so that
/// the ring never has to be held in RAM (the job queue reads it one page per pass).
///
/// The newest entry is the valid entry whose successor round the ring is empty, damaged
/// or older (ties in time go to the later position), the newest of those.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
struct NewestFinder {
    seen: u8,
    first: Option<Stamp>,
    prev: Option<Stamp>,
    best: Option<(u8, Stamp)>,
}

impl NewestFinder {
    fn judge(&mut self, i: u8, e: Option<Stamp>, next: Option<Stamp>) {
        let Some(e) = e else { return };
        let is_end = next.is_none_or(|n| e.newer_than(n));
        if is_end && self.best.is_none_or(|(_, b)| e.newer_than(b)) {
            self.best = Some((i, e));
        }
    }

    /// The next entry of the ring (`None` = empty, damaged or of the other format).
    fn push(&mut self, e: Option<Stamp>) {
        if self.seen == 0 {
            self.first = e;
        } else {
            self.judge(self.seen - 1, self.prev, e);
        }
        self.prev = e;
        self.seen = self.seen.saturating_add(1);
    }

    /// Index of the newest entry, once the whole ring was pushed.
    fn newest(mut self) -> Option<u8> {
        if self.seen > 0 {
            // The last entry's successor is the first, round the ring.
            self.judge(self.seen - 1, self.prev, self.first);
        }
        self.best.map(|(i, _)| i)
    }
}

/// The newest entry of each format, found while the log is read in order (see
/// [`NewestFinder`]): the ring of 16 format-2 slots and the ring of 32 format-1 halves.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub(crate) struct RingFinder {
    slots: NewestFinder,
    halves: NewestFinder,
}

impl RingFinder {
    /// Feeds every entry of a chunk of raw log bytes (whole slots, from slot 0 on).
    pub(crate) fn push_bytes(&mut self, raw: &[u8]) {
        for slot in raw.chunks(FAULT_ENTRY_BYTES) {
            let e = slot.get(..FAULT_ENTRY_BYTES).and_then(FaultEntry::parse);
            self.slots.push(e.map(|e| e.stamp()));
            for half in slot.chunks(V1_ENTRY_BYTES) {
                let v1 = e.is_none().then(|| FaultEntry::parse(half)).flatten();
                self.halves.push(v1.map(|e| e.stamp()));
            }
        }
    }

    /// The slot (0-15) of the newest format-2 entry and the half (0-31) of the newest
    /// format-1 entry.
    fn heads(self) -> (Option<u8>, Option<u8>) {
        (self.slots.newest(), self.halves.newest())
    }

    /// Where the next entry goes: after the newest format-2 entry, else in the slot after
    /// the newest format-1 entry's, else (an empty log) in slot 0.
    pub(crate) fn append_addr(self) -> u16 {
        let at = match self.heads() {
            (Some(slot), _) => usize::from(slot) + 1,
            (None, Some(half)) => usize::from(half) / 2 + 1,
            (None, None) => 0,
        } % FAULT_LOG_ENTRIES;
        FAULT_LOG_ADDR + (at * FAULT_ENTRY_BYTES) as u16
    }
}

/// Append one entry, overwriting the oldest when the log is full, and wait for the write
/// cycle (synchronous: tools and tests; the firmware uses the job queue).
pub fn append<E: Eeprom>(e: &mut E, entry: FaultEntry) -> Result<(), EepromError> {
    let mut raw = [0u8; LOG_BYTES];
    e.read(FAULT_LOG_ADDR, &mut raw)?;
    let mut f = RingFinder::default();
    f.push_bytes(&raw);
    e.start_write(f.append_addr(), &entry.to_bytes())?;
    super::slot::wait_ready(e)
}

/// The stored entries, newest first, into `out` (cleared first).
pub fn read_all<E: Eeprom>(
    e: &mut E,
    out: &mut heapless::Vec<FaultEntry, FAULT_LOG_ENTRIES>,
) -> Result<(), EepromError> {
    read_all_with_head(e, out).map(|_| ())
}

/// [`read_all`], also returning a ring position (below
/// [`shared_protocol::service::LOG_POSITIONS`]) for the newest entry: the service port
/// reports positions (`FaultLog::newest`), so that a PC sees a new entry even when the log
/// is full and the count no longer changes. Of a log that still holds format-1 entries
/// only the newest 16 are read.
pub fn read_all_with_head<E: Eeprom>(
    e: &mut E,
    out: &mut heapless::Vec<FaultEntry, FAULT_LOG_ENTRIES>,
) -> Result<Option<u8>, EepromError> {
    out.clear();
    let mut raw = [0u8; LOG_BYTES];
    e.read(FAULT_LOG_ADDR, &mut raw)?;
    let mut f = RingFinder::default();
    f.push_bytes(&raw);
    let (v2, v1) = f.heads();
    let slot = |i: usize| raw.get(i * FAULT_ENTRY_BYTES..(i + 1) * FAULT_ENTRY_BYTES);
    if let Some(head) = v2 {
        for back in 0..FAULT_LOG_ENTRIES {
            let i = (usize::from(head) + FAULT_LOG_ENTRIES - back) % FAULT_LOG_ENTRIES;
            if let Some(entry) = slot(i).and_then(FaultEntry::parse) {
                // Capacity equals the ring size: this push cannot fail.
                let _ = out.push(entry);
            }
        }
    }
    if let Some(head) = v1 {
        for back in 0..V1_ENTRIES {
            let i = (usize::from(head) + V1_ENTRIES - back) % V1_ENTRIES;
            if slot(i / 2).and_then(FaultEntry::parse).is_some() {
                continue;
            }
            let half = raw.get(i * V1_ENTRY_BYTES..(i + 1) * V1_ENTRY_BYTES);
            if let Some(entry) = half.and_then(FaultEntry::parse) {
                if out.push(entry).is_err() {
                    break;
                }
            }
        }
    }
    Ok(v2.or(v1))
}

/// Pages the log occupies.
pub(crate) const LOG_PAGES: usize = LOG_BYTES / PAGE_BYTES;

/// Address of page `p` of the log.
pub(crate) fn page_addr(p: usize) -> u16 {
    FAULT_LOG_ADDR + (p * PAGE_BYTES) as u16
}

/// Erase the log (every entry becomes empty), waiting for each write cycle.
pub fn clear<E: Eeprom>(e: &mut E) -> Result<(), EepromError> {
    let blank = [0xFFu8; PAGE_BYTES];
    for p in 0..LOG_PAGES {
        e.start_write(page_addr(p), &blank)?;
        super::slot::wait_ready(e)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests;
