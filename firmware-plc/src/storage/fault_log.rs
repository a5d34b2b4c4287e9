//! The fault log: the newest 32 faults with a timestamp, surviving power cycles.
//!
//! The PLC has no real-time clock, so a timestamp is (power-cycle count, seconds since
//! that power-up): enough to tell which faults came in the same session and how long
//! after switching on. Entries are 8 bytes, written one at a time round the ring, each
//! with its own CRC-16, so a power cut while logging loses at most the entry being
//! written. The ring has no head pointer to keep consistent: the newest entry is found
//! from the timestamps (power cycles compared modulo 2^16).

use super::eeprom::{Eeprom, EepromError};
use super::layout::{FAULT_ENTRY_BYTES, FAULT_LOG_ADDR, FAULT_LOG_ENTRIES};
use crc::{Crc, CRC_16_IBM_3740};

const CRC16: Crc<u16> = Crc::<u16>::new(&CRC_16_IBM_3740);
/// Largest uptime an entry can hold (24 bits of seconds, about 194 days); longer saturates.
pub const UPTIME_MAX_S: u32 = 0x00FF_FFFF;

/// One logged fault.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct FaultEntry {
    /// Fault code (drive.md; 1..=254).
    pub code: u8,
    /// Power-up count when it happened (low 16 bits of the boot record's count).
    pub power_cycle: u16,
    /// Seconds since that power-up.
    pub uptime_s: u32,
}

impl FaultEntry {
    fn to_bytes(self) -> [u8; FAULT_ENTRY_BYTES] {
        let p = self.power_cycle.to_be_bytes();
        let u = self.uptime_s.min(UPTIME_MAX_S).to_be_bytes();
        let body = [self.code, p[0], p[1], u[1], u[2], u[3]];
        let c = CRC16.checksum(&body).to_be_bytes();
        [
            body[0], body[1], body[2], body[3], body[4], body[5], c[0], c[1],
        ]
    }

    fn parse(b: &[u8]) -> Option<FaultEntry> {
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

/// Index of the newest entry: the valid entry whose successor round the ring is empty,
/// damaged or older (ties in time go to the later position), the newest of those.
fn newest(ring: &Ring) -> Option<usize> {
    let mut best: Option<(usize, FaultEntry)> = None;
    for (i, e) in ring.iter().enumerate() {
        let Some(e) = e else { continue };
        let next = ring.get((i + 1) % FAULT_LOG_ENTRIES).copied().flatten();
        let is_end = next.is_none_or(|n| e.newer_than(&n));
        if is_end && best.is_none_or(|(_, b)| e.newer_than(&b)) {
            best = Some((i, *e));
        }
    }
    best.map(|(i, _)| i)
}

/// Append one entry, overwriting the oldest when the log is full.
pub fn append<E: Eeprom>(e: &mut E, entry: FaultEntry) -> Result<(), EepromError> {
    let ring = read_ring(e)?;
    let at = newest(&ring).map_or(0, |i| (i + 1) % FAULT_LOG_ENTRIES);
    let addr = FAULT_LOG_ADDR + (at * FAULT_ENTRY_BYTES) as u16;
    e.write_page(addr, &entry.to_bytes())
}

/// The stored entries, newest first, into `out` (cleared first).
pub fn read_all<E: Eeprom>(
    e: &mut E,
    out: &mut heapless::Vec<FaultEntry, FAULT_LOG_ENTRIES>,
) -> Result<(), EepromError> {
    out.clear();
    let ring = read_ring(e)?;
    let Some(head) = newest(&ring) else {
        return Ok(());
    };
    for back in 0..FAULT_LOG_ENTRIES {
        let i = (head + FAULT_LOG_ENTRIES - back) % FAULT_LOG_ENTRIES;
        if let Some(Some(entry)) = ring.get(i) {
            // Capacity equals the ring size: this push cannot fail.
            let _ = out.push(*entry);
        }
    }
    Ok(())
}

/// Erase the log (every entry becomes empty).
pub fn clear<E: Eeprom>(e: &mut E) -> Result<(), EepromError> {
    let blank = [0xFFu8; super::eeprom::PAGE_BYTES];
    let pages = FAULT_LOG_ENTRIES * FAULT_ENTRY_BYTES / super::eeprom::PAGE_BYTES;
    for p in 0..pages {
        e.write_page(
            FAULT_LOG_ADDR + (p * super::eeprom::PAGE_BYTES) as u16,
            &blank,
        )?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::super::eeprom::MemEeprom;
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
