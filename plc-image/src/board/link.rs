//! The PLC's link task: `board_common::link` (USART1 on PA9/PA10, the core's pump) over the
//! shared PLC application. Nothing here decides anything.

use board_common::link::{self as common, LinkPort, SharedEndpoint};

use super::shared::{self, App, SharedApp};
use crate::pins::Link;

/// Opens the link USART at `baud`.
pub fn open(l: Link, baud: u32) -> LinkPort {
    common::open(l, baud)
}

struct Shared(SharedApp);

impl SharedEndpoint for Shared {
    type Endpoint<'a> = App;
    fn with<R>(&self, f: impl for<'a> FnOnce(&mut App) -> R) -> Option<R> {
        Some(shared::with(self.0, f))
    }
}

/// Moves bytes between the USART and the application's link endpoint.
#[embassy_executor::task]
pub async fn run(port: LinkPort, app: SharedApp) {
    common::run(port, Shared(app)).await
}
