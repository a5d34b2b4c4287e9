//! The 24C256 behind the core's [`Eeprom`] seam (the same trait hil-sim's `MemEeprom`
//! implements): random reads, page writes with ACK polling.

use embassy_stm32::pac::iwdg::vals::Key;
use embassy_stm32::pac::IWDG;
use embassy_time::{Duration, Instant};
use firmware_plc::storage::eeprom::{
    check_page_write, Eeprom, EepromError, PAGE_BYTES, PAGE_WRITE_MS,
};

use super::i2c_bus::SharedI2c;

/// 7-bit address of the 24C256 with A2..A0 low.
pub const ADDRESS: u8 = 0x50;
/// ACK polling gives up after twice the datasheet's worst write cycle.
const WRITE_CYCLE_LIMIT: Duration = Duration::from_millis(2 * PAGE_WRITE_MS as u64);

/// A whole-program save or load is tens of page transfers in one blocking call of the
/// storage core, during which the supervisor task cannot run: each transfer (at most about
/// 10 ms) feeds the IWDG itself, so a hang inside one still resets the MCU.
fn pet_watchdog() {
    IWDG.kr().write(|w| w.set_key(Key::RESET));
}

/// The EEPROM on the shared bus.
pub struct I2cEeprom {
    bus: SharedI2c,
}

impl I2cEeprom {
    pub fn new(bus: SharedI2c) -> Self {
        Self { bus }
    }
}

impl Eeprom for I2cEeprom {
    fn read(&mut self, addr: u16, buf: &mut [u8]) -> Result<(), EepromError> {
        let end = usize::from(addr).checked_add(buf.len());
        if end.is_none_or(|e| e > firmware_plc::storage::eeprom::EEPROM_BYTES) {
            return Err(EepromError::OutOfRange);
        }
        let mut bus = self.bus.borrow_mut();
        // Page-sized pieces (about 6 ms each at 100 kHz) so that a whole-program load keeps
        // the watchdog fed between them.
        let mut at = addr;
        for chunk in buf.chunks_mut(PAGE_BYTES) {
            pet_watchdog();
            bus.blocking_write_read(ADDRESS, &at.to_be_bytes(), chunk)
                .map_err(|_| EepromError::Bus)?;
            at = at.wrapping_add(chunk.len() as u16);
        }
        Ok(())
    }

    fn write_page(&mut self, addr: u16, data: &[u8]) -> Result<(), EepromError> {
        check_page_write(addr, data.len())?;
        if data.is_empty() {
            return Ok(());
        }
        let mut bus = self.bus.borrow_mut();
        bus.blocking_write_vectored(ADDRESS, &[&addr.to_be_bytes(), data])
            .map_err(|_| EepromError::Bus)?;
        // The chip ignores its address until the write cycle ends: poll with the address
        // bytes (a write that sets the address pointer, harmless).
        let start = Instant::now();
        loop {
            pet_watchdog();
            if bus.blocking_write(ADDRESS, &addr.to_be_bytes()).is_ok() {
                return Ok(());
            }
            if start.elapsed() > WRITE_CYCLE_LIMIT {
                return Err(EepromError::Bus);
            }
        }
    }
}
