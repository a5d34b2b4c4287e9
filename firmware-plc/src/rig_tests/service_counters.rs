//! The counters through the service port (service.md 7): `GetCounters` gives the RAM
//! values, the power-up count and the time since the last write; the record is written at
//! STOP and found again at the next power-up; both copies bad restart the counters with
//! `COUNTERS RESET` on the LCD. The counting rules, the 10-minute cadence and the power-cut
//! safety of the record are unit-tested next to the code (`service::counters`,
//! `storage::counters`).

use super::service_support::*;
use crate::storage::counters::{CounterValues, COUNTERS_BYTES};
use crate::storage::layout::COUNTERS_ADDR;
use crate::storage::Eeprom;
use shared_protocol::service::{Counters, WriteResult};

fn counters(rig: &mut Rig) -> Counters {
    match rig.ask(Request::GetCounters) {
        Answer::Counters(c) => c,
        other => panic!("{other:?}"),
    }
}

/// A power-up with `e` (`PlcApp::new` counts it), a client said `Hello`.
fn powered_up(e: MemEeprom) -> Rig {
    let mut rig = Rig::with_eeprom(e);
    rig.run_ms(20);
    rig.hello();
    rig
}

fn screen(rig: &mut Rig) -> String {
    match rig.ask(Request::GetScreen) {
        Answer::Screen(s) => s.rows.iter().map(|r| r.as_str()).collect(),
        other => panic!("{other:?}"),
    }
}

#[test]
fn saves_are_counted_written_at_stop_and_found_after_a_power_cycle() {
    let mut rig = powered_up(MemEeprom::new());
    let c = counters(&mut rig);
    assert_eq!(c.power_ups, rig.plc.storage().power_cycle());
    assert_eq!(
        (c.program_saves, c.run_starts, c.since_write_s),
        (0, 0, None)
    );
    assert!(!screen(&mut rig).contains("COUNTERS RESET"));
    rig.keys(&[Key::Star, Key::Digit(7)]);

    // A keypad save and a service write: two program saves (in RAM, not yet written).
    rig.plc.replace_program(&assemble(SMALL).unwrap());
    rig.keys(&[Key::C, Key::Digit(2)]);
    rig.run_ms(500);
    let bytes = payload(&assemble(MOTOR).unwrap());
    assert!(matches!(
        rig.push(3, &bytes),
        Answer::WriteResult(WriteResult::Saved { .. })
    ));
    rig.run_ms(300);
    let c = counters(&mut rig);
    assert_eq!((c.program_saves, c.since_write_s), (2, None));
    let page = |rig: &mut Rig, copy: usize| {
        let mut b = [0u8; COUNTERS_BYTES];
        rig.plc
            .storage()
            .eeprom()
            .read(COUNTERS_ADDR[copy], &mut b)
            .unwrap();
        b
    };
    assert_eq!(page(&mut rig, 0), [0xFF; COUNTERS_BYTES]);

    // RUN (it waits for the link: no drive here), then STOP: the record is written.
    assert_eq!(rig.ask(Request::Run { slot: 0 }), Answer::Done);
    rig.run_ms(20);
    assert_eq!(rig.ask(Request::Stop), Answer::Done);
    rig.run_ms(20);
    let want = CounterValues {
        program_saves: 2,
        ..Default::default()
    };
    assert_eq!(page(&mut rig, 0), want.to_bytes(1));
    assert_eq!(page(&mut rig, 1), [0xFF; COUNTERS_BYTES]);
    rig.run_ms(2000);
    let c = counters(&mut rig);
    assert!(
        c.since_write_s.is_some_and(|s| (1..=2).contains(&s)),
        "{c:?}"
    );

    // The next power-up reads the record; the power-up count went up.
    let before = c.power_ups;
    let mut rig = powered_up(rig.plc.storage().eeprom().clone());
    let c = counters(&mut rig);
    assert_eq!((c.program_saves, c.power_ups), (2, before + 1));
    assert!(!screen(&mut rig).contains("COUNTERS RESET"));
}

#[test]
fn both_copies_bad_restart_at_zero_with_counters_reset_on_the_lcd() {
    let mut s = Storage::new(MemEeprom::new());
    s.save(1, &assemble(SMALL).unwrap()).unwrap();
    let mut e = s.into_eeprom();
    let mut good = CounterValues {
        program_saves: 7,
        ..Default::default()
    }
    .to_bytes(4);
    good[20] ^= 1;
    for (addr, bytes) in COUNTERS_ADDR.iter().zip([good, [0u8; COUNTERS_BYTES]]) {
        e.start_write(*addr, &bytes).unwrap();
        while !e.ready().unwrap() {}
    }
    let mut rig = powered_up(e);
    assert!(screen(&mut rig).contains("COUNTERS RESET"));
    assert_eq!(counters(&mut rig).program_saves, 0);
}
