//! The link on a noisy wire: a corrupted frame is never acted on, and every command is
//! applied exactly once and in order, whatever the channel drops, duplicates, corrupts or
//! delays. The 10^6-frame runs are for `cargo test --release` (ignored in debug builds).

use std::collections::HashMap;

use shared_protocol::fault::FaultCode;
use shared_protocol::link::channel::{Channel, Impairments};
use shared_protocol::link::frame::{encode_frame, Frame, FrameReader, MAX_WIRE_FRAME};
use shared_protocol::link::pair::LinkPair;
use shared_protocol::link::{
    DriveEvent, DriveMsg, DriveState, DriveStatus, LinkConfig, PlcEvent, PlcMsg, QValue,
};
use shared_protocol::units::Micros;

struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }
    fn below(&mut self, n: u64) -> u64 {
        self.next() % n
    }
}

fn random_plc_msg(r: &mut Rng) -> PlcMsg {
    match r.below(6) {
        0 => PlcMsg::Heartbeat,
        1 => PlcMsg::Run,
        2 => PlcMsg::Direction {
            reverse: r.below(2) == 1,
        },
        3 => PlcMsg::DownloadChunk {
            first_line: r.below(150) as u8,
            data: (0..r.below(65)).map(|_| r.next() as u8).collect(),
        },
        _ => PlcMsg::QWrite(
            (0..1 + r.below(8))
                .map(|_| QValue {
                    addr: r.below(64) as u8,
                    value: r.next() as i16,
                })
                .collect(),
        ),
    }
}

/// 10^6 frames through a wire with bit error rate 1e-4: every frame the reader accepts
/// must be exactly the next-or-later frame that was sent.
fn codec_under_ber(frames: usize) {
    let mut rng = Rng(0x1234_5678);
    let imp = Impairments {
        bit_error_rate: 1e-4,
        ..Default::default()
    };
    let mut wire = Channel::new(1_000_000, imp, 42);
    let mut reader = FrameReader::new();
    let mut sent: std::collections::VecDeque<Frame<PlcMsg>> = Default::default();
    let mut out = [0u8; MAX_WIRE_FRAME];
    let mut rx = [0u8; 256];
    let (mut accepted, mut rejected) = (0u64, 0u64);
    let mut now = Micros(0);
    for k in 0..frames {
        let f = Frame {
            seq: k as u8,
            ack: rng.next() as u8,
            msg: random_plc_msg(&mut rng),
        };
        let n = encode_frame(&f, false, &mut out).unwrap();
        wire.send(&out[..n], now);
        sent.push_back(f);
        now = wire.free_at();
        let m = wire.receive(now, &mut rx);
        for &b in &rx[..m] {
            match reader.push::<PlcMsg>(b) {
                None => {}
                Some(Err(_)) => rejected += 1,
                Some(Ok(got)) => {
                    // It must be one of the frames still unmatched; older ones were lost.
                    let pos = sent.iter().position(|s| *s == got);
                    let pos = pos.unwrap_or_else(|| panic!("corrupted frame accepted: {got:?}"));
                    sent.drain(..=pos);
                    accepted += 1;
                }
            }
        }
        // Nothing outstanding lingers longer than a few frames.
        while sent.len() > 4 {
            sent.pop_front();
        }
    }
    let st = wire.stats();
    assert_eq!(st.frames, frames as u64);
    assert!(
        st.corrupted_frames > frames as u64 / 500,
        "the wire did corrupt"
    );
    assert!(rejected >= st.corrupted_frames / 2);
    // A corrupted delimiter also takes the next frame with it.
    assert!(accepted + 2 * st.corrupted_frames >= frames as u64);
    eprintln!(
        "{frames} frames, {} corrupted by {} bit flips, {accepted} accepted, {rejected} rejected, 0 corrupted accepted",
        st.corrupted_frames, st.bits_flipped
    );
}

#[test]
fn codec_rejects_every_corrupted_frame_short() {
    codec_under_ber(20_000);
}

#[test]
#[cfg_attr(
    debug_assertions,
    ignore = "10^6 frames: run with cargo test --release"
)]
fn codec_rejects_every_corrupted_frame_1e6() {
    codec_under_ber(1_000_000);
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Cmd {
    Q(u8, i16),
    Run,
    Stop,
    Dir(bool),
    Ack,
    /// The safety request mask (safety.md 9); each issued mask is distinct.
    Safety(u16),
}

/// The drive's status is made self-checking so that a corrupted status accepted by the PLC
/// would be noticed.
fn status_for(k: u16) -> DriveStatus {
    DriveStatus {
        state: DriveState::Run,
        fault: None,
        freq_dhz: k as i16,
        reverse: k % 2 == 1,
        udc_dv: (k as i16).wrapping_mul(7),
        imax_ca: (k as i16) ^ 0x5A5A,
        com: k % 1024,
        oc_hw_ca: 300,
        ov_hw_v: 40,
        warning: k
            .is_multiple_of(7)
            .then_some(shared_protocol::link::DriveWarning::PwfClamped {
                line: (k % 150) as u8,
                requested: k as i16,
                applied_hz: 488,
            }),
        sf_requested: k & 0x0FFF,
        sf_status: (k >> 3) & 0x0FFF,
        sf_sdc: k.is_multiple_of(3),
        sf_elapsed_ds: k.wrapping_mul(3) & 0x7FFF,
        sf_signature: k ^ 0xA5C3,
        sto_in_low: k.is_multiple_of(5),
        program_loaded: k.is_multiple_of(2),
        sf_turns: (k as i16).wrapping_mul(-5),
    }
}

fn status_ok(s: &DriveStatus, newest: u16) -> bool {
    let k = s.freq_dhz as u16;
    // `newest` wraps in long runs: only the fields' relation is checked then.
    *s == status_for(k) && (k <= newest || newest < 1_000)
}

/// Both endpoints on an impaired wire, the PLC issuing commands as fast as the link takes
/// them; stops after `frames` frames on the wire (both directions).
fn endpoints_on_noisy_wire(baud: u32, imp: Impairments, frames: u64, seed: u64) {
    let mut p = LinkPair::new(LinkConfig::at_baud(baud), imp, seed);
    let mut rng = Rng(seed | 1);
    let mut issued: Vec<Cmd> = Vec::new();
    let mut applied: Vec<Cmd> = Vec::new();
    let mut next_q: HashMap<u8, i16> = HashMap::new();
    let mut next_mask: u16 = 0;
    let mut status_k: u16 = 0;
    p.drive.set_status(status_for(0));
    let mut next_cmd = Micros(0);
    let mut plc_losses = 0;
    let mut faults_reported = 0u32;
    let mut faults_seen: Vec<u32> = Vec::new();
    let mut drive_losses = 0;
    while p.line.to_drive.stats().frames + p.line.to_plc.stats().frames < frames {
        let until = Micros(p.now.0 + 1_000);
        p.step(until);
        if p.now >= next_cmd && p.plc.is_up() && p.plc.unacknowledged() < 40 {
            next_cmd = Micros(p.now.0 + 50 + rng.below(400));
            let c = match rng.below(100) {
                0..=79 => {
                    let a = rng.below(6) as u8;
                    let v = next_q.entry(a).or_insert(0);
                    *v += 1;
                    Cmd::Q(a, *v)
                }
                80..=84 => Cmd::Run,
                85..=89 => Cmd::Stop,
                90..=92 => Cmd::Dir(rng.below(2) == 1),
                93..=95 => {
                    next_mask = (next_mask + 1) % 0x1000;
                    Cmd::Safety(next_mask)
                }
                _ => Cmd::Ack,
            };
            let r = match c {
                Cmd::Q(a, v) => p.plc.write_q(a, v),
                Cmd::Run => p.plc.run(),
                Cmd::Stop => p.plc.stop(),
                Cmd::Dir(d) => p.plc.set_direction(d),
                Cmd::Ack => p.plc.ack_fault(),
                Cmd::Safety(m) => p.plc.set_safety_request(m),
            };
            r.unwrap();
            issued.push(c);
        }
        if rng.below(500) == 0
            && p.drive.is_up()
            && p.drive.report_fault(FaultCode::Link, faults_reported + 1)
        {
            faults_reported += 1;
        }
        if rng.below(20) == 0 {
            status_k = status_k.wrapping_add(1) % 30_000;
            p.drive.set_status(status_for(status_k));
        }
        while let Some(e) = p.drive.poll_event() {
            match e {
                DriveEvent::QWrite { addr, value } => applied.push(Cmd::Q(addr, value)),
                DriveEvent::Run => applied.push(Cmd::Run),
                DriveEvent::Stop => applied.push(Cmd::Stop),
                DriveEvent::Direction { reverse } => applied.push(Cmd::Dir(reverse)),
                DriveEvent::AckFault => applied.push(Cmd::Ack),
                DriveEvent::SafetyRequest { requested } => applied.push(Cmd::Safety(requested)),
                DriveEvent::LinkLost => drive_losses += 1,
                DriveEvent::Connected => {}
                other => panic!("unexpected {other:?}"),
            }
        }
        while let Some(e) = p.plc.poll_event() {
            match e {
                PlcEvent::LinkLost { .. } => plc_losses += 1,
                PlcEvent::Connected => {}
                PlcEvent::DriveFault {
                    code: FaultCode::Link,
                    drive_time_ms,
                } => faults_seen.push(drive_time_ms),
                other => panic!("unexpected {other:?}"),
            }
        }
        if let Some((s, _)) = p.plc.last_status() {
            assert!(status_ok(&s, status_k), "corrupted status accepted: {s:?}");
        }
    }
    // Let everything drain on a clean wire.
    p.line.to_drive.set_impairments(Impairments::default());
    p.line.to_plc.set_impairments(Impairments::default());
    let end = Micros(p.now.0 + 200_000);
    p.run_until(end, |p| {
        while let Some(e) = p.plc.poll_event() {
            if let PlcEvent::DriveFault { drive_time_ms, .. } = e {
                faults_seen.push(drive_time_ms);
            }
        }
        while let Some(e) = p.drive.poll_event() {
            match e {
                DriveEvent::QWrite { addr, value } => applied.push(Cmd::Q(addr, value)),
                DriveEvent::Run => applied.push(Cmd::Run),
                DriveEvent::Stop => applied.push(Cmd::Stop),
                DriveEvent::Direction { reverse } => applied.push(Cmd::Dir(reverse)),
                DriveEvent::AckFault => applied.push(Cmd::Ack),
                DriveEvent::SafetyRequest { requested } => applied.push(Cmd::Safety(requested)),
                _ => {}
            }
        }
    });
    assert_eq!(plc_losses, 0, "no link loss at this error rate");
    assert_eq!(drive_losses, 0);
    assert_eq!(p.plc.unacknowledged(), 0);
    // Drive-to-PLC reliable reports: each exactly once, in order.
    assert!(faults_reported > 0);
    assert_eq!(faults_seen, (1..=faults_reported).collect::<Vec<_>>());

    check_applied(&issued, &applied);
    assert!(
        applied.iter().any(|c| matches!(c, Cmd::Safety(_))),
        "safety masks were exercised"
    );
    let (d, u) = (p.drive.stats(), p.plc.stats());
    eprintln!(
        "{} frames on the wire; {} commands issued, {} applied ({} Q writes superseded); \
         bad frames: drive {} plc {}; fault reports {}; retransmits: plc {} drive {}; duplicates ignored: drive {} plc {}",
        p.line.to_drive.stats().frames + p.line.to_plc.stats().frames,
        issued.len(),
        applied.len(),
        issued.len() - applied.len(),
        d.frames_bad,
        u.frames_bad,
        faults_reported,
        u.retransmits,
        d.retransmits,
        d.duplicates,
        u.duplicates,
    );
    assert!(d.frames_bad > 0 || imp == Impairments::default());
}

/// The delivery rules (link.md) of what the drive applied, against what the PLC issued:
/// * every command other than STOP is applied at most once, in issue order;
/// * STOP goes to the head of the PLC's queue: it overtakes commands waiting there, drops
///   the waiting Q writes and RUN, and replaces a waiting STOP;
/// * a Q write is skipped only when a newer write to the same Q superseded it or a later
///   STOP dropped it; a RUN only when a later STOP dropped it; a safety mask only when a
///   newer mask superseded it (newest wins); a direction or ACK never;
/// * the newest Q values, the newest safety mask and the newest of RUN/STOP arrive.
fn check_applied(issued: &[Cmd], applied: &[Cmd]) {
    let stops: Vec<usize> = (0..issued.len())
        .filter(|&i| issued[i] == Cmd::Stop)
        .collect();
    let stop_after = |i: usize| stops.iter().any(|&s| s > i);
    // Issue index of each applied command, matched to the earliest issued command that
    // the rules allow: commands other than STOP keep their issue order; a Q write or RUN
    // applied after a STOP was issued after it (STOP drops the waiting ones); a direction
    // or ACK may have been issued before it (overtaken). A STOP was issued after every
    // command applied before it; a STOP that replaced a waiting one stands for both.
    let mut at = Vec::with_capacity(applied.len());
    let (mut next, mut floor, mut next_stop) = (0usize, 0usize, 0usize);
    for a in applied {
        if *a == Cmd::Stop {
            let k = stops[next_stop..]
                .iter()
                .position(|&s| s >= next)
                .unwrap_or_else(|| panic!("a STOP applied that was not issued after #{next}"));
            let s = stops[next_stop + k];
            next_stop += k + 1;
            floor = s + 1;
            at.push(s);
            continue;
        }
        let from = match a {
            Cmd::Q(..) | Cmd::Run => next.max(floor),
            _ => next,
        };
        let pos = issued[from..]
            .iter()
            .position(|c| c == a)
            .unwrap_or_else(|| panic!("{a:?} applied out of order, twice, or after a STOP"));
        at.push(from + pos);
        next = from + pos + 1;
    }
    // What was never applied: a Q write superseded by a newer one to the same Q or dropped
    // by a later STOP, a RUN dropped by a later STOP, a replaced STOP; never a direction
    // or an ACK.
    for (i, c) in issued.iter().enumerate() {
        if at.contains(&i) {
            continue;
        }
        match c {
            Cmd::Stop => {}
            Cmd::Q(addr, _) => assert!(
                stop_after(i)
                    || issued[i + 1..]
                        .iter()
                        .any(|d| matches!(d, Cmd::Q(b, _) if b == addr)),
                "Q write {c:?} #{i} lost"
            ),
            Cmd::Run => assert!(stop_after(i), "RUN #{i} lost"),
            Cmd::Safety(_) => assert!(
                issued[i + 1..].iter().any(|d| matches!(d, Cmd::Safety(_))),
                "safety mask {c:?} #{i} lost"
            ),
            other => panic!("command {other:?} #{i} lost"),
        }
    }
    let last_stop = stops.last().copied();
    // The newest value of each Q, unless a later STOP dropped it.
    for (i, c) in issued.iter().enumerate() {
        if let Cmd::Q(addr, _) = c {
            let newest = !issued[i + 1..]
                .iter()
                .any(|d| matches!(d, Cmd::Q(b, _) if b == addr));
            if newest && !stop_after(i) {
                assert!(at.contains(&i), "the newest write {c:?} never applied");
            }
        }
    }
    // The newest safety mask is the drive's last (each applied at most once per issue:
    // the ordered matching above; masks repeat after 4096 in the long runs).
    let newest_mask = issued.iter().rev().find(|c| matches!(c, Cmd::Safety(_)));
    let last_mask = applied.iter().rev().find(|c| matches!(c, Cmd::Safety(_)));
    assert_eq!(last_mask, newest_mask);
    // The newest of RUN and STOP is the drive's last.
    let last_run_stop = applied
        .iter()
        .rev()
        .find(|c| matches!(c, Cmd::Run | Cmd::Stop));
    let newest_issued = issued
        .iter()
        .rev()
        .find(|c| matches!(c, Cmd::Run | Cmd::Stop));
    assert_eq!(last_run_stop, newest_issued);
    if let Some(s) = last_stop {
        assert!(applied.contains(&Cmd::Stop), "STOP #{s} never applied");
    }
}

fn harsh() -> Impairments {
    Impairments {
        bit_error_rate: 1e-4,
        byte_drop: 1e-4,
        byte_dup: 1e-4,
        frame_drop: 1e-3,
        frame_dup: 1e-3,
        max_delay_us: 300,
    }
}

#[test]
fn endpoints_exactly_once_short() {
    endpoints_on_noisy_wire(115_200, harsh(), 20_000, 5);
}

#[test]
fn endpoints_exactly_once_very_noisy() {
    let imp = Impairments {
        bit_error_rate: 1e-3,
        byte_drop: 1e-3,
        byte_dup: 1e-3,
        frame_drop: 0.02,
        frame_dup: 0.02,
        max_delay_us: 1_000,
    };
    endpoints_on_noisy_wire(115_200, imp, 20_000, 9);
}

#[test]
#[cfg_attr(
    debug_assertions,
    ignore = "10^6 frames: run with cargo test --release"
)]
fn endpoints_exactly_once_1e6_frames_ber_1e4() {
    endpoints_on_noisy_wire(1_000_000, harsh(), 1_000_000, 77);
}

#[test]
fn drive_messages_decode_under_noise() {
    // The drive's direction too: statuses through the codec at a high error rate.
    let imp = Impairments {
        bit_error_rate: 1e-3,
        ..Default::default()
    };
    let mut wire = Channel::new(115_200, imp, 3);
    let mut reader = FrameReader::new();
    let mut out = [0u8; MAX_WIRE_FRAME];
    let mut rx = [0u8; 128];
    let mut ok = 0;
    for k in 0..20_000u16 {
        let f = Frame {
            seq: 0,
            ack: k as u8,
            msg: DriveMsg::Status(status_for(k)),
        };
        let n = encode_frame(&f, false, &mut out).unwrap();
        wire.send(&out[..n], Micros(u64::from(k) * 10_000));
        let m = wire.receive(Micros(u64::from(k) * 10_000 + 9_000), &mut rx);
        for &b in &rx[..m] {
            if let Some(Ok(got)) = reader.push::<DriveMsg>(b) {
                let DriveMsg::Status(s) = got.msg else {
                    panic!()
                };
                assert!(status_ok(&s, k), "corrupted status accepted");
                ok += 1;
            }
        }
    }
    // A status with the safety fields is about 40 wire bytes: at 1e-3 about 2/3 of them
    // arrive intact (e^-0.4).
    assert!(ok > 12_000, "{ok}");
}
