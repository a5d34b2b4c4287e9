//! The 1 ms task: the application's control tick (`firmware_drive::bodies`) over
//! [`ControlRegs`], then the defmt log of its events.

use embassy_time::{Duration, Ticker};
use firmware_drive::app::{AppEvent, DriveApp};
use firmware_drive::bodies::ControlPort;
use firmware_drive::comparators::DacValues;
use firmware_drive::drive::DriveEvent;
use firmware_drive::power_port::ComparatorLevels;
use shared_protocol::units::Micros;

use super::{hw_protection, power_stage, shared, supervisor};

/// Period of the drive-section task.
pub const PERIOD: Duration = Duration::from_millis(1);

/// Ticks the application every millisecond.
#[embassy_executor::task]
pub async fn run() {
    let mut ticker = Ticker::every(PERIOD);
    loop {
        ticker.next().await;
        #[cfg(feature = "dwt-cycles")]
        let start = super::cycles::now();
        let events = DriveApp::control_tick(&mut ControlRegs);
        #[cfg(feature = "dwt-cycles")]
        super::cycles::record_tick(start);
        // Only the defmt format is chosen here.
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

/// The control tick's registers: `STO_IN`, the comparators, the threshold DACs, the break
/// interrupt's mask, the link task's wake-up, and the application in one critical section
/// per access.
struct ControlRegs;

impl ControlPort for ControlRegs {
    #[inline(always)]
    fn with_app<R>(&mut self, f: impl FnOnce(&mut DriveApp) -> R) -> Option<R> {
        shared::with(|s| f(s.app))
    }

    #[inline(always)]
    fn now(&mut self) -> Micros {
        shared::now()
    }

    #[inline(always)]
    fn sto_input_low(&mut self) -> bool {
        power_stage::sto_input_low()
    }

    #[inline(always)]
    fn comparator_levels(&mut self) -> ComparatorLevels {
        hw_protection::levels()
    }

    #[inline(always)]
    fn rearm_break_irq(&mut self) {
        power_stage::rearm_break_irq();
    }

    #[inline(always)]
    fn write_dacs(&mut self, v: DacValues) {
        hw_protection::write_dacs(v);
    }

    #[inline(always)]
    fn kick_link(&mut self) {
        board_common::link::kick();
    }
}
