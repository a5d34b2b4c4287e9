//! The boot record: which slot to load (and run) at power-up, and the power-cycle count
//! that timestamps the fault log.
//!
//! Two copies in pages 0 and 1, each with a sequence number and CRC-32; a write always
//! goes to the copy that does not hold the newest valid record, so a power cut while
//! writing it leaves the previous record in force.

use super::eeprom::{Eeprom, EepromError};
use super::layout::{BOOT_ADDR, SLOTS};
use super::slot::CRC32;

const MAGIC: [u8; 2] = *b"BR";
const VERSION: u8 = 1;
pub(crate) const RECORD_BYTES: usize = 18;
const FLAG_RUN: u8 = 1;

/// What the boot record holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BootRecord {
    /// Increases with every write; picks the newer copy.
    pub seq: u32,
    /// Slot (1..=4) last started with RUN, if any.
    pub last_run_slot: Option<u8>,
    /// The PLC was in RUN when the record was written: start RUN at power-up.
    pub run_at_power_up: bool,
    /// Power-ups counted so far (this one included once [`super::Storage::power_up`] ran).
    pub power_cycles: u32,
}

impl BootRecord {
    pub(crate) fn to_bytes(self) -> [u8; RECORD_BYTES] {
        let s = self.seq.to_be_bytes();
        let p = self.power_cycles.to_be_bytes();
        let slot = self.last_run_slot.unwrap_or(0xFF);
        let flags = if self.run_at_power_up { FLAG_RUN } else { 0 };
        let body = [
            MAGIC[0], MAGIC[1], VERSION, slot, flags, 0, s[0], s[1], s[2], s[3], p[0], p[1], p[2],
            p[3],
        ];
        let c = CRC32.checksum(&body).to_be_bytes();
        let mut out = [0u8; RECORD_BYTES];
        for (d, s) in out.iter_mut().zip(body.iter().chain(c.iter())) {
            *d = *s;
        }
        out
    }

    pub(crate) fn parse(b: &[u8; RECORD_BYTES]) -> Option<BootRecord> {
        let [m0, m1, ver, slot, flags, _, s0, s1, s2, s3, p0, p1, p2, p3, c0, c1, c2, c3] = *b;
        let body = b.get(..14)?;
        if [m0, m1] != MAGIC
            || ver != VERSION
            || CRC32.checksum(body) != u32::from_be_bytes([c0, c1, c2, c3])
        {
            return None;
        }
        Some(BootRecord {
            seq: u32::from_be_bytes([s0, s1, s2, s3]),
            last_run_slot: (1..=SLOTS).contains(&slot).then_some(slot),
            run_at_power_up: flags & FLAG_RUN != 0,
            power_cycles: u32::from_be_bytes([p0, p1, p2, p3]),
        })
    }
}

/// Keeps the newer of the valid records read so far: feed it copy 0, then copy 1.
pub(crate) fn keep_newest(
    best: Option<(BootRecord, usize)>,
    copy: usize,
    bytes: &[u8; RECORD_BYTES],
) -> Option<(BootRecord, usize)> {
    match BootRecord::parse(bytes) {
        Some(r) if best.is_none_or(|(old, _)| r.seq > old.seq) => Some((r, copy)),
        _ => best,
    }
}

/// Where the next write of `record` goes, given the newest record found: the copy not
/// holding it, with the next sequence number (set in the returned record).
pub(crate) fn next_write(
    current: Option<(BootRecord, usize)>,
    mut record: BootRecord,
) -> (u16, BootRecord) {
    let (seq, target) = match current {
        Some((old, i)) => (old.seq.wrapping_add(1), 1 - i.min(1)),
        None => (1, 0),
    };
    record.seq = seq;
    (BOOT_ADDR.get(target).copied().unwrap_or(0), record)
}

/// The newest valid record and the index of the copy holding it.
pub fn read<E: Eeprom>(e: &mut E) -> Result<Option<(BootRecord, usize)>, EepromError> {
    let mut best: Option<(BootRecord, usize)> = None;
    for (i, &addr) in BOOT_ADDR.iter().enumerate() {
        let mut b = [0u8; RECORD_BYTES];
        e.read(addr, &mut b)?;
        best = keep_newest(best, i, &b);
    }
    Ok(best)
}

/// Write `record` (its `seq` is set here) into the copy not holding the newest one, and
/// wait for the write cycle (synchronous: tools and tests; the firmware uses the job queue).
pub fn write<E: Eeprom>(e: &mut E, record: BootRecord) -> Result<BootRecord, EepromError> {
    let (addr, record) = next_write(read(e)?, record);
    e.start_write(addr, &record.to_bytes())?;
    super::slot::wait_ready(e)?;
    Ok(record)
}

#[cfg(test)]
mod tests {
    use super::super::MemEeprom;
    use super::*;

    #[test]
    fn alternates_and_survives_a_cut_at_every_byte() {
        let mut e = MemEeprom::new();
        assert_eq!(read(&mut e).unwrap(), None);
        let first = BootRecord {
            last_run_slot: Some(2),
            run_at_power_up: true,
            power_cycles: 7,
            ..Default::default()
        };
        let w1 = write(&mut e, first).unwrap();
        assert_eq!(read(&mut e).unwrap(), Some((w1, 0)));
        let second = BootRecord {
            last_run_slot: Some(3),
            power_cycles: 8,
            ..Default::default()
        };
        for cut in 0..RECORD_BYTES as u32 {
            let mut f = e.clone();
            f.cut_power_after(cut);
            assert!(write(&mut f, second).is_err());
            f.restore_power();
            assert_eq!(read(&mut f).unwrap().map(|r| r.0), Some(w1), "cut {cut}");
        }
        let w2 = write(&mut e, second).unwrap();
        assert_eq!(read(&mut e).unwrap(), Some((w2, 1)));
        assert_eq!(w2.seq, 2);
    }
}
