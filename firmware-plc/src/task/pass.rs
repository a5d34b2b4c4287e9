//! The application pass: the body of the PLC's 1 ms application task, over an [`IoPort`]
//! (pins, key matrix, output latch) and a [`CharLcd`]. The board's task awaits the
//! pass's deadline and calls [`AppPass::run`]; hil-sim calls it every simulated
//! millisecond with its pin and LCD models; the tests call it with theirs.
//!
//! One pass, in this order: the pins and keys sampled (raw), [`PlcApp::tick_1ms`]
//! (debouncing, scan, one EEPROM page of storage work, redraw), the output image
//! written, whether the link task must pass now, the service's share
//! ([`endpoint::after_scan`]: trend sample, one EEPROM step of a service read), then the
//! LCD: one changed cell ([`LcdSync`]), or, while the LCD is down, its initialisation
//! again every [`LCD_RETRY_US`].

use shared_protocol::link::pump::is_due;
use shared_protocol::units::Micros;

use super::lcd::{CharLcd, LcdSync};
use crate::app::{PlcApp, RawIo, RunState, Tick};
use crate::editor::Screen;
use crate::pace::RetryTimer;
use crate::service::endpoint;
use crate::service::Service;
use crate::storage::Eeprom;

/// A failed LCD is initialised again after this long.
pub const LCD_RETRY_US: u64 = 2_000_000;

/// The PLC's pins as the application task sees them.
pub trait IoPort {
    /// D00..D15, A00..A03 and the key matrix as they are now (raw, not debounced).
    fn sample(&mut self) -> RawIo;
    /// O00..O07 (bit n = On).
    fn write_outputs(&mut self, outputs: u8);
    /// A trip of the field I/O not yet reported (its fault-log code), once per trip; a
    /// port of bare GPIO never trips (the shield profile's does, `crate::field_io`).
    fn take_trip(&mut self) -> Option<u8> {
        None
    }
    /// RUN was started: a latched field I/O trip is cleared and checked again.
    fn rearm(&mut self) {}
}

/// What happened to the LCD in a pass, for the board's log.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LcdEvent<E> {
    /// A write failed: the LCD is down until a retry succeeds.
    Failed(E),
    /// The LCD answered its initialisation again.
    Back,
}

/// What one pass did, for the board to carry out (task wake-ups) and log.
#[must_use]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PassReport<E> {
    /// The application's tick (outputs, scan warning, keys, storage, run change).
    pub tick: Tick,
    /// The link endpoint has something due now: wake the link task.
    pub link_due: bool,
    /// The service endpoint has something due now: wake the service task.
    pub service_due: bool,
    pub lcd: Option<LcdEvent<E>>,
}

/// The application task's own state: the screen the application draws, what the LCD
/// shows, and the LCD's retry timer.
pub struct AppPass {
    screen: Screen,
    lcd: LcdSync,
    lcd_retry: RetryTimer,
}

impl AppPass {
    /// The task at power-up, with a `cols` x `rows` LCD that did (`lcd_up`) or did not
    /// answer its initialisation at `now`.
    pub fn new(cols: u8, rows: u8, lcd_up: bool, now: Micros) -> Self {
        let mut lcd_retry = RetryTimer::new(LCD_RETRY_US);
        if !lcd_up {
            lcd_retry.failed(now);
        }
        AppPass {
            screen: Screen::new(cols, rows),
            lcd: LcdSync::new(cols, rows),
            lcd_retry,
        }
    }

    /// The screen as the application last drew it.
    pub fn screen(&self) -> &Screen {
        &self.screen
    }

    /// What the LCD shows (the cells the sync has written).
    pub fn lcd(&self) -> &LcdSync {
        &self.lcd
    }

    /// Whether the LCD is in use (not waiting for a retry).
    pub fn lcd_up(&self) -> bool {
        self.lcd_retry.working()
    }

    /// One pass of the application task at `now`.
    pub fn run<E: Eeprom, P: IoPort, L: CharLcd>(
        &mut self,
        app: &mut PlcApp<E>,
        svc: &mut Service,
        io: &mut P,
        lcd: &mut L,
        now: Micros,
    ) -> PassReport<L::Error> {
        let raw = io.sample();
        // A trip of the inputs stops the program before this pass's scan.
        if let Some(code) = io.take_trip() {
            app.field_trip(code, now);
        }
        let tick = app.tick_1ms(now, raw, &mut self.screen);
        if matches!(tick.run_change, Some((RunState::Stopped, _))) {
            io.rearm();
        }
        io.write_outputs(tick.outputs);
        if let Some(code) = io.take_trip() {
            app.field_trip(code, now);
        }
        let link_due = is_due(app.link().poll_timeout(), now);
        // After the outputs: the trend sample, one EEPROM step of a service read.
        let service_due = endpoint::after_scan(svc, app, &tick, now);
        PassReport {
            tick,
            link_due,
            service_due,
            lcd: self.lcd_step(lcd, now),
        }
    }

    /// One cell to the LCD, or its initialisation again when a retry is due.
    fn lcd_step<L: CharLcd>(&mut self, lcd: &mut L, now: Micros) -> Option<LcdEvent<L::Error>> {
        if self.lcd_retry.working() {
            let e = self.lcd.sync(&self.screen, lcd).err()?;
            self.lcd_retry.failed(now);
            return Some(LcdEvent::Failed(e));
        }
        if !self.lcd_retry.retry_due(now) {
            return None;
        }
        match lcd.init() {
            Ok(()) => {
                self.lcd.reset();
                self.lcd_retry.ok();
                Some(LcdEvent::Back)
            }
            Err(_) => {
                self.lcd_retry.failed(now);
                None
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::app::BuildInfo;
    use crate::storage::MemEeprom;
    use crate::task::lcd::Cursor;
    use shared_protocol::link::LinkConfig;

    #[derive(Default)]
    struct Pins {
        raw: RawIo,
        written: Vec<u8>,
        trip: Option<u8>,
        rearms: u32,
    }

    impl IoPort for Pins {
        fn sample(&mut self) -> RawIo {
            self.raw
        }
        fn write_outputs(&mut self, outputs: u8) {
            self.written.push(outputs);
        }
        fn take_trip(&mut self) -> Option<u8> {
            self.trip.take()
        }
        fn rearm(&mut self) {
            self.rearms += 1;
        }
    }

    /// An LCD that answers or not, and counts what it was sent.
    #[derive(Default)]
    struct Lcd {
        dead: bool,
        inits: u32,
        chars: u32,
    }

    impl CharLcd for Lcd {
        type Error = &'static str;
        fn init(&mut self) -> Result<(), Self::Error> {
            self.inits += 1;
            if self.dead {
                return Err("nak");
            }
            Ok(())
        }
        fn set_address(&mut self, _: u8, _: u8) -> Result<(), Self::Error> {
            if self.dead {
                return Err("nak");
            }
            Ok(())
        }
        fn write_char(&mut self, _: u8) -> Result<(), Self::Error> {
            if self.dead {
                return Err("nak");
            }
            self.chars += 1;
            Ok(())
        }
        fn set_cursor(&mut self, _: Cursor) -> Result<(), Self::Error> {
            if self.dead {
                return Err("nak");
            }
            Ok(())
        }
    }

    struct Rig {
        app: PlcApp<MemEeprom>,
        svc: Service,
        pass: AppPass,
        pins: Pins,
        lcd: Lcd,
        now: Micros,
    }

    impl Rig {
        fn new(lcd_up: bool) -> Rig {
            let app = PlcApp::new(MemEeprom::new(), LinkConfig::default(), 20, 4, Micros(0));
            Rig {
                app,
                svc: Service::new(BuildInfo {
                    firmware: "0",
                    git: "test",
                    uid: [0; 12],
                }),
                pass: AppPass::new(20, 4, lcd_up, Micros(0)),
                pins: Pins::default(),
                lcd: Lcd {
                    dead: !lcd_up,
                    ..Lcd::default()
                },
                now: Micros(0),
            }
        }

        fn pass(&mut self) -> PassReport<&'static str> {
            self.now = Micros(self.now.0 + 1000);
            self.pass.run(
                &mut self.app,
                &mut self.svc,
                &mut self.pins,
                &mut self.lcd,
                self.now,
            )
        }
    }

    #[test]
    fn every_pass_samples_the_pins_and_writes_the_outputs() {
        let mut rig = Rig::new(true);
        for _ in 0..5 {
            let _ = rig.pass();
        }
        assert_eq!(rig.pins.written, [0; 5]);
    }

    #[test]
    fn the_lcd_gets_one_cell_per_pass() {
        let mut rig = Rig::new(true);
        let r = rig.pass();
        assert!(r.tick.redrawn);
        assert_eq!(r.lcd, None);
        assert_eq!(rig.lcd.chars, 1);
        let _ = rig.pass();
        assert_eq!(rig.lcd.chars, 2);
    }

    #[test]
    fn a_failed_lcd_is_retried_every_two_seconds_and_redrawn_when_back() {
        let mut rig = Rig::new(true);
        let _ = rig.pass();
        rig.lcd.dead = true;
        let r = rig.pass();
        assert_eq!(r.lcd, Some(LcdEvent::Failed("nak")));
        assert!(!rig.pass.lcd_up());
        let failed_at = rig.now.0;
        // Dead: one initialisation per retry period, nothing else sent.
        while rig.now.0 < failed_at + 2 * LCD_RETRY_US {
            let _ = rig.pass();
        }
        assert_eq!(rig.lcd.inits, 2);
        rig.lcd.dead = false;
        let back = (0..3000)
            .map(|_| rig.pass().lcd)
            .position(|e| e == Some(LcdEvent::Back));
        assert!(back.is_some());
        assert!(rig.pass.lcd_up());
        let chars = rig.lcd.chars;
        let _ = rig.pass();
        assert_eq!(rig.lcd.chars, chars + 1, "the cleared LCD is drawn again");
    }

    #[test]
    fn an_lcd_missing_at_power_up_is_tried_after_the_retry_period() {
        let mut rig = Rig::new(false);
        while rig.now.0 < LCD_RETRY_US - 1000 {
            assert_eq!(rig.pass().lcd, None);
        }
        assert_eq!(rig.lcd.inits, 0);
        rig.lcd.dead = false;
        let _ = rig.pass();
        assert_eq!(rig.lcd.inits, 1);
        assert!(rig.pass.lcd_up());
    }

    #[test]
    fn a_field_io_trip_stops_the_program_and_is_logged_once() {
        let mut rig = Rig::new(true);
        rig.app.run(None, rig.now);
        let _ = rig.pass();
        assert_ne!(rig.app.run_state(), RunState::Stopped);
        assert_eq!(rig.pins.rearms, 1, "RUN clears the port's latch");
        rig.pins.trip = Some(201);
        let _ = rig.pass();
        assert_eq!(rig.app.run_state(), RunState::Stopped);
        assert_eq!(rig.app.status().newest_fault.map(|(c, _)| c), Some(201));
        for _ in 0..50 {
            let _ = rig.pass();
        }
        let logged = rig.app.fault_log().iter().filter(|e| e.code == 201).count();
        assert_eq!(logged, 1);
        assert_eq!(*rig.pins.written.last().unwrap(), 0);
    }
}
