//! The clock over the service port: unset after power-up, set without remote service,
//! running on the uptime, handed to the board for the RTC, refused beyond 2099.

use super::service_support::*;
use crate::clock::rtc_format;
use crate::clock::rtc_sync::{Calendar, RtcEvent, RtcPort, MARKER};
use shared_protocol::service::WALL_MAX_S;

/// A running backup domain: the crystal up, every wait met.
#[derive(Default)]
struct BackupDomain {
    marker: u32,
    tr: u32,
    dr: u32,
}

impl RtcPort for BackupDomain {
    fn crystal_ready(&mut self) -> bool {
        true
    }
    fn marker(&mut self) -> u32 {
        self.marker
    }
    fn set_marker(&mut self, value: u32) {
        self.marker = value;
    }
    fn read_calendar(&mut self) -> Option<Calendar> {
        Some(Calendar {
            tr: self.tr,
            dr: self.dr,
            ssr: 255,
        })
    }
    fn enter_init(&mut self) -> bool {
        true
    }
    fn write_calendar(&mut self, tr: u32, dr: u32) {
        (self.tr, self.dr) = (tr, dr);
    }
    fn exit_init(&mut self) {}
}

#[test]
fn the_clock_is_set_and_read_over_the_service_port() {
    let mut rig = Rig::new();
    rig.hello();
    assert_eq!(rig.ask(Request::GetClock), Answer::Clock { seconds: None });
    // Never guarded: remote service is off.
    assert_eq!(
        rig.ask(Request::SetClock {
            seconds: 849_261_600
        }),
        Answer::Clock {
            seconds: Some(849_261_600)
        }
    );
    rig.run_ms(2_500);
    assert_eq!(
        rig.ask(Request::GetClock),
        Answer::Clock {
            seconds: Some(849_261_602)
        }
    );
    // The board's RTC task writes the time, once.
    let mut rtc = BackupDomain::default();
    let now = rig.now;
    assert_eq!(
        rig.plc.rtc_pass(&mut rtc, now),
        Some(RtcEvent::Set {
            seconds: 849_261_602
        })
    );
    assert_eq!(rtc_format::seconds(rtc.tr, rtc.dr), Some(849_261_602));
    assert_eq!(rtc.marker, MARKER);
    assert_eq!(rig.plc.rtc_pass(&mut rtc, now), None);
    assert_eq!(
        rig.ask(Request::SetClock {
            seconds: WALL_MAX_S + 1
        }),
        Answer::Refused(RefuseReason::Transfer)
    );
    assert_eq!(
        rig.ask(Request::GetClock),
        Answer::Clock {
            seconds: Some(849_261_602)
        },
        "a refused time changes nothing"
    );
}

#[test]
fn the_rtc_read_at_boot_sets_the_clock() {
    let mut rig = Rig::new();
    let (tr, dr) = rtc_format::registers(1_000);
    let mut rtc = BackupDomain {
        marker: MARKER,
        tr,
        dr,
    };
    assert_eq!(rig.plc.rtc_pass(&mut rtc, Micros(0)), None);
    rig.hello();
    rig.run_ms(1_000);
    assert_eq!(
        rig.ask(Request::GetClock),
        Answer::Clock {
            seconds: Some(1_001)
        }
    );
}
