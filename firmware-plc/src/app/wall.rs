//! The wall clock as the rest of the application reads it (the fault log's entries, the
//! service's `GetClock`). The clock itself is `crate::clock`.

use shared_protocol::units::Micros;

use super::PlcApp;
use crate::storage::Eeprom;

impl<E: Eeprom> PlcApp<E> {
    /// Seconds since 2000-01-01 00:00:00 UTC at `now`; `None` while the clock is unset.
    pub(crate) fn wall_seconds(&self, now: Micros) -> Option<u32> {
        self.wall.seconds(now)
    }
}
