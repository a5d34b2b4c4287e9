//! The bodies of the PLC MCU's tasks, each one core function over a port: the board's
//! tasks await and call them with register bindings, hil-sim with its models, the tests
//! with theirs (`docs/board.md`, "Task bodies").
//!
//! * [`pass`]: the application task's 1 ms pass ([`pass::AppPass::run`] over an
//!   [`pass::IoPort`] and a [`lcd::CharLcd`]).
//! * [`lcd`]: the LCD sync (which cell to write next) over a [`lcd::CharLcd`].
//! * The link and service tasks are the link's pump
//!   ([`shared_protocol::link::pump::Pump`]) over the application
//!   ([`crate::link`]) and over [`crate::service::endpoint::OnApp`].
//!
//! This is the top of the crate's dependency order: it uses the application and the
//! service; nothing below uses it.

pub mod lcd;
pub mod pass;

pub use lcd::{CharLcd, Cursor, LcdSync};
pub use pass::{AppPass, IoPort, LcdEvent, PassReport};
