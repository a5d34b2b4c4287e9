//! [`PlcApp`]: the PLC MCU's application: the program, the VM, the link to the drive, the
//! keypad editor and the EEPROM storage, joined. The board layer (and hil-sim) calls it;
//! it owns no hardware and no clock (time is an argument everywhere).
//!
//! | when | call |
//! | --- | --- |
//! | power-up | [`PlcApp::new`], or [`PlcApp::new_cold`] + [`PlcApp::power_up`] in place (loads the slot last run; starts RUN when it was running) |
//! | each scan (inputs sampled at its start) | [`PlcApp::scan`] → output image |
//! | UART bytes received | [`PlcApp::on_rx`] |
//! | UART transmitter free, and at least every 1 ms | [`PlcApp::poll_tx`] |
//! | a key pressed | [`PlcApp::key`] |
//! | LCD refresh (e.g. every 100 ms) | [`PlcApp::render`] |
//!
//! RUN (key `A`, [`PlcApp::run`], or power-up): verify the whole program (an error shows
//! its line and nothing starts), wait for the link, download the drive section, wait for
//! the drive's acceptance, then send RUN to the drive and start the VM in the same call.
//! A reject shows the drive's line and reason. STOP: the VM stops, the outputs go off and
//! the drive is told STOP (PWM off).
//!
//! Faults: every fault the drive reports is logged in the EEPROM (newest 32, with the
//! power-cycle count and the time since power-up) and shown on the run screen with its
//! text. Nothing restarts by itself: after a trip (including `LINK` after a cut link) the
//! drive stays in FAULT until an `ACK` (program instruction) and a new RUN from the user.
//! A lost link does not stop the PLC's own scan (its outputs may matter on their own);
//! the run screen shows the link state.

use shared_protocol::link::plc::{CommandError, PlcEvent, PlcLink, PlcLinkState};
use shared_protocol::link::Q_COUNT;
use shared_protocol::link::{
    fault_text, DownloadResult, DriveState, DriveStatus, DriveWarning, LinkConfig, RejectReason,
};
use shared_protocol::program::{verify, Mnemonic, Operand, Program, Section};
use shared_protocol::units::{CentiAmps, Decihertz, Decivolts, Micros, Volts};

use crate::editor::{Editor, Key, Notice, Page, Request, RunView, Screen, View, Warning};
use crate::storage::{Eeprom, FaultEntry, Storage, FAULT_LOG_ENTRIES};
use crate::vm::{self, DriveView, PlcVm, ScanInputs, ScanOutputs};

/// Where RUN stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
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
    pub drive_fault: Option<u8>,
    pub newest_fault: Option<u8>,
    pub warning: Option<vm::Warning>,
    pub drive_warning: Option<DriveWarning>,
}

/// The PLC application.
pub struct PlcApp<E: Eeprom> {
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
    /// Fault reports received and not yet written to the EEPROM log (code, PLC s): the
    /// write takes tens of ms, so the link pump does it after the report's
    /// acknowledgement went out ([`PlcApp::log_faults`]).
    unlogged: heapless::Deque<(u8, u32), UNLOGGED>,
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
}

/// Fault reports waiting for their EEPROM log entry (more in one pass means a storm; the
/// oldest then goes unlogged).
const UNLOGGED: usize = 4;

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
            unlogged: heapless::Deque::new(),
            warning: None,
            fault_log: heapless::Vec::new(),
            q_sent: [None; Q_COUNT],
            drive_writes_q: 0,
            scan_period_us: 1_000,
        }
    }

    /// Power-up: loads the slot last run from the EEPROM and the fault log, and starts RUN
    /// when the boot record says the PLC was running. Call once, after `new_cold`.
    pub fn power_up(&mut self, now: Micros) {
        let mut run_now = false;
        match self.storage.power_up(&mut self.program) {
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

    /// The period at which the board calls [`PlcApp::scan`] (default 1 ms). The link
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

    /// The output image O00-O05 (0 when not running).
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
            drive_fault: drive.map(|d| d.fault),
            newest_fault: self.newest_fault,
            warning: self.warning,
            drive_warning: drive.and_then(|d| d.warning),
        }
    }

    fn drive_status(&self) -> Option<DriveStatus> {
        if !self.link.is_up() {
            return None;
        }
        self.link.last_status().map(|(s, _)| s)
    }

    /// Start RUN (the editor's `A` key does this through [`PlcApp::key`]). `slot` is the
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
        if self.run == RunState::Running {
            // A new RUN while running: stop both first, then start over.
            let _ = self.link.stop();
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
        let _ = self.link.stop();
        self.run = RunState::Stopped;
        self.out = ScanOutputs::default();
        if self.storage.set_run_state(self.run_slot, false).is_err() {
            self.editor.notify(Notice::Text("EEPROM ERROR"));
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
        // Compiles the PLC section now (issue 21), not in the first scan.
        self.vm.start_program(&self.program, now.millis());
        self.link.forget_q();
        self.q_sent = [None; Q_COUNT];
        self.drive_writes_q = drive_written_q(&self.program);
        self.run = RunState::Running;
        if self.storage.set_run_state(self.run_slot, true).is_err() {
            self.editor.notify(Notice::Text("EEPROM ERROR"));
        }
    }

    /// One scan with the inputs sampled at its start; returns the outputs to write.
    /// Does nothing (outputs off) unless RUN is on.
    pub fn scan(&mut self, digital: u8, analog: [u16; 4], now: Micros) -> ScanOutputs {
        if self.run != RunState::Running {
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
            // Refused only when 96 commands wait: the link keeps the newest value for the
            // next reconnection anyway.
            let _ = self.link.write_q(n, value);
            *sent = Some(value);
        }
        if let Some(rev) = out.rev_request {
            let _ = self.link.set_direction(rev);
        }
        if out.ack_request {
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
        out
    }

    fn drive_view(&self) -> DriveView {
        match self.drive_status() {
            Some(s) => DriveView {
                com: s.com,
                frq: Decihertz(s.freq_dhz),
                udc: Decivolts(s.udc_dv),
                imx: CentiAmps(s.imax_ca),
                flt: s.fault,
                dir_reverse: s.reverse,
                ready: s.state == DriveState::Run && s.fault == 0,
                fault_latched: s.fault != 0,
                ihw: CentiAmps(s.oc_hw_ca),
                uhw: Volts(s.ov_hw_v),
            },
            None => DriveView::default(),
        }
    }

    /// Bytes from the UART.
    pub fn on_rx(&mut self, bytes: &[u8], now: Micros) {
        self.link_rx(bytes, now);
        self.log_faults();
    }

    /// [`Self::on_rx`] without the fault log's EEPROM writes ([`Self::log_faults`]): for
    /// the link pump (`crate::link`).
    pub(crate) fn link_rx(&mut self, bytes: &[u8], now: Micros) {
        self.link.receive(bytes, now);
        self.service(now);
    }

    /// [`Self::poll_tx`] without the fault log's EEPROM writes: for the link pump.
    pub(crate) fn link_tx(&mut self, now: Micros, out: &mut [u8]) -> usize {
        self.service(now);
        let n = self.link.poll_transmit(now, out);
        self.service(now);
        n
    }

    /// Writes the fault reports received since the last call to the EEPROM log (tens of
    /// ms on the board: I2C and page write cycles). The link pump calls it after the
    /// pass's frame went out, so that the reports' acknowledgement never waits for it:
    /// delayed beyond the drive's link timeout, the drive would deliver the reports again
    /// in its next session, and they would be logged again, forever.
    pub fn log_faults(&mut self) {
        if self.unlogged.is_empty() {
            return;
        }
        let mut failed = false;
        while let Some((code, s)) = self.unlogged.pop_front() {
            failed |= self.storage.log_fault(code, u64::from(s) * 1000).is_err();
        }
        if failed {
            self.editor.notify(Notice::Text("FAULT LOG ERROR"));
        }
        self.reload_fault_log();
    }

    /// The next frame for the UART (0 = nothing now); `out` must hold
    /// [`shared_protocol::link::MAX_WIRE_FRAME`] bytes. Also runs the link's timers and
    /// the RUN sequence: call it at least every millisecond.
    pub fn poll_tx(&mut self, now: Micros, out: &mut [u8]) -> usize {
        let n = self.link_tx(now, out);
        self.log_faults();
        n
    }

    /// The UART reported a line error: the link drops the frame being received and
    /// counts it (`LinkStats::line_errors`).
    pub fn on_line_error(&mut self) {
        self.link.line_error();
    }

    /// Link timers and the RUN sequence without transmitting (`poll_tx` does this too):
    /// for a board whose transmit path is driven only by UART interrupts.
    pub fn tick(&mut self, now: Micros) {
        self.link.tick(now);
        self.service(now);
        self.log_faults();
    }

    fn service(&mut self, now: Micros) {
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
                        reason: reason.short(),
                    });
                }
                PlcEvent::DriveFault { code, .. } => {
                    self.newest_fault = Some(code);
                    // The PLC's clock, not the drive's: the log's timestamps must be
                    // comparable across drive reboots. Written by `log_faults`.
                    if self.unlogged.is_full() {
                        self.unlogged.pop_front();
                    }
                    let s = u32::try_from(now.0 / 1_000_000).unwrap_or(u32::MAX);
                    let _ = self.unlogged.push_back((code, s));
                }
            }
        }
        self.advance_run(now);
    }

    fn reload_fault_log(&mut self) {
        let mut log = heapless::Vec::new();
        if self.storage.fault_log(&mut log).is_ok() {
            self.fault_log = log;
        }
    }

    /// A key of the keypad.
    pub fn key(&mut self, key: Key, now: Micros) {
        let running = self.run != RunState::Stopped;
        let Some(req) = self.editor.key(key, &mut self.program, running) else {
            return;
        };
        match req {
            Request::Save(slot) => {
                let notice = match self.storage.save(slot, &self.program) {
                    Ok(_) => Notice::Saved { slot },
                    Err(error) => Notice::SaveFailed { slot, error },
                };
                self.editor.notify(notice);
            }
            Request::Load(slot) => {
                let notice = match self.storage.load(slot, &mut self.program) {
                    Ok(r) => Notice::Loaded(r),
                    Err(error) => Notice::LoadFailed { slot, error },
                };
                self.editor.notify(notice);
            }
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
                match self.storage.clear_fault_log() {
                    Ok(()) => self.editor.notify(Notice::Text("FAULT LOG CLEARED")),
                    Err(_) => self.editor.notify(Notice::Text("EEPROM ERROR")),
                }
                self.newest_fault = None;
                self.reload_fault_log();
            }
        }
    }

    /// Draw the current page (listing, run screen or fault log) for the LCD.
    pub fn render(&self, now: Micros, screen: &mut Screen) {
        let warning = self.warning.map(|w| match w {
            vm::Warning::Div0 { line } => Warning {
                text: "DIV0",
                line: Some(line),
            },
        });
        let drive = self.drive_status();
        let drive_text = drive.and_then(|s| s.warning).map(|w| w.short());
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
                .map(|s| s.fault)
                .filter(|&f| f != 0)
                .or(self.newest_fault.filter(|_| drive.is_none())),
            lcd: self.out.lcd,
            warning,
            drive_warning,
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
