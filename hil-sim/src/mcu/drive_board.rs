//! The drive MCU on the host: the firmware's [`DriveApp`] (link endpoint + drive core),
//! called as the board's interrupts and tasks call it.

use firmware_drive::app::DriveApp;
use firmware_drive::comparators::{BoardProfile, DacValues};
use firmware_drive::power_port::{BreakReport, ComparatorLevels, PeriodAction};
use firmware_drive::{AdcSample, DriveConfig, DriveCore, DriveStatus, PwmTiming, ResetCause};
use shared_protocol::link::pump::{Pass, Pump, MAX_IDLE_US};
use shared_protocol::link::LinkConfig;
use shared_protocol::units::Micros;

/// The drive board.
pub struct DriveBoard {
    app: DriveApp,
    pump: Pump,
    timer_clock_hz: u32,
}

impl DriveBoard {
    pub fn new(link_cfg: LinkConfig) -> Self {
        Self::with_config(link_cfg, DriveConfig::default())
    }

    /// A board with its own configuration (e.g. the rig's default hardware thresholds).
    pub fn with_config(link_cfg: LinkConfig, cfg: DriveConfig) -> Self {
        Self::with_reset(link_cfg, cfg, ResetCause::PowerOn)
    }

    /// A board coming out of reset with `cause` (power-on, or its watchdog).
    pub fn with_reset(link_cfg: LinkConfig, cfg: DriveConfig, cause: ResetCause) -> Self {
        DriveBoard {
            timer_clock_hz: cfg.timer_clock_hz,
            app: DriveApp::new(cfg, cause, link_cfg),
            pump: Pump::new(MAX_IDLE_US),
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

impl DriveBoard {
    // The calls the simulator makes, as the board's interrupts and tasks make them.
    /// TIM1 update interrupt: the ADC conversion of this period in, what the power stage
    /// does out (performed over the simulator's TIM1, [`crate::tim1::SimTim1`]).
    #[inline]
    pub fn pwm_isr(&mut self, adc: &AdcSample) -> PeriodAction {
        self.app.pwm_period(adc)
    }

    /// The 1 ms system tick (drive section, state machine, link timers).
    pub fn tick_1ms(&mut self, now: Micros) {
        self.app.tick_1ms(now);
        self.drain();
    }

    /// The board reads `STO_IN` every millisecond, before the tick (safety.md 6).
    pub fn set_sto_input(&mut self, low: bool) {
        self.app.set_sto_input(low);
    }

    /// The safety monitor's commanded field turns since RUN start, 10⁻⁴ turn.
    pub fn turns_e4(&self) -> i64 {
        self.app.core().safety().turns_e4()
    }

    /// TIM1 break interrupt on `STO_IN`'s break (break 1).
    pub fn sto_break(&mut self) {
        self.app.sto_break();
    }

    /// TIM1 break interrupt with the comparators at `levels`.
    pub fn break_fired(&mut self, levels: ComparatorLevels) -> BreakReport {
        self.app.break_fired(levels)
    }

    /// Every 1 ms before the tick: the comparators at `levels` (release, re-arm).
    pub fn break_poll(&mut self, levels: ComparatorLevels) -> BreakReport {
        self.app.break_poll(levels)
    }

    /// One pass of the board's link task: the core's pump
    /// (`shared_protocol::link::pump::Pump::pass`) over the application, exactly as the
    /// board runs it. `rx`: bytes received since the last pass; `tx_room`: what the line
    /// takes now. [`Self::link_tx`] then holds the bytes for the line.
    pub fn link_pass(&mut self, rx: &[u8], tx_room: usize, now: Micros) -> Pass {
        let p = self.pump.pass(&mut self.app, rx, tx_room, now);
        self.drain();
        p
    }

    /// The bytes the last [`Self::link_pass`] handed out.
    pub fn link_tx(&self) -> &[u8] {
        self.pump.tx()
    }

    /// The application's next link deadline (`poll_timeout`): the board's tasks wake the
    /// link task when it has come.
    pub fn link_timeout(&self) -> Option<Micros> {
        self.app.poll_timeout()
    }

    /// TIM1 setup the board's init programs (later changes come as [`PeriodAction`]s).
    pub fn pwm_timing(&self) -> PwmTiming {
        self.app.pwm_timing()
    }

    /// The timer's kernel clock.
    pub fn timer_clock_hz(&self) -> u32 {
        self.timer_clock_hz
    }

    pub fn status(&self) -> DriveStatus {
        self.app.status()
    }

    /// The board's comparators (which signal, direction and DAC each one has): the drive
    /// core's profile.
    pub fn board(&self) -> &'static BoardProfile {
        self.app.core().config().board
    }

    /// What the firmware writes to the comparator threshold DACs now.
    pub fn comparator_dacs(&self) -> DacValues {
        self.app.core().comparator_dacs()
    }
}
