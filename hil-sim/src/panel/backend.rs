//! What the front panel talks to: the PLC (keypad in, LCD out) and, when there is one,
//! the co-simulated rig (I/O, frequency, speed, faults).

use firmware_plc::editor::{Editor, Key, Notice, Request, RunView, Screen, View};
use firmware_plc::storage::{FaultEntry, MemEeprom, Storage};
use shared_protocol::link::DriveState;
use shared_protocol::program::Program;

/// The rig's state for the side panel.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RigStatus {
    /// Simulated time, s.
    pub t_s: f64,
    /// Whether a plant is simulated at all (false: editor only).
    pub simulated: bool,
    pub plc_running: bool,
    pub drive_state: String,
    pub f_hz: f64,
    pub reverse: bool,
    pub speed_rpm: f64,
    pub u_dc_v: f64,
    pub i_max_a: f64,
    pub fault: u8,
    pub brake: bool,
    /// D00..D07, bit n = Dn.
    pub digital_in: u8,
    /// O00..O05, bit n = On.
    pub digital_out: u8,
    /// A00..A03, 10-bit counts.
    pub analog: [u16; 4],
}

/// The PLC and its rig as the panel drives them.
pub trait Backend {
    /// A keypad key was pressed (and released).
    fn key(&mut self, key: Key);
    /// Let `dt_ms` of simulated time pass.
    fn advance(&mut self, dt_ms: u32);
    /// The LCD as the PLC drives it now.
    fn lcd(&self) -> Screen;
    fn status(&self) -> RigStatus;
    /// Set digital input `n` (0..8).
    fn set_digital(&mut self, n: u8, on: bool);
    /// Set analog input `n` (0..4) to `counts` (0..1023).
    fn set_analog(&mut self, n: u8, counts: u16);
}

/// The editor core with an EEPROM and no plant: for editing, saving and loading, and for
/// trying the keypad when no simulation is wired up. RUN is only pretended (the program
/// is verified, nothing executes).
pub struct EditorBackend {
    editor: Editor,
    program: Program,
    storage: Storage<MemEeprom>,
    log: Vec<FaultEntry>,
    running: bool,
    now_ms: u64,
    digital: u8,
    analog: [u16; 4],
}

impl EditorBackend {
    /// Power-up with `eeprom` in the socket, then `program` (if any) in RAM.
    pub fn new(eeprom: MemEeprom, program: Option<Program>) -> Self {
        let mut storage = Storage::new(eeprom);
        let mut editor = Editor::new(20, 4);
        let mut ram = Program::default();
        let mut running = false;
        match storage.power_up(&mut ram) {
            Ok(up) => {
                if let Some(r) = up.loaded {
                    match r {
                        Ok(report) => editor.notify(Notice::Loaded(report)),
                        Err(error) => editor.notify(Notice::LoadFailed { slot: 0, error }),
                    }
                }
                running = up.run;
            }
            Err(_) => editor.notify(Notice::Text("EEPROM ERROR")),
        }
        if let Some(p) = program {
            ram = p;
            running = false;
            editor.notify(Notice::Text("PROGRAM FROM FILE"));
        }
        let mut log = heapless::Vec::<FaultEntry, 32>::new();
        let _ = storage.fault_log(&mut log);
        EditorBackend {
            editor,
            program: ram,
            storage,
            log: log.to_vec(),
            running,
            now_ms: 0,
            digital: 0,
            analog: [0; 4],
        }
    }

    pub fn program(&self) -> &Program {
        &self.program
    }

    pub fn eeprom(&mut self) -> &mut MemEeprom {
        self.storage.eeprom()
    }

    fn view(&self) -> RunView<'static> {
        RunView {
            running: self.running,
            link_up: false,
            drive_state: DriveState::Boot,
            ..RunView::default()
        }
    }

    fn carry_out(&mut self, r: Request) {
        match r {
            Request::Save(slot) => match self.storage.save(slot, &self.program) {
                Ok(_) => self.editor.notify(Notice::Saved { slot }),
                Err(error) => self.editor.notify(Notice::SaveFailed { slot, error }),
            },
            Request::Load(slot) => match self.storage.load(slot, &mut self.program) {
                Ok(report) => self.editor.notify(Notice::Loaded(report)),
                Err(error) => self.editor.notify(Notice::LoadFailed { slot, error }),
            },
            Request::Run { slot } => {
                self.running = true;
                let _ = self.storage.set_run_state(slot, true);
                self.editor.notify(Notice::Text("RUN (NO SIMULATION)"));
            }
            Request::Stop => {
                self.running = false;
                let _ = self.storage.set_run_state(None, false);
            }
            Request::New => {}
            Request::AckFaults => self.editor.notify(Notice::Text("ACK: NO DRIVE")),
            Request::ClearFaultLog => {
                let _ = self.storage.clear_fault_log();
                self.log.clear();
            }
        }
    }
}

impl Backend for EditorBackend {
    fn key(&mut self, key: Key) {
        if let Some(r) = self.editor.key(key, &mut self.program, self.running) {
            self.carry_out(r);
        }
    }

    fn advance(&mut self, dt_ms: u32) {
        self.now_ms += u64::from(dt_ms);
    }

    fn lcd(&self) -> Screen {
        let mut s = self.editor.screen();
        self.editor.render(
            &View {
                program: &self.program,
                run: self.view(),
                fault_log: &self.log,
                now_ms: self.now_ms as u32,
            },
            &mut s,
        );
        s
    }

    fn status(&self) -> RigStatus {
        RigStatus {
            t_s: self.now_ms as f64 / 1000.0,
            simulated: false,
            plc_running: self.running,
            drive_state: "-".into(),
            digital_in: self.digital,
            analog: self.analog,
            ..RigStatus::default()
        }
    }

    fn set_digital(&mut self, n: u8, on: bool) {
        if n < 8 {
            if on {
                self.digital |= 1 << n;
            } else {
                self.digital &= !(1 << n);
            }
        }
    }

    fn set_analog(&mut self, n: u8, counts: u16) {
        if let Some(a) = self.analog.get_mut(usize::from(n)) {
            *a = counts.min(1023);
        }
    }
}
