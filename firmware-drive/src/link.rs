//! The drive's end of the PLC-drive link. The state machine lives in `shared-protocol`
//! (so that tests, benchmarks and hil-sim can run both ends against each other); this is
//! the name the drive firmware uses. See `shared-protocol/docs/link.md`.

pub use shared_protocol::link::drive::{DriveEvent, DriveLink, DriveLinkState, DRIVE_WINDOW};
pub use shared_protocol::link::{
    DownloadResult, DriveState, DriveStatus, LinkConfig, LinkStats, RejectReason, MAX_WIRE_FRAME,
    PROTOCOL_VERSION,
};
