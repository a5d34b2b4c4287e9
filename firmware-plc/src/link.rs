//! The PLC's end of the PLC-drive link. The state machine lives in `shared-protocol`
//! (so that tests, benchmarks and hil-sim can run both ends against each other); this is
//! the name the PLC firmware uses. See `shared-protocol/docs/link.md`.

pub use shared_protocol::link::plc::{CommandError, PlcEvent, PlcLink, PlcLinkState, PLC_WINDOW};
pub use shared_protocol::link::pump::{LinkEndpoint, Pump};
pub use shared_protocol::link::{
    fault_name, fault_text, DownloadResult, DriveState, DriveStatus, FaultCode, LinkConfig,
    LinkStats, RejectReason, MAX_WIRE_FRAME, PROTOCOL_VERSION,
};

use crate::app::PlcApp;
use crate::storage::Eeprom;
use shared_protocol::units::Micros;

/// The PLC application is what the link pump serves (board and hil-sim): the RUN sequence
/// sees the link's events as they happen (a download's acceptance sends RUN in the same
/// pass). The slow reaction, writing a drive fault to the EEPROM log, is only queued
/// here: the storage job runs in [`PlcApp::tick_1ms`], one EEPROM page per tick, so the
/// report's acknowledgement never waits for it and [`LinkEndpoint::service`] has
/// nothing to do.
impl<E: Eeprom> LinkEndpoint for PlcApp<E> {
    fn on_rx(&mut self, bytes: &[u8], now: Micros) {
        PlcApp::on_rx(self, bytes, now);
    }
    fn poll_tx(&mut self, now: Micros, out: &mut [u8]) -> usize {
        PlcApp::poll_tx(self, now, out)
    }
    fn poll_timeout(&self) -> Option<Micros> {
        self.link().poll_timeout()
    }
    fn line_error(&mut self) {
        self.on_line_error();
    }
}
