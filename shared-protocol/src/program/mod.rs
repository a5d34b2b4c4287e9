//! The user program model (program.md sections 1-2, shared by both MCUs and the host).

mod model;

pub use model::*;
