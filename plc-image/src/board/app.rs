//! The application task: once per millisecond it samples the raw pins and key matrix,
//! hands them to [`firmware_plc::app::PlcApp::tick_1ms`] (debouncing, scan, one EEPROM
//! page of storage work, redraw: all core code), writes the output image and sends the
//! LCD one changed cell; after the outputs, the service port's share of the pass
//! (`board::service::after_scan`).
//!
//! The pass schedule is [`Pacer`]: a late pass never replays the missed periods, and the
//! task yields once per pass, so the link task and the supervisor always get their turn
//! (review D5).

use embassy_time::{Duration, Instant, Timer};
use firmware_plc::app::RawIo;
use firmware_plc::editor::Screen;
use firmware_plc::pace::{Pacer, RetryTimer};

use super::analog::AnalogInputs;
use super::inputs::DigitalInputs;
use super::keypad::KeypadScanner;
use super::lcd::{self, Lcd};
use super::outputs::DigitalOutputs;
use super::{shared, supervisor};

/// Scan and I/O sampling period.
pub const PERIOD: Duration = Duration::from_millis(1);
/// A failed LCD is initialised again after this long (review D6/D14).
pub const LCD_RETRY_US: u64 = 2_000_000;

/// The I/O the application task owns.
pub struct PlcIo {
    pub inputs: DigitalInputs,
    pub outputs: DigitalOutputs,
    pub analog: AnalogInputs,
    pub keypad: KeypadScanner,
    pub lcd: Option<Lcd>,
    pub bus: super::i2c_bus::SharedI2c,
}

/// Runs the scan loop.
#[embassy_executor::task]
pub async fn run(mut io: PlcIo, app: shared::SharedApp, svc: super::service::SharedService) {
    let mut screen = Screen::new(lcd::COLS, lcd::ROWS);
    let mut pacer = Pacer::new(PERIOD.as_micros());
    let mut lcd_retry = RetryTimer::new(LCD_RETRY_US);
    if io.lcd.is_none() {
        lcd_retry.failed(shared::now());
    }
    loop {
        let due = pacer.next(shared::now());
        Timer::at(Instant::from_micros(due.0)).await;
        // A deadline already passed completes without yielding: yield anyway.
        yield_now().await;
        #[cfg(feature = "dwt-cycles")]
        let start = super::cycles::now();
        let raw = RawIo {
            digital: io.inputs.sample(),
            analog: io.analog.sample(),
            keys: io.keypad.scan(),
        };
        let now = shared::now();
        let tick = shared::with(app, |a| a.tick_1ms(now, raw, &mut screen));
        io.outputs.write(tick.outputs);
        super::link::kick_if_due(app);
        // After the outputs: the trend sample, one EEPROM step of a service read.
        super::service::after_scan(svc, app, &tick);
        if let Some(w) = tick.warning {
            defmt::warn!("scan: {}", w);
        }
        if tick.keys_down != 0 {
            defmt::debug!("keys down {=u16:#x}", tick.keys_down);
        }
        if let Some((from, to)) = tick.run_change {
            defmt::info!("plc: {} -> {}", from, to);
        }
        if let Some(done) = tick.storage {
            let s = done.summary();
            defmt::info!(
                "storage: {} {=u8}: {} {=u32}",
                s.kind,
                s.slot,
                s.outcome,
                s.value
            );
        }
        match io.lcd.as_mut() {
            Some(l) => {
                if let Err(e) = l.refresh(&screen) {
                    defmt::warn!("lcd: {}, retrying in {=u64} ms", e, LCD_RETRY_US / 1000);
                    io.lcd = None;
                    lcd_retry.failed(now);
                }
            }
            None if lcd_retry.retry_due(now) => match Lcd::new(io.bus, false) {
                Ok(l) => {
                    defmt::info!("lcd: back");
                    io.lcd = Some(l);
                    lcd_retry.ok();
                }
                Err(_) => lcd_retry.failed(now),
            },
            None => {}
        }
        #[cfg(feature = "dwt-cycles")]
        {
            super::cycles::record_scan(start);
            super::cycles::report_every_second();
        }
        supervisor::alive(supervisor::TASK_SCAN);
    }
}

/// Returns `Pending` once (after waking itself), so that every other ready task runs.
async fn yield_now() {
    let mut yielded = false;
    core::future::poll_fn(|cx| {
        if yielded {
            core::task::Poll::Ready(())
        } else {
            yielded = true;
            cx.waker().wake_by_ref();
            core::task::Poll::Pending
        }
    })
    .await
}
