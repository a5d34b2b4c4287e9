//! Both link endpoints over the byte-timed in-memory UART: handshake, commands, download,
//! supervision, reconnection, version mismatch.

use shared_protocol::fault::FaultCode;
use shared_protocol::link::channel::Impairments;
use shared_protocol::link::frame::{encode_frame, Frame, FrameReader, MAX_WIRE_FRAME};
use shared_protocol::link::line::Pumped;
use shared_protocol::link::pair::LinkPair;
use shared_protocol::link::pump::MAX_IDLE_US;
use shared_protocol::link::{
    CommandError, DownloadResult, DriveEvent, DriveLinkState, DriveMsg, DriveState, DriveStatus,
    LinkConfig, PlcEvent, PlcLink, PlcLinkState, PlcMsg, RejectReason, PROTOCOL_VERSION,
};
use shared_protocol::program::{DriveSection, Instruction, Mnemonic, Operand};
use shared_protocol::units::Micros;

fn ms(t: u64) -> Micros {
    Micros(t * 1000)
}

fn connected_pair(baud: u32) -> LinkPair {
    let mut p = LinkPair::new(LinkConfig::at_baud(baud), Impairments::default(), 1);
    p.run_until(ms(10), |_| {});
    assert!(p.plc.is_up() && p.drive.is_up(), "handshake within 10 ms");
    assert_eq!(p.plc.poll_event(), Some(PlcEvent::Connected));
    assert_eq!(p.drive.poll_event(), Some(DriveEvent::Connected));
    p
}

fn drive_events(p: &mut LinkPair) -> Vec<DriveEvent> {
    std::iter::from_fn(|| p.drive.poll_event()).collect()
}

/// Run until the drive reports the predicate; returns the time it did.
fn until_drive(
    p: &mut LinkPair,
    limit: Micros,
    mut f: impl FnMut(&DriveEvent) -> bool,
) -> Option<Micros> {
    while p.now < limit {
        p.step(limit);
        while let Some(e) = p.drive.poll_event() {
            if f(&e) {
                return Some(p.now);
            }
        }
    }
    None
}

#[test]
fn q_write_is_applied_within_2ms_at_115200() {
    let mut p = connected_pair(115_200);
    let mut worst = 0;
    for k in 0..200u64 {
        // Issue at awkward moments relative to heartbeats and status frames.
        let issue = Micros(p.now.0 + 3_000 + (k * 377) % 9_000);
        p.run_until(issue, |_| {});
        drive_events(&mut p);
        p.plc.write_q(5, k as i16).unwrap();
        p.kick();
        let t = until_drive(&mut p, Micros(issue.0 + 50_000), |e| {
            *e == DriveEvent::QWrite {
                addr: 5,
                value: k as i16,
            }
        })
        .expect("applied");
        worst = worst.max(t.0 - issue.0);
    }
    assert!(worst <= 2_000, "worst latency {worst} us");
}

#[test]
fn commands_are_applied_once_in_order() {
    let mut p = connected_pair(115_200);
    p.plc.write_q(1, 10).unwrap();
    p.plc.set_direction(true).unwrap();
    p.plc.write_q(1, 11).unwrap();
    p.plc.run().unwrap();
    p.plc.write_q(2, -7).unwrap();
    p.plc.ack_fault().unwrap();
    let end = Micros(p.now.0 + 30_000);
    p.run_until(end, |_| {});
    assert_eq!(
        drive_events(&mut p),
        vec![
            DriveEvent::QWrite { addr: 1, value: 10 },
            DriveEvent::Direction { reverse: true },
            DriveEvent::QWrite { addr: 1, value: 11 },
            DriveEvent::Run,
            DriveEvent::QWrite { addr: 2, value: -7 },
            DriveEvent::AckFault,
        ]
    );
    assert_eq!(p.plc.unacknowledged(), 0);
}

/// The PLC's next frame, decoded.
fn next_plc_frame(p: &mut LinkPair) -> Option<PlcMsg> {
    let mut buf = [0u8; MAX_WIRE_FRAME];
    let n = p.plc.poll_transmit(p.now, &mut buf);
    let mut r = FrameReader::new();
    buf[..n]
        .iter()
        .find_map(|&b| r.push::<PlcMsg>(b))
        .map(|f| f.unwrap().msg)
}

/// Fill the PLC's command queue: RUN, every Q, then ACKs until refused. Returns the ACKs.
fn fill_queue(p: &mut LinkPair) -> usize {
    p.plc.run().unwrap();
    for addr in 0..64 {
        p.plc.write_q(addr, i16::from(addr)).unwrap();
    }
    let mut acks = 0;
    loop {
        match p.plc.ack_fault() {
            Ok(()) => acks += 1,
            Err(e) => {
                assert_eq!(e, CommandError::QueueFull);
                break;
            }
        }
        assert!(acks < 1000);
    }
    assert!(acks > 0);
    acks
}

#[test]
fn stop_with_the_queue_full_is_the_next_frame_and_drops_waiting_q_writes_and_run() {
    let mut p = connected_pair(115_200);
    let acks = fill_queue(&mut p);
    let waiting = p.plc.unacknowledged();
    assert_eq!(waiting, 1 + 64 + acks);
    p.plc
        .stop()
        .expect("STOP is never refused while the link is up");
    // RUN and the 64 Q writes are gone; STOP is in.
    assert_eq!(p.plc.unacknowledged(), 1 + acks);
    assert_eq!(next_plc_frame(&mut p), Some(PlcMsg::Stop));
    // A second STOP (the first is on the wire) goes ahead of the ACKs and drops a Q
    // write issued meanwhile; a third replaces the waiting second.
    p.plc.stop().unwrap();
    assert_eq!(p.plc.unacknowledged(), 2 + acks);
    p.plc.write_q(0, 1).unwrap();
    assert_eq!(p.plc.unacknowledged(), 3 + acks);
    p.plc.stop().unwrap();
    assert_eq!(
        p.plc.unacknowledged(),
        2 + acks,
        "the Q write and the second STOP went"
    );
    let end = Micros(p.now.0 + 1_000_000);
    let mut ev = Vec::new();
    p.run_until(end, |p| ev.extend(drive_events(p)));
    assert_eq!(ev.first(), Some(&DriveEvent::Stop));
    assert_eq!(ev.iter().filter(|e| **e == DriveEvent::Stop).count(), 2);
    assert_eq!(
        ev.iter().filter(|e| **e == DriveEvent::AckFault).count(),
        acks
    );
    assert!(
        !ev.iter()
            .any(|e| matches!(e, DriveEvent::Run | DriveEvent::QWrite { .. })),
        "{ev:?}"
    );
    assert_eq!(p.plc.unacknowledged(), 0);
}

#[test]
fn stop_overtakes_everything_not_yet_on_the_wire_and_the_drive_ends_stopped() {
    let mut p = connected_pair(115_200);
    // RUN and a first Q frame go on the wire; the rest waits.
    p.plc.run().unwrap();
    for addr in 0..40 {
        p.plc.write_q(addr, 5).unwrap();
    }
    assert_eq!(next_plc_frame(&mut p), Some(PlcMsg::Run));
    assert!(matches!(next_plc_frame(&mut p), Some(PlcMsg::QWrite(v)) if v.len() == 8));
    p.plc.set_direction(true).unwrap();
    p.plc.run().unwrap();
    p.plc.stop().unwrap();
    assert_eq!(next_plc_frame(&mut p), Some(PlcMsg::Stop));
    let end = Micros(p.now.0 + 200_000);
    let mut ev = Vec::new();
    p.run_until(end, |p| ev.extend(drive_events(p)));
    // What was on the wire arrives (RUN, one Q frame), then STOP, then the direction;
    // the second RUN and the 32 waiting Q writes were dropped.
    let commands: Vec<_> = ev
        .iter()
        .filter(|e| !matches!(e, DriveEvent::QWrite { .. }))
        .collect();
    assert_eq!(
        commands,
        [
            &DriveEvent::Run,
            &DriveEvent::Stop,
            &DriveEvent::Direction { reverse: true }
        ]
    );
    let q = ev
        .iter()
        .filter(|e| matches!(e, DriveEvent::QWrite { .. }))
        .count();
    assert_eq!(q, 8);
    assert_eq!(p.plc.unacknowledged(), 0);
}

#[test]
fn stop_is_refused_only_while_the_link_is_down() {
    let mut p = LinkPair::new(LinkConfig::default(), Impairments::default(), 1);
    assert_eq!(p.plc.stop(), Err(CommandError::NotConnected));
}

#[test]
fn waiting_q_writes_coalesce_newest_wins() {
    let mut p = connected_pair(115_200);
    // One scan writing the same Q many times, while the UART is busy.
    for v in 0..50 {
        p.plc.write_q(3, v).unwrap();
        p.plc.write_q(4, -v).unwrap();
    }
    let end = Micros(p.now.0 + 30_000);
    p.run_until(end, |_| {});
    let ev = drive_events(&mut p);
    assert!(ev.len() <= 4, "coalesced: {ev:?}");
    let last3 = ev.iter().rev().find_map(|e| match e {
        DriveEvent::QWrite { addr: 3, value } => Some(*value),
        _ => None,
    });
    let last4 = ev.iter().rev().find_map(|e| match e {
        DriveEvent::QWrite { addr: 4, value } => Some(*value),
        _ => None,
    });
    assert_eq!((last3, last4), (Some(49), Some(-49)));
}

#[test]
fn status_reaches_the_plc_and_state_changes_are_prompt() {
    let mut p = connected_pair(115_200);
    let mut s = DriveStatus {
        state: DriveState::Run,
        freq_dhz: 500,
        udc_dv: 300,
        com: 512,
        ..Default::default()
    };
    p.drive.set_status(s);
    let end = Micros(p.now.0 + 25_000);
    p.run_until(end, |_| {});
    assert_eq!(p.plc.last_status().map(|(st, _)| st), Some(s));
    // A trip is reported at once (not at the next 10 ms period) and as a reliable event.
    s.state = DriveState::Fault;
    s.fault = Some(FaultCode::Oc);
    p.drive.set_status(s);
    assert!(p.drive.report_fault(FaultCode::Oc, 1234));
    let t0 = p.now;
    let mut seen_status = None;
    let mut seen_event = None;
    p.run_until(Micros(t0.0 + 20_000), |p| {
        if seen_status.is_none()
            && p.plc.last_status().map(|x| x.0.fault) == Some(Some(FaultCode::Oc))
        {
            seen_status = Some(p.now);
        }
        if let Some(PlcEvent::DriveFault {
            code: FaultCode::Oc,
            drive_time_ms: 1234,
        }) = p.plc.poll_event()
        {
            seen_event = Some(p.now);
        }
    });
    assert!(seen_status.unwrap().0 - t0.0 < 5_000);
    assert!(seen_event.unwrap().0 - t0.0 < 5_000);
}

fn ins(mnemonic: Mnemonic, operand: Option<Operand>, constant: u16) -> Option<Instruction> {
    Some(Instruction {
        mnemonic,
        operand,
        constant,
    })
}

fn ramp_section() -> DriveSection {
    let mut d = DriveSection::default();
    d.lines[0] = ins(Mnemonic::Pwf, Some(Operand::K(0)), 5000);
    d.lines[1] = ins(Mnemonic::Ld, Some(Operand::Q(0)), 0);
    d.lines[2] = ins(Mnemonic::Wr, Some(Operand::Q(1)), 0);
    d.lines[149] = ins(Mnemonic::Fmx, Some(Operand::K(1)), 500);
    d
}

fn download(p: &mut LinkPair, section: &DriveSection) -> (Option<DownloadResult>, Vec<DriveEvent>) {
    p.plc.start_download(section).unwrap();
    assert!(p.plc.download_in_progress());
    let mut result = None;
    let mut drive = Vec::new();
    let end = Micros(p.now.0 + 300_000);
    p.run_until(end, |p| {
        while let Some(e) = p.plc.poll_event() {
            if let PlcEvent::Download(r) = e {
                result = Some(r);
            }
        }
        drive.extend(std::iter::from_fn(|| p.drive.poll_event()));
    });
    (result, drive)
}

#[test]
fn download_is_verified_and_accepted() {
    let mut p = connected_pair(115_200);
    let section = ramp_section();
    let (result, drive) = download(&mut p, &section);
    assert_eq!(result, Some(DownloadResult::Accepted));
    assert_eq!(drive, vec![DriveEvent::ProgramAccepted]);
    assert_eq!(
        p.drive.take_program().map(|v| v.section().clone()),
        Some(section)
    );
    assert!(!p.plc.download_in_progress());
}

#[test]
fn download_reject_names_line_and_reason() {
    let mut p = connected_pair(115_200);
    let mut section = ramp_section();
    // A PLC instruction in the drive section.
    section.lines[42] = ins(Mnemonic::Not, None, 0);
    let (result, drive) = download(&mut p, &section);
    let Some(DownloadResult::Rejected {
        line: 42,
        reason: RejectReason::Verify(code),
    }) = result
    else {
        panic!("{result:?}");
    };
    assert_eq!(
        drive,
        vec![DriveEvent::ProgramRejected {
            line: 42,
            reason: RejectReason::Verify(code)
        }]
    );
    assert!(p.drive.take_program().is_none());
}

#[test]
fn download_survives_a_lossy_link() {
    let imp = Impairments {
        bit_error_rate: 1e-3,
        frame_drop: 0.05,
        ..Default::default()
    };
    let mut p = LinkPair::new(LinkConfig::default(), imp, 99);
    p.run_until(ms(200), |_| {});
    assert!(p.plc.is_up());
    let section = ramp_section();
    let (result, _) = download(&mut p, &section);
    assert_eq!(result, Some(DownloadResult::Accepted));
    assert_eq!(
        p.drive.take_program().map(|v| v.section().clone()),
        Some(section)
    );
}

#[test]
fn cut_link_is_detected_on_both_sides_then_reconnects() {
    let mut p = connected_pair(115_200);
    p.plc.write_q(7, 700).unwrap();
    p.plc.set_direction(true).unwrap();
    let end = Micros(p.now.0 + 20_000);
    p.run_until(end, |_| {});
    drive_events(&mut p);

    let cut = p.now;
    p.line.to_drive.set_cut(true);
    p.line.to_plc.set_cut(true);
    p.plc.write_q(7, 701).unwrap(); // while cut: kept, resent after the handshake
    let mut drive_lost = None;
    let mut plc_lost = None;
    p.run_until(Micros(cut.0 + 150_000), |p| {
        while let Some(e) = p.drive.poll_event() {
            if e == DriveEvent::LinkLost {
                drive_lost.get_or_insert(p.now);
            }
        }
        while let Some(e) = p.plc.poll_event() {
            if let PlcEvent::LinkLost { .. } = e {
                plc_lost.get_or_insert(p.now);
            }
        }
    });
    let drive_lost = drive_lost.expect("drive saw the loss").0 - cut.0;
    let plc_lost = plc_lost.expect("PLC saw the loss").0 - cut.0;
    // 50 ms after the last valid frame, which came at most one heartbeat before the cut.
    assert!(
        (50_000 - 8_000..=51_000).contains(&drive_lost),
        "drive after {drive_lost} us"
    );
    // 40 ms after the last status, leaving 60 ms for the LCD redraw (PlcApp::alerts).
    assert!(plc_lost <= 40_000, "PLC after {plc_lost} us");
    assert_eq!(p.drive.state(), DriveLinkState::Down);
    assert_eq!(p.plc.state(), PlcLinkState::Connecting);

    p.line.to_drive.set_cut(false);
    p.line.to_plc.set_cut(false);
    let back = p.now;
    let end = Micros(back.0 + 100_000);
    p.run_until(end, |_| {});
    assert!(p.plc.is_up() && p.drive.is_up());
    assert_eq!(p.plc.poll_event(), Some(PlcEvent::Connected));
    let ev = drive_events(&mut p);
    assert_eq!(
        ev,
        vec![
            DriveEvent::Connected,
            DriveEvent::QWrite {
                addr: 7,
                value: 701
            },
            DriveEvent::Direction { reverse: true },
        ]
    );
}

#[test]
fn plc_heartbeat_gap_stays_below_10ms() {
    let mut p = connected_pair(115_200);
    let mut last = p.now;
    let mut sent = p.line.to_drive.stats().frames;
    let mut worst = 0;
    p.run_until(ms(2_000), |p| {
        let f = p.line.to_drive.stats().frames;
        if f != sent {
            worst = worst.max(p.now.0 - last.0);
            last = p.now;
            sent = f;
        }
    });
    assert!(worst <= 10_000, "gap {worst} us");
    assert!(p.drive.is_up());
}

fn hello_session(plc: &mut PlcLink, now: Micros) -> u8 {
    let mut out = [0u8; MAX_WIRE_FRAME];
    let n = plc.poll_transmit(now, &mut out);
    let mut r = FrameReader::new();
    for &b in &out[..n] {
        if let Some(Ok(Frame {
            msg: PlcMsg::Hello { version, session },
            ..
        })) = r.push::<PlcMsg>(b)
        {
            assert_eq!(version, PROTOCOL_VERSION);
            return session;
        }
    }
    panic!("no hello");
}

#[test]
fn version_mismatch_is_reported_on_both_sides() {
    let cfg = LinkConfig::default();
    // PLC side: the drive answers with version 99.
    let mut plc = PlcLink::new(cfg);
    let session = hello_session(&mut plc, Micros(0));
    let reply = Frame {
        seq: 0,
        ack: 0,
        msg: DriveMsg::HelloReply {
            version: 99,
            session,
        },
    };
    let mut out = [0u8; MAX_WIRE_FRAME];
    let n = encode_frame(&reply, true, &mut out).unwrap();
    plc.receive(&out[..n], Micros(1_000));
    assert_eq!(
        plc.poll_event(),
        Some(PlcEvent::VersionMismatch { drive_version: 99 })
    );
    assert_eq!(
        plc.state(),
        PlcLinkState::Incompatible { drive_version: 99 }
    );
    assert!(plc.run().is_err());

    // Drive side: a PLC with version 99 never brings the link up.
    let mut drive = shared_protocol::link::DriveLink::new(cfg);
    let hello = Frame {
        seq: 0,
        ack: 0,
        msg: PlcMsg::Hello {
            version: 99,
            session: 1,
        },
    };
    let n = encode_frame(&hello, true, &mut out).unwrap();
    drive.receive(&out[..n], Micros(0));
    assert_eq!(
        drive.poll_event(),
        Some(DriveEvent::VersionMismatch { plc_version: 99 })
    );
    assert!(!drive.is_up());
    // It still answers with its own version, so the PLC can show both.
    let n = drive.poll_transmit(Micros(10), &mut out);
    let mut r = FrameReader::new();
    let got: Vec<_> = out[..n]
        .iter()
        .filter_map(|&b| r.push::<DriveMsg>(b))
        .collect();
    assert_eq!(
        got,
        vec![Ok(Frame {
            seq: 0,
            ack: 0,
            msg: DriveMsg::HelloReply {
                version: PROTOCOL_VERSION,
                session: 1
            }
        })]
    );
}

#[test]
fn works_at_1_mbaud() {
    let mut p = connected_pair(1_000_000);
    p.plc.write_q(0, 1).unwrap();
    p.kick();
    let t0 = p.now;
    let t = until_drive(&mut p, ms(100), |e| {
        *e == DriveEvent::QWrite { addr: 0, value: 1 }
    });
    assert!(t.unwrap().0 - t0.0 < 500);
}

/// Run until `limit`, collecting both sides' events with their times.
type Timed<E> = Vec<(u64, E)>;

fn collect(p: &mut LinkPair, limit: Micros) -> (Timed<DriveEvent>, Timed<PlcEvent>) {
    let (mut d, mut u) = (Vec::new(), Vec::new());
    p.run_until(limit, |p| {
        while let Some(e) = p.drive.poll_event() {
            d.push((p.now.0, e));
        }
        while let Some(e) = p.plc.poll_event() {
            u.push((p.now.0, e));
        }
    });
    (d, u)
}

fn restart_plc(seed: Option<u8>) -> (Vec<(u64, DriveEvent)>, u64) {
    let mut p = connected_pair(115_200);
    for v in 0..5 {
        p.plc.write_q(1, v).unwrap();
    }
    p.plc.run().unwrap();
    let end = Micros(p.now.0 + 20_000);
    p.run_until(end, |_| {});
    drive_events(&mut p);
    // The PLC reboots; the drive keeps running.
    let t0 = p.now;
    p.restart_plc(Pumped::new(
        PlcLink::new(LinkConfig::default()),
        MAX_IDLE_US,
    ));
    if let Some(s) = seed {
        p.plc.seed_session(s);
    }
    let mut applied_at = None;
    let mut events = Vec::new();
    while p.now.0 < t0.0 + 1_000_000 && applied_at.is_none() {
        p.step(Micros(t0.0 + 1_000_000));
        if p.plc.is_up() {
            let _ = p.plc.write_q(2, 42);
        }
        while let Some(e) = p.drive.poll_event() {
            if e == (DriveEvent::QWrite { addr: 2, value: 42 }) {
                applied_at = Some(p.now.0 - t0.0);
            }
            events.push((p.now.0 - t0.0, e));
        }
    }
    (events, applied_at.expect("the new PLC's write is applied"))
}

#[test]
fn plc_restart_reusing_the_session_is_a_link_loss_for_the_drive() {
    // Same session number as before the restart: commands had flowed in that session,
    // so its Hello cannot be a retry.
    let (events, applied) = restart_plc(None);
    assert_eq!(events[0].1, DriveEvent::LinkLost);
    assert_eq!(events[1].1, DriveEvent::Connected);
    assert!(applied <= 20_000, "applied after {applied} us");
}

#[test]
fn plc_restart_with_a_new_session_is_a_link_loss_for_the_drive() {
    let (events, applied) = restart_plc(Some(77));
    assert_eq!(events[0].1, DriveEvent::LinkLost);
    assert_eq!(events[1].1, DriveEvent::Connected);
    assert!(applied <= 20_000, "applied after {applied} us");
}

#[test]
fn one_way_cut_drive_to_plc_restarts_the_session_on_both_sides() {
    let mut p = connected_pair(115_200);
    p.line.to_plc.set_cut(true);
    let t0 = p.now;
    let (d, u) = collect(&mut p, Micros(t0.0 + 70_000));
    assert!(u
        .iter()
        .any(|(_, e)| matches!(e, PlcEvent::LinkLost { .. })));
    p.line.to_plc.set_cut(false);
    let (d2, u2) = collect(&mut p, Micros(t0.0 + 200_000));
    let drive: Vec<_> = d.iter().chain(&d2).map(|(_, e)| *e).collect();
    assert_eq!(
        drive,
        vec![DriveEvent::LinkLost, DriveEvent::Connected],
        "{drive:?}"
    );
    assert!(u2.iter().any(|(_, e)| *e == PlcEvent::Connected));
    assert!(p.plc.is_up() && p.drive.is_up());
}

#[test]
fn a_sequence_disagreement_is_detected_and_healed() {
    // The drive has sent reports (its numbering is ahead) but received no command; then
    // the PLC restarts reusing the session number: the drive takes its Hello for a retry.
    let mut p = connected_pair(115_200);
    for k in 0..3 {
        assert!(p.drive.report_fault(FaultCode::Oc, k));
    }
    let end = Micros(p.now.0 + 30_000);
    p.run_until(end, |_| {});
    p.restart_plc(Pumped::new(
        PlcLink::new(LinkConfig::default()),
        MAX_IDLE_US,
    ));
    let t0 = p.now;
    let end = Micros(t0.0 + 30_000);
    p.run_until(end, |_| {});
    assert!(p.plc.is_up());
    assert!(p.drive.report_fault(FaultCode::Uv, 99));
    let mut got = None;
    p.run_until(Micros(t0.0 + 600_000), |p| {
        while let Some(e) = p.plc.poll_event() {
            if let PlcEvent::DriveFault {
                code: FaultCode::Uv,
                ..
            } = e
            {
                got.get_or_insert(p.now.0 - t0.0);
            }
        }
    });
    let got = got.expect("the report arrives after the PLC resynchronised");
    assert!(got <= 400_000, "after {got} us");
    assert!(p.plc.stats().link_losses >= 1);
}

#[test]
fn heartbeats_use_the_quiet_windows_after_scans() {
    let mut p = connected_pair(115_200);
    let mut starts = Vec::new();
    let mut sent = p.line.to_drive.stats().frames;
    let mut next_scan = p.now.0;
    while p.now.0 < 1_000_000 {
        if p.now.0 >= next_scan {
            p.plc.quiet_for(p.now, 950);
            p.kick();
            next_scan += 1_000;
        }
        let f = p.line.to_drive.stats().frames;
        if f != sent {
            starts.push(p.now.0);
            sent = f;
        }
        p.step(Micros(next_scan));
    }
    assert!(starts.len() > 100);
    for w in starts.windows(2) {
        assert!(w[1] - w[0] <= 10_000, "gap {}", w[1] - w[0]);
    }
    // Every heartbeat started at a scan (ms boundary), so it ended before the next one.
    let offsets = starts.iter().filter(|t| *t % 1_000 != 0).count();
    assert_eq!(offsets, 0);
}

#[test]
fn a_plc_with_another_version_ends_a_running_session() {
    let mut p = connected_pair(115_200);
    let hello = Frame {
        seq: 0,
        ack: 0,
        msg: PlcMsg::Hello {
            version: PROTOCOL_VERSION + 1,
            session: 9,
        },
    };
    let mut out = [0u8; MAX_WIRE_FRAME];
    let n = encode_frame(&hello, true, &mut out).unwrap();
    let now = p.now;
    p.drive.receive(&out[..n], now);
    assert_eq!(
        drive_events(&mut p),
        vec![
            DriveEvent::LinkLost,
            DriveEvent::VersionMismatch {
                plc_version: PROTOCOL_VERSION + 1
            }
        ]
    );
    assert!(!p.drive.is_up());
}

/// The drive checks a complete download in steps, one per `poll_transmit` (CRC, decode,
/// verifier, then the result), never inside `receive`: on the board each call is one
/// critical section against the PWM interrupt. Raw PLC frames, so that the
/// calls can be counted.
#[test]
fn the_drive_checks_a_download_one_step_per_transmit_call() {
    use shared_protocol::link::drive::{DECODE_LINES_PER_STEP, VERIFY_USED_LINES_PER_STEP};
    use shared_protocol::link::message::CHUNK_BYTES;
    use shared_protocol::link::plc::section_crc;
    use shared_protocol::program::{encode_slot, LINE_BYTES};

    let steps = usize::from(DECODE_LINES_PER_STEP);

    // (CRC corrupted, a line that does not decode): a good download, a bad CRC, and
    // line 120 erased (FF FF FF FF), found by the 13th decode step.
    for (corrupt, erased) in [(false, None), (true, None), (false, Some(120usize))] {
        let section = ramp_section();
        let mut bytes: Vec<u8> = section
            .lines
            .iter()
            .flat_map(|l| encode_slot(l.as_ref()))
            .collect();
        if let Some(line) = erased {
            bytes[line * LINE_BYTES..(line + 1) * LINE_BYTES].fill(0xFF);
        }
        let crc = section_crc(&bytes) ^ u32::from(corrupt);
        let mut msgs = vec![
            PlcMsg::Hello {
                version: PROTOCOL_VERSION,
                session: 1,
            },
            PlcMsg::DownloadBegin { crc },
        ];
        for (k, chunk) in bytes.chunks(CHUNK_BYTES).enumerate() {
            msgs.push(PlcMsg::DownloadChunk {
                first_line: (k * CHUNK_BYTES / LINE_BYTES) as u8,
                data: heapless::Vec::from_slice(chunk).unwrap(),
            });
        }
        msgs.push(PlcMsg::DownloadEnd);
        let mut drive = shared_protocol::link::DriveLink::new(LinkConfig::default());
        let mut out = [0u8; MAX_WIRE_FRAME];
        let now = Micros(1_000);
        for (k, msg) in msgs.into_iter().enumerate() {
            let seq = (k as u8).wrapping_sub(1); // the Hello is unnumbered
            let n = encode_frame(&Frame { seq, ack: 0, msg }, true, &mut out).unwrap();
            drive.receive(&out[..n], now);
        }
        assert_eq!(drive.poll_event(), Some(DriveEvent::Connected));
        assert_eq!(drive.poll_event(), None, "nothing checked inside receive");
        let mut calls = 0;
        let result = loop {
            assert!(
                drive.poll_timeout().is_some_and(|t| t <= now),
                "a pending step is due at once"
            );
            let sent = drive.poll_transmit(now, &mut out);
            calls += 1;
            // A step is a call of its own: no frame with it (the acknowledgement and the
            // result go out in the calls after).
            assert_eq!(sent, 0, "a check step sends no frame in the same call");
            if let Some(e) = drive.poll_event() {
                break e;
            }
            assert!(calls < 60, "no result");
        };
        if let Some(line) = erased {
            // CRC, decode up to the step of line 120, then the result.
            assert_eq!(
                result,
                DriveEvent::ProgramRejected {
                    line: line as u16,
                    reason: RejectReason::Decode
                }
            );
            assert_eq!(calls, 1 + (120 / steps + 1) + 1);
            assert!(drive.take_program().is_none());
        } else if corrupt {
            // CRC, then the result.
            assert_eq!(
                result,
                DriveEvent::ProgramRejected {
                    line: 0,
                    reason: RejectReason::Crc
                }
            );
            assert_eq!(calls, 2);
            assert!(drive.take_program().is_none());
        } else {
            // CRC, decode (150 lines in steps), verifier, then the result.
            assert_eq!(result, DriveEvent::ProgramAccepted);
            // The verifier: steps of VERIFY_USED_LINES_PER_STEP used lines, the last one
            // also over the empty lines after them.
            let used = section.lines.iter().flatten().count();
            let verify_steps = used / usize::from(VERIFY_USED_LINES_PER_STEP) + 1;
            assert_eq!(calls, 1 + 150usize.div_ceil(steps) + verify_steps + 1);
            assert_eq!(
                drive.take_program().map(|v| v.section().clone()),
                Some(section)
            );
            assert!(
                drive.poll_transmit(now, &mut out) > 0,
                "then the answer goes out"
            );
        }
    }
}

/// safety.md 9: the request mask is reliable, in order with the other commands, the
/// newest waiting one wins, it is resent after a handshake, and a change of the status's
/// safety fields is sent at once.
#[test]
fn the_safety_request_is_in_order_newest_wins_and_resent_after_a_handshake() {
    let mut p = connected_pair(115_200);
    p.plc.set_safety_request(0x0002).unwrap();
    p.plc.write_q(1, 5).unwrap();
    p.plc.set_safety_request(0x0000).unwrap();
    p.plc.ack_fault().unwrap();
    let end = Micros(p.now.0 + 30_000);
    p.run_until(end, |_| {});
    assert_eq!(
        drive_events(&mut p),
        vec![
            // The first mask was still waiting: the newest replaced it, appended after
            // the Q write, and goes before the ACK issued after it.
            DriveEvent::QWrite { addr: 1, value: 5 },
            DriveEvent::SafetyRequest { requested: 0 },
            DriveEvent::AckFault,
        ]
    );
    // One frame per change once the previous one is on the wire.
    for m in [0x0001u16, 0x0809, 0x0000] {
        p.plc.set_safety_request(m).unwrap();
        let end = Micros(p.now.0 + 10_000);
        p.run_until(end, |_| {});
        assert_eq!(
            drive_events(&mut p),
            vec![DriveEvent::SafetyRequest { requested: m }]
        );
    }
    assert_eq!(p.plc.safety_request(), Some(0));
    // Cut, a new mask while down, reconnection: the mask goes again after the handshake.
    p.line.to_drive.set_cut(true);
    p.line.to_plc.set_cut(true);
    let end = Micros(p.now.0 + 120_000);
    p.run_until(end, |_| {});
    assert!(!p.plc.is_up());
    p.plc.set_safety_request(0x0010).unwrap();
    p.line.to_drive.set_cut(false);
    p.line.to_plc.set_cut(false);
    let end = Micros(p.now.0 + 100_000);
    p.run_until(end, |_| {});
    assert!(p.plc.is_up());
    let ev = drive_events(&mut p);
    assert_eq!(
        ev.last(),
        Some(&DriveEvent::SafetyRequest { requested: 0x0010 })
    );
    // A change of the safety status goes out at once, not at the next 10 ms period.
    let end = Micros(p.now.0 + 15_000);
    p.run_until(end, |_| {});
    let mut s = p.plc.last_status().unwrap().0;
    for change in 0..4 {
        match change {
            0 => s.sf_requested = 0x0010,
            1 => s.sf_status = 0x0010,
            2 => s.sf_sdc = true,
            _ => s.sto_in_low = true,
        }
        p.drive.set_status(s);
        let t0 = p.now;
        let mut seen = None;
        p.run_until(Micros(t0.0 + 9_000), |p| {
            if seen.is_none() && p.plc.last_status().map(|x| x.0) == Some(s) {
                seen = Some(p.now.0 - t0.0);
            }
        });
        let seen = seen.expect("status seen");
        assert!(seen < 5_000, "change {change} after {seen} us");
    }
}
