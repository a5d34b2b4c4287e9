//! [`DriveCore`]: the whole drive as one sans-IO state machine. The board (or hil-sim)
//! calls three entry points and applies what they return:
//!
//! * [`DriveCore::pwm_period`] once per PWM period (TIM1 update interrupt) with the ADC
//!   sample of that period: software trips, brake chopper, modulator. Returns the duties.
//! * [`DriveCore::tick_1ms`] every millisecond: state machine, drive section, reversal,
//!   modulator parameters; returns events through the callback.
//! * [`DriveCore::command`], [`DriveCore::load_program`], [`DriveCore::trip`],
//!   [`DriveCore::hardware_break`] from the link and the break input.
//!
//! All take `&mut self`: on the target the caller serialises them (e.g. the 1 ms tick and
//! the link handler run inside a critical section or at the PWM interrupt's priority).
//! A trip latched by any of them takes effect in the next `pwm_period` at the latest, and
//! the `pwm_period` that detects a trip already returns the outputs off.

use heapless::Deque;
use shared_protocol::program::{verify_drive, DriveSection, VerifiedDriveSection, VerifyError};
use shared_protocol::program::{I_MAX_HW_LIMIT, U_MAX_HW_LIMIT};
use shared_protocol::units::{CentiAmps, Decihertz, Decivolts, Volts};

use crate::comparator_trim::{TrimFailed, TrimmedZeros};
use crate::comparators::{dac_values, DacValues, HwThresholds};
use crate::config::{DriveConfig, ResetCause};
use crate::measure::{abs_counts_to_centiamps, com_of, udc_decivolts, AdcSample, PeakTracker};
use crate::measure::{FrontEnd, ZeroCalibration};
use crate::modulator::{LegMode, Modulator, ModulatorParams, M_LIMIT_Q16};
use crate::overvoltage::{OvController, CAP_BELOW_OV_HW_VOLTS};
use crate::power_port::Causes;
use crate::protection::{FaultCode, HwBreak, Limits};
use crate::restart::AutoRestart;
use crate::reversal::Reversal;
use crate::safety::{status_outside_run, Input as SafetyInput, Monitor};
use crate::sine::phase_of_decidegrees;
use crate::state::DriveState;
use crate::timing::PwmTiming;
use crate::vm::{DriveVm, Settings, VmWarning};
use shared_protocol::program::safety_settings;
use shared_protocol::safety::FUNCTION_MASK;

/// Events queued between two `tick_1ms` calls (the queue drops the newest beyond it and
/// reports [`DriveEvent::EventsLost`]).
pub const EVENT_QUEUE: usize = 16;

/// Commands from the PLC (through the link layer).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DriveCommand {
    /// Start executing the loaded drive section (IDLE -> RUN).
    Run,
    /// Stop: PWM off at once (coast), RUN -> IDLE.
    Stop,
    /// Acknowledge the latched fault.
    Ack,
    /// The PLC wrote Q`addr` (`WR`/`WRC`): update the drive's copy.
    SetQ { addr: u8, value: i16 },
    /// The PLC's `REV` request.
    Direction { reverse: bool },
    /// The safety functions the PLC program requests (bit n = function n, safety.md 9).
    SafetyRequest { requested: u16 },
}

/// Why the drive core did not carry out a command (the link's own refusals are
/// `shared_protocol::link::plc::CommandError`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DriveRefusal {
    /// Still in BOOT.
    Booting,
    /// RUN while a fault is latched (ACK first).
    Faulted,
    /// RUN without an accepted drive section.
    NoProgram,
    /// ACK while the fault's cause is still present.
    CauseActive(FaultCode),
    /// ACK while the commanded frequency is at or above fmn.
    FrequencyNotBelowFmn,
    /// Q index beyond Q63.
    BadAddress,
    /// RUN while the hardware `STO_IN` input is low (safety.md 6: `RUN REFUSED:STO_IN`).
    StoInput,
}

impl core::fmt::Display for DriveRefusal {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            DriveRefusal::Booting => f.write_str("the drive is still booting"),
            DriveRefusal::Faulted => f.write_str("a fault is latched: acknowledge it first"),
            DriveRefusal::NoProgram => f.write_str("no accepted drive section"),
            DriveRefusal::CauseActive(c) => write!(f, "the cause of {} is still present", c.name()),
            DriveRefusal::FrequencyNotBelowFmn => {
                f.write_str("the frequency command is not below fmn")
            }
            DriveRefusal::BadAddress => f.write_str("Q index beyond Q63"),
            DriveRefusal::StoInput => f.write_str("STO_IN is low"),
        }
    }
}

impl core::error::Error for DriveRefusal {}

/// Warnings: reported, nothing latched.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DriveWarning {
    Vm(VmWarning),
}

/// What the core reports (never logs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DriveEvent {
    State {
        from: DriveState,
        to: DriveState,
    },
    /// A fault was latched (the first one; later trips while latched are not reported).
    Fault(FaultCode),
    Warning(DriveWarning),
    /// A pending direction request was applied (true = reverse).
    Reversed(bool),
    /// Events were dropped because the queue was full.
    EventsLost(u16),
}

/// What the PWM interrupt writes to TIM1.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PwmCommand {
    /// Main output enable (MOE): false = all six switches open.
    pub enable: bool,
    /// Per output leg (TIM1 CH1-3): the leg switches; false = both of its switches open
    /// (CCxE = CCxNE = 0 with OSSR = 1 holds them at their inactive level). All false when
    /// `enable` is false. A sine leg is off while f < fmn; a direct `WR PWx` leg is not
    /// (program.md 4.2 `fmn`, as the source).
    pub leg_enable: [bool; 3],
    /// Duties in counts, 0..=`period_counts`: the fraction duty/period of the period the
    /// high switch is on (0 for a leg that is off). Write them with [`PwmCommand::ccr`].
    pub duty: [u16; 3],
    /// ARR the duties refer to (= [`PwmTiming::arr`]); reprogram TIM1 when it changes.
    pub period_counts: u16,
    /// Brake-chopper switch on.
    pub brake: bool,
}

impl PwmCommand {
    /// TIM1_CCR1..3 values. In centre-aligned PWM mode 1 the output is active while
    /// CNT < CCR, and the counter touches ARR once per period, so CCR = ARR would leave a
    /// one-count low pulse at the peak (RM0440: only CCR > ARR holds the output at 1).
    /// A 100 % duty is therefore written as ARR + 1 (ARR is at most 65534, so it fits).
    #[inline(always)]
    pub fn ccr(&self) -> [u16; 3] {
        let ccr = |d: u16| {
            if d >= self.period_counts {
                self.period_counts.saturating_add(1)
            } else {
                d
            }
        };
        // Written out, not `map` (a call at opt-level "s"; the PWM interrupt runs this).
        let [d0, d1, d2] = self.duty;
        [ccr(d0), ccr(d1), ccr(d2)]
    }
}

/// The core's full status: the link's `DriveStatus` frame (`app::wire_status`) and the PLC's
/// extension operands carry part of it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CoreStatus {
    pub state: DriveState,
    pub fault: Option<FaultCode>,
    /// `FRQ`: frequency being generated (0 while the outputs are off).
    pub f_applied: Decihertz,
    /// Commanded frequency from the drive section (0 when not running).
    pub f_command: Decihertz,
    /// `DIR`: applied direction (true = reverse).
    pub reverse: bool,
    /// A direction request waits for the frv rule.
    pub reverse_pending: bool,
    /// `UDC`.
    pub u_dc: Decivolts,
    /// `IMX`: largest |phase current| over the last 10 ms.
    pub i_peak: CentiAmps,
    /// `COM`: aux channel, 10-bit.
    pub com: u16,
    /// Requested modulation index m = A / fjm + dU / 1023 (above 1.0 the drive
    /// overmodulates), 0.001 (0 while the outputs are off).
    pub modulation_permille: u16,
    pub brake: bool,
    pub pwm_millihertz: u32,
    pub program_loaded: bool,
    /// The hardware comparator thresholds in effect (`IHW`, `UHW`).
    pub hw: HwThresholds,
    /// The drive section's run-time warning while its cause lasts and the outputs switch.
    pub warning: Option<VmWarning>,
    /// Requested safety functions: the PLC's mask, plus bit 0 while `STO_IN` is low.
    pub sf_requested: u16,
    /// Safety status bits (safety.md 5's table for the states outside RUN).
    pub sf_status: u16,
    /// `SDC`: a ramp function in its delay or ramp phase (RUN only).
    pub sf_sdc: bool,
    /// `SFT`: the safety stopwatch, 0.1 s.
    pub sf_elapsed_ds: u16,
    /// `SFP`: whole commanded field turns since the activation.
    pub sf_turns: i16,
    /// The parameter signature of the accepted drive section (safety.md 8).
    pub sf_signature: u16,
    /// The hardware `STO_IN` input is low.
    pub sto_in_low: bool,
}

impl CoreStatus {
    /// `RDY`: no fault, program running.
    pub fn ready(&self) -> bool {
        self.state == DriveState::Run && self.fault.is_none()
    }
}

/// The steps of a load after [`DriveCore::load_begin`] ([`DriveCore::load_step`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum LoadStep {
    /// The VM's settings (`PWF`, limits, `fmn`...).
    Vm,
    /// The safety settings and their signature.
    Safety,
    /// Limits, timing and comparator thresholds from the new settings.
    Install,
}

/// The drive (see the module docs for how to drive it).
pub struct DriveCore {
    cfg: DriveConfig,
    reset_cause: ResetCause,
    state: DriveState,
    fault: Option<FaultCode>,
    program: Option<DriveSection>,
    vm: DriveVm,
    /// The PLC is in RUN: the section executes (also while FAULT, so that the frequency
    /// command follows the PLC and the ACK rule can see it fall below fmn).
    run_requested: bool,
    reversal: Reversal,
    limits: Limits,
    timing: PwmTiming,
    /// How many times `timing` was recomputed (wrapping): the application compares the
    /// whole timing only when this moved ([`DriveCore::timing_changes`]).
    timing_changes: u32,
    timing_key: (u16, u16),
    modulator: Modulator,
    /// Set by the tick: RUN and at least one leg switching (a direct leg, or a sine leg
    /// with f >= fmn).
    outputs_on: bool,
    /// Set by the tick: the sine legs switch (f >= fmn).
    sine_on: bool,
    /// Per output leg (after the reverse swap): switching while the outputs are on.
    legs_on: [bool; 3],
    /// The sine legs were on in the previous PWM period (to restart the sine at angle 0).
    was_on: bool,
    brake: bool,
    last: AdcSample,
    peak: PeakTracker,
    hw_break_active: Causes,
    /// The board's analog front end, calibrated at the end of BOOT.
    front_end: FrontEnd,
    zero_cal: ZeroCalibration,
    events: Deque<DriveEvent, EVENT_QUEUE>,
    events_lost: u16,
    /// The hardware thresholds in effect and their DAC values (updated at download).
    hw: HwThresholds,
    dacs: DacValues,
    /// The safety functions the PLC requests (bit n = function n, safety.md 2).
    safety_requested: u16,
    /// The hardware `STO_IN` input is low (read by the board every tick).
    sto_in_low: bool,
    /// The safety monitor (NOT RATED, `safety/`), evaluated in RUN after the section.
    safety: Monitor,
    /// The signature of the accepted section's safety settings.
    signature: u16,
    /// A load in steps ([`DriveCore::load_begin`]) has not finished.
    loading: bool,
    /// The frequency the modulator takes: the section's, under the monitor's `asr` cap
    /// and the overvoltage controller's hold.
    f_out: i16,
    /// The comparators' zero codes from the boot trim (`crate::comparator_trim`).
    trim: TrimmedZeros,
    /// The boot trim failed: `BOOT`.
    trim_failed: bool,
    /// The overvoltage controller (a board without a brake chopper).
    ovc: OvController,
    /// The frequency and amplitude applied in the last tick (the V/f ratio while the
    /// overvoltage controller holds the frequency above the command).
    applied_fa: (i16, i16),
    /// The automatic restart's counters (`arc`, `art`, `arn`).
    restart: AutoRestart,
}

/// The comparator thresholds from the settings (`OC`/`OV` when set, else the board's
/// defaults), clamped to the hardware limits.
fn hw_thresholds(s: &Settings, cfg: &DriveConfig) -> HwThresholds {
    let pick = |set: u16, default: u16, max: u16| {
        let v = if set > 0 { set } else { default };
        v.clamp(1, max) as i16
    };
    // `U>>` inside the DC link's measuring range (on the ESC1 34.3 V, where
    // the DAC would clamp a higher level and the comparator never trip), and the board's
    // default when the program sets none.
    let ov_max = ((cfg.board.scaling.udc_full_decivolts / 10) as u16).min(U_MAX_HW_LIMIT);
    let ov_default = cfg.ov_hw_default_volts.min(cfg.board.ov_hw_default_volts);
    HwThresholds {
        oc_hw: CentiAmps(pick(
            s.oc_hw_centiamps,
            cfg.oc_hw_default_centiamps,
            I_MAX_HW_LIMIT,
        )),
        ov_hw: Volts(pick(s.ov_hw_volts, ov_default, ov_max)),
    }
}

impl DriveCore {
    pub fn new(cfg: DriveConfig, reset_cause: ResetCause) -> Self {
        // Every part is built in its field's place (no local copy of the VM, no update after
        // construction): `DriveApp::new_in` builds the application in a static, not on the
        // stack.
        let settings = Settings::new(cfg.default_pwm_hz);
        let key = (settings.pwf_hz, settings.prescaler);
        let front_end = FrontEnd::new(cfg.board.scaling);
        let hw = hw_thresholds(&settings, &cfg);
        let dacs = dac_values(cfg.board, hw, &front_end, &TrimmedZeros::default());
        DriveCore {
            timing: Self::timing_for(&cfg, key),
            timing_changes: 0,
            timing_key: key,
            cfg,
            reset_cause,
            state: DriveState::Boot,
            fault: None,
            program: None,
            vm: DriveVm::new(cfg.default_pwm_hz),
            run_requested: false,
            reversal: Reversal::default(),
            limits: Limits::with_ov_hw(hw.ov_hw),
            modulator: Modulator::new(cfg.min_pulse_counts, cfg.min_max_injection),
            outputs_on: false,
            sine_on: false,
            legs_on: [false; 3],
            was_on: false,
            brake: false,
            last: AdcSample::default(),
            peak: PeakTracker::default(),
            hw_break_active: Causes::NONE,
            front_end,
            zero_cal: ZeroCalibration::default(),
            events: Deque::new(),
            events_lost: 0,
            hw,
            dacs,
            safety_requested: 0,
            sto_in_low: false,
            safety: Monitor::default(),
            signature: shared_protocol::safety::SafetySettings::default().signature(),
            loading: false,
            f_out: 0,
            trim: TrimmedZeros::default(),
            trim_failed: false,
            ovc: OvController::default(),
            applied_fa: (0, 0),
            restart: AutoRestart::default(),
        }
    }

    /// The timing a new core starts with ([`DriveCore::pwm_timing`] of
    /// `DriveCore::new(cfg, _)`): the default `PWF`/`PRx`.
    pub fn boot_timing(cfg: &DriveConfig) -> PwmTiming {
        let s = Settings::new(cfg.default_pwm_hz);
        Self::timing_for(cfg, (s.pwf_hz, s.prescaler))
    }

    fn timing_for(cfg: &DriveConfig, (pwf, pre): (u16, u16)) -> PwmTiming {
        PwmTiming::compute(
            cfg.timer_clock_hz,
            u32::from(pwf),
            u32::from(pre),
            cfg.dead_time_ns,
            cfg.min_dead_time_ns,
        )
    }

    pub fn state(&self) -> DriveState {
        self.state
    }

    pub fn fault(&self) -> Option<FaultCode> {
        self.fault
    }

    pub fn config(&self) -> &DriveConfig {
        &self.cfg
    }

    /// The interpreter (read-only: settings, Q copy, outputs).
    pub fn vm(&self) -> &DriveVm {
        &self.vm
    }

    /// The modulator (read-only: angle and parameters, for benches and hil-sim probes).
    pub fn modulator(&self) -> &Modulator {
        &self.modulator
    }

    /// The hardware thresholds in effect: the program's `I>>`/`U>>`, or the board's
    /// defaults ([`DriveConfig`]) while it sets none, within the sensors' full scale. Set
    /// when a program is loaded (the trimmers of the source, set at download).
    pub fn hw_thresholds(&self) -> HwThresholds {
        self.hw
    }

    fn compute_hw_thresholds(&self) -> HwThresholds {
        hw_thresholds(self.vm.settings(), &self.cfg)
    }

    /// What the board writes to the comparators' threshold DACs (12-bit), from
    /// [`DriveCore::hw_thresholds`] and the board profile: changes only when a program is
    /// loaded (the source's trimmers, set at download). The board writes a channel when
    /// its value differs from the one it last wrote.
    pub fn comparator_dacs(&self) -> DacValues {
        self.dacs
    }

    /// The thresholds and DAC values from the settings now (at construction and at each
    /// download).
    fn update_hw_thresholds(&mut self) {
        self.hw = self.compute_hw_thresholds();
        self.dacs = dac_values(self.cfg.board, self.hw, &self.front_end, &self.trim);
        self.limits.set_ov_hw(self.hw.ov_hw);
    }

    /// The boot trim of the comparators (`crate::comparator_trim`, run by the board before
    /// TIM1's break is armed): their thresholds count from its zero codes from now on; a
    /// failed trim ends BOOT in `BOOT`.
    pub fn set_comparator_trim(&mut self, r: Result<TrimmedZeros, TrimFailed>) {
        match r {
            Ok(z) => {
                self.trim = z;
                self.update_hw_thresholds();
            }
            Err(_) => self.trim_failed = true,
        }
    }

    /// The overvoltage controller (read-only: level and hold, for hil-sim probes).
    pub fn ov_controller(&self) -> &OvController {
        &self.ovc
    }

    /// What TIM1 must be programmed with now (changes when the program's `PWF`/`PRx` do).
    pub fn pwm_timing(&self) -> PwmTiming {
        self.timing
    }

    /// Counts the recomputations of [`DriveCore::pwm_timing`] (wrapping; 0 for a new core):
    /// while it stays, the timing is the one seen at that count.
    pub fn timing_changes(&self) -> u32 {
        self.timing_changes
    }

    /// Verify and take a new drive section. Rejected: no program, PWM off, fault `PROG`
    /// latched, and the error (line + reason) for the download reply. A download while in
    /// RUN stops first (the PLC downloads only when it starts RUN).
    // One copy, not inlined at each caller: the drive image's 64 KiB budget.
    #[inline(never)]
    pub fn load_program(&mut self, s: &DriveSection) -> Result<(), VerifyError> {
        self.stop_for_load();
        if let Err(e) = verify_drive(s) {
            self.program = None;
            self.vm.stop_outputs();
            self.trip(FaultCode::Prog);
            return Err(e);
        }
        self.load_checked(s);
        Ok(())
    }

    /// [`Self::load_program`] for a section the link has verified (it does so in a step
    /// of its own: the verifier is too long to run again here).
    // One copy, not inlined at each caller: the drive image's 64 KiB budget.
    #[inline(never)]
    pub fn load_verified(&mut self, v: &VerifiedDriveSection) {
        self.stop_for_load();
        self.load_checked(v.section());
    }

    /// [`Self::load_verified`] in steps, each a call of its own (the whole
    /// load, ~6 900 Cortex-M4 instructions, held the drive's PWM interrupt off for ~1.5
    /// periods at 20 kHz). This first step stops a RUN and moves the section in; then
    /// [`LoadStep::Vm`] (the VM's settings), [`LoadStep::Safety`] (the safety settings and
    /// their signature) and [`LoadStep::Install`] (limits, timing, comparator thresholds)
    /// through [`Self::load_step`]. Between the steps the core is out of RUN with its outputs off
    /// and refuses RUN (`NoProgram`); the caller applies no command in between (the
    /// application holds the link's events back). Returns the next step.
    #[inline(never)]
    pub fn load_begin(&mut self, v: VerifiedDriveSection) -> LoadStep {
        self.stop_for_load();
        self.loading = true;
        self.program = Some(v.into_section());
        LoadStep::Vm
    }

    /// The step `step` of a load begun with [`Self::load_begin`]; the next one, or `None`
    /// when the section is loaded.
    #[inline(never)]
    pub fn load_step(&mut self, step: LoadStep) -> Option<LoadStep> {
        match step {
            LoadStep::Vm => {
                if let Some(s) = self.program.as_ref() {
                    self.vm.load(s);
                }
                Some(LoadStep::Safety)
            }
            LoadStep::Safety => {
                if let Some(s) = self.program.as_ref() {
                    let settings = safety_settings(s.lines.iter());
                    self.safety.load(&settings);
                    self.signature = settings.signature();
                }
                Some(LoadStep::Install)
            }
            LoadStep::Install => {
                self.apply_settings();
                self.update_hw_thresholds();
                self.loading = false;
                None
            }
        }
    }

    fn load_checked(&mut self, s: &DriveSection) {
        self.loading = false;
        self.vm.load(s);
        let settings = safety_settings(s.lines.iter());
        self.safety.load(&settings);
        self.signature = settings.signature();
        self.program = Some(s.clone());
        self.apply_settings();
        self.update_hw_thresholds();
    }

    /// A new section never runs on from the old one's RUN.
    fn stop_for_load(&mut self) {
        if self.state == DriveState::Run {
            self.set_state(DriveState::Idle);
        }
        self.run_requested = false;
        self.outputs_on = false;
    }

    /// Latch a fault detected outside the core (e.g. `FaultCode::Link` from the link
    /// layer). PWM goes off at the next `pwm_period` at the latest.
    // One copy, not inlined at each caller: the drive image's 64 KiB budget.
    #[inline(never)]
    pub fn trip(&mut self, f: FaultCode) {
        self.outputs_on = false;
        if self.state != DriveState::Fault {
            let from = self.state;
            self.safety.stop();
            self.state = DriveState::Fault;
            self.fault = Some(f);
            self.push_event(DriveEvent::State {
                from,
                to: DriveState::Fault,
            });
            self.push_event(DriveEvent::Fault(f));
        }
    }

    /// The TIM1 break input fired (the hardware has already opened all switches). The
    /// cause counts as present until [`DriveCore::hardware_break_released`].
    pub fn hardware_break(&mut self, cause: HwBreak) {
        self.hw_break_active.set(cause, true);
        self.trip(cause.fault());
    }

    /// The hardware break causes latched and not yet released (their comparators still
    /// high at the last control tick).
    pub fn hw_break_active(&self) -> Causes {
        self.hw_break_active
    }

    /// The comparator behind the break input is back below its threshold.
    pub fn hardware_break_released(&mut self, cause: HwBreak) {
        self.hw_break_active.set(cause, false);
    }

    // One copy, not inlined at each caller: the drive image's 64 KiB budget.
    #[inline(never)]
    pub fn command(&mut self, c: DriveCommand) -> Result<(), DriveRefusal> {
        match c {
            DriveCommand::Run => match self.state {
                DriveState::Boot => Err(DriveRefusal::Booting),
                DriveState::Fault => Err(DriveRefusal::Faulted),
                DriveState::Run => Ok(()),
                DriveState::Idle => {
                    if self.program.is_none() || self.loading {
                        return Err(DriveRefusal::NoProgram);
                    }
                    if self.sto_in_low {
                        return Err(DriveRefusal::StoInput);
                    }
                    self.start_run();
                    Ok(())
                }
            },
            DriveCommand::Stop => {
                self.run_requested = false;
                self.outputs_on = false;
                self.vm.stop_outputs();
                if self.state == DriveState::Run {
                    self.set_state(DriveState::Idle);
                }
                Ok(())
            }
            DriveCommand::Ack => {
                let Some(f) = self.fault else {
                    return Ok(());
                };
                self.reset_allowed(f)?;
                self.fault = None;
                self.run_requested = false;
                self.vm.stop_outputs();
                self.restart.clear();
                self.set_state(DriveState::Idle);
                Ok(())
            }
            DriveCommand::SetQ { addr, value } => {
                if self.vm.set_q(addr, value) {
                    Ok(())
                } else {
                    Err(DriveRefusal::BadAddress)
                }
            }
            DriveCommand::Direction { reverse } => {
                self.reversal.request(reverse);
                Ok(())
            }
            DriveCommand::SafetyRequest { requested } => {
                self.safety_requested = requested & FUNCTION_MASK;
                Ok(())
            }
        }
    }

    /// IDLE -> RUN: the section starts from a clean state (stack, PI integrals, outputs),
    /// the sine at angle 0, the reversal without a trend.
    fn start_run(&mut self) {
        self.vm.start_run();
        self.safety.start_run();
        self.reversal.restart(0);
        self.modulator.reset_phase();
        self.run_requested = true;
        self.set_state(DriveState::Run);
    }

    /// Whether the latched fault `f` may be reset now (by an ACK or an automatic
    /// restart): its cause is gone and the frequency command is below `fmn` (or 0), so
    /// that the reset is never the start of a motor at speed.
    fn reset_allowed(&self, f: FaultCode) -> Result<(), DriveRefusal> {
        if !self.cause_gone(f) {
            return Err(DriveRefusal::CauseActive(f));
        }
        let cmd = self.f_command();
        if cmd != 0 && cmd >= self.vm.settings().fmn {
            return Err(DriveRefusal::FrequencyNotBelowFmn);
        }
        Ok(())
    }

    /// The automatic restart (`crate::restart`), every control tick: in FAULT, once the
    /// policy says so, the fault is reset as an ACK would (its conditions, and for `UV`
    /// the DC link back at `U<` + 1 V, and `STO_IN` high), and the drive returns to RUN
    /// if the PLC still commands RUN, else to IDLE.
    fn auto_restart(&mut self) {
        // A fault is latched exactly while the state is FAULT.
        let Some(f) = self.fault else {
            self.restart.out_of_fault();
            return;
        };
        let ready = self.reset_allowed(f).is_ok()
            && !self.sto_in_low
            && (f != FaultCode::Uv || self.limits.back_above_u_min(&self.last));
        let policy = self.vm.settings().restart;
        if self.restart.in_fault(&policy, f, ready) {
            self.fault = None;
            if self.run_requested {
                self.start_run();
            } else {
                self.set_state(DriveState::Idle);
            }
        }
    }

    /// The hardware `STO_IN` input, read by the board every tick (`low` = STO requested;
    /// the break input has already opened the outputs in hardware). While it is low, bit
    /// 0 of the requested mask is set (safety.md 6).
    pub fn set_sto_input(&mut self, low: bool) {
        self.sto_in_low = low;
    }

    /// The `STO_IN` break fired (safety.md 6; the hardware has already opened every
    /// switch): the input was low, however briefly. Code 9 latches at once in RUN, so no
    /// later PWM period sets the outputs again (a pulse shorter than the 1 ms
    /// read was lost), and until the board's next [`DriveCore::set_sto_input`] the input
    /// counts as low (RUN refused).
    pub fn sto_break(&mut self) {
        self.sto_in_low = true;
        if self.state == DriveState::Run {
            self.trip(FaultCode::Sto);
        }
    }

    /// TIM1's system break fired (a PVD dip, an SRAM parity or flash double-ECC
    /// error, routed by SYSCFG_CFGR2; the hardware has already opened every switch): the
    /// MCU itself is not sound, so `BOOT` latches, which only a power cycle clears.
    pub fn system_break(&mut self) {
        self.trip(FaultCode::Boot);
    }

    /// The requested safety functions: the PLC's mask, plus STO while `STO_IN` is low.
    pub fn safety_requested(&self) -> u16 {
        self.safety_requested | u16::from(self.sto_in_low)
    }

    /// The safety monitor (read-only: turns, phases, for hil-sim and tests).
    pub fn safety(&self) -> &Monitor {
        &self.safety
    }

    /// Every millisecond: [`DriveCore::tick_1ms_program`], then
    /// [`DriveCore::tick_1ms_control`]. Events (including those raised by the interrupt and
    /// by commands since the last tick) come out through `events`.
    pub fn tick_1ms(&mut self, events: &mut impl FnMut(DriveEvent)) {
        self.tick_1ms_program();
        self.tick_1ms_control(events);
    }

    /// The first half of the millisecond: the end of the boot, a pending reversal at
    /// standstill and the drive section's pass. A call of its own so that the board can
    /// run it in a critical section of its own (the whole tick at the start of
    /// RUN held the PWM interrupt off for ~1.5 periods at 20 kHz). Between the halves the
    /// PWM interrupt runs on the last millisecond's modulator, as before the tick.
    /// Not inlined into the board's 1 ms task (flash: 64 KiB budget; one call per ms).
    #[inline(never)]
    pub fn tick_1ms_program(&mut self) {
        self.peak.next_ms();
        if self.state == DriveState::Boot {
            self.finish_boot();
        }
        // At standstill a pending direction request applies before the section runs, so
        // the first PWM period of a restart is in the requested direction.
        if let Some(dir) = self.reversal.start_cycle() {
            self.push_event(DriveEvent::Reversed(dir));
        }
        let vm_active = self.run_requested
            && matches!(self.state, DriveState::Run | DriveState::Fault)
            && self.program.is_some();
        if vm_active {
            if let Some(p) = self.program.as_ref() {
                let mut warnings: heapless::Vec<VmWarning, 4> = heapless::Vec::new();
                self.vm.run(p, &mut |w| {
                    let _ = warnings.push(w);
                });
                for w in warnings {
                    self.push_event(DriveEvent::Warning(DriveWarning::Vm(w)));
                }
            }
        } else {
            self.vm.stop_outputs();
        }
    }

    /// The second half of the millisecond (after [`DriveCore::tick_1ms_program`]): the
    /// frequency command, the reversal, the safety monitor, the settings (a timing change)
    /// and the modulator for the next millisecond; the events out through `events`.
    #[inline(never)]
    pub fn tick_1ms_control(&mut self, events: &mut impl FnMut(DriveEvent)) {
        let f = self.f_command();
        if let Some(dir) = self
            .reversal
            .cycle(f, self.vm.settings().frv, self.vm.settings().fmn)
        {
            self.push_event(DriveEvent::Reversed(dir));
        }
        self.f_out = f;
        if self.state == DriveState::Run {
            self.monitor();
        }
        self.safety.follow(self.safety_requested());
        // OV (shared-protocol/docs/fault-codes.md): without a chopper, the DC link above
        // `U>` while the outputs switch; the controller's level lies below it, `U>>` above.
        if self.state == DriveState::Run
            && self.outputs_on
            && !self.cfg.board.brake_chopper
            && self.limits.above_u_max(&self.last)
        {
            self.trip(FaultCode::Ov);
        }
        self.auto_restart();
        self.apply_settings();
        self.update_modulator();
        while let Some(e) = self.events.pop_front() {
            events(e);
        }
        if self.events_lost > 0 {
            events(DriveEvent::EventsLost(self.events_lost));
            self.events_lost = 0;
        }
    }

    /// The PWM interrupt: measurements, software trips and the duties for the next period.
    #[must_use = "the command must reach the power stage"]
    #[inline(always)]
    pub fn pwm_period(&mut self, raw: &AdcSample) -> PwmCommand {
        if self.state == DriveState::Boot {
            self.zero_cal.add(raw, &self.cfg.board.scaling);
        }
        let s = &self.front_end.canonical(raw);
        self.last = *s;
        let abs_i = s.abs_current_counts();
        self.peak.record(abs_i);
        let period_counts = self.timing.arr;
        let off = |brake| PwmCommand {
            enable: false,
            leg_enable: [false; 3],
            duty: [0; 3],
            period_counts,
            brake,
        };
        match self.state {
            DriveState::Boot => return off(false),
            DriveState::Idle | DriveState::Run => {
                if self.limits.overcurrent(abs_i) {
                    self.trip(FaultCode::Oc);
                }
                // The software twin of the overvoltage comparator: the same
                // `U>>`, code 3, whichever sees it first.
                if self.limits.overvoltage(s) {
                    self.trip(FaultCode::OvHw);
                }
            }
            DriveState::Fault => {}
        }
        // Only a board with a chopper switches one (on the ESC1 PB5 is the BEMF dividers'
        // enable).
        self.brake = self.cfg.board.brake_chopper && self.limits.brake(self.brake, s);
        let mut on = self.state == DriveState::Run && self.outputs_on;
        if on && self.limits.undervoltage(s) {
            self.trip(FaultCode::Uv);
            on = false;
        }
        let sine_on = on && self.sine_on;
        if !sine_on && self.was_on {
            self.modulator.reset_phase();
        }
        self.was_on = sine_on;
        if !on {
            return off(self.brake);
        }
        let [d0, d1, d2] = self.modulator.step(period_counts);
        if !sine_on {
            // Direct legs only: the sine waits at angle 0 for f >= fmn.
            self.modulator.reset_phase();
        }
        // Written out, not a loop over the legs (the drive's crate is built for size).
        let [on0, on1, on2] = self.legs_on;
        let leg = |d: u16, leg_on: bool| if leg_on { d } else { 0 };
        PwmCommand {
            enable: true,
            leg_enable: self.legs_on,
            duty: [leg(d0, on0), leg(d1, on1), leg(d2, on2)],
            period_counts,
            brake: self.brake,
        }
    }

    pub fn status(&self) -> CoreStatus {
        let on = self.state == DriveState::Run && self.outputs_on && self.sine_on;
        let m = if on {
            (self.modulator.params().m_q16 * 1000 + 0x8000) >> 16
        } else {
            0
        };
        CoreStatus {
            state: self.state,
            fault: self.fault,
            f_applied: Decihertz(if on { self.f_out } else { 0 }),
            f_command: Decihertz(self.f_command()),
            reverse: self.reversal.applied(),
            reverse_pending: self.reversal.pending(),
            u_dc: udc_decivolts(self.last.u_dc),
            i_peak: abs_counts_to_centiamps(self.peak.peak_counts()),
            com: com_of(self.last.aux),
            modulation_permille: m as u16,
            brake: self.brake,
            pwm_millihertz: self.timing.pwm_millihertz,
            program_loaded: self.program.is_some() && !self.loading,
            hw: self.hw,
            // Only while switching: the switching frequency of an idle drive does not
            // matter (and the PLC's first Q write may still be on its way after RUN).
            warning: self
                .vm
                .active_warning()
                .filter(|_| self.state == DriveState::Run && self.outputs_on),
            sf_requested: self.safety_requested(),
            sf_status: if self.state == DriveState::Run {
                self.safety.status()
            } else {
                status_outside_run(self.state, self.safety_requested())
            },
            sf_sdc: self.state == DriveState::Run && self.safety.sdc(),
            sf_elapsed_ds: self.safety.elapsed_ds(),
            sf_turns: self.safety.turns_since_activation(),
            sf_signature: self.signature,
            sto_in_low: self.sto_in_low,
        }
    }

    fn f_command(&self) -> i16 {
        self.vm.outputs().f
    }

    /// The safety monitor's tick (safety.md 3.1): after the section and the `frv` rule,
    /// before the modulator takes f. A violation (or STO) latches its code and the
    /// outputs go off in this tick; otherwise the modulator takes the capped f. Not
    /// inlined into the tick (flash: the image has a 64 KiB budget).
    #[inline(never)]
    fn monitor(&mut self) {
        let o = *self.vm.outputs();
        let sine = o.legs.contains(&LegMode::Sine);
        let verdict = self.safety.tick(SafetyInput {
            requested: self.safety_requested(),
            // v means nothing for direct legs (the verifier allows only STO then).
            f_dhz: if sine { o.f } else { 0 },
            fmn_dhz: self.vm.settings().fmn,
            reverse: self.reversal.applied(),
        });
        if sine {
            self.f_out = verdict.f_dhz;
        }
        if let Some(code) = verdict.trip {
            self.trip(code);
        }
    }

    // One copy, not inlined at each caller: the drive image's 64 KiB budget.
    #[inline(never)]
    fn set_state(&mut self, to: DriveState) {
        let from = self.state;
        if from != to {
            if from == DriveState::Run {
                // Leaving RUN drops every safety function (safety.md 3.1).
                self.safety.stop();
            }
            self.state = to;
            self.push_event(DriveEvent::State { from, to });
        }
    }

    fn push_event(&mut self, e: DriveEvent) {
        if self.events.push_back(e).is_err() {
            self.events_lost = self.events_lost.saturating_add(1);
        }
    }

    fn cause_gone(&self, f: FaultCode) -> bool {
        match f {
            FaultCode::Oc => !self.limits.overcurrent(self.last.abs_current_counts()),
            FaultCode::OcHw => !self.hw_active(HwBreak::Overcurrent),
            FaultCode::OvHw => {
                !self.hw_active(HwBreak::Overvoltage) && !self.limits.overvoltage(&self.last)
            }
            FaultCode::Uv => !self.limits.undervoltage(&self.last),
            FaultCode::Ov => !self.limits.above_u_max(&self.last),
            // The ACK itself arrived over the link.
            FaultCode::Link => true,
            FaultCode::Prog => self.program.is_some(),
            FaultCode::Wdg => true,
            // A failed self-test needs a power cycle.
            FaultCode::Boot => false,
            // Safety codes 9-16 (safety.md 7): 9 and 10 need their request released.
            FaultCode::Sto
            | FaultCode::Ss1
            | FaultCode::Ramp
            | FaultCode::Sos
            | FaultCode::Sls
            | FaultCode::Sli
            | FaultCode::Sdi
            | FaultCode::Sla => {
                crate::safety::cause_gone(f, self.safety_requested()).unwrap_or(false)
            }
        }
    }

    fn hw_active(&self, c: HwBreak) -> bool {
        self.hw_break_active.get(c)
    }

    fn finish_boot(&mut self) {
        let table_ok = crate::sine::table_ok();
        // The dead-time floor: DTG does not depend on PSC/ARR, so a timing that passes here
        // keeps passing at every later `PWF`/`PRx`.
        let min_dead =
            crate::timing::min_dead_time_counts(self.cfg.timer_clock_hz, self.cfg.min_dead_time_ns);
        let timing_ok = self.timing.arr > 2 * self.cfg.min_pulse_counts + 2
            && self.timing.dead_time_meets(min_dead);
        let offsets_ok = match self.zero_cal.result() {
            Ok(Some(zero)) => {
                self.front_end.calibrate(zero);
                // The comparators' thresholds follow the calibrated zero.
                self.update_hw_thresholds();
                true
            }
            Ok(None) => true,
            Err(crate::measure::ZeroOutOfTolerance) => false,
        };
        if !(table_ok && timing_ok && offsets_ok) || self.trim_failed {
            self.trip(FaultCode::Boot);
        } else if self.reset_cause == ResetCause::Watchdog {
            self.trip(FaultCode::Wdg);
        } else {
            self.set_state(DriveState::Idle);
        }
    }

    /// Protection limits and timer setup from the program's settings.
    fn apply_settings(&mut self) {
        let s = *self.vm.settings();
        self.limits.set_i_max(s.i_max_centiamps);
        self.limits.set_u_min(s.u_min_volts);
        self.limits.set_u_max(s.u_max_volts);
        // Without a chopper the overvoltage controller's level stays CAP_BELOW_OV_HW_VOLTS
        // below both trips, `U>` (OV) and `U>>` (OV_HW) (docs/drive-core.md "Overvoltage").
        let ov_hw = self.hw.ov_hw.0.max(0) as u16;
        let lowest_trip = match s.u_max_volts {
            0 => ov_hw,
            u => u.min(ov_hw),
        };
        let cap = lowest_trip.saturating_sub(CAP_BELOW_OV_HW_VOLTS);
        self.ovc
            .set_cap_volts((!self.cfg.board.brake_chopper).then_some(cap));
        let key = (s.pwf_hz, s.prescaler);
        if key != self.timing_key {
            self.timing_key = key;
            self.timing = Self::timing_for(&self.cfg, key);
            self.timing_changes = self.timing_changes.wrapping_add(1);
        }
    }

    /// Modulator parameters for the next millisecond (divisions happen here, not in the
    /// interrupt).
    fn update_modulator(&mut self) {
        let s = *self.vm.settings();
        let o = *self.vm.outputs();
        // fmn stops only the sine legs (program.md 4.2, as the source): a direct `WR PWx`
        // leg keeps switching, and an unused leg (duty 0) is driven while any other is.
        let run = self.state == DriveState::Run;
        // The monitor's `asr` cap lowers f (never raises it); the overvoltage controller
        // holds it above the command while the DC link is high; A follows, keeping V/f.
        let switching = run && self.sine_on;
        let f = self
            .ovc
            .step(self.f_out.min(o.f), self.last.u_dc, switching);
        let (f_last, a_last) = self.applied_fa;
        let a = if f < o.f && o.f > 0 {
            (i32::from(o.a) * i32::from(f) / i32::from(o.f)) as i16
        } else if f > o.f && f_last > 0 {
            (i32::from(a_last) * i32::from(f) / i32::from(f_last)) as i16
        } else {
            o.a
        };
        self.f_out = f;
        self.applied_fa = (f, a);
        let sine_on = f >= s.fmn;
        let direct = o.legs.iter().any(|l| matches!(l, LegMode::Direct { .. }));
        let sine = o.legs.contains(&LegMode::Sine);
        self.sine_on = sine && sine_on;
        self.outputs_on = run && (direct || self.sine_on);
        let mut legs_on = o
            .legs
            .map(|l| self.outputs_on && (l != LegMode::Sine || sine_on));
        if self.reversal.applied() {
            legs_on.swap(0, 1);
        }
        self.legs_on = legs_on;
        // In 32 bits (hardware divisions): A < 2^15 and dU < 2^16, so both shifted terms
        // and their sum fit (`modulation_index_in_32_bits_is_the_64_bit_formula`).
        let m = modulation_q16(a, s.fjm, s.du);
        // Above the linear range the modulator clips (overmodulation, program.md 4.3).
        let m_q16 = m.min(M_LIMIT_Q16);
        let [p1, p2, p3] = o.phase_decideg;
        self.modulator.set_params(ModulatorParams {
            step: self.timing.phase_step(f),
            m_q16,
            phi: [
                phase_of_decidegrees(p1),
                phase_of_decidegrees(p2),
                phase_of_decidegrees(p3),
            ],
            legs: o.legs,
            swap_1_2: self.reversal.applied(),
        });
    }
}

/// Requested modulation index m = A / fjm + dU / 1023, Q16 (`fjm` below 1 counts as 1, a
/// negative A as 0). A <= 32767 and dU <= 65535, so `A << 16` and `dU << 16` fit in 32
/// bits and their quotients' sum stays below 2^31 + 2^22.
fn modulation_q16(a: i16, fjm: i16, du: u16) -> u32 {
    let fjm = u32::from(fjm.max(1) as u16);
    (u32::from(a.max(0) as u16) << 16) / fjm + (u32::from(du) << 16) / 1023
}

#[cfg(test)]
mod tests {
    use super::*;
    use shared_protocol::program::assemble;

    fn section(text: &str) -> DriveSection {
        assemble(text).expect("assembles").drive_section()
    }

    /// 50 Hz three-phase sine, fmn 5 Hz, limits 35 V / 25 V / 2 A.
    const SINE: &str = "
000 PWF K00 9800
001 LD  Q01
002 LD  Q01
003 LD  K01 0000
004 SN1
005 LD  K02 1200
006 SN2
007 LD  K03 2400
008 SN3
009 fmn K04 0050
010 U>  K05 0035
011 U<  K06 0025
012 I>  K07 0200
";

    fn ok_sample() -> AdcSample {
        AdcSample {
            u_dc: 2730, // 30 V
            ..AdcSample::default()
        }
    }

    fn events(core: &mut DriveCore) -> Vec<DriveEvent> {
        let mut v = Vec::new();
        core.tick_1ms(&mut |e| v.push(e));
        v
    }

    fn running(f: i16) -> DriveCore {
        let mut core = DriveCore::new(DriveConfig::default(), ResetCause::PowerOn);
        let _ = core.pwm_period(&ok_sample());
        events(&mut core);
        core.load_program(&section(SINE)).expect("valid");
        core.command(DriveCommand::SetQ { addr: 1, value: f })
            .unwrap();
        core.command(DriveCommand::Run).unwrap();
        events(&mut core);
        core
    }

    #[test]
    fn boots_to_idle_and_reports_the_transition() {
        let mut core = DriveCore::new(DriveConfig::default(), ResetCause::PowerOn);
        assert_eq!(core.state(), DriveState::Boot);
        assert_eq!(core.command(DriveCommand::Run), Err(DriveRefusal::Booting));
        assert!(!core.pwm_period(&ok_sample()).enable);
        let ev = events(&mut core);
        assert_eq!(
            ev,
            vec![DriveEvent::State {
                from: DriveState::Boot,
                to: DriveState::Idle
            }]
        );
        assert_eq!(
            core.command(DriveCommand::Run),
            Err(DriveRefusal::NoProgram)
        );
    }

    #[test]
    fn watchdog_reset_is_reported_as_wdg_and_acknowledgeable() {
        let mut core = DriveCore::new(DriveConfig::default(), ResetCause::Watchdog);
        let ev = events(&mut core);
        assert!(ev.contains(&DriveEvent::Fault(FaultCode::Wdg)));
        assert_eq!(core.fault(), Some(FaultCode::Wdg));
        core.command(DriveCommand::Ack).unwrap();
        assert_eq!(core.state(), DriveState::Idle);
    }

    #[test]
    fn current_sensor_offset_fails_the_self_test() {
        let mut core = DriveCore::new(DriveConfig::default(), ResetCause::PowerOn);
        let _ = core.pwm_period(&AdcSample {
            i_a: 2048 + 400,
            ..ok_sample()
        });
        events(&mut core);
        assert_eq!(core.fault(), Some(FaultCode::Boot));
        assert!(core.command(DriveCommand::Ack).is_err());
    }

    #[test]
    fn outputs_follow_fmn() {
        let mut core = running(40); // 4 Hz < fmn 5 Hz
        assert!(!core.pwm_period(&ok_sample()).enable);
        assert_eq!(core.status().f_applied, Decihertz(0));
        assert_eq!(core.status().f_command, Decihertz(40));
        core.command(DriveCommand::SetQ { addr: 1, value: 50 })
            .unwrap();
        events(&mut core);
        let c = core.pwm_period(&ok_sample());
        assert!(c.enable);
        assert_eq!(c.period_counts, core.pwm_timing().arr);
        assert_eq!(core.status().f_applied, Decihertz(50));
        // A = f = 5 Hz at fjm 50 Hz: m = 0.1.
        assert_eq!(core.status().modulation_permille, 100);
    }

    #[test]
    fn fmn_stops_only_the_sine_legs() {
        // Phase 1 sine from Q01, phase 2 direct at 50 %, phase 3 unused (duty 0).
        let text = "000 LD Q01\n001 LD Q01\n002 LD K00 0000\n003 SN1\n\
                    004 LD K01 0500\n005 WR PW3\n006 fmn K02 0050\n";
        let mut core = DriveCore::new(DriveConfig::default(), ResetCause::PowerOn);
        let _ = core.pwm_period(&ok_sample());
        events(&mut core);
        core.load_program(&section(text)).unwrap();
        core.command(DriveCommand::SetQ { addr: 1, value: 10 })
            .unwrap();
        core.command(DriveCommand::Run).unwrap();
        events(&mut core);
        // 1 Hz < fmn: the sine leg is off, the direct leg (and the unused one, at duty 0)
        // switch, as the source's direct PDC writes did.
        let c = core.pwm_period(&ok_sample());
        let n = c.period_counts;
        assert!(c.enable);
        assert_eq!(c.leg_enable, [false, true, true]);
        assert_eq!(c.duty, [0, n / 2 + n % 2, 0]);
        assert_eq!(core.status().f_applied, Decihertz(0));
        // At fmn the sine leg starts, at angle 0.
        core.command(DriveCommand::SetQ { addr: 1, value: 50 })
            .unwrap();
        events(&mut core);
        let c = core.pwm_period(&ok_sample());
        assert_eq!(c.leg_enable, [true; 3]);
        assert_eq!(c.duty[0], n / 2 + n % 2);
        assert_eq!(core.status().f_applied, Decihertz(50));
        // Reversed (from standstill), the enables follow their legs.
        core.command(DriveCommand::SetQ { addr: 1, value: 0 })
            .unwrap();
        events(&mut core);
        core.command(DriveCommand::Direction { reverse: true })
            .unwrap();
        core.command(DriveCommand::SetQ { addr: 1, value: 10 })
            .unwrap();
        events(&mut core);
        assert!(core.status().reverse);
        assert_eq!(
            core.pwm_period(&ok_sample()).leg_enable,
            [true, false, true]
        );
        // A program with sine legs only is all off below fmn (MOE cleared).
        let mut core = running(40);
        let c = core.pwm_period(&ok_sample());
        assert!(!c.enable && c.leg_enable == [false; 3]);
    }

    #[test]
    fn overcurrent_trips_in_the_same_period_and_needs_ack_and_run() {
        let mut core = running(500);
        assert!(core.pwm_period(&ok_sample()).enable);
        let over = AdcSample {
            i_b: 2048 - 420, // -2.05 A
            ..ok_sample()
        };
        let c = core.pwm_period(&over);
        assert!(!c.enable);
        assert_eq!(c.duty, [0; 3]);
        assert_eq!(core.fault(), Some(FaultCode::Oc));
        let ev = events(&mut core);
        assert!(ev.contains(&DriveEvent::Fault(FaultCode::Oc)));
        // Cause still present.
        assert_eq!(
            core.command(DriveCommand::Ack),
            Err(DriveRefusal::CauseActive(FaultCode::Oc))
        );
        let _ = core.pwm_period(&ok_sample());
        // The PLC still commands 50 Hz: refused.
        assert_eq!(
            core.command(DriveCommand::Ack),
            Err(DriveRefusal::FrequencyNotBelowFmn)
        );
        assert_eq!(core.command(DriveCommand::Run), Err(DriveRefusal::Faulted));
        core.command(DriveCommand::SetQ { addr: 1, value: 0 })
            .unwrap();
        events(&mut core);
        for _ in 0..100 {
            assert!(!core.pwm_period(&ok_sample()).enable);
        }
        core.command(DriveCommand::Ack).unwrap();
        assert_eq!(core.state(), DriveState::Idle);
        events(&mut core);
        // No automatic restart.
        core.command(DriveCommand::SetQ {
            addr: 1,
            value: 500,
        })
        .unwrap();
        for _ in 0..10 {
            events(&mut core);
            assert!(!core.pwm_period(&ok_sample()).enable);
        }
        core.command(DriveCommand::Run).unwrap();
        events(&mut core);
        assert!(core.pwm_period(&ok_sample()).enable);
    }

    #[test]
    fn undervoltage_only_while_the_pwm_is_on() {
        let low = AdcSample {
            u_dc: 2000, // 22 V
            ..AdcSample::default()
        };
        let mut core = running(10); // below fmn: outputs off
        assert!(!core.pwm_period(&low).enable);
        assert_eq!(core.fault(), None);
        core.command(DriveCommand::SetQ {
            addr: 1,
            value: 300,
        })
        .unwrap();
        events(&mut core);
        assert!(!core.pwm_period(&low).enable);
        assert_eq!(core.fault(), Some(FaultCode::Uv));
    }

    #[test]
    fn hardware_break_latches_until_released() {
        let mut core = running(500);
        core.hardware_break(HwBreak::Overvoltage);
        assert!(!core.pwm_period(&ok_sample()).enable);
        assert_eq!(core.fault(), Some(FaultCode::OvHw));
        core.command(DriveCommand::Stop).unwrap();
        assert_eq!(
            core.command(DriveCommand::Ack),
            Err(DriveRefusal::CauseActive(FaultCode::OvHw))
        );
        core.hardware_break_released(HwBreak::Overvoltage);
        core.command(DriveCommand::Ack).unwrap();
        assert_eq!(core.state(), DriveState::Idle);
    }

    #[test]
    fn first_fault_stays_latched() {
        let mut core = running(500);
        core.trip(FaultCode::Link);
        core.hardware_break(HwBreak::Overcurrent);
        assert_eq!(core.fault(), Some(FaultCode::Link));
        let ev = events(&mut core);
        let faults: Vec<_> = ev
            .iter()
            .filter(|e| matches!(e, DriveEvent::Fault(_)))
            .collect();
        assert_eq!(faults, vec![&DriveEvent::Fault(FaultCode::Link)]);
    }

    #[test]
    fn rejected_download_latches_prog_until_a_good_one() {
        let mut core = running(500);
        let mut bad = section(SINE);
        bad.lines[20] = Some(shared_protocol::program::Instruction {
            mnemonic: shared_protocol::program::Mnemonic::Pwf,
            operand: Some(shared_protocol::program::Operand::K(0)),
            constant: 100,
        });
        let e = core.load_program(&bad).unwrap_err();
        assert_eq!(e.line, 20);
        assert_eq!(core.fault(), Some(FaultCode::Prog));
        assert!(!core.pwm_period(&ok_sample()).enable);
        assert_eq!(
            core.command(DriveCommand::Ack),
            Err(DriveRefusal::CauseActive(FaultCode::Prog))
        );
        core.load_program(&section(SINE)).unwrap();
        core.command(DriveCommand::Ack).unwrap();
        core.command(DriveCommand::Run).unwrap();
    }

    #[test]
    fn stop_coasts_at_once() {
        let mut core = running(500);
        assert!(core.pwm_period(&ok_sample()).enable);
        core.command(DriveCommand::Stop).unwrap();
        assert!(!core.pwm_period(&ok_sample()).enable);
        assert_eq!(core.state(), DriveState::Idle);
    }

    #[test]
    fn brake_chopper_works_in_idle_and_fault() {
        let mut core = DriveCore::new(DriveConfig::default(), ResetCause::PowerOn);
        events(&mut core);
        core.load_program(&section(SINE)).unwrap();
        let high = AdcSample {
            u_dc: 3200, // 35.2 V
            ..AdcSample::default()
        };
        let c = core.pwm_period(&high);
        assert!(c.brake && !c.enable);
        core.trip(FaultCode::Link);
        assert!(core.pwm_period(&high).brake);
        assert!(!core.pwm_period(&ok_sample()).brake);
    }

    /// A sample of the bare ESC1's front end: 0 A (the bias, 1755 counts) and the DC
    /// link at `raw_udc` counts (34.3 V full scale).
    fn esc1_at(raw_udc: u16) -> AdcSample {
        AdcSample {
            i_a: 1755,
            i_b: 1755,
            u_dc: raw_udc,
            aux: 0,
        }
    }

    fn esc1() -> DriveConfig {
        DriveConfig {
            board: &crate::comparators::B_G431B_ESC1,
            ..DriveConfig::default()
        }
    }

    /// The ESC1 (no chopper) never switches one; `U>>` is 32 V by default and
    /// inside the 34.3 V range when the program sets more, and its software twin trips
    /// code 3 from the ADC reading.
    #[test]
    fn the_esc1_has_no_chopper_and_a_software_overvoltage_trip() {
        let mut core = DriveCore::new(esc1(), ResetCause::PowerOn);
        assert_eq!(core.hw_thresholds().ov_hw, Volts(32));
        events(&mut core);
        core.load_program(&section(SINE)).unwrap();
        // 27.0 V: U> (35 V) is no chopper here, nothing trips.
        let c = core.pwm_period(&esc1_at(3223));
        assert!(!c.brake && core.fault().is_none());
        // 32.5 V: above U>> 32 V.
        let c = core.pwm_period(&esc1_at(3880));
        assert!(!c.brake && !c.enable);
        assert_eq!(core.fault(), Some(FaultCode::OvHw));
        assert!(!core.cause_gone(FaultCode::OvHw));
        let _ = core.pwm_period(&esc1_at(3223));
        assert!(core.cause_gone(FaultCode::OvHw));
        // A program's U>> 40 V is clamped to the measuring range.
        let mut core = DriveCore::new(esc1(), ResetCause::PowerOn);
        events(&mut core);
        core.load_program(&section(&format!("{SINE}013 U>> K08 0040\n")))
            .unwrap();
        assert_eq!(core.hw_thresholds().ov_hw, Volts(34));
    }

    /// `OV` (code 17, shared-protocol/docs/fault-codes.md): on the ESC1 the DC link above
    /// `U>` while the outputs switch trips, once, and the ACK waits for the link to come
    /// back; in IDLE, or with a chopper, it is no trip.
    #[test]
    fn the_esc1_trips_ov_above_u_max_while_switching() {
        let mut core = DriveCore::new(esc1(), ResetCause::PowerOn);
        events(&mut core);
        let program = SINE
            .replace("U>  K05 0035", "U>  K05 0022")
            .replace("U<  K06 0025", "U<  K06 0015");
        core.load_program(&section(&program)).unwrap();
        let (supply, high) = (2388, 2687); // 20.0 V, 22.5 V
                                           // IDLE: the outputs are off, a high link is no trip.
        let _ = core.pwm_period(&esc1_at(high));
        events(&mut core);
        assert_eq!(core.fault(), None);
        core.command(DriveCommand::SetQ {
            addr: 1,
            value: 500,
        })
        .unwrap();
        core.command(DriveCommand::Run).unwrap();
        let _ = core.pwm_period(&esc1_at(supply));
        events(&mut core);
        let c = core.pwm_period(&esc1_at(supply));
        assert!(c.enable && core.fault().is_none());
        // 22.5 V > U> 22 V (below U>> 32 V): OV at the next millisecond, outputs off.
        let _ = core.pwm_period(&esc1_at(high));
        let ev = events(&mut core);
        assert_eq!(core.fault(), Some(FaultCode::Ov));
        let faults = ev
            .iter()
            .filter(|e| matches!(e, DriveEvent::Fault(_)))
            .collect::<Vec<_>>();
        assert_eq!(faults, vec![&DriveEvent::Fault(FaultCode::Ov)]);
        assert!(!core.pwm_period(&esc1_at(high)).enable);
        assert!(events(&mut core)
            .iter()
            .all(|e| !matches!(e, DriveEvent::Fault(_))));
        core.command(DriveCommand::SetQ { addr: 1, value: 0 })
            .unwrap();
        events(&mut core);
        assert_eq!(
            core.command(DriveCommand::Ack),
            Err(DriveRefusal::CauseActive(FaultCode::Ov))
        );
        let _ = core.pwm_period(&esc1_at(supply));
        core.command(DriveCommand::Ack).unwrap();
        // With a chopper (the source's sensors) U> is the chopper's level, no trip.
        let mut core = running(500);
        let _ = core.pwm_period(&AdcSample {
            u_dc: 3276, // 36 V > U> 35 V, below U>> 40 V
            ..AdcSample::default()
        });
        events(&mut core);
        assert_ne!(core.fault(), Some(FaultCode::Ov));
    }

    #[test]
    fn the_comparator_trim_moves_the_thresholds_and_a_failed_one_is_boot() {
        use crate::comparators::DacChannel;
        let mut core = DriveCore::new(esc1(), ResetCause::PowerOn);
        assert_eq!(core.comparator_dacs().get(DacChannel::Dac3Ch1), Some(1748));
        core.set_comparator_trim(Ok(TrimmedZeros([Some(1760), Some(1750), None, Some(1770)])));
        let d = core.comparator_dacs();
        assert_eq!(d.get(DacChannel::Dac3Ch1), Some(1753));
        assert_eq!(d.get(DacChannel::Dac1Ch2), Some(1743));
        assert_eq!(d.get(DacChannel::Dac3Ch2), Some(1763));
        events(&mut core);
        assert_eq!(core.state(), DriveState::Idle);
        let mut core = DriveCore::new(esc1(), ResetCause::PowerOn);
        core.set_comparator_trim(Err(TrimFailed {
            comp: 2,
            code: 4095,
        }));
        events(&mut core);
        assert_eq!(core.fault(), Some(FaultCode::Boot));
    }

    /// On the ESC1 the overvoltage controller takes the applied frequency over
    /// while the DC link is above its level (the supply's 20 V + 2 V), keeping V/f.
    #[test]
    fn the_esc1_holds_a_deceleration_while_the_dc_link_is_high() {
        let mut core = DriveCore::new(esc1(), ResetCause::PowerOn);
        events(&mut core);
        // U< 15 V for the 20 V supply.
        let program = SINE.replace("U<  K06 0025", "U<  K06 0015");
        core.load_program(&section(&program)).unwrap();
        core.command(DriveCommand::SetQ {
            addr: 1,
            value: 500,
        })
        .unwrap();
        core.command(DriveCommand::Run).unwrap();
        let supply = 2388; // 20.0 V
        for _ in 0..3 {
            let _ = core.pwm_period(&esc1_at(supply));
            events(&mut core);
        }
        assert_eq!(core.status().f_applied, Decihertz(500));
        // The command falls to 30 Hz while the link is at 23 V (level 21 V): the controller
        // takes over and raises the frequency.
        core.command(DriveCommand::SetQ {
            addr: 1,
            value: 300,
        })
        .unwrap();
        let _ = core.pwm_period(&esc1_at(2746));
        events(&mut core);
        assert!(core.ov_controller().holding());
        let held = core.status().f_applied;
        assert!(held.0 > 500, "{held:?}");
        assert_eq!(core.status().f_command, Decihertz(300));
        // Back at the supply (1 V below the level): it falls towards the command.
        let _ = core.pwm_period(&esc1_at(supply));
        events(&mut core);
        let f = core.status().f_applied.0;
        assert!(f < held.0 && f > 300, "{f}");
        // On the source's sensors (a chopper) there is no such hold.
        let mut core = running(500);
        core.command(DriveCommand::SetQ {
            addr: 1,
            value: 300,
        })
        .unwrap();
        let _ = core.pwm_period(&AdcSample {
            u_dc: 3100, // 34 V
            ..AdcSample::default()
        });
        events(&mut core);
        assert_eq!(core.status().f_applied, Decihertz(300));
    }

    #[test]
    fn pwf_change_reprograms_the_timer_and_keeps_the_frequency() {
        let mut core = running(500);
        let t1 = core.pwm_timing();
        assert_eq!(t1.arr, 8673); // 170 MHz / (2 * 9800)
        let step1 = core.modulator.params().step;
        let f1 = step1 as f64 / 2f64.powi(64) * f64::from(t1.pwm_millihertz) / 1000.0;
        assert!((f1 - 50.0).abs() < 1e-3, "{f1}");
        let p = section(&SINE.replace("PWF K00 9800", "PWF K00 9800\n013 PR0"));
        core.load_program(&p).unwrap();
        assert_eq!(core.pwm_timing().arr, 34694); // 2450 Hz
    }

    #[test]
    fn without_fmn_ack_needs_standstill() {
        let mut core = running(500);
        let p = section(&SINE.replace("009 fmn K04 0050\n", ""));
        core.load_program(&p).unwrap();
        // A download clears the drive's Q copy.
        assert_eq!(core.vm().q(1), 0);
        core.command(DriveCommand::SetQ {
            addr: 1,
            value: 500,
        })
        .unwrap();
        core.command(DriveCommand::Run).unwrap();
        events(&mut core);
        core.trip(FaultCode::Link);
        events(&mut core);
        assert_eq!(
            core.command(DriveCommand::Ack),
            Err(DriveRefusal::FrequencyNotBelowFmn)
        );
        core.command(DriveCommand::SetQ { addr: 1, value: 0 })
            .unwrap();
        events(&mut core);
        core.command(DriveCommand::Ack).unwrap();
    }

    #[test]
    fn a_full_event_queue_reports_the_loss() {
        let mut core = running(500);
        for _ in 0..(EVENT_QUEUE + 5) {
            core.command(DriveCommand::Stop).unwrap();
            core.command(DriveCommand::Run).unwrap();
        }
        let ev = events(&mut core);
        assert_eq!(ev.len(), EVENT_QUEUE + 1);
        assert!(matches!(ev.last(), Some(DriveEvent::EventsLost(n)) if *n > 0));
    }

    #[test]
    fn hardware_thresholds_are_settings_written_to_the_dacs_at_download() {
        use crate::comparators::DacChannel;
        let mut core = DriveCore::new(DriveConfig::default(), ResetCause::PowerOn);
        events(&mut core);
        // No program: the board's defaults (3.00 A, 40 V).
        let th = core.hw_thresholds();
        assert_eq!((th.oc_hw, th.ov_hw), (CentiAmps(300), Volts(40)));
        assert_eq!(core.comparator_dacs().get(DacChannel::Dac3Ch1), Some(2662));
        // I>> 1.50 A and U>> 38 V take effect at download, before any RUN.
        let p = section(&(SINE.to_string() + "020 I>> K08 0150\n021 U>> K09 0038\n"));
        core.load_program(&p).unwrap();
        let th = core.hw_thresholds();
        assert_eq!((th.oc_hw, th.ov_hw), (CentiAmps(150), Volts(38)));
        let dacs = core.comparator_dacs();
        assert_eq!(dacs.get(DacChannel::Dac3Ch1), Some(2048 + 307));
        assert_eq!(dacs.get(DacChannel::Dac3Ch2), Some(2048 + 307));
        assert_eq!(dacs.get(DacChannel::Dac1Ch1), Some(91 * 38));
        assert_eq!(core.status().hw, th);
        // A program without them: back to the defaults.
        core.load_program(&section(SINE)).unwrap();
        assert_eq!(core.hw_thresholds().oc_hw, CentiAmps(300));
    }

    #[test]
    fn a_clamped_pwf_is_an_active_warning_while_it_lasts() {
        let text = "000 PWF Q00\n".to_string() + &SINE.replace("000 PWF K00 9800\n", "");
        let mut core = DriveCore::new(DriveConfig::default(), ResetCause::PowerOn);
        events(&mut core);
        core.load_program(&section(&text)).unwrap();
        core.command(DriveCommand::Run).unwrap();
        let ev = events(&mut core);
        let w = VmWarning::PwfClamped {
            line: 0,
            requested: 0,
            applied: 488,
        };
        assert!(ev.contains(&DriveEvent::Warning(DriveWarning::Vm(w))));
        // Reported in the status only while the outputs switch (f >= fmn).
        assert_eq!(core.status().warning, None);
        core.command(DriveCommand::SetQ {
            addr: 1,
            value: 500,
        })
        .unwrap();
        events(&mut core);
        assert_eq!(core.status().warning, Some(w));
        // Still clamped: still active, reported once as an event.
        let ev = events(&mut core);
        assert!(!ev.iter().any(|e| matches!(e, DriveEvent::Warning(_))));
        assert_eq!(core.status().warning, Some(w));
        core.command(DriveCommand::SetQ {
            addr: 0,
            value: 9800,
        })
        .unwrap();
        events(&mut core);
        assert_eq!(core.status().warning, None);
        assert_eq!(core.vm().settings().pwf_hz, 9800);
    }

    #[test]
    fn status_scales_measurements() {
        let mut core = running(500);
        let _ = core.pwm_period(&AdcSample {
            i_a: 2048 + 205,
            i_b: 2048 - 100,
            u_dc: 2730,
            aux: 4095,
        });
        let s = core.status();
        assert_eq!(s.u_dc, Decivolts(300));
        assert_eq!(s.i_peak, CentiAmps(100));
        assert_eq!(s.com, 1023);
        assert!(s.ready());
    }

    /// The 32-bit modulation index is the 64-bit formula it replaced, over every A and dU
    /// and a spread of fjm (every fjm for a few A).
    #[test]
    fn modulation_index_in_32_bits_is_the_64_bit_formula() {
        let old = |a: i16, fjm: i16, du: u16| {
            let fjm = u64::from(fjm.max(1) as u16);
            (u64::from(a.max(0) as u16) << 16) / fjm + (u64::from(du) << 16) / 1023
        };
        let fjms = [
            i16::MIN,
            -1,
            0,
            1,
            2,
            3,
            7,
            50,
            499,
            500,
            501,
            1023,
            9999,
            i16::MAX,
        ];
        for a in i16::MIN..=i16::MAX {
            for fjm in fjms {
                let du = (a as u16).wrapping_mul(7);
                assert_eq!(u64::from(modulation_q16(a, fjm, du)), old(a, fjm, du));
            }
        }
        for fjm in i16::MIN..=i16::MAX {
            for a in [0, 1, 500, i16::MAX] {
                for du in [0, 1023, u16::MAX] {
                    assert_eq!(u64::from(modulation_q16(a, fjm, du)), old(a, fjm, du));
                }
            }
        }
    }

    /// `SINE` with the automatic restart of the classes `arc` (0.5 s, two in a row).
    fn restarting(arc: u16) -> DriveCore {
        let text = format!("{SINE}013 arc K08 {arc:04}\n014 art K09 0005\n015 arn K10 0002\n");
        let mut core = DriveCore::new(DriveConfig::default(), ResetCause::PowerOn);
        let _ = core.pwm_period(&ok_sample());
        events(&mut core);
        core.load_program(&section(&text)).unwrap();
        set_f(&mut core, 500);
        core.command(DriveCommand::Run).unwrap();
        events(&mut core);
        core
    }

    fn set_f(core: &mut DriveCore, value: i16) {
        core.command(DriveCommand::SetQ { addr: 1, value }).unwrap();
    }

    fn at_udc(u_dc: u16) -> AdcSample {
        AdcSample {
            u_dc,
            ..AdcSample::default()
        }
    }

    /// Milliseconds with `s` until the core leaves FAULT (None: not within `max_ms`).
    fn ms_out_of_fault(core: &mut DriveCore, s: &AdcSample, max_ms: u32) -> Option<u32> {
        (1..=max_ms).find(|_| {
            let _ = core.pwm_period(s);
            events(core);
            core.state() != DriveState::Fault
        })
    }

    /// A UV trip (24 V < `U<` 25 V while switching).
    fn trip_uv(core: &mut DriveCore) {
        set_f(core, 500);
        events(core);
        assert!(core.pwm_period(&ok_sample()).enable);
        assert!(!core.pwm_period(&at_udc(2184)).enable);
        assert_eq!(core.fault(), Some(FaultCode::Uv));
    }

    /// `arc` 1: after UV the drive restarts once the DC link has been back at `U<` + 1 V
    /// for `art`, with the frequency command below fmn, and returns to RUN with its
    /// outputs off; the motor turns again only when the section commands it.
    #[test]
    fn uv_restarts_after_the_delay_and_the_run_command_decides() {
        let mut core = restarting(1);
        trip_uv(&mut core);
        // The section still commands 50 Hz: no restart (as no ACK).
        assert_eq!(ms_out_of_fault(&mut core, &ok_sample(), 2000), None);
        set_f(&mut core, 0);
        // 25.5 V: above U< but below U< + 1 V.
        assert_eq!(ms_out_of_fault(&mut core, &at_udc(2321), 2000), None);
        // 26.0 V: out of FAULT after exactly 500 ms, in RUN (the PLC never left it).
        let mut seen = Vec::new();
        let ms = (1..=2000).find(|_| {
            let _ = core.pwm_period(&at_udc(2366));
            seen.extend(events(&mut core));
            core.state() != DriveState::Fault
        });
        assert_eq!(ms, Some(500));
        assert_eq!((core.state(), core.fault()), (DriveState::Run, None));
        assert!(seen.contains(&DriveEvent::State {
            from: DriveState::Fault,
            to: DriveState::Run
        }));
        assert!(!core.pwm_period(&ok_sample()).enable);
        set_f(&mut core, 500);
        events(&mut core);
        assert!(core.pwm_period(&ok_sample()).enable);
    }

    /// A break in the supply's return starts the delay again.
    #[test]
    fn the_delay_counts_from_the_last_low_sample() {
        let mut core = restarting(1);
        trip_uv(&mut core);
        set_f(&mut core, 0);
        assert_eq!(ms_out_of_fault(&mut core, &ok_sample(), 400), None);
        assert_eq!(ms_out_of_fault(&mut core, &at_udc(2184), 1), None);
        assert_eq!(ms_out_of_fault(&mut core, &ok_sample(), 2000), Some(500));
    }

    /// Without `arc`, or with other classes only, UV stays latched (drive.md's rule).
    #[test]
    fn without_its_class_in_arc_uv_stays_latched() {
        for arc in [0, 2, 4, 6] {
            let mut core = restarting(arc);
            trip_uv(&mut core);
            set_f(&mut core, 0);
            assert_eq!(
                ms_out_of_fault(&mut core, &ok_sample(), 3000),
                None,
                "{arc}"
            );
        }
        let mut core = running(500);
        trip_uv(&mut core);
        set_f(&mut core, 0);
        assert_eq!(ms_out_of_fault(&mut core, &ok_sample(), 3000), None);
    }

    /// `arn` 2: the third UV of a row stays latched until a manual ACK, which starts a
    /// new row.
    #[test]
    fn the_count_limit_latches_until_an_ack() {
        let mut core = restarting(1);
        for _ in 0..2 {
            trip_uv(&mut core);
            set_f(&mut core, 0);
            assert_eq!(ms_out_of_fault(&mut core, &ok_sample(), 2000), Some(500));
        }
        trip_uv(&mut core);
        set_f(&mut core, 0);
        assert_eq!(ms_out_of_fault(&mut core, &ok_sample(), 5000), None);
        core.command(DriveCommand::Ack).unwrap();
        assert_eq!(core.state(), DriveState::Idle);
        core.command(DriveCommand::Run).unwrap();
        trip_uv(&mut core);
        set_f(&mut core, 0);
        assert_eq!(ms_out_of_fault(&mut core, &ok_sample(), 2000), Some(500));
    }

    /// A PLC that left RUN (STOP) during the fault gets an IDLE drive; a low `STO_IN`
    /// holds the restart.
    #[test]
    fn a_restart_without_the_run_command_ends_in_idle_and_sto_in_holds_it() {
        let mut core = restarting(1);
        trip_uv(&mut core);
        core.command(DriveCommand::Stop).unwrap();
        assert_eq!(ms_out_of_fault(&mut core, &ok_sample(), 2000), Some(500));
        assert_eq!(core.state(), DriveState::Idle);
        let mut core = restarting(1);
        trip_uv(&mut core);
        set_f(&mut core, 0);
        core.set_sto_input(true);
        assert_eq!(ms_out_of_fault(&mut core, &ok_sample(), 2000), None);
        core.set_sto_input(false);
        assert_eq!(ms_out_of_fault(&mut core, &ok_sample(), 2000), Some(500));
    }

    /// The latched classes never restart, whatever `arc` says and whether or not an ACK
    /// would be accepted.
    #[test]
    fn latched_classes_never_restart() {
        for code in [
            FaultCode::OcHw,
            FaultCode::OvHw,
            FaultCode::Link,
            FaultCode::Sto,
            FaultCode::Ramp,
        ] {
            let mut core = restarting(7);
            set_f(&mut core, 0);
            core.trip(code);
            assert_eq!(
                ms_out_of_fault(&mut core, &ok_sample(), 2000),
                None,
                "{code:?}"
            );
            core.command(DriveCommand::Ack).unwrap();
        }
    }
}
