//! Bounds of the command line's numbers (`run`, `emu`): clap runs these while it parses,
//! so NaN, infinities and values that would overflow a time computation (`1e20` s as a
//! `Duration`) are refused with a message naming the option, before anything runs.

use anyhow::{bail, Result};

/// The longest run or linger, s (11.6 days of simulated or wall time: far beyond any
/// scenario, small enough for nanosecond counters and `Duration`s).
pub const MAX_TIME_S: f64 = 1e6;

/// The finest CSV sampling: the co-simulation's clock is 1 us, a finer record only
/// repeats values (at 0.0001 ms one simulated second was a 1.2 GB CSV).
pub const MIN_SAMPLE_MS: f64 = 0.001;
/// The coarsest CSV sampling, ms (one row a minute).
pub const MAX_SAMPLE_MS: f64 = 60_000.0;

fn number(s: &str) -> Result<f64, String> {
    s.trim()
        .parse()
        .map_err(|_| format!("{s:?} is not a number"))
}

/// A time of at least 0 s (`--zoom-at`, `--service-linger`), finite, at most
/// [`MAX_TIME_S`].
pub fn time_s(s: &str) -> Result<f64, String> {
    let v = number(s)?;
    if !(v.is_finite() && (0.0..=MAX_TIME_S).contains(&v)) {
        return Err(format!("{s} s: a time of 0 to {MAX_TIME_S} s"));
    }
    Ok(v)
}

/// `--service-speed`: virtual seconds per wall-clock second, 0.1 to 100.
pub fn speed_factor(s: &str) -> Result<f64, String> {
    let v = number(s)?;
    if !(v.is_finite() && (0.1..=100.0).contains(&v)) {
        return Err(format!("{s}: a speed of 0.1 to 100 (1 = real time)"));
    }
    Ok(v)
}

/// `--duration`: above 0, finite, at most [`MAX_TIME_S`].
pub fn duration_s(s: &str) -> Result<f64, String> {
    let v = number(s)?;
    check_duration_s(v).map_err(|e| e.to_string())?;
    Ok(v)
}

/// A run's duration from the command line or the scenario (`duration_s`).
pub fn check_duration_s(v: f64) -> Result<()> {
    if !(v.is_finite() && v > 0.0 && v <= MAX_TIME_S) {
        bail!("the duration must be above 0 and at most {MAX_TIME_S} s, got {v}");
    }
    Ok(())
}

/// `--sample-ms`: [`MIN_SAMPLE_MS`] to [`MAX_SAMPLE_MS`].
pub fn sample_ms(s: &str) -> Result<f64, String> {
    let v = number(s)?;
    if !(v.is_finite() && (MIN_SAMPLE_MS..=MAX_SAMPLE_MS).contains(&v)) {
        return Err(format!(
            "--sample-ms must be at least {MIN_SAMPLE_MS} (1 us, the simulation's time step) and at most {MAX_SAMPLE_MS}, got {s}"
        ));
    }
    Ok(v)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nan_infinity_negative_and_huge_values_are_refused() {
        for bad in ["nan", "inf", "-inf", "-1", "1e20", "1000001", "x"] {
            assert!(time_s(bad).is_err(), "{bad}");
            assert!(duration_s(bad).is_err(), "{bad}");
            assert!(sample_ms(bad).is_err(), "{bad}");
            assert!(speed_factor(bad).is_err(), "{bad}");
        }
        assert!(speed_factor("0").is_err());
        assert!(speed_factor("0.09").is_err());
        assert_eq!(speed_factor("0.1"), Ok(0.1));
        assert_eq!(speed_factor("100"), Ok(100.0));
        assert!(duration_s("0").is_err());
        assert_eq!(time_s("0"), Ok(0.0));
        assert_eq!(time_s("1e6"), Ok(1e6));
        assert_eq!(duration_s("2.5"), Ok(2.5));
        assert!(sample_ms("0.0001").is_err());
        assert_eq!(sample_ms("0.001"), Ok(0.001));
        assert!(check_duration_s(f64::NAN).is_err());
    }
}
