//! The drive MCU on the host: the firmware's [`DriveApp`] (link endpoint + drive core),
//! whose interrupt and task bodies (`firmware_drive::bodies`) run over the simulator's
//! TIM1 ([`SimTim1`]) and plant, at the board's cadence.

use firmware_drive::app::DriveApp;
use firmware_drive::bodies::ControlPort;
use firmware_drive::comparators::{BoardProfile, DacValues};
use firmware_drive::power_port::ComparatorLevels;
use firmware_drive::{AdcSample, CoreStatus, DriveConfig, DriveCore, PwmTiming, ResetCause};

use crate::plant::{Comparators, Plant};
use crate::tim1::SimTim1;
use shared_protocol::link::pump::{Pass, Pump, MAX_IDLE_US};
use shared_protocol::link::LinkConfig;
use shared_protocol::units::Micros;

/// The drive MCU (the board's image, on the host).
pub struct SimDrive {
    app: DriveApp,
    pump: Pump,
    timer_clock_hz: u32,
}

impl SimDrive {
    pub fn new(link_cfg: LinkConfig) -> Self {
        Self::with_config(link_cfg, DriveConfig::default())
    }

    /// A board with its own configuration (e.g. the rig's default hardware thresholds).
    pub fn with_config(link_cfg: LinkConfig, cfg: DriveConfig) -> Self {
        Self::with_reset(link_cfg, cfg, ResetCause::PowerOn)
    }

    /// A board coming out of reset with `cause` (power-on, or its watchdog).
    pub fn with_reset(link_cfg: LinkConfig, cfg: DriveConfig, cause: ResetCause) -> Self {
        SimDrive {
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

impl SimDrive {
    // The calls the simulator makes, as the board's interrupts and tasks make them.
    /// TIM1 update interrupt ([`DriveApp::pwm_interrupt`]): the ADC conversion of this
    /// period in, the power stage's action performed on the simulator's TIM1.
    pub fn pwm_interrupt(&mut self, tim: &mut SimTim1, plant: &mut Plant, adc: AdcSample) {
        self.app.pwm_interrupt(&mut tim.pwm_port(plant, adc));
    }

    /// TIM1 break interrupt ([`DriveApp::break_interrupt`]).
    pub fn break_interrupt(&mut self, tim: &mut SimTim1, plant: &mut Plant) {
        self.app.break_interrupt(&mut tim.break_port(plant));
    }

    /// The board's 1 ms task ([`DriveApp::control_tick`]): whether it woke the link task.
    pub fn control_tick(&mut self, tim: &mut SimTim1, plant: &mut Plant, now: Micros) -> bool {
        let mut port = SimControl {
            app: &mut self.app,
            tim,
            plant,
            now,
            kick: false,
        };
        // The board logs these over defmt; the simulator has no use for them.
        let _ = DriveApp::control_tick(&mut port);
        port.kick
    }

    /// The threshold DACs as the board's start-up writes them (after the trim).
    pub fn boot_dacs(&mut self, plant: &mut Plant) {
        let dacs = self.app.boot_dacs();
        plant.set_comparators(Comparators {
            board: self.board(),
            dacs,
        });
    }

    /// The safety monitor's commanded field turns since RUN start, 10⁻⁴ turn.
    pub fn turns_e4(&self) -> i64 {
        self.app.core().safety().turns_e4()
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

    /// TIM1 setup the board's init programs (later changes come as [`PeriodAction`](firmware_drive::power_port::PeriodAction)s).
    pub fn pwm_timing(&self) -> PwmTiming {
        self.app.pwm_timing()
    }

    /// The timer's kernel clock.
    pub fn timer_clock_hz(&self) -> u32 {
        self.timer_clock_hz
    }

    pub fn status(&self) -> CoreStatus {
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

/// [`ControlPort`] over the simulator: `STO_IN` and the comparators from the plant, the
/// DACs into it, the break interrupt's mask in [`SimTim1`].
struct SimControl<'a> {
    app: &'a mut DriveApp,
    tim: &'a mut SimTim1,
    plant: &'a mut Plant,
    now: Micros,
    kick: bool,
}

impl ControlPort for SimControl<'_> {
    fn with_app<R>(&mut self, f: impl FnOnce(&mut DriveApp) -> R) -> Option<R> {
        Some(f(self.app))
    }

    fn now(&mut self) -> Micros {
        self.now
    }

    fn sto_input_low(&mut self) -> bool {
        self.plant.sto_in_low()
    }

    fn comparator_levels(&mut self) -> ComparatorLevels {
        self.plant.comparator_levels()
    }

    fn rearm_break_irq(&mut self) {
        self.tim.unmask_break_irq();
    }

    fn write_dacs(&mut self, dacs: DacValues) {
        let board = self.app.core().config().board;
        self.plant.set_comparators(Comparators { board, dacs });
    }

    fn kick_link(&mut self) {
        self.kick = true;
    }
}
