//! Where everything lives in the 24C256 (see `docs/eeprom-image.md`).
//!
//! Every record starts on a page boundary so that one record's page writes never touch
//! another record: a power cut can then only damage the record being written.

use super::eeprom::PAGE_BYTES;

/// Program slots, numbered 1..=SLOTS on the keypad, the LCD, the service port and in
/// this API (the service protocol's constant).
pub use shared_protocol::service::SLOTS;
/// The two copies of a slot.
pub const COPIES: u8 = 2;

/// Boot record copies: pages 0 and 1.
pub const BOOT_ADDR: [u16; 2] = [0, PAGE_BYTES as u16];
/// Fault log: 16 entries of 16 bytes in pages 2..=5 (format 1: 32 of 8; every page is
/// taken, so the entries that hold a time of day and two values are half as many).
pub const FAULT_LOG_ADDR: u16 = 2 * PAGE_BYTES as u16;
/// Entries kept in the fault log.
pub const FAULT_LOG_ENTRIES: usize = 16;
/// Bytes per fault log entry.
pub const FAULT_ENTRY_BYTES: usize = 16;
/// First page of the slot copies.
const SLOT_FIRST_PAGE: usize = 6;
/// Pages per copy: 63 pages = 4032 bytes, enough for all 1000 lines in the sparse form.
pub const COPY_PAGES: usize = 63;
/// Bytes per copy (header + payload).
pub const COPY_BYTES: usize = COPY_PAGES * PAGE_BYTES;
/// Copy header size.
pub const COPY_HEADER_BYTES: usize = 16;
/// Largest payload a copy can hold.
pub const PAYLOAD_MAX: usize = COPY_BYTES - COPY_HEADER_BYTES;

/// Counters record copies: pages 510 and 511 (after slot 4's copy B).
pub const COUNTERS_ADDR: [u16; 2] = [510 * PAGE_BYTES as u16, 511 * PAGE_BYTES as u16];

/// First byte address of `copy` (0 = A, 1 = B) of `slot` (1..=SLOTS).
pub fn copy_addr(slot: u8, copy: u8) -> Option<u16> {
    if !(1..=SLOTS).contains(&slot) || copy >= COPIES {
        return None;
    }
    let index = usize::from(slot - 1) * usize::from(COPIES) + usize::from(copy);
    let page = SLOT_FIRST_PAGE + index * COPY_PAGES;
    u16::try_from(page * PAGE_BYTES).ok()
}

#[cfg(test)]
mod tests {
    use super::super::eeprom::EEPROM_BYTES;
    use super::*;

    #[test]
    fn everything_fits_without_overlap() {
        let log_end = usize::from(FAULT_LOG_ADDR) + FAULT_LOG_ENTRIES * FAULT_ENTRY_BYTES;
        assert!(usize::from(BOOT_ADDR[1]) + PAGE_BYTES <= usize::from(FAULT_LOG_ADDR));
        let first = usize::from(copy_addr(1, 0).unwrap());
        assert!(log_end <= first);
        let last = usize::from(copy_addr(SLOTS, 1).unwrap()) + COPY_BYTES;
        assert!(last <= EEPROM_BYTES, "{last}");
        assert!(last <= usize::from(COUNTERS_ADDR[0]), "{last}");
        assert_eq!(usize::from(COUNTERS_ADDR[1]) + PAGE_BYTES, EEPROM_BYTES);
        assert_eq!(copy_addr(0, 0), None);
        assert_eq!(copy_addr(5, 0), None);
        assert_eq!(copy_addr(1, 2), None);
    }
}
