//! PLC MCU core: everything the PLC does, as synchronous sans-IO state machines.
#![cfg_attr(not(test), no_std)]
// The cores touch no registers: `unsafe` belongs to the image crates only.
#![forbid(unsafe_code)]
#![cfg_attr(
    not(test),
    deny(
        clippy::unwrap_used,
        clippy::expect_used,
        clippy::indexing_slicing,
        clippy::panic
    )
)]

pub mod app;
pub mod bus_recovery;
pub mod clock;
pub mod debounce;
pub mod editor;
pub mod field_io;
pub mod link;
pub mod pace;
pub mod service;
pub mod storage;
pub mod task;
pub mod wide_div;

#[cfg(test)]
mod rig_tests;
/// The PLC logic VM, from its own crate (`plc-vm`, built for speed in the image while
/// this crate is built for size; docs/size.md).
pub use plc_vm as vm;
