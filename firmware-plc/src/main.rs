#![cfg_attr(target_os = "none", no_std, no_main)]
//! Board layer: binds the sans-IO core of this crate to the STM32G431 peripherals.

#[cfg(target_os = "none")]
mod board {}

#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!("this is firmware: build it with --target thumbv7em-none-eabihf (see README.md)");
}
