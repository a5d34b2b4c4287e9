//! The calendar date of a day count, for the times of day the PLC shows (seconds since
//! 2000-01-01 00:00:00 UTC, the fault log's and the clock's epoch).

/// Days from 0000-03-01 (proleptic Gregorian) to 2000-01-01.
const DAYS_0000_03_01_TO_2000: u32 = 730_425;

/// Year, month (1-12) and day (1-31) of `days` after 2000-01-01: H. Hinnant's
/// `civil_from_days` (days from 0000-03-01, so that the leap day ends a year), in unsigned
/// arithmetic: every `u32` second count (up to 2136) is in range.
pub(crate) fn date(days: u32) -> (u32, u32, u32) {
    let z = days + DAYS_0000_03_01_TO_2000;
    let era = z / 146_097;
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let (m, march_based_year) = if mp < 10 { (mp + 3, 0) } else { (mp - 9, 1) };
    (yoe + era * 400 + march_based_year, m, d)
}

#[cfg(test)]
mod tests {
    use super::date;

    #[test]
    fn known_days() {
        assert_eq!(date(0), (2000, 1, 1));
        assert_eq!(date(59), (2000, 2, 29));
        assert_eq!(date(60), (2000, 3, 1));
        assert_eq!(date(365), (2000, 12, 31));
        assert_eq!(date(366), (2001, 1, 1));
        assert_eq!(date(9829), (2026, 11, 29));
        // 2100 is not a leap year.
        assert_eq!(date(36_583), (2100, 2, 28));
        assert_eq!(date(36_584), (2100, 3, 1));
        // The last day a u32 of seconds reaches.
        assert_eq!(date(u32::MAX / 86_400), (2136, 2, 7));
    }

    /// Every day of the range follows the one before it: the next day of the month, or
    /// the 1st after the month's last day (30/31 days, February 28 or 29 by the
    /// Gregorian rule).
    #[test]
    fn every_day_follows_the_day_before() {
        let mut prev = date(0);
        for days in 1..=u32::MAX / 86_400 {
            let (y, m, d) = date(days);
            let (py, pm, pd) = prev;
            let leap = py % 4 == 0 && (py % 100 != 0 || py % 400 == 0);
            let month_days = match pm {
                2 if leap => 29,
                2 => 28,
                4 | 6 | 9 | 11 => 30,
                _ => 31,
            };
            let want = if pd < month_days {
                (py, pm, pd + 1)
            } else if pm < 12 {
                (py, pm + 1, 1)
            } else {
                (py + 1, 1, 1)
            };
            assert_eq!((y, m, d), want, "day {days}");
            prev = (y, m, d);
        }
    }
}
