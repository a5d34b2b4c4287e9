//! Tests of the real firmware images: both release ELFs, as CI builds and users flash them,
//! run in the emulator of the two boards (`hil-sim emu`). One test binary; the images are
//! built once (a no-op when they are up to date) by the first test that needs them.

#![allow(dead_code)]

mod common;

mod board_findings;
mod boot;
mod cli;
mod clock;
mod exceptions;
mod io;
mod link;
mod motor;
mod oc_levels;
mod power_stage;
mod safety;
mod service;
mod silicon_faults;
mod storage;
mod timing;
mod trips;
