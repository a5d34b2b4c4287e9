//! link.md: a `WR Q` in the PLC scan is applied by the drive within 2 ms at 115200 baud on
//! a clean link, measured here through both applications and the byte-timed wires.

use hil_sim::latency::{q_write_latencies_flooded_ns, q_write_latencies_ns};

fn check(baud: u32) {
    let l = q_write_latencies_ns(baud, 60, 1.0).unwrap();
    let max = *l.iter().max().unwrap();
    let mean = l.iter().sum::<u64>() as f64 / l.len() as f64;
    println!(
        "{baud} baud: mean {:.0} us, max {} us",
        mean / 1e3,
        max / 1000
    );
    assert_eq!(l.len(), 60);
    assert!(max < 2_000_000, "max latency {max} ns at {baud} baud");
    // Not faster than the bytes can travel: at least one frame time.
    assert!(*l.iter().min().unwrap() > 10 * 1_000_000_000 / u64::from(baud));
}

#[test]
fn q_write_reaches_the_drive_within_2_ms_at_115200() {
    check(115_200);
}

#[test]
fn q_write_reaches_the_drive_within_2_ms_at_1_mbaud() {
    check(1_000_000);
}

/// service.md 10: the Q-write latency stays <= 2 ms with the service port flooded
/// (`[service] flood = true`): the same writes give the same latencies, to the ns,
/// because the service never delays the scan or the link (service.md 5).
#[test]
fn a_flooded_service_port_leaves_the_q_write_latency_unchanged() {
    let plain = q_write_latencies_ns(115_200, 60, 1.0).unwrap();
    let flooded = q_write_latencies_flooded_ns(115_200, 60, 1.0, 7).unwrap();
    let max = *flooded.iter().max().unwrap();
    println!(
        "115200 baud, service port flooded: max {} us (unflooded max {} us)",
        max / 1000,
        plain.iter().max().unwrap() / 1000
    );
    assert_eq!(flooded, plain);
    assert!(max < 2_000_000, "max latency {max} ns with the flood");
}
