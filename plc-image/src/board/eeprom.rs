//! The 24C256 behind the core's [`Eeprom`] port (the same trait hil-sim's `MemEeprom`
//! implements): random reads, page writes that only latch the data, and one ACK poll per
//! [`Eeprom::ready`]. No call here waits for the write cycle or feeds the watchdog: the
//! storage core (`storage::job`) moves one page per pass of the application task and asks
//! `ready` on later passes.

use embassy_stm32::i2c::Error as I2cError;
use firmware_plc::storage::eeprom::{
    check_page_write, Eeprom, EepromError, EEPROM_BYTES, PAGE_BYTES,
};

use super::i2c_bus::SharedI2c;

/// 7-bit address of the 24C256 with A2..A0 low.
pub const ADDRESS: u8 = 0x50;

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
        if end.is_none_or(|e| e > EEPROM_BYTES) {
            return Err(EepromError::OutOfRange);
        }
        if buf.is_empty() {
            return Ok(());
        }
        // One transaction per page at most (about 6.5 ms at 100 kHz): a longer one (the
        // fault log's 256 bytes at power-up, 23 ms) would exceed the bus's transaction
        // timeout (`i2c_bus::TRANSACTION_TIMEOUT_MS`). The storage jobs read a page or less.
        let mut bus = self.bus.borrow_mut();
        let mut at = addr;
        for chunk in buf.chunks_mut(PAGE_BYTES) {
            bus.blocking_write_read(ADDRESS, &at.to_be_bytes(), chunk)
                .map_err(|_| EepromError::Bus)?;
            at = at.wrapping_add(chunk.len() as u16);
        }
        Ok(())
    }

    fn start_write(&mut self, addr: u16, data: &[u8]) -> Result<(), EepromError> {
        check_page_write(addr, data.len())?;
        if data.is_empty() {
            return Ok(());
        }
        self.bus
            .borrow_mut()
            .blocking_write_vectored(ADDRESS, &[&addr.to_be_bytes(), data])
            .map_err(|_| EepromError::Bus)
    }

    fn ready(&mut self) -> Result<bool, EepromError> {
        // The chip ignores its address until the write cycle ends. The poll writes the two
        // address bytes of location 0 (it only sets the address pointer; harmless).
        match self.bus.borrow_mut().blocking_write(ADDRESS, &[0, 0]) {
            Ok(()) => Ok(true),
            Err(I2cError::Nack) => Ok(false),
            Err(_) => Err(EepromError::Bus),
        }
    }
}
