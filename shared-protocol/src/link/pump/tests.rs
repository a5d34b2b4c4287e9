//! Both endpoints pumped over byte-timed wires, woken only by arriving bytes, their
//! deadlines and a line becoming free: as the boards and hil-sim run them.

use super::*;
use crate::link::channel::{Channel, Impairments};
use crate::link::drive::{DriveEvent, DriveLink};
use crate::link::message::DownloadResult;
use crate::link::plc::{PlcEvent, PlcLink};
use crate::link::LinkConfig;
use crate::program::DriveSection;

/// The boards' bound: a pass at least every 10 ms (the supervisor checks every 20 ms).
const MAX_IDLE_US: u64 = 10_000;

struct Side<E> {
    ep: E,
    pump: Pump,
    wake: Micros,
    /// Passes woken by the side's own deadline (not by arriving bytes).
    passes: u32,
    /// The old PLC loop: every frame the endpoint hands out, each written (awaited)
    /// before the next, RX read only after the last.
    greedy: bool,
}

impl<E: LinkEndpoint> Side<E> {
    fn new(ep: E) -> Self {
        Side {
            ep,
            pump: Pump::new(MAX_IDLE_US),
            wake: Micros(0),
            passes: 0,
            greedy: false,
        }
    }

    fn pass(&mut self, inbox: &mut Channel, outbox: &mut Channel, now: Micros) {
        if self.wake <= now {
            self.passes += 1;
        }
        let mut buf = [0u8; 512];
        let n = inbox.receive(now, &mut buf);
        let rx = &buf[..n];
        if self.greedy {
            self.ep.on_rx(rx, now);
            let mut frame = [0u8; MAX_WIRE_FRAME];
            let mut t = now;
            loop {
                let n = self.ep.poll_tx(t, &mut frame);
                if n == 0 {
                    break;
                }
                outbox.send(&frame[..n], t);
                t = outbox.free_at();
            }
            self.wake = Micros(t.0.max(now.0 + 1_000));
            return;
        }
        let room = if outbox.is_idle(now) {
            MAX_WIRE_FRAME
        } else {
            0
        };
        let p = self.pump.pass(&mut self.ep, rx, room, now);
        assert!(p.tx_len <= room, "never more than the line takes");
        assert_eq!(self.pump.tx().len(), p.tx_len);
        if p.tx_len > 0 {
            outbox.send(self.pump.tx(), now);
        }
        self.wake = p.wake_at;
        assert!(self.wake >= now && self.wake.0 <= now.0 + MAX_IDLE_US);
        if (self.pump.holding() || self.wake <= now) && !outbox.is_idle(now) {
            // Something to send but the line is busy: pass again when it is free.
            self.wake = self.wake.max(outbox.free_at());
        }
    }
}

struct Rig {
    plc: Side<PlcLink>,
    drive: Side<DriveLink>,
    to_drive: Channel,
    to_plc: Channel,
    now: Micros,
    plc_events: Vec<(Micros, PlcEvent)>,
    drive_events: Vec<(Micros, DriveEvent)>,
}

impl Rig {
    fn new() -> Self {
        let cfg = LinkConfig::default();
        Rig {
            plc: Side::new(PlcLink::new(cfg)),
            drive: Side::new(DriveLink::new(cfg)),
            to_drive: Channel::new(cfg.baud, Impairments::default(), 1),
            to_plc: Channel::new(cfg.baud, Impairments::default(), 2),
            now: Micros(0),
            plc_events: Vec::new(),
            drive_events: Vec::new(),
        }
    }

    /// Advance to the next thing that wakes a side (bytes arriving, a deadline) and pass
    /// the sides it wakes.
    fn step(&mut self) {
        let arrive_plc = self.to_plc.next_arrival();
        let arrive_drive = self.to_drive.next_arrival();
        let plc_at = arrive_plc.map_or(self.plc.wake, |a| a.min(self.plc.wake));
        let drive_at = arrive_drive.map_or(self.drive.wake, |a| a.min(self.drive.wake));
        // At least 1 us on: a side that keeps asking for "now" without sending anything
        // shows up as a pass count far too high.
        self.now = Micros(plc_at.min(drive_at).0.max(self.now.0 + 1));
        if plc_at <= self.now {
            self.plc
                .pass(&mut self.to_plc, &mut self.to_drive, self.now);
        }
        if drive_at <= self.now {
            self.drive
                .pass(&mut self.to_drive, &mut self.to_plc, self.now);
        }
        let now = self.now;
        self.plc_events
            .extend(std::iter::from_fn(|| self.plc.ep.poll_event()).map(|e| (now, e)));
        self.drive_events
            .extend(std::iter::from_fn(|| self.drive.ep.poll_event()).map(|e| (now, e)));
    }

    fn run_until(&mut self, t: Micros) {
        while self.now < t {
            self.step();
        }
    }

    fn connected() -> Self {
        let mut r = Rig::new();
        r.run_until(Micros(20_000));
        assert!(r.plc.ep.is_up() && r.drive.ep.is_up(), "handshake");
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
    let start = r.now;
    r.plc.ep.start_download(&section()).unwrap();
    // The download is queued all at once: the PLC's window (8 frames, ~52 ms of line
    // time) is full at the first pass.
    r.run_until(Micros(start.0 + 1_000_000));
    let (t, result) = r.download_result().expect("download answered");
    assert_eq!(result, DownloadResult::Accepted);
    assert!(t.0 - start.0 < 150_000, "took {} us", t.0 - start.0);
    assert_eq!(r.plc_losses(), 0);
    assert_eq!(r.plc.ep.stats().link_losses, 0);
}

#[test]
fn the_old_send_the_whole_window_loop_livelocks_in_the_same_rig() {
    // The control: the same rig with the PLC's old loop does not finish (this is what
    // the one-frame-per-pass rule fixes).
    let mut r = Rig::connected();
    r.plc.greedy = true;
    let start = r.now;
    r.plc.ep.start_download(&section()).unwrap();
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
    let (p0, d0) = (r.plc.passes, r.drive.passes);
    r.run_until(Micros(r.now.0 + 1_000_000));
    let (plc, drive) = (r.plc.passes - p0, r.drive.passes - d0);
    // The drive's status every 10 ms, the PLC's heartbeat every 8 ms (each also owes an
    // ack to the other's frame): about 100-250 timer wake-ups a second, not a thousand.
    assert!(
        plc <= 250 && drive <= 250,
        "passes: plc {plc}, drive {drive}"
    );
    assert!(r.plc.ep.is_up() && r.drive.ep.is_up());
    assert_eq!(r.plc_losses(), 0);
    // And the exact deadlines: the drive's next status, the PLC's next heartbeat.
    let now = r.now;
    let p = r.drive.pump.pass(&mut r.drive.ep, &[], 0, now);
    let status_us = r.drive.ep.config().status_us;
    assert!(p.wake_at > now && p.wake_at.0 <= now.0 + status_us);
    let p = r.plc.pump.pass(&mut r.plc.ep, &[], 0, now);
    let heartbeat_us = r.plc.ep.config().heartbeat_us;
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
    let now = Micros(r.now.0 + 1);
    r.plc.ep.run().unwrap();
    let mut pump = Pump::new(MAX_IDLE_US);
    let p = pump.pass(&mut r.plc.ep, &[], 0, now);
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
        let p = pump.pass(&mut r.plc.ep, &[], 4, t);
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
    let (mut s, mut drive_pump) = (r.drive, Pump::new(MAX_IDLE_US));
    drive_pump.pass(&mut s.ep, &wire, 0, t);
    got.extend(std::iter::from_fn(|| s.ep.poll_event()));
    assert_eq!(got, vec![DriveEvent::Run]);
}

#[test]
fn timers_run_while_the_line_stays_busy() {
    let mut r = Rig::connected();
    let start = r.now;
    let mut pump = Pump::new(MAX_IDLE_US);
    let mut t = start;
    let mut passes = 0;
    let mut last = t;
    while r.plc.ep.is_up() && t.0 < start.0 + 100_000 {
        last = t;
        let p = pump.pass(&mut r.plc.ep, &[], 0, t);
        assert_eq!(p.tx_len, 0);
        // The ack owed is due at once, but the line never frees: 1 ms steps.
        t = p.wake_at.max(Micros(t.0 + 1_000));
        passes += 1;
    }
    let timeout = r.plc.ep.config().plc_timeout_us;
    assert!(!r.plc.ep.is_up(), "link loss detected with the line busy");
    assert!(last.0 - start.0 <= timeout, "at its deadline");
    assert!(passes <= 41, "{passes} passes");
}

#[test]
fn line_errors_are_counted_and_logged_at_a_limited_rate() {
    let mut r = Rig::connected();
    let mut pump = Pump::new(MAX_IDLE_US);
    let t0 = r.now.0;
    let mut logs = Vec::new();
    // A floating RX pin: an error every 100 us for 2.5 s.
    for k in 0..25_000u64 {
        if let Some(n) = pump.line_error(&mut r.plc.ep, Micros(t0 + k * 100)) {
            logs.push(n);
        }
    }
    assert_eq!(logs, vec![1, 10_000, 10_000]);
    assert_eq!(r.plc.ep.stats().line_errors, 25_000);
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
