//! The PLC's time of day, as the fault log stores it.

use shared_protocol::units::Micros;

use super::PlcApp;
use crate::storage::Eeprom;

impl<E: Eeprom> PlcApp<E> {
    /// seconds since 2000-01-01 00:00:00 UTC; None while the clock is unset
    pub(crate) fn wall_seconds(&self, now: Micros) -> Option<u32> {
        let _ = now;
        None
    }
}
