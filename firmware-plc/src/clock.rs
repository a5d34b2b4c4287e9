//! The PLC's time of day (issue item "time of day on the PLC"; seed 004 §2.3.3: each log
//! entry has a date and a time), sans-IO: the wall clock is the second it was at a
//! reference uptime, or unset.
//!
//! Its source is the MCU's RTC on the NUCLEO's 32.768 kHz crystal, in the backup domain:
//! it runs on through every reset and is lost with the supply (the board has no battery on
//! VBAT). The RTC task ([`rtc_sync::pass`]) reads the RTC at boot and then every
//! [`RESYNC_US`] ([`WallClock::rtc_read`]: the uptime runs on HSI16, ±1 %, the RTC on the
//! crystal), and writes it when [`WallClock::take_rtc_write`] hands it a time set from the
//! service port.
//! On hosts without an RTC (hil-sim) the uptime alone carries the clock once set.
//!
//! Time zone rule: the PLC keeps UTC, as seconds since 2000-01-01 00:00:00 UTC (the RTC's
//! own epoch, year 00); only a PC shows local time (`plcctl`).

pub mod rtc_format;
pub mod rtc_sync;

use shared_protocol::service::WALL_MAX_S;
use shared_protocol::units::Micros;

/// The board reads the RTC again after this long (the uptime's ±1 % is then at most
/// 0.6 s).
pub const RESYNC_US: u64 = 60_000_000;

const US_PER_S: u64 = 1_000_000;

/// The wall clock: `seconds` (since 2000-01-01 00:00:00 UTC) at uptime `at`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct WallClock {
    anchor: Option<(u32, Micros)>,
    /// A time was set: the board writes it to the RTC.
    rtc_write_due: bool,
    /// The board reads the RTC again from this uptime (µs; 0: at once).
    next_read_us: u64,
}

impl WallClock {
    /// Unset (a power-on before the RTC was read).
    pub const fn new() -> Self {
        WallClock {
            anchor: None,
            rtc_write_due: false,
            next_read_us: 0,
        }
    }

    /// Sets the clock to `seconds` at `now` (the service's `SetClock`); the RTC is written
    /// next. Refused (false) beyond [`WALL_MAX_S`], the RTC's last second.
    pub fn set(&mut self, seconds: u32, now: Micros) -> bool {
        if seconds > WALL_MAX_S {
            return false;
        }
        self.anchor = Some((seconds, now));
        self.rtc_write_due = true;
        true
    }

    /// The RTC as the board read it at `now`: `Some` when it holds a set time. An unset RTC
    /// leaves the clock as it is (a set time not yet written, or a board without a crystal
    /// whose clock runs on the uptime).
    pub fn rtc_read(&mut self, seconds: Option<u32>, now: Micros) {
        self.next_read_us = now.0.saturating_add(RESYNC_US);
        if let Some(s) = seconds {
            if !self.rtc_write_due {
                self.anchor = Some((s.min(WALL_MAX_S), now));
            }
        }
    }

    /// The board reads the RTC now: at the first pass after boot, then every
    /// [`RESYNC_US`].
    pub fn rtc_read_due(&self, now: Micros) -> bool {
        now.0 >= self.next_read_us
    }

    /// A set time waits for the RTC: the board prepares it (LSE ready, initialization
    /// mode), then takes the time with [`WallClock::take_rtc_write`] and writes it at once.
    pub fn rtc_write_due(&self) -> bool {
        self.rtc_write_due
    }

    /// The time the board must write to the RTC now, once per [`WallClock::set`].
    pub fn take_rtc_write(&mut self, now: Micros) -> Option<u32> {
        if !core::mem::take(&mut self.rtc_write_due) {
            return None;
        }
        self.seconds(now)
    }

    /// Seconds since 2000-01-01 00:00:00 UTC at `now`; `None` while unset. It stops at
    /// [`WALL_MAX_S`] as the RTC does; an uptime before the anchor reads the anchor.
    pub fn seconds(&self, now: Micros) -> Option<u32> {
        let (s, at) = self.anchor?;
        let elapsed = now.0.saturating_sub(at.0) / US_PER_S;
        let elapsed = u32::try_from(elapsed).unwrap_or(u32::MAX);
        Some(s.saturating_add(elapsed).min(WALL_MAX_S))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn s(secs: u64) -> Micros {
        Micros(secs * US_PER_S)
    }

    #[test]
    fn unset_until_set_and_then_counts_whole_seconds() {
        let mut c = WallClock::new();
        assert_eq!(c.seconds(s(5)), None);
        assert_eq!(c.take_rtc_write(s(5)), None);
        assert!(c.set(1_000, s(10)));
        assert_eq!(c.seconds(s(10)), Some(1_000));
        assert_eq!(c.seconds(Micros(10_999_999)), Some(1_000));
        assert_eq!(c.seconds(s(11)), Some(1_001));
        assert_eq!(c.seconds(s(3_610)), Some(4_600));
    }

    #[test]
    fn the_rtc_is_read_at_once_and_then_every_minute() {
        let mut c = WallClock::new();
        assert!(c.rtc_read_due(s(0)));
        c.rtc_read(None, s(1));
        assert!(!c.rtc_read_due(s(60)));
        assert!(c.rtc_read_due(s(61)));
    }

    #[test]
    fn a_set_time_is_written_to_the_rtc_once() {
        let mut c = WallClock::new();
        assert!(!c.rtc_write_due());
        c.set(500, s(1));
        assert!(c.rtc_write_due());
        assert_eq!(c.take_rtc_write(s(3)), Some(502));
        assert!(!c.rtc_write_due());
        assert_eq!(c.take_rtc_write(s(4)), None);
    }

    #[test]
    fn the_rtc_read_sets_and_corrects_the_clock_but_never_unsets_it() {
        let mut c = WallClock::new();
        c.rtc_read(None, s(0));
        assert_eq!(c.seconds(s(1)), None, "an unset RTC: unset");
        c.rtc_read(Some(7_000), s(2));
        assert_eq!(c.seconds(s(2)), Some(7_000));
        // The uptime ran 1 % fast: the next read corrects it.
        c.rtc_read(Some(7_060), s(62));
        assert_eq!(c.seconds(s(63)), Some(7_061));
        // The RTC lost its time (not while running, but never trusted): the clock stays.
        c.rtc_read(None, s(70));
        assert_eq!(c.seconds(s(70)), Some(7_068));
    }

    #[test]
    fn a_set_time_waiting_for_the_rtc_is_not_overwritten_by_an_older_read() {
        let mut c = WallClock::new();
        c.rtc_read(Some(100), s(0));
        c.set(9_000, s(1));
        c.rtc_read(Some(101), s(1));
        assert_eq!(c.seconds(s(2)), Some(9_001));
        assert_eq!(c.take_rtc_write(s(2)), Some(9_001));
        c.rtc_read(Some(9_002), s(3));
        assert_eq!(c.seconds(s(3)), Some(9_002));
    }

    #[test]
    fn it_stops_at_the_rtcs_last_second_and_refuses_later_times() {
        let mut c = WallClock::new();
        assert!(!c.set(WALL_MAX_S + 1, s(0)));
        assert!(!c.set(u32::MAX, s(0)));
        assert_eq!(c.seconds(s(0)), None);
        assert!(c.set(WALL_MAX_S - 1, s(0)));
        assert_eq!(c.seconds(s(1)), Some(WALL_MAX_S));
        assert_eq!(c.seconds(s(100)), Some(WALL_MAX_S), "frozen, no wrap");
        // Uptime far beyond u32 seconds: no overflow.
        assert_eq!(c.seconds(Micros(u64::MAX)), Some(WALL_MAX_S));
        let mut c = WallClock::new();
        c.rtc_read(Some(u32::MAX), s(0));
        assert_eq!(c.seconds(s(0)), Some(WALL_MAX_S));
    }

    #[test]
    fn an_uptime_before_the_anchor_reads_the_anchor() {
        let mut c = WallClock::new();
        c.set(42, s(10));
        assert_eq!(c.seconds(s(9)), Some(42));
    }

    #[test]
    fn two_thousand_is_second_zero() {
        // 2026-11-29 00:00:00 UTC = Unix 1_795_910_400.
        use shared_protocol::service::WALL_EPOCH_UNIX_S;
        assert_eq!(1_795_910_400 - WALL_EPOCH_UNIX_S, 849_225_600);
        assert_eq!(WALL_MAX_S, 3_155_759_999);
    }
}
