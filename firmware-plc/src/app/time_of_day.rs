//! The wall clock (`crate::clock`) as the application, the board and the service use it:
//! the time read (the fault log's entries, `GetClock`), the RTC read in, the time to write
//! out, the time a PC sets.

use shared_protocol::units::Micros;

use super::PlcApp;
use crate::storage::Eeprom;

impl<E: Eeprom> PlcApp<E> {
    /// Seconds since 2000-01-01 00:00:00 UTC at `now`; `None` while the clock is unset.
    pub(crate) fn wall_seconds(&self, now: Micros) -> Option<u32> {
        self.wall.seconds(now)
    }

    /// The RTC as the board read it at `now` (at boot, then every
    /// [`crate::clock::RESYNC_US`]): `Some` seconds since 2000-01-01 00:00:00 UTC when it
    /// holds a set time.
    pub fn rtc_read(&mut self, seconds: Option<u32>, now: Micros) {
        self.wall.rtc_read(seconds, now);
    }

    /// The board reads the RTC now (at the first pass, then every
    /// [`crate::clock::RESYNC_US`]).
    pub fn rtc_read_due(&self, now: Micros) -> bool {
        self.wall.rtc_read_due(now)
    }

    /// A time set from the service waits to be written to the RTC.
    pub fn rtc_write_due(&self) -> bool {
        self.wall.rtc_write_due()
    }

    /// The time the board must write to the RTC now (once per time set).
    pub fn take_rtc_write(&mut self, now: Micros) -> Option<u32> {
        self.wall.take_rtc_write(now)
    }

    /// Sets the clock (service `SetClock`); false beyond the RTC's last second.
    pub(crate) fn set_wall_clock(&mut self, seconds: u32, now: Micros) -> bool {
        self.wall.set(seconds, now)
    }
}
