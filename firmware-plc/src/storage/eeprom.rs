//! The EEPROM seen by the storage code (its RAM model for tests and hil-sim is
//! `mem_eeprom`).
//!
//! The trait is deliberately small (read anywhere, latch a write within one page, ask
//! whether the write cycle has ended) so that the board layer can implement it over I2C
//! without waiting inside a call, and so that the RAM model can inject the failures that
//! matter: a power cut in the middle of a page write, bit flips in stored data, and a
//! chip that stays busy for a while after each write.

/// Size of the 24C256 in bytes (32 KiB).
pub const EEPROM_BYTES: usize = 32 * 1024;
/// Page size of the 24C256: one write never crosses a page boundary.
pub const PAGE_BYTES: usize = 64;
/// Worst-case duration of one page write cycle of the 24C256.
pub const PAGE_WRITE_MS: u32 = 5;

/// Why an EEPROM access failed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum EepromError {
    /// Address range outside the device.
    OutOfRange,
    /// A write that would cross a page boundary (the chip would wrap inside the page).
    CrossesPage,
    /// The device did not acknowledge (bus error, or the write cycle never ended).
    Bus,
    /// The supply failed during the write (only the RAM model reports this).
    PowerLost,
}

impl core::fmt::Display for EepromError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            EepromError::OutOfRange => "EEPROM address out of range",
            EepromError::CrossesPage => "EEPROM write crosses a page boundary",
            EepromError::Bus => "EEPROM did not acknowledge",
            EepromError::PowerLost => "supply lost during the EEPROM write",
        })
    }
}

impl core::error::Error for EepromError {}

/// A byte-addressed EEPROM with page writes (the 24C256 and compatible parts).
///
/// No call waits for the chip: after [`Eeprom::start_write`] the chip runs its write
/// cycle (up to [`PAGE_WRITE_MS`]) and answers nothing until it has ended, so the caller
/// asks [`Eeprom::ready`] (on later passes) before the next access. The storage code
/// (`storage::job`) does exactly that; nothing else may access the chip in between.
pub trait Eeprom {
    /// Read `buf.len()` bytes starting at `addr` (one bus transaction on hardware).
    fn read(&mut self, addr: u16, buf: &mut [u8]) -> Result<(), EepromError>;

    /// Latch `data` at `addr` and start the write cycle; all of it must lie within one
    /// [`PAGE_BYTES`] page. Returns as soon as the chip has taken the bytes.
    fn start_write(&mut self, addr: u16, data: &[u8]) -> Result<(), EepromError>;

    /// One non-blocking look: has the last write cycle ended? (On the 24C256: does the
    /// chip acknowledge its address again; a NACK is `Ok(false)`, not an error.)
    fn ready(&mut self) -> Result<bool, EepromError>;
}

impl<T: Eeprom + ?Sized> Eeprom for &mut T {
    fn read(&mut self, addr: u16, buf: &mut [u8]) -> Result<(), EepromError> {
        (**self).read(addr, buf)
    }
    fn start_write(&mut self, addr: u16, data: &[u8]) -> Result<(), EepromError> {
        (**self).start_write(addr, data)
    }
    fn ready(&mut self) -> Result<bool, EepromError> {
        (**self).ready()
    }
}

/// Check a write request against the page rule; shared by every implementation.
pub fn check_page_write(addr: u16, len: usize) -> Result<(), EepromError> {
    let start = usize::from(addr);
    let end = start.checked_add(len).ok_or(EepromError::OutOfRange)?;
    if end > EEPROM_BYTES {
        return Err(EepromError::OutOfRange);
    }
    if len > 0 && start / PAGE_BYTES != (end - 1) / PAGE_BYTES {
        return Err(EepromError::CrossesPage);
    }
    Ok(())
}
