//! The 1 ms task: the comparator levels to the application's break monitor (release and
//! re-arming are its decisions), the application's millisecond tick (link supervision,
//! drive section, state machine, status), the threshold DACs it asks for, and the defmt
//! log of the application's events.

use embassy_time::{Duration, Ticker};
use firmware_drive::app::{AppEvent, TickStep};
use firmware_drive::drive::DriveEvent;
use heapless::Vec;

use super::{hw_protection, power_stage, shared, supervisor};

/// Period of the drive-section task.
pub const PERIOD: Duration = Duration::from_millis(1);

/// Events taken per tick for logging (the application keeps the newest 32; the link task
/// leaves its events for this task).
const EVENTS_PER_TICK: usize = 32;

/// Ticks the application every millisecond.
#[embassy_executor::task]
pub async fn run() {
    let mut ticker = Ticker::every(PERIOD);
    // The threshold DACs as written at start-up (the core's defaults).
    let mut dacs = shared::with(|s| s.app.core().comparator_dacs());
    loop {
        ticker.next().await;
        let levels = hw_protection::levels();
        let mut events: Vec<AppEvent, EVENTS_PER_TICK> = Vec::new();
        #[cfg(feature = "dwt-cycles")]
        let start = super::cycles::now();
        let rearm = shared::with(|s| {
            // safety.md 6: the STO input's level, every tick, before the break monitor
            // (no re-arming while it is low) and the tick.
            s.app.set_sto_input(power_stage::sto_input_low());
            s.app.break_poll(levels).rearm
        });
        // Each step of the tick in a critical section of its own (review N8: the whole
        // tick at the start of RUN held the PWM interrupt off for ~1.5 periods at 20 kHz).
        // No await in between: no other task runs between the steps, only interrupts.
        let t = shared::now();
        for step in TickStep::ALL {
            shared::with(|s| s.app.tick_step(step, t));
        }
        shared::with(|s| {
            // A download may have changed I>>/U>>: write the core's new DAC values.
            let now = s.app.core().comparator_dacs();
            if Some(now) != dacs {
                hw_protection::write_dacs(now);
                dacs = Some(now);
            }
            while !events.is_full() {
                match s.app.poll_event() {
                    Some(e) => {
                        let _ = events.push(e);
                    }
                    None => break,
                }
            }
        });
        #[cfg(feature = "dwt-cycles")]
        super::cycles::record_tick(start);
        super::link::kick_if_due();
        if rearm == Some(true) {
            power_stage::rearm_break_irq();
        }
        for e in events {
            match e {
                AppEvent::Core(DriveEvent::Fault(code)) => defmt::error!("drive: fault {}", code),
                AppEvent::Core(DriveEvent::EventsLost(n)) => {
                    defmt::warn!("drive: {} events lost", n)
                }
                AppEvent::Core(other) => defmt::info!("drive: {}", other),
                AppEvent::Link(l) => defmt::info!("link: {}", l),
                AppEvent::Refused { command, error } => {
                    defmt::warn!("drive: {} refused: {}", command, error)
                }
                AppEvent::LoadFailed => {
                    defmt::error!("drive: accepted section missing at hand-over")
                }
                AppEvent::AckReasonLost => {
                    defmt::warn!("drive: ACK refused, reason not sent (link queue full)")
                }
            }
        }
        #[cfg(feature = "dwt-cycles")]
        super::cycles::report_every_second();
        supervisor::alive(supervisor::TASK_CONTROL);
    }
}
