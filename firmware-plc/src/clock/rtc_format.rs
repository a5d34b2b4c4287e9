//! The RTC's calendar registers (RM0440 RTC_TR, RTC_DR: BCD, 24-hour format, two-digit
//! year from 2000, week day 1 = Monday) to and from seconds since 2000-01-01 00:00:00 UTC,
//! so that the board only moves words between the registers and the core.

use shared_protocol::service::WALL_MAX_S;

use crate::editor::calendar;

const SECONDS_PER_DAY: u32 = 86_400;

/// `v` (0-99) in BCD: 16 per ten instead of 10.
fn bcd(v: u32) -> u32 {
    v + 6 * (v / 10)
}

/// A BCD field's value (digits above 9 give a number [`seconds`]' check refuses).
fn from_bcd(v: u32) -> u32 {
    v - 6 * (v >> 4)
}

/// Days from 2000-01-01 to `year` (0-99 from 2000), `month` (1-12), `day` (1-31): the
/// inverse of [`calendar::date`] for the RTC's century. Days are counted from a March 1st
/// (the leap day ends a year, `(153 * m + 2) / 5` days before March-based month `m`), from
/// four years early so that January and February of 2000 stay unsigned. Fields out of
/// range give some day count, never an overflow.
fn days(year: u32, month: u32, day: u32) -> u32 {
    let march_based = (month + 9) % 12;
    let y = year + 4 - u32::from(month <= 2);
    // 1461: the four years added; 59: 2000-01-01 to 2000-03-01, less the first day.
    (365 * y + y / 4 + (153 * march_based + 2) / 5 + day + 59).saturating_sub(1461)
}

/// RTC_TR and RTC_DR for `seconds` (at most [`WALL_MAX_S`]; later values write its
/// last second).
pub fn registers(seconds: u32) -> (u32, u32) {
    let seconds = seconds.min(WALL_MAX_S);
    let days = seconds / SECONDS_PER_DAY;
    let in_day = seconds % SECONDS_PER_DAY;
    // 2000-01-01 was a Saturday (6).
    let weekday = (days + 5) % 7 + 1;
    let (year, month, day) = calendar::date(days);
    let tr = bcd(in_day % 60) | bcd(in_day / 60 % 60) << 8 | bcd(in_day / 3600) << 16;
    let dr = bcd(day) | bcd(month) << 8 | weekday << 13 | bcd(year - 2000) << 16;
    (tr, dr)
}

/// Seconds since 2000-01-01 00:00:00 for RTC_TR and RTC_DR as read (24-hour format);
/// `None` unless they are exactly what [`registers`] writes for it (a field out of range,
/// a digit above 9, a wrong week day or reserved bits set: a calendar this firmware did
/// not write).
pub fn seconds(tr: u32, dr: u32) -> Option<u32> {
    let days = days(
        from_bcd(dr >> 16 & 0xFF),
        from_bcd(dr >> 8 & 0x1F),
        from_bcd(dr & 0x3F),
    );
    let in_day =
        from_bcd(tr >> 16 & 0x3F) * 3600 + from_bcd(tr >> 8 & 0x7F) * 60 + from_bcd(tr & 0x7F);
    let s = days.wrapping_mul(SECONDS_PER_DAY).wrapping_add(in_day);
    (registers(s) == (tr, dr)).then_some(s)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_dates_in_rm0440s_bcd() {
        // 2000-01-01 00:00:00 was a Saturday (6); the backup-domain reset DR says Monday.
        assert_eq!(registers(0), (0, 0x0000_C101));
        // 2024-02-29 13:45:07, Thursday (4).
        let s = 8_825 * 86_400 + 13 * 3600 + 45 * 60 + 7;
        assert_eq!(registers(s), (0x0013_4507, 0x0024_8229));
        // 2099-12-31 23:59:59, Thursday.
        assert_eq!(registers(WALL_MAX_S), (0x0023_5959, 0x0099_9231));
        assert_eq!(registers(u32::MAX), registers(WALL_MAX_S));
    }

    #[test]
    fn every_day_of_the_century_round_trips() {
        for day in 0..36_525u32 {
            for in_day in [0, 43_199, 86_399] {
                let s = day * 86_400 + in_day;
                let (tr, dr) = registers(s);
                assert_eq!(seconds(tr, dr), Some(s), "{s}: {tr:#x} {dr:#x}");
            }
        }
    }

    #[test]
    fn fields_out_of_range_read_as_no_time() {
        assert_eq!(seconds(0, 0x0000_C100), None, "day 0");
        assert_eq!(seconds(0, 0x0000_C001), None, "month 0");
        assert_eq!(seconds(0, 0x0000_D301), None, "month 13");
        assert_eq!(seconds(0x0024_0000, 0x0000_C101), None, "hour 24");
        assert_eq!(seconds(0x0000_000A, 0x0000_C101), None, "not BCD");
        assert_eq!(seconds(0, 0x0000_C230), None, "30 February");
        assert_eq!(seconds(0, 0x0000_2101), None, "the reset value's Monday");
        assert_eq!(seconds(0x0040_0000, 0x0000_C101), None, "PM");
        assert_eq!(seconds(0, 0x0000_C101), Some(0));
        assert_eq!(seconds(u32::MAX, u32::MAX), None);
    }
}
