//! Tests of the real firmware images: both release ELFs, as CI builds and users flash them,
//! run in the emulator of the two boards (`hil-sim emu`). One test binary; the images are
//! built once (a no-op when they are up to date) by the first test that needs them.
//!
//! Release builds only (`cargo test --release`, the README's command): the images are built
//! with the firmware profile either way, so a second run of this suite in the dev profile
//! would only add overflow checks to the emulator, which its own unit tests (`g431-emu`) run
//! under in the dev profile. CI's `test_checked` step skips it for that reason; clippy
//! (dev profile) still lints it.

#![cfg(any(not(debug_assertions), clippy))]
#![allow(dead_code)]

mod common;

mod board_findings;
mod boot;
mod campaign;
mod cli;
mod clock;
mod exceptions;
mod io;
mod lift;
mod link;
mod motor;
mod oc_levels;
mod power_stage;
mod restart;
mod reversal;
mod safety;
mod service;
mod silicon_faults;
mod storage;
mod timing;
mod trips;
