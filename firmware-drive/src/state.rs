//! The drive's operating states (drive.md "States"): shared with the link's status frame
//! and the PLC (one copy, in `shared-protocol`).

pub use shared_protocol::drive_state::DriveState;
