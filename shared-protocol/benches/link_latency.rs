//! Link benchmark: end-to-end latency of a Q write (PLC endpoint -> drive endpoint) on a
//! clean byte-timed wire, wire bandwidth use at the default heartbeat/status rates, and
//! the codec's CPU cost on the host.
//!
//! `cargo bench -p shared-protocol --bench link_latency`

use std::time::Instant;

use shared_protocol::link::channel::Impairments;
use shared_protocol::link::frame::{encode_frame, Frame, FrameReader, MAX_WIRE_FRAME};
use shared_protocol::link::pair::LinkPair;
use shared_protocol::link::{DriveEvent, DriveState, DriveStatus, LinkConfig, PlcMsg, QValue};
use shared_protocol::units::Micros;

fn connected(baud: u32) -> LinkPair {
    let mut p = LinkPair::new(LinkConfig::at_baud(baud), Impairments::default(), 1);
    p.drive.set_status(DriveStatus {
        state: DriveState::Run,
        freq_dhz: 500,
        udc_dv: 300,
        imax_ca: 150,
        com: 512,
        ..Default::default()
    });
    p.run_until(Micros(20_000), |_| {});
    assert!(p.plc.is_up() && p.drive.is_up());
    while p.drive.poll_event().is_some() {}
    while p.plc.poll_event().is_some() {}
    p
}

/// Q writes at pseudo-random moments against the heartbeat and status traffic;
/// returns sorted latencies in microseconds. With `scan_us` = Some(period), the PLC scans
/// every period: writes happen only at scan times, and after each scan the caller tells
/// the link it will be quiet until the next one (`PlcLink::quiet_for`, as `PlcApp` does),
/// so heartbeats go right after a scan. With `None`, writes come at any microsecond and
/// the link knows nothing of the scans (worst case).
fn latencies(baud: u32, writes_per_scan: u8, samples: usize, scan_us: Option<u64>) -> Vec<u64> {
    let mut p = connected(baud);
    let mut x: u64 = 12345;
    let mut out = Vec::with_capacity(samples);
    let mut next_scan = p.now.0;
    // Run to `t`, announcing the quiet window at every scan on the way.
    let advance = |p: &mut LinkPair, t: u64, next_scan: &mut u64| {
        while p.now.0 < t {
            if let Some(period) = scan_us {
                if p.now.0 >= *next_scan {
                    p.plc.quiet_for(p.now, period - 50);
                    p.kick();
                    *next_scan += period;
                }
                p.step(Micros(t.min(*next_scan)));
            } else {
                p.step(Micros(t));
            }
        }
    };
    for k in 0..samples {
        x = x
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let mut issue = p.now.0 + 2_000 + (x >> 33) % 15_000;
        if let Some(period) = scan_us {
            issue = issue.div_ceil(period) * period;
        }
        advance(&mut p, issue, &mut next_scan);
        while p.drive.poll_event().is_some() {}
        let value = (k % 30_000) as i16;
        for a in 0..writes_per_scan {
            p.plc.write_q(a, value).unwrap();
        }
        if let Some(period) = scan_us {
            p.plc.quiet_for(p.now, period - 50);
            next_scan = issue + period;
        }
        p.kick();
        let last = writes_per_scan - 1;
        let limit = issue + 100_000;
        let mut done = None;
        while p.now.0 < limit && done.is_none() {
            let t = p.now.0 + 10;
            advance(&mut p, t, &mut next_scan);
            while let Some(e) = p.drive.poll_event() {
                if e == (DriveEvent::QWrite { addr: last, value }) {
                    done = Some(p.now);
                }
            }
        }
        out.push(done.expect("applied").0 - issue);
    }
    out.sort_unstable();
    out
}

fn report(name: &str, v: &[u64]) {
    let mean = v.iter().sum::<u64>() as f64 / v.len() as f64;
    let pct = |q: f64| v[((v.len() - 1) as f64 * q) as usize];
    println!(
        "{name:<48} n={:<5} min {:>5} us  mean {:>7.1} us  p50 {:>5} us  p99 {:>5} us  max {:>5} us",
        v.len(),
        v[0],
        mean,
        pct(0.5),
        pct(0.99),
        v[v.len() - 1]
    );
}

/// Bytes per second each way over `secs` of simulated RUN; `q_every_ms` adds a Q write
/// at that period (0 = none).
fn bandwidth(baud: u32, secs: u64, q_every_ms: u64, scans: bool) -> (f64, f64) {
    let mut p = connected(baud);
    let start_d = p.line.to_drive.stats().busy_ns;
    let start_p = p.line.to_plc.stats().busy_ns;
    let t0 = p.now;
    let mut next_q = t0;
    let mut v = 0i16;
    let end = Micros(t0.0 + secs * 1_000_000);
    let mut next_scan = t0;
    while p.now < end {
        if scans && p.now >= next_scan {
            // 1 ms scans announcing their quiet window (PlcApp does this).
            p.plc.quiet_for(p.now, 950);
            p.kick();
            next_scan = Micros(next_scan.0 + 1000);
        }
        if q_every_ms > 0 && p.now >= next_q {
            v = v.wrapping_add(1);
            p.plc.write_q(0, v).unwrap();
            next_q = Micros(next_q.0 + q_every_ms * 1000);
        }
        let mut until = end.0;
        if q_every_ms > 0 {
            until = until.min(next_q.0);
        }
        if scans {
            until = until.min(next_scan.0);
        }
        p.step(Micros(until.max(p.now.0 + 1)));
        while p.drive.poll_event().is_some() {}
    }
    let span_ns = (p.now.0 - t0.0) as f64 * 1000.0;
    (
        (p.line.to_drive.stats().busy_ns - start_d) as f64 / span_ns * 100.0,
        (p.line.to_plc.stats().busy_ns - start_p) as f64 / span_ns * 100.0,
    )
}

fn main() {
    println!("== Q write latency, PLC write_q -> drive QWrite event, clean byte-timed wire ==");
    for (scan, what) in [(Some(1_000), "1 ms scans"), (None, "unsynchronised")] {
        for n in [1u8, 2, 4] {
            let name = format!("115200 baud, {n} Q in a scan, {what}");
            report(&name, &latencies(115_200, n, 2_000, scan));
        }
    }
    report(
        "1 Mbaud, 1 Q, unsynchronised",
        &latencies(1_000_000, 1, 2_000, None),
    );
    println!("\n== wire use (% of capacity, 8N1) in RUN at default rates ==");
    for (baud, q, scans) in [
        (115_200, 0, false),
        (115_200, 0, true),
        (115_200, 10, true),
        (115_200, 1, true),
        (1_000_000, 0, true),
        (1_000_000, 1, true),
    ] {
        let (down, up) = bandwidth(baud, 20, q, scans);
        let mut what = if q == 0 {
            "heartbeat + status only".to_string()
        } else {
            format!("+ a Q change every {q} ms")
        };
        if scans {
            what += ", 1 ms scans";
        }
        println!("{baud:>7} baud, {what:<40} PLC->drive {down:5.1} %  drive->PLC {up:5.1} %");
    }

    println!("\n== codec cost on this host (not the MCU) ==");
    let mut w = heapless::Vec::new();
    w.push(QValue {
        addr: 1,
        value: 1234,
    })
    .unwrap();
    let f = Frame {
        seq: 1,
        ack: 2,
        msg: PlcMsg::QWrite(w),
    };
    let mut buf = [0u8; MAX_WIRE_FRAME];
    let n = encode_frame(&f, false, &mut buf).unwrap();
    let iters = 1_000_000u32;
    let t = Instant::now();
    let mut total = 0usize;
    for _ in 0..iters {
        total += encode_frame(std::hint::black_box(&f), false, &mut buf).unwrap();
    }
    let enc = t.elapsed().as_nanos() as f64 / f64::from(iters);
    let mut r = FrameReader::new();
    let t = Instant::now();
    let mut ok = 0u32;
    for _ in 0..iters {
        for &b in std::hint::black_box(&buf[..n]) {
            if let Some(Ok(_)) = r.push::<PlcMsg>(b) {
                ok += 1;
            }
        }
    }
    let dec = t.elapsed().as_nanos() as f64 / f64::from(iters);
    assert_eq!(ok, iters);
    println!("Q-write frame: {n} wire bytes; encode {enc:.0} ns, decode {dec:.0} ns per frame ({total} bytes)");
}
