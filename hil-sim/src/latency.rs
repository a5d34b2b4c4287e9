//! End-to-end latency of a `WR Q` (link.md "Latency"), measured in the full
//! co-simulation: from the PLC scan that writes the new value to the moment the drive's
//! copy of the Q variable holds it (both applications, both UART wires, the scheduler).

use anyhow::Result;

use shared_protocol::service::{SERVICE_BAUD, SERVICE_VERSION};

use crate::run::parse_program;
use crate::scenario::Scenario;
use crate::service::{line, Attached, ServiceLine};
use crate::sim::{RunOptions, Simulation};

/// Q10 = A02 on every scan (`LDC B99` puts a 1 in S0 so that `WR` writes).
const PROGRAM: &str = "150 LDC B99\n151 LD A02\n152 WR Q10\n";

/// The Q the measurement writes.
const Q: u8 = 10;

/// Latencies (ns) of `count` writes at `baud` with a clean link. Write k changes A02 at
/// 200 ms + k x 23.7 ms (so the writes fall on every phase of the link's traffic); the
/// latency runs from the first scan that sees the new value.
pub fn q_write_latencies_ns(baud: u32, count: usize, scan_time_ms: f64) -> Result<Vec<u64>> {
    q_write_latencies_with(baud, count, scan_time_ms, None)
}

/// [`q_write_latencies_ns`] with the service port flooded (service.md 9 and 10, `[service]
/// flood = true`): seeded random bytes at the service baud into the PLC's service core
/// for the whole measurement, stepped after every 1 ms tick as `hil-sim run` does. The
/// service must not delay the scan or the link (service.md 5): the latencies are the
/// unflooded ones.
pub fn q_write_latencies_flooded_ns(
    baud: u32,
    count: usize,
    scan_time_ms: f64,
    flood_seed: u64,
) -> Result<Vec<u64>> {
    q_write_latencies_with(baud, count, scan_time_ms, Some(flood_seed))
}

fn q_write_latencies_with(
    baud: u32,
    count: usize,
    scan_time_ms: f64,
    flood_seed: Option<u64>,
) -> Result<Vec<u64>> {
    let program = parse_program(PROGRAM, "latency.plc")?;
    let mut toml = format!("[plant]\nscan_time_ms = {scan_time_ms}\n[link]\nbaud = {baud}\n");
    let first_ns = 200_000_000u64;
    let spacing_ns = 23_700_000u64;
    for k in 0..count {
        let at_ns = first_ns + k as u64 * spacing_ns;
        toml.push_str(&format!(
            "[[event]]\nat_s = {}\nset = {{ A02 = {} }}\n",
            at_ns as f64 * 1e-9,
            (k % 1000) + 1
        ));
    }
    let scenario = Scenario::parse(&toml)?;
    let scan_ns = scenario.scan_time_ns;
    let mut sim = Simulation::new(&program, scenario, RunOptions::default())?;
    let mut flood = flood_seed.map(|seed| {
        Attached::detached(ServiceLine::new(
            line::build_info(seed),
            SERVICE_BAUD,
            SERVICE_VERSION,
            Some(seed),
        ))
    });
    let mut run_until = |sim: &mut Simulation, t: u64| match flood.as_mut() {
        Some(svc) => svc.run_until(sim, t, &mut |_| {}),
        None => sim.run_until(t, |_| {}),
    };
    let mut out = Vec::with_capacity(count);
    for k in 0..count {
        let at_ns = first_ns + k as u64 * spacing_ns;
        let value = ((k % 1000) + 1) as i16;
        // The first scan at or after the input change reads it.
        let scan_at = at_ns.div_ceil(scan_ns) * scan_ns;
        run_until(&mut sim, at_ns);
        let mut t = scan_at;
        let deadline = scan_at + 20_000_000;
        loop {
            run_until(&mut sim, t);
            if sim.drive().core().vm().q(Q) == value {
                out.push(t - scan_at);
                break;
            }
            if t >= deadline {
                anyhow::bail!("write {k} not applied within 20 ms");
            }
            t += 1_000;
        }
    }
    if let Some(svc) = flood.as_mut() {
        // The flood really ran: the line was kept full (~11.5 bytes per ms).
        let ms = sim.now_ns() / 1_000_000;
        if svc.line().flooded_bytes() < ms * 10 {
            anyhow::bail!(
                "the flood sent {} bytes in {ms} ms",
                svc.line().flooded_bytes()
            );
        }
    }
    Ok(out)
}
