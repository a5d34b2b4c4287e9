//! [`PlcApp`]: the PLC MCU's application: the program, the VM, the link to the drive, the
//! keypad editor and the EEPROM storage, joined. The board layer (and hil-sim) calls it;
//! it owns no hardware and no clock (time is an argument everywhere).
//!
//! | when | call |
//! | --- | --- |
//! | power-up | [`PlcApp::new`], or [`PlcApp::new_cold`] + [`PlcApp::power_up`] in place (loads the slot last run; starts RUN when it was running) |
//! | every 1 ms, the pins as sampled | [`PlcApp::tick_1ms`] (through `crate::task::AppPass::run`) |
//! | UART bytes received, transmitter free | the link pump over the application (`crate::link`) |
//!
//! [`PlcApp::tick_1ms`] takes the **raw** pin levels and key matrix: it debounces them,
//! runs the scan at its cadence, steps the EEPROM jobs (one page per pass) and redraws
//! the screen at its cadence. Its single steps are public only to test rigs (feature
//! `sim`).
//!
//! Dependencies: this module uses the storage, the editor and the VM; the service
//! endpoint (`crate::service`) and the task bodies (`crate::task`) use it, never the other
//! way (`docs/board.md`, "Crate structure").
//!
//! Storage: saves, loads, the fault log and the boot record are queued as
//! [`crate::storage::Job`]s and done one EEPROM page per `tick_1ms`: nothing
//! ever stalls the board's executor, and a save is allowed in RUN. Only power-up
//! ([`PlcApp::power_up`]) reads synchronously, before the watchdog runs.
//!
//! RUN (key `A`, [`PlcApp::run`], or power-up): verify the whole program (an error shows
//! its line and nothing starts), wait for the link, download the drive section, wait for
//! the drive's acceptance, then send RUN to the drive and start the VM in the same call.
//! A reject shows the drive's line and reason. STOP: the VM stops, the outputs go off and
//! the drive is told STOP (PWM off).
//!
//! Faults: every fault the drive reports and every application fault (`ALM`) is logged
//! in the EEPROM (newest 16, with the time of day, the power-cycle count and the time
//! since power-up, and the first two `LCD` fields of the last scan: the lift's floor and
//! target) and a drive fault is shown on the run screen with its text. Nothing restarts by itself: after a trip (including `LINK` after a cut link) the
//! drive stays in FAULT until an `ACK` (program instruction) and a new RUN from the user.
//! A lost link does not stop the PLC's own scan (its outputs may matter on their own);
//! the run screen shows the link state.

use shared_protocol::link::plc::{CommandError, PlcEvent, PlcLink, PlcLinkState};
use shared_protocol::link::Q_COUNT;
use shared_protocol::link::{
    fault_text, DownloadResult, DriveState, DriveStatus, DriveWarning, FaultCode, LinkConfig,
    RejectReason,
};
use shared_protocol::program::{
    safety_settings, uses_safety, verify, Mnemonic, Operand, Program, Section, ShortText,
};
use shared_protocol::shift;
use shared_protocol::units::{CentiAmps, Decihertz, Decivolts, Micros, Volts};

use crate::debounce::{Debouncer, KeyMatrix};
use crate::editor::text::Text;
use crate::editor::{
    Editor, Key, Notice, Page, Request, RunView, SafetyView, Screen, View, Warning,
};
use crate::storage::{
    BootChange, Eeprom, FaultEntry, Job, JobDone, Storage, StorageError, FAULT_LOG_ENTRIES,
    NO_VALUE, WALL_UNSET,
};
use crate::vm::{self, DriveView, PlcVm, ScanInputs, ScanOutputs};

mod service;
mod time_of_day;

pub(crate) use service::checked_slot;
pub(crate) use service::up_to;
pub use service::{BuildInfo, Outcome};

/// Where RUN stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RunState {
    Stopped,
    /// RUN requested, program verified: waiting for the link to come up.
    WaitLink,
    /// The drive section is being sent; waiting for the drive's answer.
    Downloading,
    /// Both run.
    Running,
}

/// Everything the run screen shows (also for hil-sim's summary and tests).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RunStatus {
    pub run: RunState,
    pub link: PlcLinkState,
    /// The drive's newest status, `None` while the link is down.
    pub drive: Option<DriveStatus>,
    /// The newest fault reported by the drive in this power cycle: code and text.
    pub newest_fault: Option<(u8, &'static str)>,
    /// The 4 `LCD` fields of the last scan.
    pub lcd: [Option<i16>; 4],
    /// The newest run-time warning (`DIV0 @ line`), kept until the next RUN.
    pub warning: Option<vm::Warning>,
    /// The drive's run-time warning while its status reports it (e.g. `PWF` clamped).
    pub drive_warning: Option<DriveWarning>,
}

/// What must reach the LCD at once when it changes (link.md and panel.md: a lost link
/// shown within 100 ms, faults without an `LCD` instruction). Boards redraw when this
/// differs from its value at their last redraw, besides their periodic refresh.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Alerts {
    pub run: RunState,
    pub link: PlcLinkState,
    pub drive_state: Option<DriveState>,
    pub drive_fault: Option<FaultCode>,
    pub newest_fault: Option<u8>,
    pub warning: Option<vm::Warning>,
    pub drive_warning: Option<DriveWarning>,
    /// The drive's safety request and status masks (the status row's `S:` items).
    pub sf_requested: u16,
    pub sf_status: u16,
}

/// The PLC application.
pub struct PlcApp<E: Eeprom> {
    /// The safety functions' requests and their times (safety.md 10, `S:<name> DEC`).
    safety: SafetyTimes,
    /// In RUN, the drive has reported an accepted drive section since RUN started: its
    /// report of none afterwards means it restarted ([`PlcApp::watch_drive_restart`]).
    drive_had_program: bool,
    program: Program,
    vm: PlcVm,
    link: PlcLink,
    storage: Storage<E>,
    editor: Editor,
    run: RunState,
    /// The slot RUN was started from (for the boot record).
    run_slot: Option<u8>,
    out: ScanOutputs,
    newest_fault: Option<u8>,
    warning: Option<vm::Warning>,
    /// The stored fault log, newest first (read at power-up, kept up to date).
    fault_log: heapless::Vec<FaultEntry, FAULT_LOG_ENTRIES>,
    /// Per Q: the value last handed to the link in this RUN.
    q_sent: [Option<i16>; Q_COUNT],
    /// Bit n: the drive section writes Qn itself (`WR Qn`), so every PLC write of Qn
    /// must reach the drive even when the value is unchanged.
    drive_writes_q: u64,
    /// Time from one scan to the next, for the link's quiet window.
    scan_period_us: u64,
    /// Digital inputs, debounced in [`PlcApp::tick_1ms`].
    inputs: Debouncer<{ vm::INPUTS as usize }>,
    /// The keypad, debounced in [`PlcApp::tick_1ms`].
    keys: KeyMatrix,
    /// `tick_1ms` calls since power-up (scan and redraw cadence).
    ticks: u32,
    /// [`PlcApp::alerts`] at the last redraw.
    drawn_alerts: Option<Alerts>,
    /// The run state last reported in a [`Tick`] (changes made by the link calls
    /// between ticks are reported by the next tick).
    reported_run: RunState,
    /// What the service port reports besides the above, and remote service
    /// (`app/service.rs`).
    observed: service::Observed,
    /// The time of day (`crate::clock`).
    wall: crate::clock::WallClock,
}

/// When each safety function was last requested (the rise of its bit in the drive's
/// reported mask), for the status row's `S:<name> DEC n.ns`; and the RUN's signature
/// check (safety.md 8).
#[derive(Debug, Clone, Copy, Default)]
struct SafetyTimes {
    seen: u16,
    since_ms: [u32; 12],
    /// The signature of the program RUN started, checked against the drive's status
    /// once the drive reports RUN.
    expected: Option<u16>,
}

/// Digital inputs: a level must hold for 5 samples (5 ms at one `tick_1ms` per ms) to
/// count; a shorter pulse never reaches the scan.
pub const INPUT_DEBOUNCE_SAMPLES: u8 = 5;
/// Keypad: a key must be stable for 10 full-matrix samples (10 ms) to count.
pub const KEY_DEBOUNCE_SAMPLES: u8 = 10;
/// The screen is redrawn every this many ticks (100 ms), and at once after a key or a
/// change of [`Alerts`]; the LCD driver then sends the changed cells.
pub const RENDER_TICKS: u32 = 100;

/// The raw levels a board samples once per millisecond.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct RawIo {
    /// D00..D15 as read at the pins (bit n = Dn, 1 = on), not debounced.
    pub digital: u16,
    /// A00..A03, 10-bit counts.
    pub analog: [u16; 4],
    /// The key matrix as scanned (bit `4 * row + column` = pressed), not debounced.
    pub keys: u16,
}

/// What one [`PlcApp::tick_1ms`] did, for the board to carry out and log.
#[must_use]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Tick {
    /// The output image to write to O00..O07.
    pub outputs: u8,
    /// A scan ran in this tick (its warning, if any).
    pub scanned: bool,
    pub warning: Option<vm::Warning>,
    /// The screen was redrawn: the LCD driver has cells to send.
    pub redrawn: bool,
    /// Debounced keys pressed in this tick (bit as in [`RawIo::keys`]).
    pub keys_down: u16,
    /// The storage job that finished in this tick.
    pub storage: Option<JobDone>,
    /// The storage step used the I2C bus.
    pub storage_used_bus: bool,
    /// The run state changed in this tick (from, to).
    pub run_change: Option<(RunState, RunState)>,
}

/// Margin kept between the end of a heartbeat sent after a scan and the next scan.
const QUIET_MARGIN_US: u64 = 50;

/// The Q variables the drive section writes with its own `WR` (bit n = Qn).
pub fn drive_written_q(program: &Program) -> u64 {
    program
        .section(Section::Drive)
        .filter(|(_, i)| i.mnemonic == Mnemonic::Wr)
        .filter_map(|(_, i)| match i.operand {
            Some(Operand::Q(n)) if usize::from(n) < Q_COUNT => Some(1u64 << n),
            _ => None,
        })
        .fold(0, |a, b| a | b)
}

impl<E: Eeprom> PlcApp<E> {
    /// Power-up with the EEPROM in `eeprom` and an LCD of `cols` x `rows` (20x4 or 16x2):
    /// [`PlcApp::new_cold`] then [`PlcApp::power_up`]. Convenient on the host; the MCU
    /// builds the application in its static slot and calls `power_up` there, because this
    /// by-value constructor needs several copies of the ~15 KiB application on the stack.
    pub fn new(eeprom: E, link: LinkConfig, cols: u8, rows: u8, now: Micros) -> Self {
        let mut app = Self::new_cold(eeprom, link, cols, rows);
        app.power_up(now);
        app
    }

    /// The application with nothing loaded and no EEPROM access yet (stopped, empty
    /// program). Call [`PlcApp::power_up`] next.
    pub fn new_cold(eeprom: E, link: LinkConfig, cols: u8, rows: u8) -> Self {
        PlcApp {
            program: Program::default(),
            vm: PlcVm::new(),
            link: PlcLink::new(link),
            storage: Storage::new(eeprom),
            editor: Editor::new(cols, rows),
            run: RunState::Stopped,
            run_slot: None,
            out: ScanOutputs::default(),
            newest_fault: None,
            warning: None,
            fault_log: heapless::Vec::new(),
            q_sent: [None; Q_COUNT],
            drive_writes_q: 0,
            scan_period_us: 1_000,
            inputs: Debouncer::new(INPUT_DEBOUNCE_SAMPLES),
            keys: KeyMatrix::new(KEY_DEBOUNCE_SAMPLES),
            ticks: 0,
            drawn_alerts: None,
            reported_run: RunState::Stopped,
            observed: service::Observed::default(),
            wall: crate::clock::WallClock::new(),
            safety: SafetyTimes {
                seen: 0,
                since_ms: [0; 12],
                expected: None,
            },
            drive_had_program: false,
        }
    }

    /// Power-up: loads the slot last run from the EEPROM and the fault log, and starts RUN
    /// when the boot record says the PLC was running. Call once, after `new_cold`.
    pub fn power_up(&mut self, now: Micros) {
        let mut t = now.0;
        let mut clock = || {
            t += 1000;
            Micros(t)
        };
        self.power_up_clocked(now, &mut clock);
    }

    /// [`PlcApp::power_up`] with the real clock that times the EEPROM's write cycles (the
    /// board's: power-up runs synchronously before the watchdog is started).
    pub fn power_up_clocked(&mut self, now: Micros, clock: &mut dyn FnMut() -> Micros) {
        let mut run_now = false;
        match self.storage.power_up_clocked(&mut self.program, clock) {
            Ok(p) => {
                match p.loaded {
                    Some(Ok(report)) => {
                        self.editor.notify(Notice::Loaded(report));
                        self.run_slot = Some(report.slot);
                    }
                    Some(Err(error)) => self.editor.notify(Notice::LoadFailed { slot: 0, error }),
                    None => {}
                }
                run_now = p.run;
                // A restarted PLC must not reuse the session the drive still knows.
                self.link.seed_session(p.power_cycle as u8);
            }
            Err(_) => self.editor.notify(Notice::Text("EEPROM ERROR")),
        }
        self.reload_fault_log();
        if run_now {
            let slot = self.run_slot;
            self.run(slot, now);
        }
    }

    /// The scan period [`PlcApp::tick_1ms`] runs the scan at (default 1 ms). The link
    /// sends its heartbeats right after a scan when they fit before the next one, so that
    /// a Q write never waits behind a heartbeat (latency one frame, ≈ 1.13 ms at 115200).
    pub fn set_scan_period_us(&mut self, us: u64) {
        self.scan_period_us = us;
    }

    pub fn program(&self) -> &Program {
        &self.program
    }

    /// The program, for loading it from elsewhere (e.g. hil-sim from a text file) while
    /// stopped. Changing it while running has no effect until the next RUN: the drive
    /// runs the section downloaded at RUN, the PLC the section compiled at RUN.
    pub fn program_mut(&mut self) -> &mut Program {
        &mut self.program
    }

    /// Replaces the program in RAM from elsewhere (e.g. the PC panel's program file) while
    /// stopped; it is unsaved and belongs to no slot, so `D` `n` asks before discarding it.
    /// Refused (false) in RUN.
    pub fn replace_program(&mut self, program: &Program) -> bool {
        if self.run != RunState::Stopped {
            return false;
        }
        self.program.clone_from(program);
        self.editor.mark_modified();
        true
    }

    pub fn vm(&self) -> &PlcVm {
        &self.vm
    }

    pub fn link(&self) -> &PlcLink {
        &self.link
    }

    pub fn editor(&self) -> &Editor {
        &self.editor
    }

    pub fn storage(&mut self) -> &mut Storage<E> {
        &mut self.storage
    }

    pub fn run_state(&self) -> RunState {
        self.run
    }

    /// The PLC's copy of Qn.
    pub fn q(&self, n: u8) -> i16 {
        self.vm.q(n)
    }

    /// The output image O00-O07 (0 when not running).
    pub fn outputs(&self) -> u8 {
        self.out.outputs
    }

    /// The stored fault log, newest first.
    pub fn fault_log(&self) -> &[FaultEntry] {
        &self.fault_log
    }

    pub fn status(&self) -> RunStatus {
        RunStatus {
            run: self.run,
            link: self.link.state(),
            drive: self.drive_status(),
            newest_fault: self.newest_fault.map(|c| (c, fault_text(c))),
            lcd: self.out.lcd,
            warning: self.warning,
            drive_warning: self.drive_status().and_then(|s| s.warning),
        }
    }

    /// See [`Alerts`].
    pub fn alerts(&self) -> Alerts {
        let drive = self.drive_status();
        Alerts {
            run: self.run,
            link: self.link.state(),
            drive_state: drive.map(|d| d.state),
            drive_fault: drive.and_then(|d| d.fault),
            newest_fault: self.newest_fault,
            warning: self.warning,
            drive_warning: drive.and_then(|d| d.warning),
            sf_requested: drive.map_or(0, |d| d.sf_requested),
            sf_status: drive.map_or(0, |d| d.sf_status),
        }
    }

    // Out of line: eight callers had their own copy.
    #[inline(never)]
    fn drive_status(&self) -> Option<DriveStatus> {
        if !self.link.is_up() {
            return None;
        }
        self.link.last_status().map(|(s, _)| s)
    }

    /// Start RUN (the editor's `A` key does this through the debounced keys of [`PlcApp::tick_1ms`]). `slot` is the
    /// slot the program came from, recorded so that it runs again at power-up.
    pub fn run(&mut self, slot: Option<u8>, now: Micros) {
        if let Err(e) = verify(&self.program) {
            self.editor.notify(Notice::RunRefused {
                line: Some(e.line),
                reason: e.kind.short(),
            });
            self.run = RunState::Stopped;
            return;
        }
        // safety.md 6: the drive refuses RUN while its STO input is low; say why here.
        if self.drive_status().is_some_and(|s| s.sto_in_low) {
            self.editor.notify(Notice::Text("RUN REFUSED:STO_IN"));
            self.run = RunState::Stopped;
            return;
        }
        if self.run == RunState::Running {
            // A new RUN while running: stop both first, then start over.
            self.send_stop();
        }
        self.run_slot = slot.or(self.run_slot);
        self.out = ScanOutputs::default();
        self.warning = None;
        self.run = RunState::WaitLink;
        self.editor.show_page(Page::Run);
        self.advance_run(now);
    }

    /// STOP: the VM stops, the outputs go off, the drive is told to stop.
    pub fn stop(&mut self) {
        self.send_stop();
        self.run = RunState::Stopped;
        self.out = ScanOutputs::default();
        // Every control bit is 1 again after STOP (safety.md 5).
        let _ = self.link.set_safety_request(0);
        self.safety.expected = None;
        self.queue_boot(false);
    }

    /// A trip of the field I/O (`crate::field_io`, fault-log code `code`): the port has
    /// already turned the outputs off; the program stops (and with it the drive), the
    /// code is shown as the newest fault and logged.
    pub fn field_trip(&mut self, code: u8, now: Micros) {
        if self.run != RunState::Stopped {
            self.stop();
        }
        self.newest_fault = Some(code);
        self.editor.notify(Notice::Text("FIELD I/O TRIP"));
        self.log_fault(code, now);
    }

    /// Hands STOP to the link, which never refuses it for lack of room (it goes to the
    /// head of the queue, `PlcLink::stop`). Refused only while the link is down: nothing
    /// to send then, the drive stops by itself on a lost link (`LINK`, and STOP).
    fn send_stop(&mut self) {
        if let Err(e) = self.link.stop() {
            debug_assert_eq!(e, CommandError::NotConnected);
        }
    }

    /// Queues the boot record's run state (a waiting change is replaced by this one).
    fn queue_boot(&mut self, running: bool) {
        let job = Job::Boot(BootChange::Run {
            slot: self.run_slot,
            running,
        });
        if self.storage.queue(job).is_err() {
            self.editor.notify(Notice::Text("EEPROM BUSY"));
        }
    }

    /// Acknowledge the drive's latched fault from outside the program (a key or a panel
    /// button; the program's own `ACK` instruction does the same). The drive accepts it
    /// only when the cause is gone and the frequency command is below `fmn`; it then goes
    /// to IDLE, and a new RUN is needed. Refused while the link is down.
    pub fn ack_fault(&mut self) -> Result<(), CommandError> {
        self.link.ack_fault()
    }

    fn advance_run(&mut self, now: Micros) {
        if self.run == RunState::WaitLink
            && self.link.is_up()
            && self
                .link
                .start_download(&self.program.drive_section())
                .is_ok()
        {
            self.run = RunState::Downloading;
        }
        let _ = now;
    }

    fn start_both(&mut self, now: Micros) {
        if self.link.run().is_err() {
            // The link went down between the answer and now: try again from the start.
            self.run = RunState::WaitLink;
            return;
        }
        // Every control bit is 1 at RUN start (safety.md 5): nothing requested until the
        // program's first `SFR` says so.
        let _ = self.link.set_safety_request(0);
        let settings = safety_settings(self.program.lines.iter());
        self.safety.expected = Some(settings.signature());
        if uses_safety(&self.program) {
            self.editor.notify(Notice::NotRated {
                signature: settings.signature(),
            });
        }
        // Compiles the PLC section now, not in the first scan.
        self.vm.start_program(&self.program, now.millis());
        self.link.forget_q();
        self.q_sent = [None; Q_COUNT];
        self.drive_writes_q = drive_written_q(&self.program);
        self.run = RunState::Running;
        self.observed.run_started();
        self.queue_boot(true);
    }

    /// One scan with the inputs sampled at its start; returns the outputs to write.
    /// Does nothing (outputs off) unless RUN is on.
    fn scan_once(&mut self, digital: u16, analog: [u16; 4], now: Micros) -> ScanOutputs {
        let running = self.run == RunState::Running;
        self.observed.scanned(digital, analog, now, running);
        if !running {
            self.out = ScanOutputs::default();
            return self.out;
        }
        let inputs = ScanInputs {
            digital,
            analog,
            drive: self.drive_view(),
        };
        let mut out = ScanOutputs::default();
        self.vm.scan(&self.program, &inputs, now.millis(), &mut out);
        if let Some(rev) = out.rev_request {
            // The direction goes first (lift.md 2.2): a program reversing from standstill
            // executes `REV` before, or in the same scan as, the `WR` that starts the
            // motor, and the drive must have the new direction before the new setpoint.
            // Remembered while the link is down and resent after each handshake; refused
            // only with 95 commands waiting, and the program asks again every scan.
            let _ = self.link.set_direction(rev);
        }
        for n in out.dirty_q() {
            let value = self.vm.q(n);
            let Some(sent) = self.q_sent.get_mut(usize::from(n)) else {
                continue;
            };
            // An unchanged value is not sent again unless the drive section may have
            // overwritten its copy: the drive's copy equals the PLC's last write either
            // way, and the wire stays free for the changes (latency budget).
            let drive_writes = self.drive_writes_q & (1u64 << n) != 0;
            if *sent == Some(value) && !drive_writes {
                continue;
            }
            // Refused only when 95 commands wait (`QueueFull`; the link keeps the newest
            // value for the next reconnection anyway) and never for the address
            // (`dirty_q` gives Q00-Q63 only).
            let _ = self.link.write_q(n, value);
            *sent = Some(value);
        }
        if let Some(mask) = out.sf_request {
            // Before the ACK of the same scan (safety_lab.plc releases, then ACKs); newest
            // wins in the link's queue; remembered while the link is down.
            let _ = self.link.set_safety_request(mask);
        }
        if out.ack_request {
            // A program's ACK while the link is down has nothing to acknowledge: the
            // drive's fault is read again after the reconnection.
            let _ = self.link.ack_fault();
        }
        // No command until the next scan: a heartbeat that is due soon goes now, so it is
        // never on the wire when the next scan's writes want it.
        let quiet = self.scan_period_us.saturating_sub(QUIET_MARGIN_US);
        self.link.quiet_for(now, quiet);
        if out.warning.is_some() {
            self.warning = out.warning;
        }
        self.out = out;
        if let Some(n) = out.alarm {
            // `ALM`: an application fault, logged like a drive fault under its own codes,
            // with this scan's `LCD` fields.
            self.log_fault(shared_protocol::service::app_fault_code(n), now);
        }
        out
    }

    /// The fault-log entry for `code` at `now`: the time of day, and the first two `LCD`
    /// fields of the last scan as the application values (none while stopped).
    pub(crate) fn log_entry(&self, code: u8, now: Micros) -> FaultEntry {
        let lcd = |n: usize| self.out.lcd.get(n).copied().flatten().unwrap_or(NO_VALUE);
        FaultEntry {
            wall_s: self.wall_seconds(now).unwrap_or(WALL_UNSET),
            values: [lcd(0), lcd(1)],
            ..self.storage.fault_entry(code, now.0 / 1000)
        }
    }

    /// Queue the fault-log entry for `code` at `now`.
    pub(crate) fn log_fault(&mut self, code: u8, now: Micros) {
        let entry = self.log_entry(code, now);
        if self.storage.queue(Job::LogFault(entry)).is_err() {
            self.editor.notify(Notice::Text("FAULT LOG ERROR"));
        }
    }

    fn drive_view(&self) -> DriveView {
        match self.drive_status() {
            Some(s) => DriveView {
                com: s.com,
                frq: Decihertz(s.freq_dhz),
                udc: Decivolts(s.udc_dv),
                imx: CentiAmps(s.imax_ca),
                flt: s.fault.map_or(0, FaultCode::code),
                dir_reverse: s.reverse,
                ready: s.state == DriveState::Run && s.fault.is_none(),
                fault_latched: s.fault.is_some(),
                ihw: CentiAmps(s.oc_hw_ca),
                uhw: Volts(s.ov_hw_v),
                sf_status: s.sf_status,
                sf_sdc: s.sf_sdc,
                sf_elapsed_ds: s.sf_elapsed_ds,
                sf_turns: s.sf_turns,
            },
            None => DriveView::default(),
        }
    }

    /// Bytes from the UART.
    pub fn on_rx(&mut self, bytes: &[u8], now: Micros) {
        self.link.receive(bytes, now);
        self.service(now);
    }

    /// The next frame for the UART (0 = nothing now); `out` must hold
    /// [`shared_protocol::link::MAX_WIRE_FRAME`] bytes. Also runs the link's timers and
    /// the RUN sequence: call it at least every millisecond.
    #[must_use = "the frame in `out` must be sent"]
    pub fn poll_tx(&mut self, now: Micros, out: &mut [u8]) -> usize {
        self.service(now);
        let n = self.link.poll_transmit(now, out);
        self.service(now);
        n
    }

    /// The UART reported a line error: the link drops the frame being received and
    /// counts it (`LinkStats::line_errors`).
    pub fn on_line_error(&mut self) {
        self.link.line_error();
    }

    fn service(&mut self, now: Micros) {
        self.service_link(now);
        self.track_safety(now);
        self.watch_drive_restart();
    }

    /// A drive that restarts (supply cut, watchdog) comes back without its drive section
    /// and in IDLE: the program would run on with a drive that ignores it and nothing on
    /// the LCD would say why. RUN stops (outputs off), the LCD says `DRIVE RESTARTED` (or
    /// shows the drive's WDG/BOOT fault), and `A` starts RUN again with a new download.
    /// Never an automatic restart (drive.md).
    fn watch_drive_restart(&mut self) {
        if self.run != RunState::Running {
            self.drive_had_program = false;
            return;
        }
        let Some(s) = self.drive_status() else {
            return;
        };
        if s.program_loaded {
            self.drive_had_program = true;
        } else if self.drive_had_program {
            self.drive_had_program = false;
            self.stop();
            // After a watchdog reset or a failed self-test the drive's fault (WDG, BOOT)
            // says why, at once on the status row.
            if s.fault.is_none() {
                self.editor.notify(Notice::Text("DRIVE RESTARTED"));
            }
        }
    }

    fn service_link(&mut self, now: Micros) {
        while let Some(e) = self.link.poll_event() {
            match e {
                PlcEvent::Connected => {}
                PlcEvent::LinkLost { .. } => {
                    if self.run == RunState::Downloading {
                        self.run = RunState::WaitLink;
                    }
                }
                PlcEvent::VersionMismatch { .. } => {
                    self.editor.notify(Notice::Text("DRIVE VERSION DIFF"));
                }
                PlcEvent::Download(DownloadResult::Accepted) => {
                    if self.run == RunState::Downloading {
                        self.start_both(now);
                    }
                }
                PlcEvent::Download(DownloadResult::Rejected { line, reason }) => {
                    if self.run == RunState::Downloading {
                        self.run = RunState::Stopped;
                    }
                    self.editor.notify(Notice::RunRefused {
                        line: match reason {
                            RejectReason::Verify(_) | RejectReason::Decode => Some(line),
                            RejectReason::Crc | RejectReason::Incomplete => None,
                        },
                        reason: ShortText::Fixed(reason.short()),
                    });
                }
                PlcEvent::AckRefused(why) => self.editor.notify(Notice::Text(why.message())),
                PlcEvent::DriveFault { code, .. } => {
                    // The log and `FLT` keep the raw code (the log also holds events).
                    let code = code.code();
                    self.newest_fault = Some(code);
                    // The PLC's clock, not the drive's: the log's timestamps must be
                    // comparable across drive reboots. Queued: the job runs in
                    // `tick_1ms`, one EEPROM page per tick, so the link pass that
                    // received the report (and its acknowledgement) never waits for it.
                    self.log_fault(code, now);
                }
            }
        }
        self.advance_run(now);
    }

    fn reload_fault_log(&mut self) {
        let mut log = heapless::Vec::new();
        if let Ok(head) = self.storage.fault_log_with_head(&mut log) {
            self.fault_log = log;
            self.observed.log_head = head;
        }
    }

    /// A key of the keypad (debounced; [`PlcApp::tick_1ms`] calls it).
    fn on_key(&mut self, key: Key, now: Micros) {
        let running = self.run != RunState::Stopped;
        self.editor.set_program_use(self.storage.program_use());
        let Some(req) = self.editor.key(key, &mut self.program, running) else {
            return;
        };
        match req {
            Request::Save(slot) => match self.storage.queue(Job::Save { slot }) {
                Ok(()) => self.editor.notify(Notice::Text("SAVING...")),
                Err(_) => self.editor.notify(Notice::SaveFailed {
                    slot,
                    error: StorageError::Busy,
                }),
            },
            Request::Load(slot) => match self.storage.queue(Job::Load { slot }) {
                Ok(()) => self.editor.notify(Notice::Text("LOADING...")),
                Err(_) => self.editor.notify(Notice::LoadFailed {
                    slot,
                    error: StorageError::Busy,
                }),
            },
            Request::Run { slot } => self.run(slot, now),
            Request::Stop => self.stop(),
            Request::New => {}
            Request::AckFaults => {
                let text = match self.ack_fault() {
                    Ok(()) => "FAULT ACK SENT",
                    Err(_) => "ACK: NO LINK",
                };
                self.editor.notify(Notice::Text(text));
            }
            Request::ClearFaultLog => {
                if self.queue_clear_fault_log(now).is_err() {
                    self.editor.notify(Notice::Text("EEPROM BUSY"));
                }
            }
            Request::ToggleRemote => self.toggle_remote(now),
        }
    }

    /// Erase the fault log and log the event `LOGCLR` (240) as the emptied log's first
    /// entry (service.md 6), so the log itself says when and in which power-up it was
    /// cleared. Keypad `*` `0` and the service's `ClearFaultLog`.
    fn queue_clear_fault_log(&mut self, now: Micros) -> Result<(), crate::storage::QueueFull> {
        self.storage.queue(Job::ClearFaultLog)?;
        self.newest_fault = None;
        // The queue had room for the clear; the event follows it (a full queue loses
        // only the event).
        self.log_fault(shared_protocol::service::EVENT_LOG_CLEARED, now);
        Ok(())
    }

    /// Moves the storage queue on by one EEPROM page (see [`Storage::step`]) and takes
    /// the outcome of a finished job into the application. `tick_1ms` calls it.
    fn storage_step(&mut self, now: Micros) -> crate::storage::JobStep {
        let step = self.storage.step(now, &mut self.program);
        if let Some(done) = step.done {
            self.storage_done(done, now);
        }
        step
    }

    fn storage_done(&mut self, done: JobDone, now: Micros) {
        match done {
            JobDone::Saved { slot, result } => self.editor.notify(match result {
                Ok(_) => Notice::Saved { slot },
                Err(error) => Notice::SaveFailed { slot, error },
            }),
            JobDone::Loaded { slot, result } => {
                let run_now = self.observed.run_after_load.take() == Some(slot) && result.is_ok();
                self.editor.notify(match result {
                    Ok(r) => Notice::Loaded(r),
                    Err(error) => Notice::LoadFailed { slot, error },
                });
                if self.observed.written_load.take() == Some(slot) && result.is_ok() {
                    self.editor.notify(Notice::Written { slot });
                }
                if run_now {
                    self.run(Some(slot), now);
                }
            }
            JobDone::FaultLogged { entry, result } => match result {
                Ok(()) => {
                    // The RAM copy follows the EEPROM's: newest first, the oldest drops.
                    if self.fault_log.is_full() {
                        let _ = self.fault_log.pop();
                    }
                    // Cannot fail: there is room now.
                    let _ = shift::insert_front(&mut self.fault_log, entry);
                    self.observed.logged();
                }
                Err(_) => self.editor.notify(Notice::Text("FAULT LOG ERROR")),
            },
            JobDone::FaultLogCleared { result } => match result {
                Ok(()) => {
                    self.fault_log.clear();
                    self.observed.log_head = None;
                    self.editor.notify(Notice::Text("FAULT LOG CLEARED"));
                }
                Err(_) => self.editor.notify(Notice::Text("EEPROM ERROR")),
            },
            JobDone::BootWritten { result, .. } => {
                if result.is_err() {
                    self.editor.notify(Notice::Text("EEPROM ERROR"));
                }
            }
            JobDone::Written { slot, result } => self.program_written(slot, result, now),
        }
    }

    /// The board's 1 ms pass, with the pins as sampled (raw). In this order: debounce the
    /// inputs and keys (a level counts after [`INPUT_DEBOUNCE_SAMPLES`] /
    /// [`KEY_DEBOUNCE_SAMPLES`] equal samples), hand the pressed keys to the editor, run
    /// the scan when due (every scan period, see [`PlcApp::set_scan_period_us`]), move the
    /// storage queue on by one EEPROM page, and redraw `screen` every [`RENDER_TICKS`],
    /// after a key, or when the [`Alerts`] change.
    ///
    /// A board that falls behind calls this once per pass, not once per missed
    /// millisecond: debouncing then takes longer, never shorter.
    pub fn tick_1ms(&mut self, now: Micros, raw: RawIo, screen: &mut Screen) -> Tick {
        let digital = self.inputs.update(u32::from(raw.digital)) as u16;
        let mut pressed: heapless::Vec<Key, 16> = heapless::Vec::new();
        let mut keys_down = 0u16;
        self.keys.update(raw.keys, &mut |e| {
            if e.down {
                if let Some(i) = Key::ALL.iter().position(|k| *k == e.key) {
                    keys_down |= 1 << i;
                }
                // At most 16 keys: always fits.
                let _ = pressed.push(e.key);
            }
        });
        for k in &pressed {
            self.on_key(*k, now);
        }
        self.expire_remote(now);
        let scan_ticks = u32::try_from(self.scan_period_us.div_ceil(1000).max(1)).unwrap_or(1);
        let scanned = self.ticks.is_multiple_of(scan_ticks);
        let mut warning = None;
        if scanned {
            let out = self.scan_once(digital, raw.analog, now);
            warning = out.warning;
        }
        let step = self.storage_step(now);
        let alerts = self.alerts();
        let redrawn = !pressed.is_empty()
            || self.ticks.is_multiple_of(RENDER_TICKS)
            || self.drawn_alerts != Some(alerts);
        if redrawn {
            self.draw(now, screen);
            self.drawn_alerts = Some(alerts);
        }
        self.ticks = self.ticks.wrapping_add(1);
        let reported = core::mem::replace(&mut self.reported_run, self.run);
        Tick {
            outputs: self.out.outputs,
            scanned,
            warning,
            redrawn,
            keys_down,
            storage: step.done,
            storage_used_bus: step.used_bus,
            run_change: (reported != self.run).then_some((reported, self.run)),
        }
    }

    /// The request times of the `S:` items, and the signature check: once the drive
    /// reports RUN (it loaded the section before), its signature must be the program's,
    /// or RUN stops with `SIG MISMATCH` (safety.md 8).
    fn track_safety(&mut self, now: Micros) {
        let Some(s) = self.drive_status() else {
            self.safety.seen = 0;
            return;
        };
        let rose = s.sf_requested & !self.safety.seen;
        self.safety.seen = s.sf_requested;
        for (n, t) in self.safety.since_ms.iter_mut().enumerate() {
            if rose & (1 << n) != 0 {
                *t = now.millis().0;
            }
        }
        if self.run == RunState::Running && s.state == DriveState::Run {
            if let Some(expected) = self.safety.expected.take() {
                if s.sf_signature != expected {
                    self.stop();
                    self.editor.notify(Notice::Text("SIG MISMATCH"));
                }
            }
        }
    }

    /// Draw the current page (listing, run screen or fault log) for the LCD.
    fn draw(&self, now: Micros, screen: &mut Screen) {
        let warning = self.warning.map(|w| match w {
            vm::Warning::Div0 { line } => Warning {
                text: "DIV0",
                line: Some(line),
            },
        });
        let drive = self.drive_status();
        let drive_text = drive.and_then(|s| s.warning).map(|w| {
            let mut t = Text::new();
            t.drive_warning(w);
            t
        });
        let drive_warning = drive_text.as_ref().map(|t| Warning {
            text: t.as_str(),
            line: None,
        });
        let run = RunView {
            running: self.run == RunState::Running,
            link_up: self.link.is_up(),
            drive_state: drive.map_or(DriveState::Boot, |s| s.state),
            freq_dhz: drive.map_or(0, |s| s.freq_dhz),
            reverse: drive.is_some_and(|s| s.reverse),
            fault: drive
                .and_then(|s| s.fault)
                .map(FaultCode::code)
                .or(self.newest_fault.filter(|_| drive.is_none())),
            lcd: self.out.lcd,
            warning,
            drive_warning,
            safety: drive.map(|s| SafetyView {
                requested: s.sf_requested,
                status: s.sf_status,
                since_ms: self.safety.since_ms,
            }),
            remote: self.remote_service(now),
        };
        let view = View {
            program: &self.program,
            run,
            fault_log: &self.fault_log,
            now_ms: now.millis().0,
        };
        self.editor.render(&view, screen);
    }
}

/// The steps of [`PlcApp::tick_1ms`] one by one, for test rigs that step the
/// application outside the board's pass (unit tests only; never in the image).
#[cfg(test)]
impl<E: Eeprom> PlcApp<E> {
    /// One scan now (see [`PlcApp::tick_1ms`] for the board's cadence).
    #[must_use = "the outputs must be written to the pins"]
    pub fn scan(&mut self, digital: u16, analog: [u16; 4], now: Micros) -> ScanOutputs {
        self.scan_once(digital, analog, now)
    }

    /// A debounced key now.
    pub fn key(&mut self, key: Key, now: Micros) {
        self.on_key(key, now)
    }

    /// One step of the storage queue now.
    pub fn step_storage(&mut self, now: Micros) -> crate::storage::JobStep {
        self.storage_step(now)
    }

    /// The current page, drawn now.
    pub fn render(&self, now: Micros, screen: &mut Screen) {
        self.draw(now, screen)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use shared_protocol::program::assemble;

    #[test]
    fn finds_the_q_the_drive_section_writes() {
        let motor = include_str!("../../shared-protocol/programs/motor.plc");
        let p = assemble(motor).unwrap();
        // The motor program's drive section writes only Q01 (the PI output); the PLC
        // writes Q00 and Q02.
        assert_eq!(drive_written_q(&p), 1 << 1);
        let p = assemble("000 LD K00 0001\n001 WR Q63\n002 WR PW1\n").unwrap();
        assert_eq!(drive_written_q(&p), 1 << 63);
    }
}
