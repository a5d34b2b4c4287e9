//! Automatic restart after a trip, per fault class: the drive-section settings `arc`
//! (which classes), `art` (the delay) and `arn` (how many in a row), as industrial drives
//! offer it (`docs/drive-core.md` "Automatic restart"). Without `arc` nothing restarts:
//! drive.md's "the drive never restarts by itself" stays the default.
//!
//! Which classes may restart at all is this module's rule, not the program's: only the
//! software trips whose cause lies outside the drive and goes away by itself (`UV`, `OV`,
//! `OC`). The latched classes never do, whatever `arc` says: the hardware trips `OC_HW`
//! and `OV_HW`, `STO` and the safety functions, `LINK`, `PROG`, `WDG` and `BOOT`.
//!
//! A restart resets the fault; it does not start the motor. The core takes the drive back
//! to RUN only while the PLC still commands RUN, and the outputs come on only when the
//! drive section commands `fmn` or more again, as after any RUN.

use crate::protection::FaultCode;

/// Restarts count as "in a row" until the drive has been out of FAULT this long after one.
pub const WINDOW_MS: u32 = 60_000;

/// The program's restart settings (`arc`, `art`, `arn`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RestartPolicy {
    /// `arc`: the classes that restart, bit 0 `UV`, bit 1 `OV`, bit 2 `OC` ([`class_bit`]).
    pub classes: u16,
    /// `art`: how long the cause must have been gone without a break, 0.1 s.
    pub delay_ds: u16,
    /// `arn`: restarts in a row; the next trip of the row stays latched until an ACK.
    pub limit: u16,
}

impl RestartPolicy {
    /// A program without `arc`: no class restarts. `art` 1.0 s and `arn` 3 apply to a
    /// program that sets `arc` alone.
    pub const OFF: RestartPolicy = RestartPolicy {
        classes: 0,
        delay_ds: 10,
        limit: 3,
    };
}

/// The bit of `arc` that lets `f` restart; 0 for the classes that never restart: the fault
/// table's `arc` column (`shared_protocol::fault`), where every code states it.
pub const fn class_bit(f: FaultCode) -> u16 {
    f.restart_bit()
}

/// The restart's counters, stepped every millisecond by the control tick.
#[derive(Debug, Clone, Default)]
pub struct AutoRestart {
    /// Milliseconds in FAULT with the cause gone, without a break.
    gone_ms: u32,
    /// Restarts in the current row.
    count: u16,
    /// Milliseconds out of FAULT since the last restart (the row ends at [`WINDOW_MS`]).
    quiet_ms: u32,
}

impl AutoRestart {
    /// One millisecond in FAULT with `fault` latched. `ready`: its cause is gone (for `UV`
    /// with the hysteresis) and an ACK would be accepted now. True: reset the fault now.
    pub fn in_fault(&mut self, p: &RestartPolicy, fault: FaultCode, ready: bool) -> bool {
        self.quiet_ms = 0;
        if !ready || p.classes & class_bit(fault) == 0 || self.count >= p.limit {
            self.gone_ms = 0;
            return false;
        }
        self.gone_ms += 1;
        if self.gone_ms < u32::from(p.delay_ds) * 100 {
            return false;
        }
        self.gone_ms = 0;
        self.count += 1;
        true
    }

    /// One millisecond out of FAULT: [`WINDOW_MS`] of them end the row.
    pub fn out_of_fault(&mut self) {
        self.gone_ms = 0;
        if self.quiet_ms < WINDOW_MS {
            self.quiet_ms += 1;
        } else {
            self.count = 0;
        }
    }

    /// A manual ACK: the row ends.
    pub fn clear(&mut self) {
        self.count = 0;
    }

    /// Restarts in the current row.
    pub fn count(&self) -> u16 {
        self.count
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const UV_ONLY: RestartPolicy = RestartPolicy {
        classes: 1,
        delay_ds: 5,
        limit: 2,
    };

    /// Milliseconds in FAULT until the restart (None: not within 10 s).
    fn ms_to_restart(r: &mut AutoRestart, p: &RestartPolicy, f: FaultCode) -> Option<u32> {
        (1..=10_000).find(|_| r.in_fault(p, f, true))
    }

    #[test]
    fn only_the_classes_set_restart_after_the_delay() {
        let mut r = AutoRestart::default();
        assert_eq!(ms_to_restart(&mut r, &UV_ONLY, FaultCode::Uv), Some(500));
        let mut r = AutoRestart::default();
        assert_eq!(ms_to_restart(&mut r, &UV_ONLY, FaultCode::Ov), None);
        assert_eq!(ms_to_restart(&mut r, &UV_ONLY, FaultCode::Oc), None);
        let all = RestartPolicy {
            classes: 7,
            delay_ds: 0,
            ..UV_ONLY
        };
        for f in [FaultCode::Uv, FaultCode::Ov, FaultCode::Oc] {
            let mut r = AutoRestart::default();
            assert_eq!(ms_to_restart(&mut r, &all, f), Some(1), "{f:?}");
        }
        assert_eq!(
            ms_to_restart(
                &mut AutoRestart::default(),
                &RestartPolicy::OFF,
                FaultCode::Uv
            ),
            None
        );
    }

    #[test]
    fn the_delay_starts_again_when_the_cause_comes_back() {
        let mut r = AutoRestart::default();
        for _ in 0..499 {
            assert!(!r.in_fault(&UV_ONLY, FaultCode::Uv, true));
        }
        assert!(!r.in_fault(&UV_ONLY, FaultCode::Uv, false));
        assert_eq!(ms_to_restart(&mut r, &UV_ONLY, FaultCode::Uv), Some(500));
    }

    #[test]
    fn the_limit_latches_until_a_clear_and_a_quiet_window_ends_the_row() {
        let mut r = AutoRestart::default();
        assert!(ms_to_restart(&mut r, &UV_ONLY, FaultCode::Uv).is_some());
        r.out_of_fault();
        assert!(ms_to_restart(&mut r, &UV_ONLY, FaultCode::Uv).is_some());
        assert_eq!(r.count(), 2);
        // Just short of the window: the third trip of the row stays latched.
        for _ in 0..WINDOW_MS {
            r.out_of_fault();
        }
        assert_eq!(ms_to_restart(&mut r, &UV_ONLY, FaultCode::Uv), None);
        r.clear();
        assert!(ms_to_restart(&mut r, &UV_ONLY, FaultCode::Uv).is_some());
        // A whole window out of FAULT: a new row.
        for _ in 0..=WINDOW_MS {
            r.out_of_fault();
        }
        assert_eq!(r.count(), 0);
    }

    #[test]
    fn the_latched_classes_have_no_bit() {
        for f in FaultCode::ALL {
            let restartable = matches!(f, FaultCode::Uv | FaultCode::Ov | FaultCode::Oc);
            assert_eq!(class_bit(f) != 0, restartable, "{f:?}");
        }
    }
}
