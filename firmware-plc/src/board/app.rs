//! The application task: every millisecond it samples the I/O, debounces it, runs the PLC
//! scan and refreshes the LCD. Everything above the pins is the `firmware_plc` core.

use embassy_time::{Duration, Instant, Ticker};
use firmware_plc::debounce::{Debouncer, KeyMatrix};
use firmware_plc::editor::Screen;

use super::analog::AnalogInputs;
use super::eeprom::I2cEeprom;
use super::inputs::DigitalInputs;
use super::keypad::KeypadScanner;
use super::lcd::{self, Lcd};
use super::outputs::DigitalOutputs;
use super::supervisor;

/// Scan and I/O sampling period.
pub const PERIOD: Duration = Duration::from_millis(1);
/// Digital inputs: a level must hold for 5 samples (5 ms) to count.
pub const INPUT_DEBOUNCE_SAMPLES: u8 = 5;
/// Keypad: a key must be stable for 10 full-matrix samples (10 ms) to count.
pub const KEY_DEBOUNCE_SAMPLES: u8 = 10;

/// The I/O the application task owns.
pub struct PlcIo {
    pub inputs: DigitalInputs,
    pub outputs: DigitalOutputs,
    pub analog: AnalogInputs,
    pub keypad: KeypadScanner,
    pub lcd: Option<Lcd>,
    pub eeprom: I2cEeprom,
}

/// Runs the scan loop.
#[embassy_executor::task]
pub async fn run(mut io: PlcIo) {
    let mut inputs = Debouncer::<8>::new(INPUT_DEBOUNCE_SAMPLES);
    let mut keys = KeyMatrix::new(KEY_DEBOUNCE_SAMPLES);
    let mut screen = Screen::new(lcd::COLS, lcd::ROWS);
    screen.put(0, 0, super::IMAGE);
    screen.put(1, 0, env!("CARGO_PKG_VERSION"));
    let _eeprom = &mut io.eeprom;
    let mut ticker = Ticker::every(PERIOD);
    loop {
        ticker.next().await;
        #[cfg(feature = "dwt-cycles")]
        let start = super::cycles::now();
        let now = Instant::now();
        let digital = inputs.update(u32::from(io.inputs.sample())) as u8;
        let analog = io.analog.sample();
        keys.update(io.keypad.scan(), &mut |e| {
            defmt::debug!("key {} {}", e.key, if e.down { "down" } else { "up" });
            // Call site of the PLC application's key input (issue 8: `PlcApp`).
        });
        // Call site of the PLC application's scan (issue 8: `PlcApp` with
        // `Storage<I2cEeprom>`): scan with `digital`/`analog` at `now`, then write its
        // output image and show its screen.
        defmt::trace!(
            "scan at {} ms: D {=u8:#x} A {}",
            now.as_millis(),
            digital,
            analog
        );
        io.outputs.write(0);
        if let Some(l) = io.lcd.as_mut() {
            if let Err(e) = l.refresh(&screen) {
                defmt::warn!("lcd: {}", e);
                io.lcd = None;
            }
        }
        #[cfg(feature = "dwt-cycles")]
        {
            super::cycles::record_scan(start);
            super::cycles::report_every_second();
        }
        supervisor::alive(supervisor::TASK_SCAN);
    }
}
