//! The PLC MCU on the host: the EEPROM with the program, the [`PlcVm`], the link endpoint
//! [`PlcLink`] and the run screen, joined as the firmware joins them.
//!
//! Power-up loads the slot last run from the EEPROM; when the EEPROM says RUN at
//! power-up, RUN starts: verify, download the drive section, wait for the drive to accept
//! it, RUN both.

use firmware_plc::editor::{Editor, Key, Notice, Page, Request, RunView, View, Warning};
use firmware_plc::link::{PlcEvent, PlcLink};
use firmware_plc::storage::{FaultEntry, MemEeprom, OtherCopy, Storage, FAULT_LOG_ENTRIES};
use firmware_plc::vm::{DriveView, PlcVm, ScanInputs, ScanOutputs};
use shared_protocol::link::message::{DownloadResult, DriveState};
use shared_protocol::link::LinkConfig;
use shared_protocol::program::{verify, Program};
use shared_protocol::units::{CentiAmps, Decihertz, Decivolts, Micros, Millis};

use super::{Lcd, PlcMcu, PlcPins};

/// Where RUN stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RunState {
    Stopped,
    /// RUN asked for: waiting for the link to download the drive section.
    Starting,
    /// Drive section sent, waiting for the drive's answer.
    Downloading,
    Running,
}

/// The PLC board.
pub struct PlcBoard {
    storage: Storage<MemEeprom>,
    program: Program,
    vm: PlcVm,
    link: PlcLink,
    run: RunState,
    out: ScanOutputs,
    lcd: Lcd,
    editor: Editor,
    /// Newest drive fault reported over the link.
    last_fault: Option<u8>,
    /// Slot the running program came from (for the boot record).
    run_slot: Option<u8>,
    /// A `DIV0` warning of the last scan: the line.
    div0_line: Option<u16>,
    now_ms: u32,
}

impl PlcBoard {
    /// Power-up with `eeprom` in the socket.
    pub fn new(eeprom: MemEeprom, link_cfg: LinkConfig) -> Self {
        let mut storage = Storage::new(eeprom);
        let mut program = Program::default();
        let mut editor = Editor::new(20, 4);
        let mut run_slot = None;
        let run_at_power_up = match storage.power_up(&mut program) {
            Ok(p) => {
                match p.loaded {
                    Some(Ok(report)) => {
                        run_slot = Some(report.slot);
                        // A clean load needs no message (it would hide the fault line
                        // until the first key); a damaged copy must be reported.
                        if matches!(report.other, OtherCopy::Bad(_)) {
                            editor.notify(Notice::Loaded(report));
                        }
                    }
                    Some(Err(error)) => editor.notify(Notice::LoadFailed { slot: 0, error }),
                    None => {}
                }
                p.run
            }
            Err(_) => {
                editor.notify(Notice::Text("EEPROM ERROR"));
                false
            }
        };
        let mut b = PlcBoard {
            storage,
            program,
            vm: PlcVm::new(),
            link: PlcLink::new(link_cfg),
            run: RunState::Stopped,
            out: ScanOutputs::default(),
            lcd: Lcd::default(),
            editor,
            last_fault: None,
            run_slot,
            div0_line: None,
            now_ms: 0,
        };
        if run_at_power_up {
            b.editor.show_page(Page::Run);
            b.start_run();
        }
        b.render();
        b
    }

    pub fn program(&self) -> &Program {
        &self.program
    }

    pub fn link(&self) -> &PlcLink {
        &self.link
    }

    pub fn run_state(&self) -> RunState {
        self.run
    }

    pub fn storage(&mut self) -> &mut Storage<MemEeprom> {
        &mut self.storage
    }

    pub fn editor(&self) -> &Editor {
        &self.editor
    }

    /// RUN: verify first; nothing starts with an invalid program.
    pub fn start_run(&mut self) {
        if let Err(e) = verify(&self.program) {
            self.editor.notify(Notice::RunRefused {
                line: Some(e.line),
                reason: e.kind.short(),
            });
            self.run = RunState::Stopped;
            return;
        }
        self.div0_line = None;
        self.run = RunState::Starting;
    }

    fn stop_run(&mut self) {
        if self.run == RunState::Running {
            let _ = self.link.stop();
        }
        self.run = RunState::Stopped;
    }

    fn handle(&mut self, r: Request) {
        match r {
            Request::Save(slot) => {
                let n = match self.storage.save(slot, &self.program) {
                    Ok(_) => Notice::Saved { slot },
                    Err(error) => Notice::SaveFailed { slot, error },
                };
                self.editor.notify(n);
            }
            Request::Load(slot) => {
                let n = match self.storage.load(slot, &mut self.program) {
                    Ok(report) => Notice::Loaded(report),
                    Err(error) => Notice::LoadFailed { slot, error },
                };
                self.editor.notify(n);
            }
            Request::Run { slot } => {
                self.run_slot = slot;
                let _ = self.storage.set_run_state(slot, true);
                self.start_run();
            }
            Request::Stop => {
                let _ = self.storage.set_run_state(None, false);
                self.stop_run();
            }
            Request::New => self.run_slot = None,
            Request::ClearFaultLog => {
                let _ = self.storage.clear_fault_log();
            }
        }
    }

    fn drive_view(&self) -> DriveView {
        match self.link.last_status() {
            Some((s, _)) => DriveView {
                com: s.com,
                frq: Decihertz(s.freq_dhz),
                udc: Decivolts(s.udc_dv),
                imx: CentiAmps(s.imax_ca),
                flt: s.fault,
                dir_reverse: s.reverse,
                ready: s.state == DriveState::Run && s.fault == 0,
                fault_latched: s.fault != 0,
            },
            None => DriveView::default(),
        }
    }

    fn service_link(&mut self, now: Micros) {
        while let Some(e) = self.link.poll_event() {
            match e {
                PlcEvent::Connected => {}
                PlcEvent::LinkLost { .. } => {
                    if matches!(self.run, RunState::Downloading) {
                        self.run = RunState::Starting;
                    }
                }
                PlcEvent::VersionMismatch { .. } => {
                    self.editor.notify(Notice::Text("DRIVE VERSION?"));
                }
                PlcEvent::Download(DownloadResult::Accepted) => {
                    if self.run == RunState::Downloading && self.link.run().is_ok() {
                        self.vm.start(Millis((now.0 / 1000) as u32));
                        self.run = RunState::Running;
                    }
                }
                PlcEvent::Download(DownloadResult::Rejected { line, reason }) => {
                    self.editor.notify(Notice::RunRefused {
                        line: Some(line),
                        reason: reason.short(),
                    });
                    self.run = RunState::Stopped;
                }
                PlcEvent::DriveFault {
                    code,
                    drive_time_ms,
                } => {
                    self.last_fault = Some(code);
                    let _ = self.storage.log_fault(code, u64::from(drive_time_ms));
                }
            }
        }
        if self.run == RunState::Starting
            && self.link.is_up()
            && self
                .link
                .start_download(&self.program.drive_section())
                .is_ok()
        {
            self.run = RunState::Downloading;
        }
    }

    /// Draws the LCD with the firmware's editor (run screen, listing, fault log).
    fn render(&mut self) {
        let mut log: heapless::Vec<FaultEntry, FAULT_LOG_ENTRIES> = heapless::Vec::new();
        let _ = self.storage.fault_log(&mut log);
        let status = self.link.last_status().filter(|_| self.link.is_up());
        let div0 = self.div0_line.map(|line| Warning {
            text: "DIV0",
            line: Some(line),
        });
        let view = View {
            program: &self.program,
            run: RunView {
                running: self.run == RunState::Running,
                link_up: self.link.is_up(),
                drive_state: status.map_or(DriveState::Boot, |(s, _)| s.state),
                freq_dhz: status.map_or(0, |(s, _)| s.freq_dhz),
                reverse: status.is_some_and(|(s, _)| s.reverse),
                fault: self.last_fault,
                lcd: self.out.lcd,
                warning: div0,
            },
            fault_log: &log,
            now_ms: self.now_ms,
        };
        let mut screen = self.editor.screen();
        self.editor.render(&view, &mut screen);
        for r in 0..screen.rows() {
            self.lcd.set_row(usize::from(r), screen.row(r));
        }
    }
}

impl PlcMcu for PlcBoard {
    fn tick_1ms(&mut self, now: Micros) {
        self.now_ms = (now.0 / 1000) as u32;
        self.link.tick(now);
        self.service_link(now);
        if now.0 % 100_000 < 1000 {
            // The LCD is refreshed every 100 ms, as on the board.
            self.render();
        }
    }

    fn scan(&mut self, pins: &PlcPins, now: Micros) {
        if self.run != RunState::Running {
            return;
        }
        let inputs = ScanInputs {
            digital: pins.digital,
            analog: pins.analog,
            drive: self.drive_view(),
        };
        let mut out = ScanOutputs::default();
        self.vm.scan(
            &self.program,
            &inputs,
            Millis((now.0 / 1000) as u32),
            &mut out,
        );
        for n in out.dirty_q() {
            let _ = self.link.write_q(n, self.vm.q(n));
        }
        if let Some(rev) = out.rev_request {
            let _ = self.link.set_direction(rev);
        }
        if out.ack_request {
            let _ = self.link.ack_fault();
        }
        if let Some(firmware_plc::vm::Warning::Div0 { line }) = out.warning {
            self.div0_line = Some(line);
        }
        self.out = out;
    }

    fn key(&mut self, key: char, down: bool, _now: Micros) {
        if !down {
            return;
        }
        let Some(k) = Key::from_char(key) else {
            return;
        };
        let running = self.run != RunState::Stopped;
        if let Some(r) = self.editor.key(k, &mut self.program, running) {
            self.handle(r);
        }
        self.render();
    }

    fn uart_rx(&mut self, bytes: &[u8], now: Micros) {
        self.link.receive(bytes, now);
        self.service_link(now);
    }

    fn uart_tx(&mut self, now: Micros, out: &mut [u8]) -> usize {
        let n = self.link.poll_transmit(now, out);
        self.service_link(now);
        n
    }

    fn outputs(&self) -> u8 {
        self.out.outputs
    }

    fn q(&self, n: u8) -> i16 {
        self.vm.q(n)
    }

    fn lcd_fields(&self) -> [Option<i16>; 4] {
        self.out.lcd
    }

    fn lcd(&self) -> &Lcd {
        &self.lcd
    }

    fn running(&self) -> bool {
        self.run == RunState::Running
    }
}
