//! The PLC MCU on the host: the firmware's [`PlcApp`] (program, VM, link endpoint, keypad
//! editor, EEPROM storage) with a [`MemEeprom`] in the socket and its service endpoint,
//! driven as the board's tasks drive them and through the same core functions:
//!
//! * the application task: every millisecond [`AppPass::run`] over the simulated pins
//!   ([`PlcPins`], the key matrix, the output latch) and the simulated HD44780
//!   ([`SimLcd`]): the raw pins sampled, the tick, the outputs, the service's share, one
//!   LCD cell;
//! * the link task: the link's [`Pump`] over the application ([`SimPlc::link_pass`]);
//! * the service task: a second [`Pump`] over [`OnApp`] ([`SimPlc::service_pass`]), woken
//!   as the board's is: by bytes, by its deadline, or by the application pass.

use firmware_plc::app::{BuildInfo, PlcApp, RawIo, RunState, RunStatus, Tick};
use firmware_plc::editor::{Editor, Key, Screen};
use firmware_plc::service::endpoint::OnApp;
use firmware_plc::service::Service;
use firmware_plc::storage::MemEeprom;
use firmware_plc::task::{AppPass, IoPort};
use shared_protocol::link::pump::{LinkEndpoint, Pass, Pump, MAX_IDLE_US};
use shared_protocol::link::LinkConfig;
use shared_protocol::program::Program;
use shared_protocol::units::Micros;

use super::{PlcPins, SimLcd};

/// The LCD fitted to the simulated PLC.
const LCD_COLS: u8 = 20;
const LCD_ROWS: u8 = 4;

/// The simulated PLC board.
pub struct SimPlc {
    app: PlcApp<MemEeprom>,
    /// The service endpoint (the board keeps it in its own static, beside the app).
    svc: Service,
    /// The application task's state (screen, LCD sync, LCD retry).
    pass: AppPass,
    lcd: SimLcd,
    io: SimIo,
    /// The board's link pump (its link task's state).
    pump: Pump,
    /// The service task's pump.
    svc_pump: Pump,
    /// The last application pass asked for a service pass.
    service_due: bool,
    /// What the last tick did.
    tick: Option<Tick>,
}

/// The pins, the key matrix and the output latch as the application task's port.
#[derive(Debug, Clone, Copy, Default)]
struct SimIo {
    pins: PlcPins,
    /// Keys held down now (bit as in [`RawIo::keys`]).
    keys: u16,
    outputs: u8,
}

impl IoPort for SimIo {
    fn sample(&mut self) -> RawIo {
        RawIo {
            digital: self.pins.digital,
            analog: self.pins.analog,
            keys: self.keys,
        }
    }

    fn write_outputs(&mut self, outputs: u8) {
        self.outputs = outputs;
    }
}

/// The simulated PLC's identity when no service line gave it another.
const DEFAULT_BUILD: BuildInfo = BuildInfo {
    firmware: env!("CARGO_PKG_VERSION"),
    git: "sim",
    uid: *b"\0\0\0\0\0\0\0\0HSIM",
};

impl SimPlc {
    /// Power-up at `now` with `eeprom` in the socket (20x4 LCD, which answers).
    pub fn new(eeprom: MemEeprom, link_cfg: LinkConfig, now: Micros) -> Self {
        SimPlc {
            app: PlcApp::new(eeprom, link_cfg, LCD_COLS, LCD_ROWS, now),
            svc: Service::new(DEFAULT_BUILD),
            pass: AppPass::new(LCD_COLS, LCD_ROWS, true, now),
            lcd: SimLcd::default(),
            io: SimIo::default(),
            pump: Pump::new(MAX_IDLE_US),
            svc_pump: Pump::new(MAX_IDLE_US),
            service_due: false,
            tick: None,
        }
    }

    pub fn app(&self) -> &PlcApp<MemEeprom> {
        &self.app
    }

    pub fn app_mut(&mut self) -> &mut PlcApp<MemEeprom> {
        &mut self.app
    }

    pub fn editor(&self) -> &Editor {
        self.app.editor()
    }

    pub fn program(&self) -> &Program {
        self.app.program()
    }

    pub fn run_state(&self) -> RunState {
        self.app.run_state()
    }

    pub fn run_status(&self) -> RunStatus {
        self.app.status()
    }

    /// The screen as the application last drew it, with its cursor (the LCD comes to
    /// show it one cell per pass: [`SimPlc::lcd`]).
    pub fn screen(&self) -> &Screen {
        self.pass.screen()
    }

    /// The service endpoint (figures; a service line gives it its identity).
    pub fn service(&mut self) -> &mut Service {
        &mut self.svc
    }

    /// The board's identity and service version, as a service line plugs in (the
    /// endpoint keeps what it has counted since power-up).
    pub fn set_service_identity(&mut self, build: BuildInfo, version: u16) {
        self.svc.set_build(build);
        self.svc.port().set_version(version);
    }
}

impl SimPlc {
    // The calls the simulator makes, as the board's interrupts and tasks make them.

    /// The application task's 1 ms pass with the pins as they are at `now`.
    pub fn tick_1ms(&mut self, pins: &PlcPins, now: Micros) {
        self.io.pins = *pins;
        let report = self.pass.run(
            &mut self.app,
            &mut self.svc,
            &mut self.io,
            &mut self.lcd,
            now,
        );
        self.service_due |= report.service_due;
        self.tick = Some(report.tick);
    }

    /// What the last tick did.
    pub fn last_tick(&self) -> Option<Tick> {
        self.tick
    }

    /// A keypad key went down or up.
    pub fn key(&mut self, key: char, down: bool, _now: Micros) {
        let Some(k) = Key::from_char(key) else {
            return;
        };
        let Some(bit) = Key::ALL.iter().position(|x| *x == k) else {
            return;
        };
        if down {
            self.io.keys |= 1 << bit;
        } else {
            self.io.keys &= !(1 << bit);
        }
    }

    /// See [`super::SimDrive::link_pass`].
    pub fn link_pass(&mut self, rx: &[u8], tx_room: usize, now: Micros) -> Pass {
        self.pump.pass(&mut self.app, rx, tx_room, now)
    }

    pub fn link_tx(&self) -> &[u8] {
        self.pump.tx()
    }

    pub fn link_timeout(&self) -> Option<Micros> {
        self.app.poll_timeout()
    }

    /// Whether an application pass since the last service pass asked for one (the
    /// board's application task kicks the service task then); cleared.
    pub fn take_service_due(&mut self) -> bool {
        core::mem::take(&mut self.service_due)
    }

    /// One pass of the service task's pump: the received bytes in, a frame out when the
    /// line has room for it.
    pub fn service_pass(&mut self, rx: &[u8], tx_room: usize, now: Micros) -> Pass {
        self.service_due = false;
        let mut ep = OnApp::new(&mut self.svc, &mut self.app);
        self.svc_pump.pass(&mut ep, rx, tx_room, now)
    }

    /// The frame the last service pass put out.
    pub fn service_tx(&self) -> &[u8] {
        self.svc_pump.tx()
    }

    /// Output pins O00..O07, bit n = On.
    pub fn outputs(&self) -> u8 {
        self.io.outputs
    }

    /// The PLC's copy of Qn.
    pub fn q(&self, n: u8) -> i16 {
        self.app.q(n)
    }

    /// The run screen's 4 value fields.
    pub fn lcd_fields(&self) -> [Option<i16>; 4] {
        self.app.status().lcd
    }

    /// The LCD as the user sees it.
    pub fn lcd(&self) -> &SimLcd {
        &self.lcd
    }

    /// The run-time warnings the PLC shows on its status line (default: none known).
    pub fn warnings(&self) -> super::Warnings {
        let s = self.app.status();
        super::Warnings {
            plc: s.warning,
            drive: s.drive_warning,
        }
    }

    /// The user program is running.
    pub fn running(&self) -> bool {
        self.app.run_state() == RunState::Running
    }
}
