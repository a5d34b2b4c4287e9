//! The application task: every millisecond it samples the I/O, debounces it, hands key
//! events and one scan to the application ([`firmware_plc::app::PlcApp`]), writes the
//! output image and moves the LCD one step towards the application's screen.

use embassy_time::{Duration, Ticker};
use firmware_plc::debounce::{Debouncer, KeyMatrix};
use firmware_plc::editor::Screen;

use super::analog::AnalogInputs;
use super::inputs::DigitalInputs;
use super::keypad::KeypadScanner;
use super::lcd::{self, Lcd};
use super::outputs::DigitalOutputs;
use super::{shared, supervisor};

/// Scan and I/O sampling period.
pub const PERIOD: Duration = Duration::from_millis(1);
/// Digital inputs: a level must hold for 5 samples (5 ms) to count.
pub const INPUT_DEBOUNCE_SAMPLES: u8 = 5;
/// Keypad: a key must be stable for 10 full-matrix samples (10 ms) to count.
pub const KEY_DEBOUNCE_SAMPLES: u8 = 10;
/// The application draws its screen every this many periods (100 ms); the LCD driver then
/// sends the changed cells one per period.
pub const RENDER_PERIODS: u32 = 100;

/// The I/O the application task owns.
pub struct PlcIo {
    pub inputs: DigitalInputs,
    pub outputs: DigitalOutputs,
    pub analog: AnalogInputs,
    pub keypad: KeypadScanner,
    pub lcd: Option<Lcd>,
}

/// Runs the scan loop.
#[embassy_executor::task]
pub async fn run(mut io: PlcIo, app: shared::SharedApp) {
    let mut inputs = Debouncer::<8>::new(INPUT_DEBOUNCE_SAMPLES);
    let mut keys = KeyMatrix::new(KEY_DEBOUNCE_SAMPLES);
    let mut screen = Screen::new(lcd::COLS, lcd::ROWS);
    let mut ticks: u32 = 0;
    let mut run_state = shared::with(app, |a| a.run_state());
    // A change of these (link lost, fault, warning) redraws at once: link.md wants a lost
    // link on the LCD within 100 ms, the periodic refresh alone could take 100 ms more.
    let mut drawn_alerts = None;
    let mut ticker = Ticker::every(PERIOD);
    loop {
        ticker.next().await;
        #[cfg(feature = "dwt-cycles")]
        let start = super::cycles::now();
        let digital = inputs.update(u32::from(io.inputs.sample())) as u8;
        let analog = io.analog.sample();
        let matrix = io.keypad.scan();
        let image = shared::with(app, |app| {
            let now = shared::now();
            let mut key_down = false;
            keys.update(matrix, &mut |e| {
                defmt::debug!("key {} {}", e.key, if e.down { "down" } else { "up" });
                if e.down {
                    app.key(e.key, now);
                    key_down = true;
                }
            });
            let out = app.scan(digital, analog, now);
            if let Some(w) = out.warning {
                defmt::warn!("scan: {}", w);
            }
            // Redraw at once after a key or an alert change, as hil-sim's board does.
            let alerts = app.alerts();
            if key_down || ticks.is_multiple_of(RENDER_PERIODS) || drawn_alerts != Some(alerts) {
                app.render(now, &mut screen);
                drawn_alerts = Some(alerts);
            }
            let state = app.run_state();
            if state != run_state {
                defmt::info!("plc: {} -> {}", run_state, state);
                run_state = state;
            }
            out.outputs
        });
        io.outputs.write(image);
        super::link::kick_if_due(app);
        if let Some(l) = io.lcd.as_mut() {
            if let Err(e) = l.refresh(&screen) {
                defmt::warn!("lcd: {}, running without it", e);
                io.lcd = None;
            }
        }
        ticks = ticks.wrapping_add(1);
        #[cfg(feature = "dwt-cycles")]
        {
            super::cycles::record_scan(start);
            super::cycles::report_every_second();
        }
        supervisor::alive(supervisor::TASK_SCAN);
    }
}
