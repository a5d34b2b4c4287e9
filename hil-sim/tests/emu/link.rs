//! The link between the real images.

use shared_protocol::link::message::DriveState;

use crate::common::{emu, ns, MOTOR_PLC, MOTOR_TOML};

/// The PLC powers up in RUN with the motor program in slot 1: it must download the drive
/// section over the real USART/DMA link and start the drive. The first emulation of the
/// images found the PLC's link task sending a whole go-back-N window before it read RX
/// again (52 ms of line time against a 40 ms link timeout): the download never completed.
#[test]
fn the_download_completes_and_the_drive_runs() {
    let mut sim = emu(MOTOR_PLC, MOTOR_TOML);
    let mut running_at = None;
    sim.run_until(ns(1.0), |s| {
        let _ = s;
    });
    for step in 1..=10 {
        if sim.status().is_some_and(|s| s.state == DriveState::Run) {
            running_at = Some(step);
            break;
        }
        sim.run_until(ns(1.0 + 0.1 * f64::from(step)), |_| {});
    }
    let status = sim.status();
    assert!(
        running_at.is_some(),
        "drive not running 2 s after power-up: status {status:?}; PLC log:\n{}",
        sim.plc()
            .log()
            .iter()
            .rev()
            .take(12)
            .map(|l| l.to_string())
            .collect::<Vec<_>>()
            .join("\n")
    );
    // The PLC never stopped feeding its watchdog for more than half its timeout.
    let gap_ms = g431_emu::time::cycles_to_ns(sim.plc().soc().iwdg().longest_gap) / 1_000_000;
    assert!(gap_ms < 50, "PLC watchdog feed gap {gap_ms} ms");
}
