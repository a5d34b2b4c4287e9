//! The drive's link task: `board_common::link` (USART1 on PB6/PB7, the core's pump) over
//! the shared drive application. Nothing here decides anything.

use board_common::link::{self as common, LinkPort, SharedEndpoint};
use firmware_drive::app::DriveApp;

use super::shared;
use crate::pins::Link;

/// Opens the link USART at `baud`.
pub fn open(l: Link, baud: u32) -> LinkPort {
    common::open(l, baud)
}

/// Each access is one critical section (the PWM interrupt shares the application).
struct Shared;

impl SharedEndpoint for Shared {
    type Endpoint<'a> = DriveApp;
    fn with<R>(&self, f: impl for<'a> FnOnce(&mut DriveApp) -> R) -> Option<R> {
        shared::with(|s| f(s.app))
    }
}

/// Moves bytes between the USART and the application's link endpoint.
#[embassy_executor::task]
pub async fn run(port: LinkPort) {
    common::run(port, Shared).await
}
