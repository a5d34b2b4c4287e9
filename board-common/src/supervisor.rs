//! Independent watchdog, fed only while every registered task shows it is alive.
//!
//! Each long-running task calls [`alive`] with its own bit at least once per
//! [`CHECK_PERIOD_MS`]; the supervisor task checks the bits every period and feeds the IWDG
//! only when all the required ones were set (the rule and the "report a silent task once"
//! decision: `shared_protocol::supervision::Supervisor`), so one stuck task resets the MCU
//! even if the executor still runs.

use core::sync::atomic::{AtomicU32, Ordering};

use embassy_stm32::gpio::{AnyPin, Level, Output, Speed};
use embassy_stm32::peripherals::IWDG;
use embassy_stm32::wdg::IndependentWatchdog;
use embassy_stm32::Peri;
use embassy_time::{Duration, Ticker};
use shared_protocol::supervision::Supervisor;

/// IWDG timeout: five supervision periods, so a task that stalls for more than about
/// 0.1 s restarts the MCU (outputs off through reset) while start-up never comes close.
pub const WATCHDOG_TIMEOUT_US: u32 = 100_000;
/// The heartbeat LED toggles every this many fed checks (0.5 s).
const LED_TOGGLE_CHECKS: u32 = 25;
/// How often the supervisor checks the alive bits and feeds the IWDG.
pub const CHECK_PERIOD_MS: u64 = 20;

/// Alive bit of the link task (both boards).
pub const TASK_LINK: u32 = 1 << 0;
/// Alive bit of the board's main periodic task (the PLC's scan loop, the drive's 1 ms
/// control task).
pub const TASK_MAIN: u32 = 1 << 1;

static ALIVE: AtomicU32 = AtomicU32::new(0);

/// Marks the calling task alive for the current supervision period.
pub fn alive(task: u32) {
    ALIVE.fetch_or(task, Ordering::Relaxed);
}

/// Feeds the IWDG for as long as every task in `required` keeps reporting, and blinks the
/// heartbeat LED while it does. With a debugger attached the IWDG is frozen while the core
/// is halted ([`crate::debug`]; checked at every period, so a probe attached later counts).
#[embassy_executor::task]
pub async fn run(iwdg: Peri<'static, IWDG>, led: Peri<'static, AnyPin>, required: u32) {
    let mut led = Output::new(led, Level::Low, Speed::Low);
    crate::debug::freeze_watchdog_when_halted();
    let mut wdg = IndependentWatchdog::new(iwdg, WATCHDOG_TIMEOUT_US);
    wdg.unleash();
    let mut ticker = Ticker::every(Duration::from_millis(CHECK_PERIOD_MS));
    let mut supervisor = Supervisor::new(required, LED_TOGGLE_CHECKS);
    loop {
        ticker.next().await;
        crate::debug::freeze_watchdog_when_halted();
        let v = supervisor.check(ALIVE.swap(0, Ordering::Relaxed));
        if v.feed {
            wdg.pet();
        }
        if v.toggle_led {
            led.toggle();
        }
        if let Some(silent) = v.report_silent {
            defmt::warn!("watchdog: tasks {=u32:#x} silent, not feeding", silent);
        }
    }
}
