//! Independent watchdog, fed only while every registered task shows it is alive.
//!
//! Each long-running task calls [`alive`] with its own bit at least once per
//! [`CHECK_PERIOD_MS`]; the supervisor pets the IWDG only when all bits of [`ALL_TASKS`] were
//! set since its last check, so one stuck task resets the MCU even if the executor still runs.

use core::sync::atomic::{AtomicU32, Ordering};

use embassy_stm32::gpio::AnyPin;
use embassy_stm32::gpio::{Level, Output, Speed};
use embassy_stm32::peripherals::IWDG;
use embassy_stm32::wdg::IndependentWatchdog;
use embassy_stm32::Peri;
use embassy_time::{Duration, Ticker};

/// IWDG timeout: ten supervision periods, so a task that stalls for more than about 0.1 s
/// restarts the MCU (outputs off through reset) while start-up never comes close.
pub const WATCHDOG_TIMEOUT_US: u32 = 100_000;
/// The heartbeat LED toggles every this many fed checks (0.5 s).
const LED_TOGGLE_CHECKS: u32 = 25;
/// How often the supervisor checks the alive bits and pets the IWDG.
pub const CHECK_PERIOD_MS: u64 = 20;

/// Alive bit of the link task.
pub const TASK_LINK: u32 = 1 << 0;
/// Alive bit of the 1 ms control task.
pub const TASK_CONTROL: u32 = 1 << 1;
/// Tasks that must report before the watchdog is fed.
pub const ALL_TASKS: u32 = TASK_LINK | TASK_CONTROL;

static ALIVE: AtomicU32 = AtomicU32::new(0);

/// Marks the calling task alive for the current supervision period.
pub fn alive(task: u32) {
    ALIVE.fetch_or(task, Ordering::Relaxed);
}

/// Feeds the IWDG for as long as every task keeps reporting, and blinks the heartbeat LED
/// while it does.
#[embassy_executor::task]
pub async fn run(iwdg: Peri<'static, IWDG>, led: Peri<'static, AnyPin>) {
    let mut led = Output::new(led, Level::Low, Speed::Low);
    let mut fed: u32 = 0;
    let mut wdg = IndependentWatchdog::new(iwdg, WATCHDOG_TIMEOUT_US);
    wdg.unleash();
    let mut ticker = Ticker::every(Duration::from_millis(CHECK_PERIOD_MS));
    let mut missing_reported = false;
    loop {
        ticker.next().await;
        let seen = ALIVE.swap(0, Ordering::Relaxed);
        if seen & ALL_TASKS == ALL_TASKS {
            wdg.pet();
            fed = fed.wrapping_add(1);
            if fed.is_multiple_of(LED_TOGGLE_CHECKS) {
                led.toggle();
            }
            missing_reported = false;
        } else if !missing_reported {
            defmt::warn!(
                "watchdog: tasks {=u32:#x} silent, not feeding",
                ALL_TASKS & !seen
            );
            missing_reported = true;
        }
    }
}
