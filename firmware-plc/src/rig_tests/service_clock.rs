//! The clock over the service port: unset after power-up, set without remote service,
//! running on the uptime, handed to the board for the RTC, refused beyond 2099.

use super::service_support::*;
use shared_protocol::service::WALL_MAX_S;

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
    assert!(rig.plc.rtc_write_due());
    rig.run_ms(2_500);
    assert_eq!(
        rig.ask(Request::GetClock),
        Answer::Clock {
            seconds: Some(849_261_602)
        }
    );
    // The board's RTC task takes the time to write, once.
    let now = rig.now;
    assert_eq!(rig.plc.take_rtc_write(now), Some(849_261_602));
    assert!(!rig.plc.rtc_write_due());
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
    rig.plc.rtc_read(Some(1_000), Micros(0));
    rig.hello();
    rig.run_ms(1_000);
    assert_eq!(
        rig.ask(Request::GetClock),
        Answer::Clock {
            seconds: Some(1_001)
        }
    );
}
