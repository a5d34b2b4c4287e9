//! Drive MCU core: everything the drive does, as synchronous sans-IO state machines.
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

// Drive core modules. Units, scaling and every decision: `docs/drive-core.md`.
pub mod app;
pub mod blanking;
pub mod bodies;
pub mod comparator_trim;
pub mod comparators;
pub mod config;
pub mod drive;
pub mod front_end;
pub mod link;
pub mod measure;
pub mod modulator;
pub mod overvoltage;
pub mod power_port;
pub mod protection;
pub mod restart;
pub mod reversal;
pub mod safety;
pub mod sine;
pub mod state;
pub mod timing;
pub mod vm;

pub use crate::config::{DriveConfig, ResetCause};
pub use crate::drive::{
    CoreStatus, DriveCommand, DriveCore, DriveEvent, DriveRefusal, DriveWarning, PwmCommand,
};
pub use crate::measure::AdcSample;
pub use crate::protection::{FaultCode, HwBreak};
pub use crate::state::DriveState;
pub use crate::timing::PwmTiming;
