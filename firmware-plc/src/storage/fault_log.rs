//! The fault log: the newest 32 faults with a timestamp, surviving power cycles.
//!
//! The PLC has no real-time clock, so a timestamp is (power-cycle count, seconds since
//! that power-up): enough to tell which faults came in the same session and how long
//! after switching on. Entries are 8 bytes, written one at a time round the ring, each
//! with its own CRC-16, so a power cut while logging loses at most the entry being
//! written. The ring has no head pointer to keep consistent: the newest entry is found
//! from the timestamps (power cycles compared modulo 2^16).

use super::eeprom::{Eeprom, EepromError, PAGE_BYTES};
use super::layout::{FAULT_ENTRY_BYTES, FAULT_LOG_ADDR, FAULT_LOG_ENTRIES};
use crc::{Crc, CRC_16_IBM_3740};

/// The entries' CRC (and the counters record's): one table in the image.
pub(crate) static CRC16: Crc<u16> = Crc::<u16>::new(&CRC_16_IBM_3740);
/// Largest uptime an entry can hold (24 bits of seconds, about 194 days); longer saturates.
pub const UPTIME_MAX_S: u32 = 0x00FF_FFFF;

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
}

impl FaultEntry {
    pub(crate) fn to_bytes(self) -> [u8; FAULT_ENTRY_BYTES] {
        let p = self.power_cycle.to_be_bytes();
        let u = self.uptime_s.min(UPTIME_MAX_S).to_be_bytes();
        let body = [self.code, p[0], p[1], u[1], u[2], u[3]];
        let c = CRC16.checksum(&body).to_be_bytes();
        [
            body[0], body[1], body[2], body[3], body[4], body[5], c[0], c[1],
        ]
    }

    pub(crate) fn parse(b: &[u8]) -> Option<FaultEntry> {
        let [code, p0, p1, u0, u1, u2, c0, c1] = <[u8; FAULT_ENTRY_BYTES]>::try_from(b).ok()?;
        if code == 0 || code == 0xFF || CRC16.checksum(b.get(..6)?) != u16::from_be_bytes([c0, c1])
        {
            return None;
        }
        Some(FaultEntry {
            code,
            power_cycle: u16::from_be_bytes([p0, p1]),
            uptime_s: u32::from_be_bytes([0, u0, u1, u2]),
        })
    }

    /// Whether `self` happened after `other`.
    fn newer_than(&self, other: &FaultEntry) -> bool {
        let d = self.power_cycle.wrapping_sub(other.power_cycle) as i16;
        d > 0 || (d == 0 && self.uptime_s > other.uptime_s)
    }
}

type Ring = [Option<FaultEntry>; FAULT_LOG_ENTRIES];

fn read_ring<E: Eeprom>(e: &mut E) -> Result<Ring, EepromError> {
    let mut raw = [0u8; FAULT_LOG_ENTRIES * FAULT_ENTRY_BYTES];
    e.read(FAULT_LOG_ADDR, &mut raw)?;
    let mut ring: Ring = [None; FAULT_LOG_ENTRIES];
    for (slot, chunk) in ring.iter_mut().zip(raw.chunks(FAULT_ENTRY_BYTES)) {
        *slot = FaultEntry::parse(chunk);
    }
    Ok(ring)
}

/// Finds the newest entry while the ring is read in order, entry 0 first, so that the
/// ring never has to be held in RAM (the job queue reads it one page per pass).
///
/// The newest entry is the valid entry whose successor round the ring is empty, damaged
/// or older (ties in time go to the later position), the newest of those.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub(crate) struct NewestFinder {
    seen: usize,
    first: Option<FaultEntry>,
    prev: Option<FaultEntry>,
    best: Option<(usize, FaultEntry)>,
}

impl NewestFinder {
    fn judge(&mut self, i: usize, e: Option<FaultEntry>, next: Option<FaultEntry>) {
        let Some(e) = e else { return };
        let is_end = next.is_none_or(|n| e.newer_than(&n));
        if is_end && self.best.is_none_or(|(_, b)| e.newer_than(&b)) {
            self.best = Some((i, e));
        }
    }

    /// The next entry of the ring (`None` = empty or damaged).
    pub(crate) fn push(&mut self, e: Option<FaultEntry>) {
        if self.seen == 0 {
            self.first = e;
        } else {
            self.judge(self.seen - 1, self.prev, e);
        }
        self.prev = e;
        self.seen += 1;
    }

    /// Feeds every entry of a chunk of raw ring bytes.
    pub(crate) fn push_bytes(&mut self, raw: &[u8]) {
        for chunk in raw.chunks(FAULT_ENTRY_BYTES) {
            self.push(FaultEntry::parse(chunk));
        }
    }

    /// Index of the newest entry, once the whole ring was pushed.
    pub(crate) fn newest(mut self) -> Option<usize> {
        if self.seen > 0 {
            // The last entry's successor is the first, round the ring.
            self.judge(self.seen - 1, self.prev, self.first);
        }
        self.best.map(|(i, _)| i)
    }

    /// Where the next entry goes: after the newest, or at 0 in an empty log.
    pub(crate) fn append_addr(self) -> u16 {
        let at = self.newest().map_or(0, |i| (i + 1) % FAULT_LOG_ENTRIES);
        FAULT_LOG_ADDR + (at * FAULT_ENTRY_BYTES) as u16
    }
}

/// Index of the newest entry (see [`NewestFinder`]).
fn newest(ring: &Ring) -> Option<usize> {
    let mut f = NewestFinder::default();
    for e in ring {
        f.push(*e);
    }
    f.newest()
}

/// Append one entry, overwriting the oldest when the log is full, and wait for the write
/// cycle (synchronous: tools and tests; the firmware uses the job queue).
pub fn append<E: Eeprom>(e: &mut E, entry: FaultEntry) -> Result<(), EepromError> {
    let mut raw = [0u8; FAULT_LOG_ENTRIES * FAULT_ENTRY_BYTES];
    e.read(FAULT_LOG_ADDR, &mut raw)?;
    let mut f = NewestFinder::default();
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

/// [`read_all`], also returning the ring position (0-31) of the newest entry: the
/// service port reports it (`FaultLog::newest`), so that a PC sees a new entry even when
/// the log is full and the count no longer changes.
pub fn read_all_with_head<E: Eeprom>(
    e: &mut E,
    out: &mut heapless::Vec<FaultEntry, FAULT_LOG_ENTRIES>,
) -> Result<Option<u8>, EepromError> {
    out.clear();
    let ring = read_ring(e)?;
    let Some(head) = newest(&ring) else {
        return Ok(None);
    };
    for back in 0..FAULT_LOG_ENTRIES {
        let i = (head + FAULT_LOG_ENTRIES - back) % FAULT_LOG_ENTRIES;
        if let Some(Some(entry)) = ring.get(i) {
            // Capacity equals the ring size: this push cannot fail.
            let _ = out.push(*entry);
        }
    }
    Ok(Some(head as u8))
}

/// Pages the log occupies.
pub(crate) const LOG_PAGES: usize = FAULT_LOG_ENTRIES * FAULT_ENTRY_BYTES / PAGE_BYTES;

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
mod tests {
    use super::super::MemEeprom;
    use super::*;

    fn entry(code: u8, power_cycle: u16, uptime_s: u32) -> FaultEntry {
        FaultEntry {
            code,
            power_cycle,
            uptime_s,
        }
    }

    fn all(e: &mut MemEeprom) -> heapless::Vec<FaultEntry, 32> {
        let mut v = heapless::Vec::new();
        read_all(e, &mut v).unwrap();
        v
    }

    #[test]
    fn keeps_newest_32_newest_first() {
        let mut e = MemEeprom::new();
        assert!(all(&mut e).is_empty());
        for n in 0..40u32 {
            // Two faults per second, power cycle changing every 10 entries.
            append(&mut e, entry(1 + (n % 7) as u8, (n / 10) as u16, n / 2)).unwrap();
        }
        let v = all(&mut e);
        assert_eq!(v.len(), 32);
        let expect: heapless::Vec<FaultEntry, 32> = (8..40u32)
            .rev()
            .map(|n| entry(1 + (n % 7) as u8, (n / 10) as u16, n / 2))
            .collect();
        assert_eq!(v, expect);
    }

    #[test]
    fn torn_entry_loses_only_itself() {
        let mut e = MemEeprom::new();
        for n in 0..5u32 {
            append(&mut e, entry(3, 1, n)).unwrap();
        }
        for cut in 1..FAULT_ENTRY_BYTES as u32 {
            let mut f = e.clone();
            f.cut_power_after(cut);
            assert!(append(&mut f, entry(4, 2, 0)).is_err());
            f.restore_power();
            let v = all(&mut f);
            assert_eq!(v.len(), 5, "cut {cut}");
            assert_eq!(v[0], entry(3, 1, 4));
            append(&mut f, entry(5, 2, 1)).unwrap();
            assert_eq!(all(&mut f)[0], entry(5, 2, 1));
        }
    }

    #[test]
    fn power_cycle_wraps() {
        let mut e = MemEeprom::new();
        append(&mut e, entry(1, u16::MAX, 5)).unwrap();
        append(&mut e, entry(2, 0, 1)).unwrap();
        append(&mut e, entry(3, 1, 1)).unwrap();
        let codes: heapless::Vec<u8, 32> = all(&mut e).iter().map(|x| x.code).collect();
        assert_eq!(&codes[..], &[3, 2, 1]);
        clear(&mut e).unwrap();
        assert!(all(&mut e).is_empty());
    }
}
