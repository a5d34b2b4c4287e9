//! The drive MCU on the host: the firmware's [`DriveApp`] (link endpoint + drive core),
//! called as the board's interrupts and tasks call it.

use firmware_drive::app::DriveApp;
use firmware_drive::comparators::{BoardProfile, DacValues};
use firmware_drive::power_port::{BreakReport, ComparatorLevels, PeriodAction};
use firmware_drive::{AdcSample, DriveConfig, DriveCore, DriveStatus, PwmTiming, ResetCause};
use shared_protocol::link::LinkConfig;
use shared_protocol::units::Micros;

use super::DriveMcu;

/// The drive board.
pub struct DriveBoard {
    app: DriveApp,
    timer_clock_hz: u32,
}

impl DriveBoard {
    pub fn new(link_cfg: LinkConfig) -> Self {
        Self::with_config(link_cfg, DriveConfig::default())
    }

    /// A board with its own configuration (e.g. the rig's default hardware thresholds).
    pub fn with_config(link_cfg: LinkConfig, cfg: DriveConfig) -> Self {
        DriveBoard {
            timer_clock_hz: cfg.timer_clock_hz,
            app: DriveApp::new(cfg, ResetCause::PowerOn, link_cfg),
        }
    }

    pub fn app(&self) -> &DriveApp {
        &self.app
    }

    pub fn core(&self) -> &DriveCore {
        self.app.core()
    }

    fn drain(&mut self) {
        // The board logs these over defmt; the simulator has no use for them.
        while self.app.poll_event().is_some() {}
    }
}

impl DriveMcu for DriveBoard {
    #[inline]
    fn pwm_isr(&mut self, adc: &AdcSample) -> PeriodAction {
        self.app.pwm_period(adc)
    }

    fn tick_1ms(&mut self, now: Micros) {
        self.app.tick_1ms(now);
        self.drain();
    }

    fn break_fired(&mut self, levels: ComparatorLevels) -> BreakReport {
        self.app.break_fired(levels)
    }

    fn break_poll(&mut self, levels: ComparatorLevels) -> BreakReport {
        self.app.break_poll(levels)
    }

    fn uart_rx(&mut self, bytes: &[u8], now: Micros) {
        self.app.on_rx(bytes, now);
        self.drain();
    }

    fn uart_tx(&mut self, now: Micros, out: &mut [u8]) -> usize {
        let n = self.app.poll_tx(now, out);
        self.drain();
        n
    }

    fn pwm_timing(&self) -> PwmTiming {
        self.app.pwm_timing()
    }

    fn timer_clock_hz(&self) -> u32 {
        self.timer_clock_hz
    }

    fn status(&self) -> DriveStatus {
        self.app.status()
    }

    fn board(&self) -> &'static BoardProfile {
        self.app.core().config().board
    }

    fn comparator_dacs(&self) -> DacValues {
        self.app.core().comparator_dacs()
    }
}
