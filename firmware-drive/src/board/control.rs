//! The 1 ms control task: runs the drive section and the state machine of the core.

use embassy_time::{Duration, Ticker};

use super::power_stage::GatesOff;
use super::supervisor;

/// Period of the drive-section task.
pub const PERIOD: Duration = Duration::from_millis(1);

/// Ticks the core every millisecond.
#[embassy_executor::task]
pub async fn run(_gates: GatesOff) {
    let mut ticker = Ticker::every(PERIOD);
    loop {
        ticker.next().await;
        supervisor::alive(supervisor::TASK_CONTROL);
    }
}
