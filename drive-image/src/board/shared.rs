//! The drive application, shared between the PWM interrupt and the tasks.
//!
//! Every access is one `critical_section` (interrupts masked): the PWM interrupt's section
//! is the application's PWM interrupt body; the 1 ms task's is one step of its tick
//! (`ControlPort::with_app`), the link task's one `on_rx` or `poll_tx`. A task holding the
//! section delays the PWM interrupt at most by that long;
//! the compare registers are preloaded, so a late interrupt repeats the previous duties for
//! one period instead of glitching. `dwt-cycles` measures both.

use core::cell::RefCell;

use embassy_stm32::gpio::Output;
use embassy_sync::blocking_mutex::CriticalSectionMutex;
use firmware_drive::app::DriveApp;
use firmware_drive::config::{DriveConfig, ResetCause};
use shared_protocol::link::LinkConfig;
use shared_protocol::units::Micros;
use static_cell::StaticCell;

/// What the interrupt and the tasks share.
pub struct Shared {
    /// The drive application (core + link endpoint), in its own static ([`app_in_place`]).
    pub app: &'static mut DriveApp,
    /// Brake chopper gate, written by the PWM interrupt; `None` on a board without one
    /// (`BoardProfile::brake_chopper`: on the ESC1 PB5 enables the BEMF dividers).
    pub brake: Option<Output<'static>>,
}

/// A reference, so that the static is `.bss` (an `Option<Shared>` initialised to `None`
/// would keep a flash image of the whole application in `.data`).
static SHARED: CriticalSectionMutex<RefCell<Option<&'static mut Shared>>> =
    CriticalSectionMutex::new(RefCell::new(None));

/// The application's clock: microseconds since boot (`board_common::time::now`, one
/// out-of-line copy).
pub fn now() -> Micros {
    board_common::time::now()
}

/// The application, built in its static ([`DriveApp::new_in`]): it is ~6 KiB, and built on the stack
/// and then moved into [`Shared`] it made the start-up task's stack frame 8.5 KiB
/// (`docs/size.md`). Called once, at start-up.
pub fn app_in_place(
    cfg: DriveConfig,
    cause: ResetCause,
    link: LinkConfig,
) -> &'static mut DriveApp {
    static APP: StaticCell<DriveApp> = StaticCell::new();
    DriveApp::new_in(APP.uninit(), cfg, cause, link)
}

/// Installs the shared state (once, before TIM1's interrupt is unmasked).
pub fn install(s: Shared) {
    static MEMORY: StaticCell<Shared> = StaticCell::new();
    let s: &'static mut Shared = MEMORY.init(s);
    SHARED.lock(|cell| *cell.borrow_mut() = Some(s));
}

/// Runs `f` on the shared state inside a critical section; `None` before [`install`].
#[inline(always)]
pub fn with<R>(f: impl FnOnce(&mut Shared) -> R) -> Option<R> {
    SHARED.lock(|cell| cell.borrow_mut().as_mut().map(|s| f(s)))
}
