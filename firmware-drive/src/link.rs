//! The drive's end of the PLC-drive link. The state machine lives in `shared-protocol`
//! (so that tests, benchmarks and hil-sim can run both ends against each other); this is
//! the name the drive firmware uses. See `shared-protocol/docs/link.md`.

pub use shared_protocol::link::drive::{DriveEvent, DriveLink, DriveLinkState, DRIVE_WINDOW};
pub use shared_protocol::link::pump::{LinkEndpoint, Pump};
pub use shared_protocol::link::{
    DownloadResult, DriveState, DriveStatus, LinkConfig, LinkStats, RejectReason, MAX_WIRE_FRAME,
    PROTOCOL_VERSION,
};

use crate::app::DriveApp;
use shared_protocol::units::Micros;

/// The drive application is what the link pump serves (board and hil-sim): commands reach
/// the core as their frames arrive.
impl LinkEndpoint for DriveApp {
    fn on_rx(&mut self, bytes: &[u8], now: Micros) {
        DriveApp::on_rx(self, bytes, now);
    }
    fn poll_tx(&mut self, now: Micros, out: &mut [u8]) -> usize {
        DriveApp::poll_tx(self, now, out)
    }
    fn poll_timeout(&self) -> Option<Micros> {
        DriveApp::poll_timeout(self)
    }
    fn line_error(&mut self) {
        self.on_line_error();
    }
}
