//! The application task: awaits each 1 ms pass's deadline and runs the pass,
//! [`firmware_plc::task::AppPass::run`] (pins sampled, tick, outputs, the service's
//! share, one LCD cell or the LCD's retry: all core code), over this board's pins and
//! LCD; then wakes the link and service tasks the pass asks for, and logs what it did.
//!
//! The pass schedule is [`Pacer`]: a late pass never replays the missed periods, and the
//! task yields once per pass, so the link task and the supervisor always get their turn.

use embassy_time::{Duration, Instant, Timer};
use firmware_plc::app::RawIo;
use firmware_plc::pace::Pacer;
use firmware_plc::task::{AppPass, IoPort, LcdEvent, PassReport};

use super::analog::AnalogInputs;
use super::inputs::DigitalInputs;
use super::keypad::KeypadScanner;
use super::lcd::{self, Lcd, LcdError};
#[cfg(not(feature = "shield-plc01a1"))]
use super::outputs::DigitalOutputs;
use super::{shared, supervisor};

pub use firmware_plc::task::pass::LCD_RETRY_US;

/// Scan and I/O sampling period.
pub const PERIOD: Duration = Duration::from_millis(1);

/// The pins the application task owns.
pub struct PlcIo {
    pub inputs: DigitalInputs,
    #[cfg(not(feature = "shield-plc01a1"))]
    pub outputs: DigitalOutputs,
    /// D00..D07 and O00..O07 through the X-NUCLEO-PLC01A1.
    #[cfg(feature = "shield-plc01a1")]
    pub outputs: super::shield::ShieldIo,
    pub analog: AnalogInputs,
    pub keypad: KeypadScanner,
}

#[cfg(not(feature = "shield-plc01a1"))]
impl IoPort for PlcIo {
    fn sample(&mut self) -> RawIo {
        RawIo {
            digital: self.inputs.sample(),
            analog: self.analog.sample(),
            keys: self.keypad.scan(),
        }
    }

    fn write_outputs(&mut self, outputs: u8) {
        self.outputs.write(outputs);
    }
}

/// D00..D07 from the shield's CLT01-38SQ7, D08..D15 from the GPIO pins.
#[cfg(feature = "shield-plc01a1")]
impl IoPort for PlcIo {
    fn sample(&mut self) -> RawIo {
        RawIo {
            digital: u16::from(self.outputs.read_inputs()) | self.inputs.sample() << 8,
            analog: self.analog.sample(),
            keys: self.keypad.scan(),
        }
    }

    fn write_outputs(&mut self, outputs: u8) {
        self.outputs.write_outputs(outputs);
    }

    fn take_trip(&mut self) -> Option<u8> {
        self.outputs.take_trip()
    }

    fn rearm(&mut self) {
        self.outputs.rearm();
    }
}

/// Runs the scan loop; `lcd_up`: the LCD answered its power-on initialisation.
#[embassy_executor::task]
pub async fn run(
    mut io: PlcIo,
    mut lcd: Lcd,
    lcd_up: bool,
    app: shared::SharedApp,
    svc: super::service::SharedService,
) {
    let mut pass = AppPass::new(lcd::COLS, lcd::ROWS, lcd_up, shared::now());
    let mut pacer = Pacer::new(PERIOD.as_micros());
    loop {
        let due = pacer.next(shared::now());
        Timer::at(Instant::from_micros(due.0)).await;
        // A deadline already passed completes without yielding: yield anyway.
        yield_now().await;
        #[cfg(feature = "dwt-cycles")]
        let start = super::cycles::now();
        let now = shared::now();
        let report = shared::with(app, |a| {
            let report = svc.lock(|s| pass.run(a, &mut s.borrow_mut(), &mut io, &mut lcd, now));
            super::rtc::pass(a, now);
            report
        });
        if report.link_due {
            board_common::link::kick();
        }
        if report.service_due {
            super::service::kick();
        }
        log(&report);
        #[cfg(feature = "dwt-cycles")]
        {
            super::cycles::record_scan(start);
            super::cycles::report_every_second();
        }
        supervisor::alive(supervisor::TASK_SCAN);
    }
}

/// What the pass did, to defmt.
fn log(report: &PassReport<LcdError>) {
    let tick = &report.tick;
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
    match report.lcd {
        Some(LcdEvent::Failed(e)) => {
            defmt::warn!("lcd: {}, retrying in {=u64} ms", e, LCD_RETRY_US / 1000)
        }
        Some(LcdEvent::Back) => defmt::info!("lcd: back"),
        None => {}
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
