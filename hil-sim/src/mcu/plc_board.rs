//! The PLC MCU on the host: the firmware's [`PlcApp`] (program, VM, link endpoint, keypad
//! editor, EEPROM storage) with a [`MemEeprom`] in the socket, called as the board's
//! tasks call it. The LCD is refreshed every 100 ms, as on the board.

use firmware_plc::app::{Alerts, PlcApp, RunState, RunStatus};
use firmware_plc::editor::{Editor, Key, Screen};
use firmware_plc::storage::MemEeprom;
use shared_protocol::link::pump::{LinkEndpoint, Pass, Pump, MAX_IDLE_US};
use shared_protocol::link::LinkConfig;
use shared_protocol::program::Program;
use shared_protocol::units::Micros;

use super::{Lcd, PlcMcu, PlcPins};

/// LCD refresh period.
pub const LCD_REFRESH_US: u64 = 100_000;

/// The PLC board.
pub struct PlcBoard {
    app: PlcApp<MemEeprom>,
    screen: Screen,
    lcd: Lcd,
    outputs: u8,
    lcd_fields: [Option<i16>; 4],
    last_render_us: Option<u64>,
    /// `PlcApp::alerts()` at the last redraw: a change (link lost, fault, warning)
    /// redraws at once, as the board does, so the LCD shows it within the 100 ms of
    /// link.md instead of waiting for the periodic refresh.
    drawn_alerts: Option<Alerts>,
    /// The board's link pump (its link task's state).
    pump: Pump,
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
            lcd_fields: [None; 4],
            last_render_us: None,
            drawn_alerts: None,
            pump: Pump::new(MAX_IDLE_US),
        };
        b.render(now);
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

    fn render(&mut self, now: Micros) {
        self.app.render(now, &mut self.screen);
        for r in 0..self.screen.rows() {
            self.lcd.set_row(usize::from(r), self.screen.row(r));
        }
        self.last_render_us = Some(now.0);
        self.drawn_alerts = Some(self.app.alerts());
    }
}

impl PlcMcu for PlcBoard {
    fn tick_1ms(&mut self, now: Micros) {
        self.app.tick(now);
        if self
            .last_render_us
            .is_none_or(|t| now.0.saturating_sub(t) >= LCD_REFRESH_US)
            || self.drawn_alerts != Some(self.app.alerts())
        {
            self.render(now);
        }
    }

    fn scan(&mut self, pins: &PlcPins, now: Micros) {
        let out = self.app.scan(pins.digital, pins.analog, now);
        self.outputs = out.outputs;
        self.lcd_fields = out.lcd;
    }

    fn key(&mut self, key: char, down: bool, now: Micros) {
        if !down {
            return;
        }
        if let Some(k) = Key::from_char(key) {
            self.app.key(k, now);
            // The board redraws at once after a key.
            self.render(now);
        }
    }

    fn link_pass(&mut self, rx: &[u8], tx_room: usize, now: Micros) -> Pass {
        self.pump.pass(&mut self.app, rx, tx_room, now)
    }

    fn link_tx(&self) -> &[u8] {
        self.pump.tx()
    }

    fn link_timeout(&self) -> Option<Micros> {
        self.app.poll_timeout()
    }

    fn outputs(&self) -> u8 {
        self.outputs
    }

    fn q(&self, n: u8) -> i16 {
        self.app.q(n)
    }

    fn lcd_fields(&self) -> [Option<i16>; 4] {
        self.lcd_fields
    }

    fn lcd(&self) -> &Lcd {
        &self.lcd
    }

    fn warnings(&self) -> super::Warnings {
        let s = self.app.status();
        super::Warnings {
            plc: s.warning,
            drive: s.drive_warning,
        }
    }

    fn running(&self) -> bool {
        self.app.run_state() == RunState::Running
    }
}
