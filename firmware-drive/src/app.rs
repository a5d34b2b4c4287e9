//! [`DriveApp`]: the drive MCU's application, the link endpoint joined to the drive core.
//! The board layer (and hil-sim) calls it; it owns no hardware and no clock.
//!
//! | when | call |
//! | --- | --- |
//! | UART bytes received (DMA/idle-line interrupt) | [`DriveApp::on_rx`] |
//! | UART transmitter free, and at least every 1 ms | [`DriveApp::poll_tx`] |
//! | every 1 ms | [`DriveApp::tick_1ms`] (or each of [`TickStep::ALL`] with [`DriveApp::tick_step`]) |
//! | every PWM period (TIM1 update) | [`DriveApp::pwm_interrupt`] ([`DriveApp::pwm_period`], then [`PeriodAction::apply`]) |
//! | TIM1 break interrupt | [`DriveApp::break_interrupt`] ([`DriveApp::break_fired`], [`DriveApp::sto_break`], [`DriveApp::system_break`]) |
//! | every 1 ms | [`DriveApp::control_tick`] ([`DriveApp::set_sto_input`], [`DriveApp::break_poll`], [`TickStep::ALL`], the DACs) |
//!
//! The interrupt and task bodies are core functions over ports (`crate::bodies`): the
//! board implements the ports with registers, hil-sim with its plant, so both run the
//! same sequence and the same decisions.
//!
//! What it adds to the two parts:
//! * Commands from the PLC are applied to the core as soon as their frame is received
//!   (`on_rx`), not at the next tick: that is what the link's latency budget counts.
//! * Link lost: the core trips `LINK` when in RUN, and is told STOP either way (the PLC
//!   is gone as far as the drive knows): PWM off, the drive section stops, so that the
//!   frequency command falls and a later ACK is possible. Nothing restarts by itself:
//!   after the reconnection the PLC must ACK and send RUN again.
//! * A download is checked by the link (CRC, decode, `verify_drive`, one step per
//!   `poll_tx` so that no call holds the PWM interrupt off for long) and then
//!   handed, as a `VerifiedDriveSection`, to the core in four `poll_tx` calls of their
//!   own ([`DriveCore::load_begin`], then [`DriveCore::load_step`] three times: the whole load is
//!   ~6 900 instructions, more than a PWM period at 20 kHz in one critical section, review
//!   N8). The link's events wait in its queue while the load runs, so every command from
//!   the PLC finds the new section loaded. A reject trips `PROG`.
//! * The 1 ms tick is four steps ([`TickStep`]), each one call on the board (one critical
//!   section): link supervision, the drive section's pass, the rest of the core's
//!   millisecond, the reports.
//! * Every fault the core latches is reported to the PLC (reliably, with the drive's
//!   millisecond clock); the status frame is refreshed from the core every tick.

use shared_protocol::link::drive::{DriveEvent as LinkEvent, DriveLink, DriveLinkState};
use shared_protocol::link::session::AT_ONCE;
use shared_protocol::link::{
    AckRefusal, DriveStatus as WireStatus, DriveWarning as WireWarning, LinkConfig,
};
use shared_protocol::units::Micros;

use crate::comparators::DacValues;
use crate::config::{DriveConfig, ResetCause};
use crate::drive::{
    CoreStatus, DriveCommand, DriveCore, DriveEvent, DriveRefusal, LoadStep, PwmCommand,
    EVENT_QUEUE,
};
use crate::measure::AdcSample;
use crate::power_port::{BreakMonitor, BreakReport, ComparatorLevels, PeriodAction};
use crate::protection::FaultCode;
use crate::state::DriveState;
use crate::timing::PwmTiming;
use crate::vm::VmWarning;

/// Fault reports waiting for room in the link's queue.
const UNREPORTED: usize = 8;

/// What the application reports to the board (for logging over defmt, a debug LED, or
/// hil-sim's trace). Nothing needs to be done with them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum AppEvent {
    /// From the core (state changes, faults, warnings, reversals).
    Core(DriveEvent),
    /// From the link (connection, commands as received, downloads).
    Link(LinkEvent),
    /// The core refused a command from the PLC (e.g. RUN while a fault is latched); the
    /// PLC sees the outcome in the status.
    Refused {
        command: DriveCommand,
        error: DriveRefusal,
    },
    /// An ACK was refused but the link's queue had no room for the reason (16 reports
    /// waiting): the PLC shows no reason this time.
    AckReasonLost,
    /// The link reported an accepted section but had none to hand over (cannot happen:
    /// `ProgramAccepted` is pushed with the section in place; kept so it would be seen).
    LoadFailed,
}

const APP_EVENTS: usize = 32;

/// Most events one [`DriveCore::tick_1ms`] delivers.
const TICK_EVENTS: usize = EVENT_QUEUE + 1;

/// The load of an accepted section, one step per [`DriveApp::poll_tx`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Load {
    Idle,
    /// Accepted by the link, not begun ([`DriveCore::load_begin`] next).
    Accepted,
    Step(LoadStep),
}

/// The steps of the 1 ms tick, in their order ([`DriveApp::tick_step`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TickStep {
    /// Link supervision (a lost link stops the core).
    Link,
    /// The core's first half: the drive section's pass ([`DriveCore::tick_1ms_program`]).
    Program,
    /// The core's second half: monitor, settings, modulator, events
    /// ([`DriveCore::tick_1ms_control`]).
    Control,
    /// Fault reports and the status frame to the link.
    Report,
}

impl TickStep {
    pub const ALL: [TickStep; 4] = [
        TickStep::Link,
        TickStep::Program,
        TickStep::Control,
        TickStep::Report,
    ];
}

/// The drive application.
pub struct DriveApp {
    core: DriveCore,
    link: DriveLink,
    unreported: heapless::Deque<FaultCode, UNREPORTED>,
    events: heapless::Deque<AppEvent, APP_EVENTS>,
    /// The timing TIM1 is programmed with (the last one a [`PeriodAction`] carried).
    programmed: PwmTiming,
    /// The core's [`DriveCore::timing_changes`] when `programmed` last matched its timing.
    programmed_changes: u32,
    breaks: BreakMonitor,
    /// Where the load of a section the link accepted stands (one step per `poll_tx`).
    load: Load,
    /// The threshold DAC values last handed to the board ([`DriveApp::boot_dacs`],
    /// [`DriveApp::dacs_to_write`]).
    dacs_written: Option<DacValues>,
}

impl DriveApp {
    // Inlined: `new_in` needs the parts, not a finished value (see there).
    #[inline(always)]
    pub fn new(core: DriveConfig, reset_cause: ResetCause, link: LinkConfig) -> Self {
        // One struct expression with every part built in its field's place: a part built
        // in a local first and then moved passes through the stack (`new_in`).
        DriveApp {
            programmed: DriveCore::boot_timing(&core),
            programmed_changes: 0,
            core: DriveCore::new(core, reset_cause),
            link: DriveLink::new(link),
            unreported: heapless::Deque::new(),
            events: heapless::Deque::new(),
            breaks: BreakMonitor::default(),
            load: Load::Idle,
            dacs_written: None,
        }
    }

    /// [`DriveApp::new`] built in `slot` (the board's static) rather than on the caller's
    /// stack. With `new` and the parts' constructors inlined (struct expressions, nothing
    /// updated after construction), the compiler writes each part straight into `slot`
    /// (the zeroed arrays as `memset`s); built as a value and moved, the application
    /// (~6 KiB) passed through the stack and made the drive's start-up task's stack frame
    /// 8.5 KiB. `.ci/run`'s `stack` step checks the frames (`docs/size.md`).
    #[inline(never)]
    pub fn new_in(
        slot: &mut core::mem::MaybeUninit<DriveApp>,
        core: DriveConfig,
        reset_cause: ResetCause,
        link: LinkConfig,
    ) -> &mut DriveApp {
        slot.write(DriveApp::new(core, reset_cause, link))
    }

    pub fn core(&self) -> &DriveCore {
        &self.core
    }

    /// The comparators' boot trim, run by the board before the break is armed
    /// ([`DriveCore::set_comparator_trim`]).
    pub fn set_comparator_trim(
        &mut self,
        r: Result<crate::comparator_trim::TrimmedZeros, crate::comparator_trim::TrimFailed>,
    ) {
        self.core.set_comparator_trim(r);
    }

    pub fn link(&self) -> &DriveLink {
        &self.link
    }

    pub fn link_state(&self) -> DriveLinkState {
        self.link.state()
    }

    /// The threshold DAC values the board writes at start-up, once the comparators are
    /// trimmed ([`DriveCore::comparator_dacs`]); later changes come from
    /// [`DriveApp::control_tick`](crate::bodies).
    pub fn boot_dacs(&mut self) -> DacValues {
        let v = self.core.comparator_dacs();
        self.dacs_written = Some(v);
        v
    }

    /// The core's threshold DAC values if they differ from those last handed out (a
    /// download changed `I>>`/`U>>`), now counted as written.
    pub fn dacs_to_write(&mut self) -> Option<DacValues> {
        let v = self.core.comparator_dacs();
        if self.dacs_written == Some(v) {
            return None;
        }
        self.dacs_written = Some(v);
        Some(v)
    }

    /// The core's full status (more than the link's status frame carries).
    pub fn status(&self) -> CoreStatus {
        self.core.status()
    }

    /// What TIM1 is programmed with: at start-up, what the board's init writes; later,
    /// the last timing a [`PeriodAction`] carried.
    pub fn pwm_timing(&self) -> PwmTiming {
        self.programmed
    }

    /// Oldest event not yet taken (the queue keeps the newest 32).
    pub fn poll_event(&mut self) -> Option<AppEvent> {
        self.events.pop_front()
    }

    fn push(&mut self, e: AppEvent) {
        if self.events.is_full() {
            self.events.pop_front();
        }
        // Cannot fail: room was made above (the newest events are kept).
        let _ = self.events.push_back(e);
    }

    /// Bytes from the UART: commands are applied to the core at once (after a load in
    /// progress: [`DriveApp::poll_tx`]).
    pub fn on_rx(&mut self, bytes: &[u8], now: Micros) {
        self.link.receive(bytes, now);
        self.apply_link_events();
    }

    /// The next frame for the UART (0 = nothing now); `out` must hold
    /// [`shared_protocol::link::MAX_WIRE_FRAME`] bytes.
    #[must_use = "the frame in `out` must be sent"]
    pub fn poll_tx(&mut self, now: Micros, out: &mut [u8]) -> usize {
        if self.load_next() {
            // This pass is a load step's; the link's frames and timers wait for the next
            // one, which is due at once (`poll_timeout`).
            return 0;
        }
        let n = self.link.poll_transmit(now, out);
        // A link loss is detected by the timers poll_transmit runs.
        self.apply_link_events();
        n
    }

    /// The UART reported a line error: the link drops the frame being received and
    /// counts it (`LinkStats::line_errors`).
    pub fn on_line_error(&mut self) {
        self.link.line_error();
    }

    /// The 1 ms tick: link supervision, the core's state machine and drive section,
    /// fault reports and the status frame; [`TickStep::ALL`] in order.
    pub fn tick_1ms(&mut self, now: Micros) {
        for step in TickStep::ALL {
            self.tick_step(step, now);
        }
    }

    /// One step of the 1 ms tick ([`DriveApp::tick_1ms`] runs them all, in the order of
    /// [`TickStep::ALL`]). The board runs each in a critical section of its own, so that
    /// the PWM interrupt waits for one step at most.
    pub fn tick_step(&mut self, step: TickStep, now: Micros) {
        match step {
            TickStep::Link => {
                self.link.tick(now);
                self.apply_link_events();
            }
            TickStep::Program => self.core.tick_1ms_program(),
            TickStep::Control => self.tick_control(),
            TickStep::Report => self.report(now),
        }
    }

    /// [`TickStep::Control`]: the core's second half, its events and faults queued.
    #[inline(never)]
    fn tick_control(&mut self) {
        // A tick delivers at most its queue of EVENT_QUEUE events plus `EventsLost`: the
        // pushes below cannot fail.
        let mut faults: heapless::Vec<FaultCode, TICK_EVENTS> = heapless::Vec::new();
        let mut core_events: heapless::Vec<DriveEvent, TICK_EVENTS> = heapless::Vec::new();
        self.core.tick_1ms_control(&mut |e| {
            if let DriveEvent::Fault(f) = e {
                let _ = faults.push(f);
            }
            let _ = core_events.push(e);
        });
        for e in core_events {
            self.push(AppEvent::Core(e));
        }
        for code in faults {
            if self.unreported.push_back(code).is_err() {
                // Keep the newest reports.
                self.unreported.pop_front();
                // Cannot fail: room was made just above.
                let _ = self.unreported.push_back(code);
            }
        }
    }

    /// [`TickStep::Report`]: fault reports to the link, the status frame from the core.
    #[inline(never)]
    fn report(&mut self, now: Micros) {
        let ms = now.millis().0;
        while let Some(&code) = self.unreported.front() {
            if !self.link.report_fault(code, ms) {
                break;
            }
            self.unreported.pop_front();
        }
        self.link.set_status(wire_status(&self.core.status()));
    }

    /// The PWM interrupt: measurements and trips in, what the power stage does this period
    /// out (perform it with [`PeriodAction::apply`]).
    #[must_use = "the action must be applied to the power stage"]
    #[inline(always)]
    pub fn pwm_period(&mut self, adc: &AdcSample) -> PeriodAction {
        let cmd: PwmCommand = self.core.pwm_period(adc);
        if self.core.timing_changes() == self.programmed_changes {
            // TIM1 has the core's timing: `from_command` with the same timing twice, whose
            // field-by-field compare (~30 instructions every period) the compiler drops.
            PeriodAction::from_command(&cmd, &self.programmed, &self.programmed)
        } else {
            self.retime(&cmd)
        }
    }

    /// [`DriveApp::pwm_period`] after the core recomputed its timing: compared with what
    /// TIM1 has, and programmed if it differs.
    #[inline(never)]
    fn retime(&mut self, cmd: &PwmCommand) -> PeriodAction {
        let wanted = self.core.pwm_timing();
        let action = PeriodAction::from_command(cmd, &self.programmed, &wanted);
        if action.timing.is_some() {
            self.programmed = wanted;
        }
        // `programmed` equals the core's timing now, either way.
        self.programmed_changes = self.core.timing_changes();
        action
    }

    /// The hardware `STO_IN` input as the board reads it every millisecond, before
    /// `tick_1ms` (`low` = STO requested; safety.md 6).
    pub fn set_sto_input(&mut self, low: bool) {
        self.breaks.set_sto_input(low);
        self.core.set_sto_input(low);
    }

    /// The TIM1 break interrupt found the `STO_IN` break's flag (the hardware has already
    /// opened every switch; the board has masked the interrupt and clears the flag after
    /// this call): the core latches it ([`DriveCore::sto_break`]).
    pub fn sto_break(&mut self) {
        self.breaks.other_fired();
        self.core.sto_break();
    }

    /// The TIM1 break interrupt found the system break's flag, as
    /// [`DriveApp::sto_break`]: the core latches `BOOT` ([`DriveCore::system_break`]).
    pub fn system_break(&mut self) {
        self.breaks.other_fired();
        self.core.system_break();
    }

    /// The TIM1 break interrupt with the comparators at `levels` (the hardware has
    /// already opened every switch; the board has cleared the flag and masked the
    /// interrupt): the causes are latched as faults.
    #[must_use = "the report says whether to re-arm the break input"]
    pub fn break_fired(&mut self, levels: ComparatorLevels) -> BreakReport {
        let report = self.breaks.fired(self.core.config().board, levels);
        for cause in report.fired.iter() {
            self.core.hardware_break(cause);
        }
        report
    }

    /// Every millisecond, with the comparators at `levels`: causes whose comparators went
    /// low are released (the fault stays latched until ACK); `rearm` tells the board to
    /// clear the break flag and unmask the break interrupt.
    #[must_use = "the report says whether to re-arm the break input"]
    pub fn break_poll(&mut self, levels: ComparatorLevels) -> BreakReport {
        let report = self.breaks.poll(self.core.config().board, levels);
        for cause in report.released.iter() {
            self.core.hardware_break_released(cause);
        }
        report
    }

    fn command(&mut self, command: DriveCommand) {
        if let Err(error) = self.core.command(command) {
            self.push(AppEvent::Refused { command, error });
            // The PLC shows why an ACK was refused: the fault stays latched
            // and the user must know what to change.
            let why = match error {
                DriveRefusal::CauseActive(f) => Some(AckRefusal::CauseActive(f)),
                DriveRefusal::FrequencyNotBelowFmn => Some(AckRefusal::FrequencyNotBelowFmn),
                _ => None,
            };
            if let Some(why) = why {
                if !self.link.report_ack_refused(why) {
                    self.push(AppEvent::AckReasonLost);
                }
            }
        }
    }

    /// When `poll_tx` must run next: at once while a load is pending, else the link's
    /// deadline.
    pub fn poll_timeout(&self) -> Option<Micros> {
        if self.load != Load::Idle {
            Some(AT_ONCE)
        } else {
            self.link.poll_timeout()
        }
    }

    /// The next step of loading the section the link accepted, if one waits; whether it
    /// ran one (or found no section). The last step applies the link's events that
    /// waited for the load.
    fn load_next(&mut self) -> bool {
        self.load = match self.load {
            Load::Idle => return false,
            Load::Accepted => match self.link.take_program() {
                Some(p) => Load::Step(self.core.load_begin(p)),
                None => {
                    self.push(AppEvent::LoadFailed);
                    Load::Idle
                }
            },
            Load::Step(step) => match self.core.load_step(step) {
                Some(next) => Load::Step(next),
                None => Load::Idle,
            },
        };
        if self.load == Load::Idle {
            self.apply_link_events();
        }
        true
    }

    /// The link's events to the core, in order. While a section loads they wait in the
    /// link's queue (32 events, 4 passes of load): every command from the PLC finds the
    /// new section loaded.
    fn apply_link_events(&mut self) {
        while self.load == Load::Idle {
            let Some(e) = self.link.poll_event() else {
                break;
            };
            self.push(AppEvent::Link(e));
            match e {
                LinkEvent::Connected | LinkEvent::VersionMismatch { .. } => {}
                LinkEvent::LinkLost => {
                    if self.core.state() == DriveState::Run {
                        self.core.trip(FaultCode::Link);
                    }
                    self.command(DriveCommand::Stop);
                }
                LinkEvent::QWrite { addr, value } => {
                    self.command(DriveCommand::SetQ { addr, value })
                }
                LinkEvent::Run => self.command(DriveCommand::Run),
                LinkEvent::Stop => self.command(DriveCommand::Stop),
                LinkEvent::Direction { reverse } => {
                    self.command(DriveCommand::Direction { reverse })
                }
                LinkEvent::AckFault => self.command(DriveCommand::Ack),
                LinkEvent::SafetyRequest { requested } => {
                    self.command(DriveCommand::SafetyRequest { requested })
                }
                LinkEvent::ProgramAccepted => self.load = Load::Accepted,
                LinkEvent::ProgramRejected { .. } => self.core.trip(FaultCode::Prog),
            }
        }
    }
}

/// The link's status frame from the core's status.
pub fn wire_status(s: &CoreStatus) -> WireStatus {
    WireStatus {
        state: s.state,
        fault: s.fault,
        freq_dhz: s.f_applied.0,
        reverse: s.reverse,
        udc_dv: s.u_dc.0,
        imax_ca: s.i_peak.0,
        com: s.com,
        oc_hw_ca: s.hw.oc_hw.0,
        ov_hw_v: s.hw.ov_hw.0,
        warning: s.warning.map(|w| match w {
            VmWarning::PwfClamped {
                line,
                requested,
                applied,
            } => WireWarning::PwfClamped {
                line: line.min(u16::from(u8::MAX)) as u8,
                requested,
                applied_hz: applied,
            },
        }),
        sf_requested: s.sf_requested,
        sf_status: s.sf_status,
        sf_sdc: s.sf_sdc,
        sf_elapsed_ds: s.sf_elapsed_ds,
        sf_signature: s.sf_signature,
        sto_in_low: s.sto_in_low,
        program_loaded: s.program_loaded,
        sf_turns: s.sf_turns,
    }
}
