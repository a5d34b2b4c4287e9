//! The PLC's end of the PLC-drive link. The state machine lives in `shared-protocol`
//! (so that tests, benchmarks and hil-sim can run both ends against each other); this is
//! the name the PLC firmware uses. See `shared-protocol/docs/link.md`.

pub use shared_protocol::link::plc::{CommandError, PlcEvent, PlcLink, PlcLinkState, PLC_WINDOW};
pub use shared_protocol::link::{
    fault_name, fault_text, DownloadResult, DriveState, DriveStatus, LinkConfig, LinkStats,
    RejectReason, MAX_WIRE_FRAME, PROTOCOL_VERSION,
};
