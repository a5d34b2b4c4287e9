//! The PLC MCU on the host: the EEPROM with the program, the [`PlcVm`], the link endpoint
//! [`PlcLink`] and the run screen, joined as the firmware joins them.
//!
//! Power-up loads the slot last run from the EEPROM; when the EEPROM says RUN at
//! power-up, RUN starts: verify, download the drive section, wait for the drive to accept
//! it, RUN both.

use firmware_plc::link::{PlcEvent, PlcLink};
use firmware_plc::storage::{MemEeprom, Storage};
use firmware_plc::vm::{DriveView, PlcVm, ScanInputs, ScanOutputs};
use shared_protocol::link::message::{fault_name, DownloadResult, DriveState};
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
    /// Newest drive fault reported over the link.
    last_fault: Option<u8>,
    /// A message for the status line (verifier error, download reject...).
    message: Option<String>,
}

impl PlcBoard {
    /// Power-up with `eeprom` in the socket.
    pub fn new(eeprom: MemEeprom, link_cfg: LinkConfig) -> Self {
        let mut storage = Storage::new(eeprom);
        let mut program = Program::default();
        let mut message = None;
        let run_at_power_up = match storage.power_up(&mut program) {
            Ok(p) => p.run,
            Err(e) => {
                message = Some(format!("EEPROM {e:?}"));
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
            last_fault: None,
            message,
        };
        if run_at_power_up {
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

    /// RUN: verify first; nothing starts with an invalid program.
    pub fn start_run(&mut self) {
        if let Err(e) = verify(&self.program) {
            self.message = Some(format!("ERR {e}"));
            self.run = RunState::Stopped;
            return;
        }
        self.run = RunState::Starting;
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
                PlcEvent::VersionMismatch { drive_version } => {
                    self.message = Some(format!("DRIVE VERSION {drive_version}"));
                }
                PlcEvent::Download(DownloadResult::Accepted) => {
                    if self.run == RunState::Downloading && self.link.run().is_ok() {
                        self.vm.start(Millis((now.0 / 1000) as u32));
                        self.run = RunState::Running;
                    }
                }
                PlcEvent::Download(DownloadResult::Rejected { line, reason }) => {
                    self.message = Some(format!("DRV {line:03} {}", reason.short()));
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

    /// The run screen (the PLC application's own screen replaces this once it exists).
    fn render(&mut self) {
        let field = |v: Option<i16>| v.map_or(String::new(), |v| v.to_string());
        let f = self.out.lcd;
        self.lcd
            .set_row(0, &format!("{:<10}{:<10}", field(f[0]), field(f[1])));
        self.lcd
            .set_row(1, &format!("{:<10}{:<10}", field(f[2]), field(f[3])));
        let run = match self.run {
            RunState::Stopped => "STOP",
            RunState::Starting | RunState::Downloading => "LOAD",
            RunState::Running => "RUN",
        };
        let link = if self.link.is_up() { "LNK" } else { "---" };
        let (drv, f_dhz) = match self.link.last_status() {
            Some((s, _)) if self.link.is_up() => (s.state.text(), s.freq_dhz),
            _ => ("?", 0),
        };
        self.lcd.set_row(
            2,
            &format!(
                "{run:<4} {link} {drv:<5}{:>3}.{}",
                f_dhz / 10,
                (f_dhz % 10).abs()
            ),
        );
        let status = if let Some(m) = &self.message {
            m.clone()
        } else if let Some(code) = self.last_fault {
            format!("F{code} {}", fault_name(code))
        } else {
            String::new()
        };
        self.lcd.set_row(3, &status);
    }
}

impl PlcMcu for PlcBoard {
    fn tick_1ms(&mut self, now: Micros) {
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
        self.out = out;
    }

    fn key(&mut self, _key: char, _down: bool, _now: Micros) {
        // The keypad editor belongs to the PLC application; without it keys do nothing.
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
