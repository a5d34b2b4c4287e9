//! The PLC MCU on the host: the firmware's [`PlcApp`] (program, VM, link endpoint, keypad
//! editor, EEPROM storage) with a [`MemEeprom`] in the socket, called as the board's
//! tasks call it: every millisecond [`PlcApp::tick_1ms`] with the **raw** pin levels and
//! key matrix (debouncing, scan cadence, one EEPROM page of storage work and the redraw
//! cadence are the core's, as on the board), UART bytes in and out as the link task does.

use firmware_plc::app::{PlcApp, RawIo, RunState, RunStatus, Tick};
use firmware_plc::editor::{Editor, Key, Screen};
use firmware_plc::storage::MemEeprom;
use shared_protocol::link::pump::{LinkEndpoint, Pass, Pump, MAX_IDLE_US};
use shared_protocol::link::LinkConfig;
use shared_protocol::program::Program;
use shared_protocol::units::Micros;

use super::{Lcd, PlcPins};

/// The PLC board.
pub struct PlcBoard {
    app: PlcApp<MemEeprom>,
    screen: Screen,
    lcd: Lcd,
    outputs: u8,
    /// The board's link pump (its link task's state).
    pump: Pump,
    /// The pins as the last [`PlcBoard::scan`] call gave them (raw levels).
    pins: PlcPins,
    /// Keys held down now (bit as in [`RawIo::keys`]).
    keys: u16,
    /// What the last tick did, until the service port takes it (`crate::service`).
    tick: Option<Tick>,
}

impl PlcBoard {
    /// Power-up at `now` with `eeprom` in the socket (20x4 LCD).
    pub fn new(eeprom: MemEeprom, link_cfg: LinkConfig, now: Micros) -> Self {
        let app = PlcApp::new(eeprom, link_cfg, 20, 4, now);
        let mut b = PlcBoard {
            screen: Screen::new(20, 4),
            app,
            lcd: Lcd::default(),
            outputs: 0,
            pump: Pump::new(MAX_IDLE_US),
            pins: PlcPins::default(),
            keys: 0,
            tick: None,
        };
        b.app.render(now, &mut b.screen);
        b.show();
        b
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

    /// The LCD with its cursor, as the HD44780 shows it.
    pub fn screen(&self) -> &Screen {
        &self.screen
    }

    fn show(&mut self) {
        for r in 0..self.screen.rows() {
            self.lcd.set_row(usize::from(r), self.screen.row(r));
        }
    }
}

impl PlcBoard {
    // The calls the simulator makes, as the board's interrupts and tasks make them.
    /// The 1 ms system tick (link timers, keypad debouncing, LCD refresh).
    pub fn tick_1ms(&mut self, now: Micros) {
        self.app.tick(now);
        let raw = RawIo {
            digital: self.pins.digital,
            analog: self.pins.analog,
            keys: self.keys,
        };
        let tick = self.app.tick_1ms(now, raw, &mut self.screen);
        self.outputs = tick.outputs;
        self.tick = Some(tick);
        if tick.redrawn {
            self.show();
        }
    }

    /// What the last tick did, once (the service port's samples follow scans).
    pub fn take_tick(&mut self) -> Option<Tick> {
        self.tick.take()
    }

    /// One PLC scan with the pins as they are now.
    pub fn scan(&mut self, pins: &PlcPins, _now: Micros) {
        // Sampled (raw) by the next tick, as the board samples its pins.
        self.pins = *pins;
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
            self.keys |= 1 << bit;
        } else {
            self.keys &= !(1 << bit);
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

    /// Output pins O00..O07, bit n = On.
    pub fn outputs(&self) -> u8 {
        self.outputs
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
    pub fn lcd(&self) -> &Lcd {
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
