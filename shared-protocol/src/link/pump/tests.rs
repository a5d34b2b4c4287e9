//! Both endpoints pumped on the co-simulation rig (`link::pair`), woken only by arriving
//! bytes, their deadlines and a line becoming free: as the boards and hil-sim run them.

use super::*;
use crate::link::channel::Impairments;
use crate::link::drive::{DriveEvent, DriveLink};
use crate::link::line::{End, Line, LinkTask};
use crate::link::message::DownloadResult;
use crate::link::pair::Pair;
use crate::link::plc::{PlcEvent, PlcLink};
use crate::link::LinkConfig;
use crate::program::DriveSection;

/// The boards' bound: a pass at least every 10 ms (the supervisor checks every 20 ms).
const MAX_IDLE_US: u64 = 10_000;

/// An endpoint's link task: its pump, or (`greedy`) the old PLC loop that handed the UART
/// every frame the endpoint had, each written (awaited) before the next, and read RX only
/// after the last.
struct Side<E> {
    ep: E,
    pump: Pump,
    greedy: bool,
    /// What the greedy loop wrote in its last pass, and when its writes end.
    written: Vec<u8>,
    line_free_ns: u64,
    byte_ns: u64,
}

impl<E: LinkEndpoint> Side<E> {
    fn new(ep: E, baud: u32) -> Self {
        Side {
            ep,
            pump: Pump::new(MAX_IDLE_US),
            greedy: false,
            written: Vec::new(),
            line_free_ns: 0,
            byte_ns: 10_000_000_000 / u64::from(baud),
        }
    }
}

impl<E: LinkEndpoint> LinkTask for Side<E> {
    fn pass(&mut self, rx: &[u8], room: usize, now: Micros) -> Pass {
        self.written.clear();
        if self.greedy {
            self.ep.on_rx(rx, now);
            let mut frame = [0u8; MAX_WIRE_FRAME];
            let mut t_ns = self.line_free_ns.max(now.0 * 1000);
            loop {
                let n = self.ep.poll_tx(Micros(t_ns.div_ceil(1000)), &mut frame);
                if n == 0 {
                    break;
                }
                self.written.extend_from_slice(&frame[..n]);
                t_ns += n as u64 * self.byte_ns;
            }
            self.line_free_ns = t_ns;
            return Pass {
                tx_len: self.written.len(),
                wake_at: Micros(t_ns.div_ceil(1000).max(now.0 + 1_000)),
            };
        }
        let p = self.pump.pass(&mut self.ep, rx, room, now);
        assert!(p.tx_len <= room, "never more than the line takes");
        assert_eq!(self.pump.tx().len(), p.tx_len);
        assert!(p.wake_at >= now && p.wake_at.0 <= now.0 + MAX_IDLE_US);
        p
    }
    fn tx(&self) -> &[u8] {
        if self.greedy {
            &self.written
        } else {
            self.pump.tx()
        }
    }
    fn timeout(&self) -> Option<Micros> {
        self.ep.poll_timeout()
    }
}

/// Both endpoints on the co-simulation rig, woken only by arriving bytes, their deadlines
/// and a line becoming free.
struct Rig {
    pair: Pair<Side<PlcLink>, Side<DriveLink>>,
    plc_events: Vec<(Micros, PlcEvent)>,
    drive_events: Vec<(Micros, DriveEvent)>,
}

impl Rig {
    fn new() -> Self {
        let cfg = LinkConfig::default();
        Rig {
            pair: Pair::with_line(
                Side::new(PlcLink::new(cfg), cfg.baud),
                Side::new(DriveLink::new(cfg), cfg.baud),
                Line::new(cfg.baud, Impairments::default(), 1),
            ),
            plc_events: Vec::new(),
            drive_events: Vec::new(),
        }
    }

    fn run_until(&mut self, t: Micros) {
        let (plc_events, drive_events) = (&mut self.plc_events, &mut self.drive_events);
        self.pair.run_until(t, |p| {
            let now = p.now;
            plc_events.extend(std::iter::from_fn(|| p.plc.ep.poll_event()).map(|e| (now, e)));
            drive_events.extend(std::iter::from_fn(|| p.drive.ep.poll_event()).map(|e| (now, e)));
        });
    }

    fn connected() -> Self {
        let mut r = Rig::new();
        r.run_until(Micros(20_000));
        assert!(
            r.pair.plc.ep.is_up() && r.pair.drive.ep.is_up(),
            "handshake"
        );
        r
    }

    fn download_result(&self) -> Option<(Micros, DownloadResult)> {
        self.plc_events.iter().find_map(|(t, e)| match e {
            PlcEvent::Download(r) => Some((*t, *r)),
            _ => None,
        })
    }

    fn plc_losses(&self) -> usize {
        let lost = |e: &&(Micros, PlcEvent)| matches!(e.1, PlcEvent::LinkLost { .. });
        self.plc_events.iter().filter(lost).count()
    }
}

fn section() -> DriveSection {
    DriveSection::default()
}

#[test]
fn a_full_window_of_download_frames_completes_when_both_sides_pump() {
    let mut r = Rig::connected();
    let start = r.pair.now;
    r.pair.plc.ep.start_download(&section()).unwrap();
    // The download is queued all at once: the PLC's window (8 frames, ~52 ms of line
    // time) is full at the first pass.
    r.run_until(Micros(start.0 + 1_000_000));
    let (t, result) = r.download_result().expect("download answered");
    assert_eq!(result, DownloadResult::Accepted);
    assert!(t.0 - start.0 < 150_000, "took {} us", t.0 - start.0);
    assert_eq!(r.plc_losses(), 0);
    assert_eq!(r.pair.plc.ep.stats().link_losses, 0);
}

#[test]
fn the_old_send_the_whole_window_loop_livelocks_in_the_same_rig() {
    // The control: the same rig with the PLC's old loop does not finish (this is what
    // the one-frame-per-pass rule fixes).
    let mut r = Rig::connected();
    r.pair.plc.greedy = true;
    let start = r.pair.now;
    r.pair.plc.ep.start_download(&section()).unwrap();
    r.run_until(Micros(start.0 + 1_000_000));
    assert_eq!(r.download_result(), None);
    assert!(
        r.plc_losses() > 0,
        "the link timed out while the acks sat unread"
    );
}

#[test]
fn an_idle_link_wakes_on_deadlines_not_every_millisecond() {
    let mut r = Rig::connected();
    let passes = |r: &Rig| {
        (
            r.pair.line.timer_passes(End::Plc),
            r.pair.line.timer_passes(End::Drive),
        )
    };
    let (p0, d0) = passes(&r);
    r.run_until(Micros(r.pair.now.0 + 1_000_000));
    let (p1, d1) = passes(&r);
    let (plc, drive) = (p1 - p0, d1 - d0);
    // The drive's status every 10 ms, the PLC's heartbeat every 8 ms (each also owes an
    // ack to the other's frame): about 100-250 timer wake-ups a second, not a thousand.
    assert!(
        plc <= 250 && drive <= 250,
        "passes: plc {plc}, drive {drive}"
    );
    assert!(r.pair.plc.ep.is_up() && r.pair.drive.ep.is_up());
    assert_eq!(r.plc_losses(), 0);
    // And the exact deadlines: the drive's next status, the PLC's next heartbeat.
    let now = r.pair.now;
    let p = r.pair.drive.pump.pass(&mut r.pair.drive.ep, &[], 0, now);
    let status_us = r.pair.drive.ep.config().status_us;
    assert!(p.wake_at > now && p.wake_at.0 <= now.0 + status_us);
    let p = r.pair.plc.pump.pass(&mut r.pair.plc.ep, &[], 0, now);
    let heartbeat_us = r.pair.plc.ep.config().heartbeat_us;
    assert!(p.wake_at > now && p.wake_at.0 <= now.0 + heartbeat_us);
}

#[test]
fn deadlines_of_a_lone_endpoint() {
    let cfg = LinkConfig::default();
    let mut pump = Pump::new(MAX_IDLE_US);
    // A drive with no PLC: no timer, so the idle bound.
    let mut drive = DriveLink::new(cfg);
    let p = pump.pass(&mut drive, &[], MAX_WIRE_FRAME, Micros(1_000));
    assert_eq!((p.tx_len, p.wake_at), (0, Micros(1_000 + MAX_IDLE_US)));
    // A PLC sends Hello at once, then wakes for the retry.
    let mut plc = PlcLink::new(cfg);
    let mut pump = Pump::new(1_000_000);
    let p = pump.pass(&mut plc, &[], MAX_WIRE_FRAME, Micros(5));
    assert!(p.tx_len > 0);
    assert_eq!(p.wake_at, Micros(5 + cfg.hello_retry_us));
    let p = pump.pass(&mut plc, &[], MAX_WIRE_FRAME, Micros(6));
    assert_eq!(p.tx_len, 0, "no second Hello before the retry time");
}

#[test]
fn no_frame_while_the_line_is_busy_and_never_more_than_the_room() {
    let mut r = Rig::connected();
    let now = Micros(r.pair.now.0 + 1);
    r.pair.plc.ep.run().unwrap();
    let mut pump = Pump::new(MAX_IDLE_US);
    let p = pump.pass(&mut r.pair.plc.ep, &[], 0, now);
    assert_eq!(p.tx_len, 0);
    assert!(pump.tx().is_empty() && !pump.holding());
    assert_eq!(
        p.wake_at, now,
        "the RUN is due: pass again when the line is free"
    );
    // A transmitter with a 4-byte FIFO: the frame goes out in pieces, one per pass.
    let mut wire = Vec::new();
    let mut t = now;
    loop {
        let p = pump.pass(&mut r.pair.plc.ep, &[], 4, t);
        assert!(p.tx_len <= 4);
        wire.extend_from_slice(pump.tx());
        t = Micros(t.0 + 350);
        if !pump.holding() {
            break;
        }
    }
    assert_eq!(wire.last(), Some(&0), "one whole frame, delimiter last");
    assert_eq!(wire.iter().filter(|&&b| b == 0).count(), 1, "and only one");
    let mut got = Vec::new();
    let (mut s, mut drive_pump) = (r.pair.drive, Pump::new(MAX_IDLE_US));
    drive_pump.pass(&mut s.ep, &wire, 0, t);
    got.extend(std::iter::from_fn(|| s.ep.poll_event()));
    assert_eq!(got, vec![DriveEvent::Run]);
}

#[test]
fn timers_run_while_the_line_stays_busy() {
    let mut r = Rig::connected();
    let start = r.pair.now;
    let mut pump = Pump::new(MAX_IDLE_US);
    let mut t = start;
    let mut passes = 0;
    let mut last = t;
    while r.pair.plc.ep.is_up() && t.0 < start.0 + 100_000 {
        last = t;
        let p = pump.pass(&mut r.pair.plc.ep, &[], 0, t);
        assert_eq!(p.tx_len, 0);
        // The ack owed is due at once, but the line never frees: 1 ms steps.
        t = p.wake_at.max(Micros(t.0 + 1_000));
        passes += 1;
    }
    let timeout = r.pair.plc.ep.config().plc_timeout_us;
    assert!(
        !r.pair.plc.ep.is_up(),
        "link loss detected with the line busy"
    );
    assert!(last.0 - start.0 <= timeout, "at its deadline");
    assert!(passes <= 41, "{passes} passes");
}

#[test]
fn line_errors_are_counted_and_logged_at_a_limited_rate() {
    let mut r = Rig::connected();
    let mut pump = Pump::new(MAX_IDLE_US);
    let t0 = r.pair.now.0;
    let mut logs = Vec::new();
    // A floating RX pin: an error every 100 us for 2.5 s.
    for k in 0..25_000u64 {
        if let Some(n) = pump.line_error(&mut r.pair.plc.ep, Micros(t0 + k * 100)) {
            logs.push(n);
        }
    }
    assert_eq!(logs, vec![1, 10_000, 10_000]);
    assert_eq!(r.pair.plc.ep.stats().line_errors, 25_000);
}

#[test]
fn is_due_compares_with_now() {
    assert!(!is_due(None, Micros(5)));
    assert!(is_due(Some(Micros(0)), Micros(5)));
    assert!(is_due(Some(Micros(5)), Micros(5)));
    assert!(!is_due(Some(Micros(6)), Micros(5)));
}

/// Records the order of the pump's calls; its reaction queues a frame.
#[derive(Default)]
struct Order {
    calls: Vec<&'static str>,
    queued: bool,
}

impl LinkEndpoint for Order {
    fn on_rx(&mut self, _: &[u8], _: Micros) {
        self.calls.push("rx");
    }
    fn poll_tx(&mut self, _: Micros, out: &mut [u8]) -> usize {
        if out.is_empty() {
            return 0;
        }
        self.calls.push("tx");
        out[..3].copy_from_slice(b"ack");
        3
    }
    fn poll_timeout(&self) -> Option<Micros> {
        self.queued.then_some(Micros(0))
    }
    fn line_error(&mut self) {}
    fn service(&mut self, _: Micros) {
        self.calls.push("service");
        self.queued = true;
    }
}

#[test]
fn the_reaction_runs_after_the_frame_is_handed_out_and_moves_the_deadline() {
    let mut ep = Order::default();
    let mut pump = Pump::new(MAX_IDLE_US);
    let p = pump.pass(&mut ep, b"x", MAX_WIRE_FRAME, Micros(500));
    assert_eq!(ep.calls, ["rx", "tx", "service"]);
    assert_eq!(pump.tx(), b"ack");
    // What the reaction queued is due at once, not at the idle bound.
    assert_eq!(p.wake_at, Micros(500));
}

#[test]
fn frame_pieces_end_at_most_one_frame_each_and_keep_every_byte() {
    let rx = [0, 5, 6, 0, 7, 0, 8, 9];
    let pieces: Vec<&[u8]> = frame_pieces(&rx).collect();
    assert_eq!(pieces, [&[0][..], &[5, 6, 0], &[7, 0], &[8, 9]]);
    for p in &pieces {
        assert!(p.iter().filter(|&&b| b == 0).count() <= 1);
    }
    assert_eq!(pieces.concat(), rx);
    assert_eq!(frame_pieces(&[]).count(), 0);
}
