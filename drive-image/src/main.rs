#![no_std]
#![no_main]
//! Board layer: binds the sans-IO core (`firmware_drive`) to the STM32G431 peripherals.
//!
//! Everything here is peripheral binding; the behaviour lives in the `firmware_drive` library
//! so that hil-sim and the host tests exercise the same code.

mod board;
mod pins;

use defmt_rtt as _;

#[embassy_executor::main]
async fn main(spawner: embassy_executor::Spawner) {
    board::start(spawner).await;
}
