//! The EEPROM seen by the storage code, and a RAM model of the 24C256 for tests and hil-sim.
//!
//! The trait is deliberately small (read anywhere, write within one page) so that the
//! board layer can implement it over I2C with ACK polling, and so that the RAM model can
//! inject the failures that matter: a power cut in the middle of a page write, and bit
//! flips in stored data.

/// Size of the 24C256 in bytes (32 KiB).
pub const EEPROM_BYTES: usize = 32 * 1024;
/// Page size of the 24C256: one write never crosses a page boundary.
pub const PAGE_BYTES: usize = 64;
/// Worst-case duration of one page write cycle of the 24C256.
pub const PAGE_WRITE_MS: u32 = 5;

/// Why an EEPROM access failed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
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

/// A byte-addressed EEPROM with page writes (the 24C256 and compatible parts).
pub trait Eeprom {
    /// Read `buf.len()` bytes starting at `addr`.
    fn read(&mut self, addr: u16, buf: &mut [u8]) -> Result<(), EepromError>;

    /// Write `data` starting at `addr`; all of it must lie within one
    /// [`PAGE_BYTES`] page. Returns when the write cycle has ended (on hardware: ACK
    /// polling, at most [`PAGE_WRITE_MS`]), so that the next access sees the data.
    fn write_page(&mut self, addr: u16, data: &[u8]) -> Result<(), EepromError>;
}

impl<T: Eeprom + ?Sized> Eeprom for &mut T {
    fn read(&mut self, addr: u16, buf: &mut [u8]) -> Result<(), EepromError> {
        (**self).read(addr, buf)
    }
    fn write_page(&mut self, addr: u16, data: &[u8]) -> Result<(), EepromError> {
        (**self).write_page(addr, data)
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

/// A 24C256 in RAM, erased (all `0xFF`) when new, with failure injection.
///
/// Power-cut model: after [`MemEeprom::cut_power_after`]`(n)`, the next `n` bytes written
/// are stored, and the write that would store byte `n + 1` stops there (the rest of that
/// page write and every later write are lost and report [`EepromError::PowerLost`]) until
/// [`MemEeprom::restore_power`]. That is the worst a real part does short of
/// scrambling the page being written, and it lets a test stop a save at every single byte.
#[derive(Clone)]
pub struct MemEeprom {
    bytes: [u8; EEPROM_BYTES],
    /// Bytes that may still be written before the power fails; `None` = no cut armed.
    budget: Option<u32>,
    powered: bool,
    bytes_written: u32,
    pages_written: u32,
}

impl Default for MemEeprom {
    fn default() -> Self {
        Self::new()
    }
}

impl MemEeprom {
    /// A new, erased device.
    pub const fn new() -> Self {
        MemEeprom {
            bytes: [0xFF; EEPROM_BYTES],
            budget: None,
            powered: true,
            bytes_written: 0,
            pages_written: 0,
        }
    }

    /// A device holding `image` (shorter images leave the rest erased, longer are cut).
    pub fn from_image(image: &[u8]) -> Self {
        let mut e = Self::new();
        for (d, s) in e.bytes.iter_mut().zip(image) {
            *d = *s;
        }
        e
    }

    /// The whole content, as a programmer would read it off the chip.
    pub fn image(&self) -> &[u8; EEPROM_BYTES] {
        &self.bytes
    }

    /// Arm a power cut: `n` more bytes get written, then nothing.
    pub fn cut_power_after(&mut self, n: u32) {
        self.budget = Some(n);
    }

    /// Power is back (a reboot): writes work again, the content is what was stored.
    pub fn restore_power(&mut self) {
        self.budget = None;
        self.powered = true;
    }

    /// Whether an armed power cut has happened.
    pub fn power_lost(&self) -> bool {
        !self.powered
    }

    /// Flip one bit of the stored data (a retention error); out-of-range is ignored.
    pub fn flip_bit(&mut self, addr: u16, bit: u8) {
        if let Some(b) = self.bytes.get_mut(usize::from(addr)) {
            *b ^= 1 << (bit & 7);
        }
    }

    /// Bytes stored by page writes since creation (what a power cut counts).
    pub fn bytes_written(&self) -> u32 {
        self.bytes_written
    }

    /// Page write cycles since creation (each costs up to [`PAGE_WRITE_MS`] on the chip).
    pub fn pages_written(&self) -> u32 {
        self.pages_written
    }
}

impl Eeprom for MemEeprom {
    fn read(&mut self, addr: u16, buf: &mut [u8]) -> Result<(), EepromError> {
        let start = usize::from(addr);
        let src = start
            .checked_add(buf.len())
            .and_then(|end| self.bytes.get(start..end))
            .ok_or(EepromError::OutOfRange)?;
        buf.copy_from_slice(src);
        Ok(())
    }

    fn write_page(&mut self, addr: u16, data: &[u8]) -> Result<(), EepromError> {
        check_page_write(addr, data.len())?;
        if !self.powered {
            return Err(EepromError::PowerLost);
        }
        self.pages_written = self.pages_written.saturating_add(1);
        for (i, &b) in data.iter().enumerate() {
            if let Some(left) = self.budget.as_mut() {
                if *left == 0 {
                    self.powered = false;
                    return Err(EepromError::PowerLost);
                }
                *left -= 1;
            }
            if let Some(d) = self.bytes.get_mut(usize::from(addr) + i) {
                *d = b;
            }
            self.bytes_written = self.bytes_written.saturating_add(1);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn page_rule() {
        let mut e = MemEeprom::new();
        assert_eq!(e.write_page(60, &[0; 8]), Err(EepromError::CrossesPage));
        assert_eq!(e.write_page(64, &[1; 64]), Ok(()));
        assert_eq!(e.write_page(32767, &[1, 2]), Err(EepromError::OutOfRange));
        let mut b = [0u8; 3];
        e.read(63, &mut b).unwrap();
        assert_eq!(b, [0xFF, 1, 1]);
    }

    #[test]
    fn power_cut_stops_mid_page() {
        let mut e = MemEeprom::new();
        e.cut_power_after(5);
        assert_eq!(e.write_page(0, &[0; 8]), Err(EepromError::PowerLost));
        assert_eq!(e.write_page(64, &[0; 8]), Err(EepromError::PowerLost));
        let mut b = [0u8; 8];
        e.read(0, &mut b).unwrap();
        assert_eq!(b, [0, 0, 0, 0, 0, 0xFF, 0xFF, 0xFF]);
        e.restore_power();
        assert_eq!(e.write_page(0, &[7; 8]), Ok(()));
        assert_eq!(e.bytes_written(), 13);
    }
}
