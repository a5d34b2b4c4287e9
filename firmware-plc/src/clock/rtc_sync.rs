//! The RTC task body: what the board does with the backup domain's RTC after each
//! application pass, decided here over an [`RtcPort`] that only moves register words. The
//! board, the tests and any simulated board run this same function.
//!
//! * A time set from the service port is written once the crystal runs (RCC_BDCR.LSERDY):
//!   before, the calendar would count from a stopped clock, so the time stays due and the
//!   clock runs on the uptime meanwhile.
//! * The write clears the [`MARKER`] first and sets it after the calendar: a write cut
//!   half-way (a reset, INITF never set) reads back as unset, never as a wrong time.
//! * Otherwise the RTC is read when the clock asks (the first pass, then every
//!   [`super::RESYNC_US`]); anything but the marker reads as unset (a power-on lost the
//!   backup domain: the NUCLEO has no battery on VBAT).

use shared_protocol::units::Micros;

use super::{rtc_format, WallClock};

/// TAMP_BKP0R after a complete set of the calendar by this firmware.
pub const MARKER: u32 = 0x504C_4331;

/// One count of RTC_SSR with PREDIV_S at its reset value 255 (RM0440 RTC_PRER): 1/256 s.
const SUBSECOND_US: u64 = 3_906;

/// The calendar's shadow registers as read (RM0440 RTC_TR, RTC_DR, RTC_SSR).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Calendar {
    /// RTC_TR.
    pub tr: u32,
    /// RTC_DR.
    pub dr: u32,
    /// RTC_SSR: counts down from PREDIV_S (255) within the second.
    pub ssr: u32,
}

/// The backup domain's RTC as a board reaches it: register moves and RM0440's bounded
/// waits, no decision.
pub trait RtcPort {
    /// RCC_BDCR.LSERDY: the 32.768 kHz crystal runs.
    fn crystal_ready(&mut self) -> bool;
    /// TAMP_BKP0R.
    fn marker(&mut self) -> u32;
    /// Writes TAMP_BKP0R.
    fn set_marker(&mut self, value: u32);
    /// The shadow registers once RTC_ICSR.RSF is set; `None` when it did not set within
    /// the board's bound.
    fn read_calendar(&mut self) -> Option<Calendar>;
    /// Unlocks the RTC (RTC_WPR) and enters initialization mode: true once
    /// RTC_ICSR.INITF is set within the board's bound.
    fn enter_init(&mut self) -> bool;
    /// Writes RTC_TR and RTC_DR (in initialization mode).
    fn write_calendar(&mut self, tr: u32, dr: u32);
    /// Leaves initialization mode and locks the RTC again.
    fn exit_init(&mut self);
}

/// What a pass did that the board logs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RtcEvent {
    /// The calendar was set to this many seconds since 2000-01-01 00:00:00 UTC.
    Set { seconds: u32 },
}

/// After each application pass: the write `clock` asks for once the crystal runs, else
/// the read it asks for.
pub fn pass(clock: &mut WallClock, rtc: &mut impl RtcPort, now: Micros) -> Option<RtcEvent> {
    if clock.rtc_write_due() {
        if rtc.crystal_ready() {
            return write(clock, rtc, now);
        }
    } else if clock.rtc_read_due(now) {
        match read(rtc) {
            Some((seconds, elapsed_us)) => {
                clock.rtc_read(Some(seconds), Micros(now.0.saturating_sub(elapsed_us)))
            }
            None => clock.rtc_read(None, now),
        }
    }
    None
}

/// The calendar when a set one runs: seconds since 2000, and the second's elapsed
/// fraction in microseconds.
fn read(rtc: &mut impl RtcPort) -> Option<(u32, u64)> {
    if rtc.marker() != MARKER {
        return None;
    }
    let c = rtc.read_calendar()?;
    let elapsed = 255u64.saturating_sub(u64::from(c.ssr & 0xFF)) * SUBSECOND_US;
    Some((rtc_format::seconds(c.tr, c.dr)?, elapsed))
}

/// RM0440 "Calendar initialization and configuration": the marker cleared, the calendar
/// written in initialization mode, the marker set. Without INITF the time stays due.
fn write(clock: &mut WallClock, rtc: &mut impl RtcPort, now: Micros) -> Option<RtcEvent> {
    rtc.set_marker(0);
    let seconds = if rtc.enter_init() {
        clock.take_rtc_write(now)
    } else {
        None
    };
    if let Some(s) = seconds {
        let (tr, dr) = rtc_format::registers(s);
        rtc.write_calendar(tr, dr);
    }
    rtc.exit_init();
    let s = seconds?;
    rtc.set_marker(MARKER);
    Some(RtcEvent::Set { seconds: s })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A backup domain as RM0440 describes it, with the waits' outcomes chosen.
    #[derive(Default)]
    struct Rtc {
        lserdy: bool,
        marker: u32,
        tr: u32,
        dr: u32,
        ssr: u32,
        rsf: bool,
        initf: bool,
        in_init: bool,
        /// Every register access, in order.
        trace: Vec<&'static str>,
    }

    impl RtcPort for Rtc {
        fn crystal_ready(&mut self) -> bool {
            self.lserdy
        }
        fn marker(&mut self) -> u32 {
            self.marker
        }
        fn set_marker(&mut self, value: u32) {
            self.trace
                .push(if value == MARKER { "marker" } else { "unmark" });
            self.marker = value;
        }
        fn read_calendar(&mut self) -> Option<Calendar> {
            self.trace.push("read");
            self.rsf.then_some(Calendar {
                tr: self.tr,
                dr: self.dr,
                ssr: self.ssr,
            })
        }
        fn enter_init(&mut self) -> bool {
            self.trace.push("init");
            self.in_init = self.initf;
            self.initf
        }
        fn write_calendar(&mut self, tr: u32, dr: u32) {
            assert!(
                self.in_init,
                "RTC_TR/DR are written in initialization mode only"
            );
            self.trace.push("write");
            (self.tr, self.dr) = (tr, dr);
        }
        fn exit_init(&mut self) {
            self.trace.push("exit");
            self.in_init = false;
        }
    }

    fn s(seconds: u64) -> Micros {
        Micros(seconds * 1_000_000)
    }

    #[test]
    fn a_set_time_waits_for_the_crystal_then_is_written_between_the_marker_writes() {
        let mut clock = WallClock::new();
        let mut rtc = Rtc {
            initf: true,
            rsf: true,
            ..Rtc::default()
        };
        assert!(clock.set(849_261_600, s(0)));
        assert_eq!(pass(&mut clock, &mut rtc, s(1)), None);
        assert!(rtc.trace.is_empty(), "nothing touched before LSERDY");
        rtc.lserdy = true;
        assert_eq!(
            pass(&mut clock, &mut rtc, s(3)),
            Some(RtcEvent::Set {
                seconds: 849_261_603
            })
        );
        assert_eq!(rtc.trace, ["unmark", "init", "write", "exit", "marker"]);
        assert_eq!(rtc_format::seconds(rtc.tr, rtc.dr), Some(849_261_603));
        assert_eq!(pass(&mut clock, &mut rtc, s(4)), None, "written once");
    }

    #[test]
    fn without_initf_the_time_stays_due_and_the_rtc_reads_unset() {
        let mut clock = WallClock::new();
        let mut rtc = Rtc {
            lserdy: true,
            marker: MARKER,
            ..Rtc::default()
        };
        assert!(clock.set(1_000, s(0)));
        assert_eq!(pass(&mut clock, &mut rtc, s(0)), None);
        assert_eq!(rtc.trace, ["unmark", "init", "exit"]);
        assert_eq!(
            rtc.marker, 0,
            "a write that did not happen leaves no marker"
        );
        assert!(clock.rtc_write_due());
        rtc.initf = true;
        assert_eq!(
            pass(&mut clock, &mut rtc, s(2)),
            Some(RtcEvent::Set { seconds: 1_002 })
        );
    }

    #[test]
    fn a_marked_rtc_sets_the_clock_to_its_second_and_fraction() {
        let mut clock = WallClock::new();
        let (tr, dr) = rtc_format::registers(7_000);
        // 64 of 256 counts left: 3/4 s of the second have passed.
        let mut rtc = Rtc {
            marker: MARKER,
            rsf: true,
            tr,
            dr,
            ssr: 63,
            ..Rtc::default()
        };
        let now = Micros(10_000_000);
        assert_eq!(pass(&mut clock, &mut rtc, now), None);
        assert_eq!(clock.seconds(now), Some(7_000));
        // The next second starts 1/4 s later (to 3 906 us a count), not a whole second later.
        assert_eq!(clock.seconds(Micros(10_249_000)), Some(7_000));
        assert_eq!(clock.seconds(Micros(10_251_000)), Some(7_001));
        assert!(!clock.rtc_read_due(Micros(10_000_001)));
    }

    #[test]
    fn an_unmarked_or_unsynchronised_rtc_reads_unset() {
        let (tr, dr) = rtc_format::registers(7_000);
        for (marker, rsf) in [(0, true), (MARKER ^ 1, true), (MARKER, false)] {
            let mut clock = WallClock::new();
            let mut rtc = Rtc {
                marker,
                rsf,
                tr,
                dr,
                ..Rtc::default()
            };
            assert_eq!(pass(&mut clock, &mut rtc, s(0)), None);
            assert_eq!(clock.seconds(s(0)), None, "marker {marker:#x}, rsf {rsf}");
            assert!(!clock.rtc_read_due(s(1)), "read again after RESYNC_US only");
        }
    }

    #[test]
    fn a_calendar_out_of_range_reads_unset() {
        let mut clock = WallClock::new();
        let mut rtc = Rtc {
            marker: MARKER,
            rsf: true,
            tr: 0x0099_9999,
            dr: 0x0099_9999,
            ..Rtc::default()
        };
        assert_eq!(pass(&mut clock, &mut rtc, s(0)), None);
        assert_eq!(clock.seconds(s(0)), None);
    }
}
