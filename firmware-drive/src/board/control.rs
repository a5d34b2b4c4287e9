//! The 1 ms task: the core's millisecond tick (drive section, state machine), the release of
//! hardware trips, and the defmt log of the core's events.

use embassy_time::{Duration, Ticker};
use firmware_drive::drive::DriveEvent;
use heapless::Vec;

use super::{hw_protection, power_stage, shared, supervisor};

/// Period of the drive-section task.
pub const PERIOD: Duration = Duration::from_millis(1);

/// Events kept from one tick for logging (the core's own queue holds 16 and reports loss).
const EVENTS_PER_TICK: usize = firmware_drive::drive::EVENT_QUEUE + 1;

/// Ticks the core every millisecond.
#[embassy_executor::task]
pub async fn run() {
    let mut ticker = Ticker::every(PERIOD);
    loop {
        ticker.next().await;
        let causes = hw_protection::active();
        let mut events: Vec<DriveEvent, EVENTS_PER_TICK> = Vec::new();
        #[cfg(feature = "dwt-cycles")]
        let start = super::cycles::now();
        shared::with(|s| {
            for (cause, present) in causes {
                if !present {
                    s.core.hardware_break_released(cause);
                }
            }
            s.core.tick_1ms(&mut |e| {
                let _ = events.push(e);
            });
        });
        #[cfg(feature = "dwt-cycles")]
        super::cycles::record_tick(start);
        if causes.iter().all(|(_, present)| !present) {
            power_stage::rearm_break_irq();
        }
        for e in events {
            match e {
                DriveEvent::Fault(code) => defmt::error!("drive: fault {}", code),
                DriveEvent::EventsLost(n) => defmt::warn!("drive: {} events lost", n),
                other => defmt::info!("drive: {}", other),
            }
        }
        #[cfg(feature = "dwt-cycles")]
        super::cycles::report_every_second();
        supervisor::alive(supervisor::TASK_CONTROL);
    }
}
