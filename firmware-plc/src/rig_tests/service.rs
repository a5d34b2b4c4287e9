//! The service endpoint on the whole application (service.md 10, core): requests,
//! answers and refusals; `Hello`; remote service from the keypad and its expiry; a
//! repeated guarded request executed once; EEPROM writes refused in RUN; the event
//! `LOGCLR`; samples; garbage on the line.

use super::service_support::*;

#[test]
fn requests_before_hello_are_refused_and_hello_tells_the_version() {
    let mut rig = Rig::new();
    assert_eq!(
        rig.ask(Request::GetStatus),
        Answer::Refused(RefuseReason::Hello)
    );
    // Another version: the PLC still tells its own, and goes on refusing.
    assert_eq!(
        rig.ask(Request::Hello { version: 99 }),
        Answer::HelloReply {
            version: SERVICE_VERSION
        }
    );
    assert_eq!(rig.ask(Request::Stop), Answer::Refused(RefuseReason::Hello));
    rig.hello();
    assert!(matches!(rig.ask(Request::GetStatus), Answer::Status(_)));
    // 30 s without a valid frame: a new client, `Hello` again.
    rig.run_ms(30_000);
    assert_eq!(
        rig.ask(Request::GetStatus),
        Answer::Refused(RefuseReason::Hello)
    );
    // The PLC can announce another version (hil-sim `--service-version`).
    rig.svc.port().set_version(99);
    assert_eq!(
        rig.ask(Request::Hello {
            version: SERVICE_VERSION
        }),
        Answer::HelloReply { version: 99 }
    );
    assert_eq!(
        rig.ask(Request::GetStatus),
        Answer::Refused(RefuseReason::Hello)
    );
}

#[test]
fn reads_answer_from_ram_and_the_eeprom() {
    let motor = assemble(MOTOR).unwrap();
    let small = assemble(SMALL).unwrap();
    let mut s = Storage::new(MemEeprom::new());
    s.save(1, &motor).unwrap();
    s.save(3, &small).unwrap();
    s.save(3, &small).unwrap();
    for (code, t) in [(3u8, 5_000u64), (1, 9_000), (7, 12_000)] {
        s.log_fault(code, t).unwrap();
    }
    let mut rig = Rig::with_eeprom(s.into_eeprom());
    rig.run_ms(5);
    rig.hello();

    let Answer::Identity(id) = rig.ask(Request::Identify) else {
        panic!()
    };
    assert_eq!(
        (id.firmware.as_str(), id.git.as_str()),
        ("0.1.0", "abcdef0")
    );
    assert_eq!(id.uid, BUILD.uid);
    assert_eq!(id.power_ups, 1);
    assert_eq!(id.uptime_ms, rig.now.0 / 1000);

    let Answer::Status(st) = rig.ask(Request::GetStatus) else {
        panic!()
    };
    assert_eq!(st.plc, PlcState::Stop);
    assert!(!st.remote);
    assert_eq!(st.link, LinkView::Lost);
    assert_eq!(st.drive, None);
    assert_eq!(st.uptime_ms, rig.now.0 / 1000);
    // Three entries from position 0: the newest is at 2, code 7.
    assert_eq!(st.newest_log, Some((2, 7)));

    let Answer::Screen(sc) = rig.ask(Request::GetScreen) else {
        panic!()
    };
    assert_eq!(sc.rows.len(), 4);
    for (r, row) in sc.rows.iter().enumerate() {
        assert_eq!(row.as_str(), rig.screen.row(r as u8).trim_end(), "row {r}");
    }

    let Answer::FaultLog(log) = rig.ask(Request::ReadFaultLog {
        from: LOG_FROM_NEWEST,
        count: 8,
    }) else {
        panic!()
    };
    assert_eq!((log.total, log.newest), (3, Some(2)));
    let got: Vec<(u8, u8, u32)> = log
        .entries
        .iter()
        .map(|e| (e.pos, e.code, e.uptime_s))
        .collect();
    assert_eq!(got, vec![(2, 7, 12), (1, 1, 9), (0, 3, 5)]);
    // From a position, and a count.
    let Answer::FaultLog(log) = rig.ask(Request::ReadFaultLog { from: 1, count: 1 }) else {
        panic!()
    };
    assert_eq!(log.entries.len(), 1);
    assert_eq!((log.entries[0].pos, log.entries[0].code), (1, 1));

    let Answer::Slots(slots) = rig.ask(Request::ListSlots) else {
        panic!()
    };
    let states: Vec<SlotState> = slots.slots.iter().map(|s| s.state).collect();
    assert_eq!(
        states,
        vec![
            SlotState::Valid,
            SlotState::Empty,
            SlotState::Valid,
            SlotState::Empty
        ]
    );
    assert_eq!(slots.slots[2].generation, 2);
    assert_eq!(slots.slots[0].crc, CRC32C.checksum(&payload(&motor)));
    assert_eq!(slots.slots[0].len as usize, payload(&motor).len());

    // Slot 1 chunk by chunk: the stored payload, its CRC-32C, the generation.
    let (data, crc, generation) = pull(&mut rig, 1);
    assert_eq!(data, payload(&motor));
    assert_eq!(crc, CRC32C.checksum(&data));
    assert_eq!(generation, 1);
    assert!(data.len() > CHUNK_BYTES, "several chunks");
    // Slot 0: the program in RAM (empty now; power-up loaded nothing).
    let (data, _, _) = pull(&mut rig, 0);
    assert!(data.is_empty());
    assert_eq!(
        rig.ask(Request::ReadProgram { slot: 2, offset: 0 }),
        Answer::Refused(RefuseReason::Slot)
    );
    assert_eq!(
        rig.ask(Request::ReadProgram { slot: 5, offset: 0 }),
        Answer::Refused(RefuseReason::Slot)
    );
    assert_eq!(
        rig.ask(Request::ReadProgram {
            slot: 1,
            offset: 4096
        }),
        Answer::Refused(RefuseReason::Transfer)
    );
    // A keypad save into slot 3 is seen by the next read.
    rig.plc.replace_program(&motor);
    rig.keys(&[Key::C, Key::Digit(3)]);
    rig.run_ms(300);
    let (data, _, generation) = pull(&mut rig, 3);
    assert_eq!((data, generation), (payload(&motor), 3));
}

#[test]
fn guarded_requests_need_remote_service_and_a_repeat_runs_once() {
    let mut rig = Rig::new();
    rig.plc.replace_program(&assemble(SMALL).unwrap());
    rig.hello();
    for req in [
        Request::Run { slot: 0 },
        Request::Ack,
        Request::ClearFaultLog,
        Request::WriteCommit,
    ] {
        assert_eq!(rig.ask(req), Answer::Refused(RefuseReason::Locked));
    }
    // Stop is never guarded.
    assert_eq!(rig.ask(Request::Stop), Answer::Done);

    rig.keys(&[Key::Star, Key::Digit(7)]);
    // The next periodic redraw shows the notice.
    rig.run_ms(100);
    assert!(
        rig.screen.to_string().contains("REMOTE SVC ON"),
        "{}",
        rig.screen
    );
    let Answer::Status(st) = rig.ask(Request::GetStatus) else {
        panic!()
    };
    assert!(st.remote);

    assert_eq!(rig.ask_id(40, Request::Run { slot: 0 }), Answer::Done);
    assert_ne!(rig.plc.run_state(), RunState::Stopped);
    assert_eq!(rig.ask_id(41, Request::Stop), Answer::Done);
    assert_eq!(rig.plc.run_state(), RunState::Stopped);
    // The host did not hear the answer and sends Run 40 again: the stored answer, and
    // nothing runs.
    assert_eq!(rig.ask_id(40, Request::Run { slot: 0 }), Answer::Done);
    assert_eq!(rig.plc.run_state(), RunState::Stopped);
    // A new id runs again.
    assert_eq!(rig.ask_id(42, Request::Run { slot: 0 }), Answer::Done);
    assert_ne!(rig.plc.run_state(), RunState::Stopped);
    // EEPROM writes are refused while not stopped.
    assert_eq!(
        rig.ask(Request::ClearFaultLog),
        Answer::Refused(RefuseReason::InRun)
    );
    assert_eq!(
        rig.ask(Request::WriteBegin {
            slot: 1,
            len: 4,
            crc: 0
        }),
        Answer::Refused(RefuseReason::InRun)
    );
    assert_eq!(rig.ask(Request::Stop), Answer::Done);
    // Run of a slot: empty slot refused; unsaved edits refused.
    assert_eq!(
        rig.ask(Request::Run { slot: 2 }),
        Answer::Refused(RefuseReason::Unsaved)
    );
    rig.keys(&[Key::C, Key::Digit(2)]);
    rig.run_ms(300);
    assert_eq!(
        rig.ask(Request::Run { slot: 4 }),
        Answer::Refused(RefuseReason::Slot)
    );
    assert_eq!(rig.ask(Request::Run { slot: 2 }), Answer::Done);
    rig.run_ms(300);
    assert_ne!(rig.plc.run_state(), RunState::Stopped, "loaded, then RUN");

    // `*` `7` again: off.
    rig.keys(&[Key::Star, Key::Digit(7)]);
    rig.run_ms(100);
    assert!(rig.screen.to_string().contains("REMOTE SVC OFF"));
    assert_eq!(rig.ask(Request::Ack), Answer::Refused(RefuseReason::Locked));
}

#[test]
fn remote_service_switches_itself_off_30_minutes_after_the_last_guarded_request() {
    let mut rig = Rig::new();
    rig.hello();
    rig.keys(&[Key::Star, Key::Digit(7)]);
    let on_at = rig.now.0 / 1000;
    assert!(rig.plc.remote_service(rig.now));
    // A guarded request 10 min later renews it until 40 min after the start.
    let later = Micros(rig.now.0 + 10 * 60 * 1_000_000);
    assert!(rig.plc.remote_service(later));
    rig.now = later;
    assert_eq!(rig.ask(Request::Stop), Answer::Done); // not guarded: no renewal
    let _ = rig.ask(Request::Ack); // guarded (no link: refused, but renews)
    let renewed_at = rig.now.0 / 1000;
    assert!(renewed_at > on_at);
    assert!(rig
        .plc
        .remote_service(Micros((on_at + REMOTE_TIMEOUT_MS + 1000) * 1000)));
    assert!(!rig
        .plc
        .remote_service(Micros((renewed_at + REMOTE_TIMEOUT_MS) * 1000)));
    // The tick switches it off and says so.
    rig.now = Micros((renewed_at + REMOTE_TIMEOUT_MS) * 1000);
    rig.run_ms(100);
    assert!(rig.screen.to_string().contains("REMOTE SVC OFF"));
}

#[test]
fn clearing_the_log_leaves_the_event_logclr_keypad_and_service() {
    let mut s = Storage::new(MemEeprom::new());
    s.log_fault(3, 5_000).unwrap();
    let mut rig = Rig::with_eeprom(s.into_eeprom());
    // Keypad: fault-log page, `*` `0`.
    rig.plc.key(Key::B, rig.now);
    rig.plc.key(Key::B, rig.now);
    rig.keys(&[Key::Star, Key::Digit(0)]);
    rig.run_ms(100);
    let codes: Vec<u8> = rig.plc.fault_log().iter().map(|e| e.code).collect();
    assert_eq!(codes, vec![EVENT_LOG_CLEARED]);
    // Service.
    rig.plc.storage().log_fault(5, 1000).unwrap();
    rig.hello();
    rig.keys(&[Key::Star, Key::Digit(7)]);
    assert_eq!(rig.ask(Request::ClearFaultLog), Answer::Done);
    rig.run_ms(100);
    let Answer::FaultLog(log) = rig.ask(Request::ReadFaultLog {
        from: LOG_FROM_NEWEST,
        count: 8,
    }) else {
        panic!()
    };
    assert_eq!(log.total, 1);
    assert_eq!(log.entries[0].code, EVENT_LOG_CLEARED);
    assert_eq!(log.newest, Some(0));
    // Events are not the run screen's newest fault.
    assert_eq!(rig.plc.status().newest_fault, None);
}

#[test]
fn samples_follow_the_period_and_busy_ones_are_dropped_and_counted() {
    let mut rig = Rig::new();
    rig.hello();
    assert_eq!(
        rig.ask(Request::Subscribe {
            period_ms: 5,
            q: heapless::Vec::new()
        }),
        Answer::Subscribed { period_ms: 10 },
        "clamped to 10 ms"
    );
    rig.samples.clear();
    rig.run_ms(100);
    let t: Vec<u64> = rig.samples.iter().map(|s| s.uptime_ms).collect();
    assert!(t.len() >= 9 && t.len() <= 11, "{t:?}");
    assert!(t.iter().all(|t| t % 10 == 0), "{t:?}");
    assert!(rig.samples.iter().all(|s| s.q.len() == 8 && s.dropped == 0));
    // A transmitter that does not take frames for 50 ms: 4 samples dropped, counted in
    // the next one that goes.
    rig.poll = false;
    rig.run_ms(50);
    rig.poll = true;
    rig.samples.clear();
    rig.run_ms(30);
    let dropped: u32 = rig.samples.iter().map(|s| s.dropped).sum();
    assert_eq!(dropped, 4, "{:?}", rig.samples);
    // Answers go before samples.
    let q: heapless::Vec<u8, 8> = heapless::Vec::from_slice(&[60, 61]).unwrap();
    assert_eq!(
        rig.ask(Request::Subscribe { period_ms: 100, q }),
        Answer::Subscribed { period_ms: 100 }
    );
    rig.samples.clear();
    rig.run_ms(200);
    assert!(rig.samples.iter().all(|s| s.q.len() == 2));
    assert_eq!(
        rig.ask(Request::Subscribe {
            period_ms: 0,
            q: heapless::Vec::new()
        }),
        Answer::Subscribed { period_ms: 0 }
    );
    rig.samples.clear();
    rig.run_ms(200);
    assert!(rig.samples.is_empty());
}

#[test]
fn garbage_on_the_line_never_stops_the_port() {
    let mut rig = Rig::new();
    let mut x = 0x1234_5678u32;
    for _ in 0..200 {
        let mut junk = [0u8; 64];
        for b in &mut junk {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            *b = x as u8;
        }
        rig.svc.on_rx(&junk, rig.now);
        rig.tick();
    }
    rig.svc.on_rx(&[0], rig.now);
    rig.hello();
    assert!(matches!(rig.ask(Request::GetStatus), Answer::Status(_)));
    assert!(rig.svc.port().stats().frames_bad > 0);
}
