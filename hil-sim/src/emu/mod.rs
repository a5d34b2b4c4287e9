//! `hil-sim emu`: the exact release images of both firmware crates, run in an emulator of
//! the two STM32G431 boards (`g431-emu`), joined by their real UARTs, with hil-sim's plant
//! in the loop, the same scenario and the same record as `hil-sim run`.
//!
//! * [`images`]: where the ELFs are (and building them for the tests).
//! * [`analog`]: the scenario's `[analog]` keys as the drive MCU's analog errors.
//! * [`boards`]: what each pin of the two MCUs is wired to.
//! * [`sim`]: the co-simulation.
//! * [`silicon`]: the scenario's faults of the silicon applied to the MCUs.
//! * [`run`]: one whole `emu` run as the CLI does it.

pub mod analog;
pub mod boards;
pub mod images;
pub mod run;
pub mod silicon;
pub mod sim;
