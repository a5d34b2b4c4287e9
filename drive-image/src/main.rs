#![cfg_attr(target_os = "none", no_std, no_main)]
//! Board layer: binds the sans-IO core of this crate to the STM32G431 peripherals.
//!
//! Everything here is peripheral binding; the behaviour lives in the `firmware_drive` library
//! so that hil-sim and the host tests exercise the same code.

#[cfg(target_os = "none")]
mod board;
#[cfg(target_os = "none")]
mod pins;

#[cfg(target_os = "none")]
use defmt_rtt as _;

#[cfg(target_os = "none")]
#[embassy_executor::main]
async fn main(spawner: embassy_executor::Spawner) {
    board::start(spawner).await;
}

#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!("this is firmware: build it with --target thumbv7em-none-eabihf (see README.md)");
}
