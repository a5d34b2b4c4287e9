//! The decisions of both boards' supervision, as plain functions the host tests reach:
//! whether the watchdog may be fed (every required task reported alive), when the
//! heartbeat LED toggles, when a silent task is reported, and what the reset flags mean.
//! The boards (`board-common`) only read and write the registers.

/// Why the MCU last started, decoded from the reset flags (RCC_CSR on the G4).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ResetCause {
    /// Power-on or brown-out (both set BORRSTF on the G4).
    PowerOn,
    /// The independent or window watchdog restarted the MCU (the drive reports it as
    /// fault `WDG` after boot).
    Watchdog,
    /// Any other reset (pin, software, option-byte load, low-power): treated like power-on.
    Other,
}

/// The reset flags the decision looks at (RCC_CSR bits of the same names).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ResetFlags {
    pub iwdg: bool,
    pub wwdg: bool,
    pub bor: bool,
}

impl ResetCause {
    /// A watchdog flag wins over BOR: a watchdog reset during a brown-out still means the
    /// firmware stalled.
    pub fn decode(f: ResetFlags) -> Self {
        if f.iwdg || f.wwdg {
            ResetCause::Watchdog
        } else if f.bor {
            ResetCause::PowerOn
        } else {
            ResetCause::Other
        }
    }
}

/// What the supervisor does after one check of the alive bits.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Verdict {
    /// Every required task reported: feed the watchdog.
    pub feed: bool,
    /// Toggle the heartbeat LED (it blinks only while the watchdog is fed).
    pub toggle_led: bool,
    /// Report these silent tasks (bits), once per stall: not every check.
    pub report_silent: Option<u32>,
}

/// The watchdog is fed only while every task in `required` set its bit since the last
/// check, so one stuck task resets the MCU even if the executor still runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Supervisor {
    required: u32,
    led_every: u32,
    fed: u32,
    silent_reported: bool,
}

impl Supervisor {
    /// `required`: the alive bits that must all be seen; `led_every`: the LED toggles
    /// every this many fed checks.
    pub const fn new(required: u32, led_every: u32) -> Self {
        Supervisor {
            required,
            led_every,
            fed: 0,
            silent_reported: false,
        }
    }

    /// One check with the bits `seen` since the previous one.
    pub fn check(&mut self, seen: u32) -> Verdict {
        let silent = self.required & !seen;
        if silent == 0 {
            self.fed = self.fed.wrapping_add(1);
            self.silent_reported = false;
            return Verdict {
                feed: true,
                toggle_led: self.led_every != 0 && self.fed.is_multiple_of(self.led_every),
                report_silent: None,
            };
        }
        let report = !self.silent_reported;
        self.silent_reported = true;
        Verdict {
            feed: false,
            toggle_led: false,
            report_silent: report.then_some(silent),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reset_flags_decode() {
        let d = |iwdg, wwdg, bor| ResetCause::decode(ResetFlags { iwdg, wwdg, bor });
        assert_eq!(d(false, false, true), ResetCause::PowerOn);
        assert_eq!(d(true, false, true), ResetCause::Watchdog);
        assert_eq!(d(false, true, false), ResetCause::Watchdog);
        assert_eq!(d(false, false, false), ResetCause::Other);
    }

    #[test]
    fn fed_only_while_every_task_reports() {
        let mut s = Supervisor::new(0b11, 2);
        let v = s.check(0b11);
        assert!(v.feed && !v.toggle_led);
        assert!(
            s.check(0b111).toggle_led,
            "every 2nd fed check; extra bits ignored"
        );
        let v = s.check(0b01);
        assert_eq!(
            v,
            Verdict {
                feed: false,
                toggle_led: false,
                report_silent: Some(0b10)
            }
        );
        // The same stall is reported once, not every check.
        assert_eq!(s.check(0b01).report_silent, None);
        assert!(!s.check(0).feed);
        assert!(s.check(0b11).feed);
        assert_eq!(s.check(0b01).report_silent, Some(0b10), "a new stall");
    }
}
