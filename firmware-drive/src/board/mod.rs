//! Drive board layer: brings up the STM32G431 and binds the peripherals; no drive logic.

pub mod clocks;
pub mod control;
pub mod link;
pub mod power_stage;
pub mod reset_cause;
pub mod supervisor;

use embassy_executor::Spawner;

use crate::pins;

/// Name in the boot line and in probe-rs logs.
pub const IMAGE: &str = "firmware-drive";

/// Brings the board up and starts every task.
pub async fn start(spawner: Spawner) {
    let cause = reset_cause::take();
    let p = embassy_stm32::init(clocks::config());
    defmt::info!(
        "{=str} {=str} boot: {} MHz, reset cause {}",
        IMAGE,
        env!("CARGO_PKG_VERSION"),
        clocks::SYSCLK_HZ / 1_000_000,
        cause
    );
    let board = pins::split(p);
    // Outputs off first: nothing below may run with the gates floating.
    let gates = power_stage::hold_off(board.power);
    let port = link::open(board.link);

    spawner.spawn(supervisor::run(board.misc.iwdg).expect("spawn supervisor"));
    spawner.spawn(link::run(port).expect("spawn link"));
    spawner.spawn(control::run(gates).expect("spawn control"));
}
