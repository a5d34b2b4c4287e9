//! The PLC scan loop: reads the inputs, runs the core, writes the outputs.

use embassy_time::{Duration, Ticker};

use super::outputs::DigitalOutputs;
use super::supervisor;

/// Scan period.
pub const PERIOD: Duration = Duration::from_millis(1);

/// Runs the scan every [`PERIOD`].
#[embassy_executor::task]
pub async fn run(mut outputs: DigitalOutputs) {
    let mut ticker = Ticker::every(PERIOD);
    loop {
        ticker.next().await;
        // Call site of the PLC core's scan (issue 8).
        outputs.write(0);
        supervisor::alive(supervisor::TASK_SCAN);
    }
}
