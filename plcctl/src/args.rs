//! Checks of the command line's numbers, run by clap while it parses (a bad value is a
//! usage error, exit 1, before any port is opened): no NaN, no infinity, nothing that
//! would overflow a time computation, no slot the PLC does not have.

use shared_protocol::service::SLOTS;

/// The longest `--duration` (one year, s): far beyond any recording, and small enough that
/// `now + duration` never overflows a clock.
pub const MAX_DURATION_S: f64 = 365.0 * 24.0 * 3600.0;

/// Line rates a USB serial adapter can be set to (the PLC itself speaks 115200).
pub const BAUD_RANGE: std::ops::RangeInclusive<u32> = 300..=4_000_000;

/// `--duration`: seconds, finite, above 0, at most [`MAX_DURATION_S`].
pub fn duration_s(s: &str) -> Result<f64, String> {
    let v: f64 = s
        .trim()
        .parse()
        .map_err(|_| format!("{s:?} is not a number of seconds"))?;
    if !v.is_finite() || v <= 0.0 || v > MAX_DURATION_S {
        return Err(format!(
            "{s} s: a duration is a finite number of seconds above 0 and at most {MAX_DURATION_S} (one year)"
        ));
    }
    Ok(v)
}

/// `--baud`: within [`BAUD_RANGE`].
pub fn baud(s: &str) -> Result<u32, String> {
    let v: u32 = s
        .trim()
        .parse()
        .map_err(|_| format!("{s:?} is not a whole number of bit/s"))?;
    if !BAUD_RANGE.contains(&v) {
        return Err(format!(
            "{v} bit/s: the line rate must be {}-{} (the PLC's is 115200)",
            BAUD_RANGE.start(),
            BAUD_RANGE.end()
        ));
    }
    Ok(v)
}

fn slot_number(s: &str) -> Result<u8, String> {
    s.trim()
        .parse()
        .map_err(|_| format!("{s:?} is not a slot number"))
}

/// A slot a program is stored in: 1 to [`SLOTS`].
pub fn stored_slot(s: &str) -> Result<u8, String> {
    let v = slot_number(s)?;
    if !(1..=SLOTS).contains(&v) {
        return Err(format!("slot {v}: the PLC's slots are 1-{SLOTS}"));
    }
    Ok(v)
}

/// A slot or the program in RAM: 0 to [`SLOTS`].
pub fn any_slot(s: &str) -> Result<u8, String> {
    let v = slot_number(s)?;
    if v > SLOTS {
        return Err(format!(
            "slot {v}: the PLC's slots are 1-{SLOTS} (0: the program in RAM)"
        ));
    }
    Ok(v)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn durations_refuse_nan_infinity_zero_negative_and_huge() {
        for bad in ["nan", "NaN", "inf", "-inf", "0", "-1", "1e20", "x", ""] {
            assert!(duration_s(bad).is_err(), "{bad}");
        }
        assert_eq!(duration_s("2.5"), Ok(2.5));
        assert_eq!(duration_s("31536000"), Ok(MAX_DURATION_S));
    }

    #[test]
    fn baud_refuses_zero_and_absurd_rates() {
        for bad in ["0", "1", "299", "4000001", "-5", "1e6"] {
            assert!(baud(bad).is_err(), "{bad}");
        }
        assert_eq!(baud("115200"), Ok(115_200));
    }

    #[test]
    fn slots_are_checked_before_the_plc_is_asked() {
        assert!(stored_slot("0").is_err());
        assert!(stored_slot("5").is_err());
        assert_eq!(stored_slot("4"), Ok(4));
        assert_eq!(any_slot("0"), Ok(0));
        assert!(any_slot("5").is_err());
        assert!(any_slot("255").is_err());
        assert!(any_slot("256").is_err());
    }
}
