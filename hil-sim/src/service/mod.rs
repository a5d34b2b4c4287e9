//! The PLC's service port in the simulation (service.md 9): the firmware's sans-IO
//! [`Service`](firmware_plc::service::Service) endpoint bound to a byte-timed UART ([`ServiceLine`]), and that line bound
//! to a real pseudo-terminal ([`pty::Pty`]) with real-time pacing while a client has it
//! open ([`attach::Attached`]).
//!
//! The service is stepped after each of the PLC's 1 ms ticks, outside the simulation's
//! event loop: it only borrows the application between ticks (as the board's service
//! task, which runs below the application and link tasks), so attaching it, or flooding
//! it with garbage, changes no scan instant, link frame or output (the flood test).
//!
//! Decisions: `shared-protocol/docs/service.md` ("hil-sim").

pub mod attach;
pub mod line;
pub mod pty;

pub use attach::{Attached, PtyOptions};
pub use line::ServiceLine;
