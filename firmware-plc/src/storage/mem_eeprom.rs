//! A RAM model of the 24C256 with failure injection, for tests and hil-sim (feature
//! `sim`: the firmware image never compiles it).

use super::eeprom::{check_page_write, Eeprom, EepromError, EEPROM_BYTES};

/// A 24C256 in RAM, erased (all `0xFF`) when new, with failure injection.
///
/// Power-cut model: after [`MemEeprom::cut_power_after`]`(n)`, the next `n` bytes written
/// are stored, and the write that would store byte `n + 1` stops there (the rest of that
/// page write and every later write are lost and report [`EepromError::PowerLost`]) until
/// [`MemEeprom::restore_power`]. That is the worst a real part does short of
/// scrambling the page being written, and it lets a test stop a save at every single byte.
///
/// Write-cycle model: with [`MemEeprom::set_busy_polls`]`(n)`, the chip stays busy after
/// each write until [`Eeprom::ready`] has been asked `n` times; an access while busy fails
/// with [`EepromError::Bus`] (the chip NACKs) and is counted in
/// [`MemEeprom::busy_violations`]. By default (`n = 0`) a write cycle ends at once.
#[derive(Clone)]
pub struct MemEeprom {
    bytes: [u8; EEPROM_BYTES],
    /// Bytes that may still be written before the power fails; `None` = no cut armed.
    budget: Option<u32>,
    powered: bool,
    bytes_written: u32,
    pages_written: u32,
    transfers: u32,
    busy_polls: u32,
    busy_left: u32,
    busy_violations: u32,
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
            transfers: 0,
            busy_polls: 0,
            busy_left: 0,
            busy_violations: 0,
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

    /// Power is back (a reboot): writes work again, the content is what was stored, and a
    /// write cycle that was running is over.
    pub fn restore_power(&mut self) {
        self.budget = None;
        self.powered = true;
        self.busy_left = 0;
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

    /// Page write cycles since creation (each costs up to [`PAGE_WRITE_MS`](super::eeprom::PAGE_WRITE_MS) on the chip).
    pub fn pages_written(&self) -> u32 {
        self.pages_written
    }

    /// Reads and writes since creation (each one bus transaction on the board; `ready`
    /// polls are not counted).
    pub fn transfers(&self) -> u32 {
        self.transfers
    }

    /// Each write cycle lasts until `ready` has been asked `n` times (see the type's docs).
    pub fn set_busy_polls(&mut self, n: u32) {
        self.busy_polls = n;
    }

    /// Reads or writes attempted while a write cycle was running.
    pub fn busy_violations(&self) -> u32 {
        self.busy_violations
    }

    fn check_idle(&mut self) -> Result<(), EepromError> {
        if self.busy_left > 0 {
            self.busy_violations = self.busy_violations.saturating_add(1);
            return Err(EepromError::Bus);
        }
        Ok(())
    }
}

impl Eeprom for MemEeprom {
    fn read(&mut self, addr: u16, buf: &mut [u8]) -> Result<(), EepromError> {
        self.check_idle()?;
        let start = usize::from(addr);
        let src = start
            .checked_add(buf.len())
            .and_then(|end| self.bytes.get(start..end))
            .ok_or(EepromError::OutOfRange)?;
        buf.copy_from_slice(src);
        self.transfers = self.transfers.saturating_add(1);
        Ok(())
    }

    fn start_write(&mut self, addr: u16, data: &[u8]) -> Result<(), EepromError> {
        check_page_write(addr, data.len())?;
        self.check_idle()?;
        if !self.powered {
            return Err(EepromError::PowerLost);
        }
        self.transfers = self.transfers.saturating_add(1);
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
        self.busy_left = self.busy_polls;
        Ok(())
    }

    fn ready(&mut self) -> Result<bool, EepromError> {
        if !self.powered {
            return Err(EepromError::PowerLost);
        }
        if self.busy_left > 0 {
            self.busy_left -= 1;
            return Ok(false);
        }
        Ok(true)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn page_rule() {
        let mut e = MemEeprom::new();
        assert_eq!(e.start_write(60, &[0; 8]), Err(EepromError::CrossesPage));
        assert_eq!(e.start_write(64, &[1; 64]), Ok(()));
        assert_eq!(e.start_write(32767, &[1, 2]), Err(EepromError::OutOfRange));
        let mut b = [0u8; 3];
        e.read(63, &mut b).unwrap();
        assert_eq!(b, [0xFF, 1, 1]);
    }

    #[test]
    fn power_cut_stops_mid_page() {
        let mut e = MemEeprom::new();
        e.cut_power_after(5);
        assert_eq!(e.start_write(0, &[0; 8]), Err(EepromError::PowerLost));
        assert_eq!(e.start_write(64, &[0; 8]), Err(EepromError::PowerLost));
        let mut b = [0u8; 8];
        e.read(0, &mut b).unwrap();
        assert_eq!(b, [0, 0, 0, 0, 0, 0xFF, 0xFF, 0xFF]);
        e.restore_power();
        assert_eq!(e.start_write(0, &[7; 8]), Ok(()));
        assert_eq!(e.bytes_written(), 13);
    }

    #[test]
    fn busy_write_cycle_refuses_access_until_polled_ready() {
        let mut e = MemEeprom::new();
        e.set_busy_polls(2);
        e.start_write(0, &[1, 2]).unwrap();
        let mut b = [0u8; 2];
        assert_eq!(e.read(0, &mut b), Err(EepromError::Bus));
        assert_eq!(e.busy_violations(), 1);
        assert_eq!(e.ready(), Ok(false));
        assert_eq!(e.ready(), Ok(false));
        assert_eq!(e.ready(), Ok(true));
        e.read(0, &mut b).unwrap();
        assert_eq!(b, [1, 2]);
        assert_eq!(e.transfers(), 2);
    }
}
