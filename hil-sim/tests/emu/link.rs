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

/// A line error (here a framing error: a stop bit read low) is counted and
/// logged by both link tasks, reception goes on with the next character (the link's own
/// DMA ring never stops: `board_common::link_rx`; embassy's stopped and re-enabled its
/// channel by EN only, which the emulator rejects as RM0440 does), and the link stays up:
/// no LINK trip, the drive keeps running.
#[test]
fn a_framing_error_is_counted_and_reception_goes_on() {
    let mut sim = emu(MOTOR_PLC, MOTOR_TOML);
    sim.run_until(ns(1.0), |_| {});
    assert_eq!(sim.status().map(|s| s.state), Some(DriveState::Run));
    let faults_before = sim.faults().len();
    let drive_log_from = sim.drive().log().len();
    let plc_log_from = sim.plc().log().len();
    sim.inject_framing_errors(true, 3);
    sim.inject_framing_errors(false, 3);
    sim.run_until(ns(1.5), |_| {});
    let text = |lines: &[g431_emu::log::LogLine]| {
        lines
            .iter()
            .map(|l| l.to_string())
            .collect::<Vec<_>>()
            .join("\n")
    };
    let drive_log = text(&sim.drive().log()[drive_log_from..]);
    let plc_log = text(&sim.plc().log()[plc_log_from..]);
    assert!(drive_log.contains("line error"), "drive log:\n{drive_log}");
    assert!(plc_log.contains("line error"), "PLC log:\n{plc_log}");
    assert!(!drive_log.contains("LinkLost"), "drive log:\n{drive_log}");
    assert_eq!(sim.faults().len(), faults_before, "{:?}", sim.faults());
    assert_eq!(sim.status().map(|s| s.state), Some(DriveState::Run));
}
