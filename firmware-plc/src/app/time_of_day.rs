//! The wall clock (`crate::clock`) as the application, the board and the service use it:
//! the time read (the fault log's entries, `GetClock`), the RTC task's pass, the time a PC
//! sets.

use shared_protocol::units::Micros;

use super::PlcApp;
use crate::storage::Eeprom;

impl<E: Eeprom> PlcApp<E> {
    /// Seconds since 2000-01-01 00:00:00 UTC at `now`; `None` while the clock is unset.
    pub(crate) fn wall_seconds(&self, now: Micros) -> Option<u32> {
        self.wall.seconds(now)
    }

    /// The RTC task body after each application pass (`crate::clock::rtc_sync::pass`):
    /// the write of a time set from the service port, else the read the clock asks for.
    pub fn rtc_pass(
        &mut self,
        rtc: &mut impl crate::clock::rtc_sync::RtcPort,
        now: Micros,
    ) -> Option<crate::clock::rtc_sync::RtcEvent> {
        crate::clock::rtc_sync::pass(&mut self.wall, rtc, now)
    }

    /// Sets the clock (service `SetClock`); false beyond the RTC's last second.
    pub(crate) fn set_wall_clock(&mut self, seconds: u32, now: Micros) -> bool {
        self.wall.set(seconds, now)
    }
}
