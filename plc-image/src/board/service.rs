//! The service port (service.md 1-2): LPUART1 on PA2/PA3, the NUCLEO-G431RB's ST-LINK/V3
//! virtual COM port, 8N1 at [`SERVICE_BAUD`], TX and RX on DMA1 CH3/CH4 (RX into the
//! ring receiver `board_common::link_rx::Service`, which a line error never stops). The
//! bytes move through the link's machinery (`board_common::link::open_port` and `run_task`, the core's
//! pump) into the core's service endpoint ([`firmware_plc::service::endpoint`]). Nothing
//! here decides anything: what runs when, and who touches the EEPROM, is the endpoint's.
//!
//! * The service lives in its own static, outside the application (whose builder's stack
//!   frame grows with it); both are thread-mode mutexes borrowed for one synchronous call,
//!   never across an `await`.
//! * The service task is one more task of the thread-mode executor: each of its passes is
//!   bounded (the frame reader per received byte, at most one answer executed and encoded),
//!   and it yields between them. It is not on the watchdog: a silent service must never
//!   reset a running machine (the scan's and the link's bits still catch a stalled
//!   executor).
//! * The application pass (`firmware_plc::task::AppPass::run`) does the service's share
//!   after each scan (the trend sample, one step of the EEPROM reads a request waits for:
//!   the bus is idle then) and says when this task must pass; the application task then
//!   [`kick`]s it.

use core::cell::RefCell;

use board_common::link::{self as common, ServicePort, SharedEndpoint, Task};
use board_common::link_rx::{self, RING_BYTES};
use embassy_stm32::interrupt::typelevel::{Handler, DMA1_CHANNEL4, LPUART1};
use embassy_stm32::{bind_interrupts, dma, peripherals, usart};
use embassy_sync::blocking_mutex::ThreadModeMutex;
use embassy_sync::signal::Signal;
use firmware_plc::app::BuildInfo;
use firmware_plc::service::endpoint::OnApp;
use firmware_plc::service::Service;
use shared_protocol::service::SERVICE_BAUD;
use static_cell::StaticCell;

use super::eeprom::I2cEeprom;
use super::shared::{self, SharedApp};
use crate::pins;

// The ring receiver's handlers first (`board_common::link_rx`): they take the
// IDLE and half-transfer flags they use; embassy's then find nothing of theirs.
bind_interrupts!(struct Irqs {
    LPUART1 => RxIdle, usart::InterruptHandler<peripherals::LPUART1>;
    DMA1_CHANNEL3 => dma::InterruptHandler<peripherals::DMA1_CH3>;
    DMA1_CHANNEL4 => RxHalf, dma::InterruptHandler<peripherals::DMA1_CH4>;
});

/// LPUART1's interrupt, before embassy's: the service ring's IDLE wake-up.
struct RxIdle;

impl Handler<LPUART1> for RxIdle {
    unsafe fn on_interrupt() {
        link_rx::on_idle::<link_rx::Service>();
    }
}

/// DMA1 channel 4's interrupt, before embassy's: the service ring's half events.
struct RxHalf;

impl Handler<DMA1_CHANNEL4> for RxHalf {
    unsafe fn on_interrupt() {
        link_rx::on_half::<link_rx::Service>();
    }
}

/// The service endpoint, shared by the service task and the application task.
pub type SharedService = &'static ThreadModeMutex<RefCell<Service>>;

/// The service task.
static TASK: Task = Task {
    name: "service",
    alive: 0,
    kick: Signal::new(),
    #[cfg(feature = "dwt-cycles")]
    rx_cycles: &board_common::cycles::SERVICE_RX,
    #[cfg(feature = "dwt-cycles")]
    tx_cycles: &board_common::cycles::SERVICE_TX,
};

/// This build and chip, as `Identify` reports them. The git hash comes from the
/// environment of the build (`PLC_GIT_HASH`, CI sets it), else "unknown".
fn build_info() -> BuildInfo {
    BuildInfo {
        firmware: env!("CARGO_PKG_VERSION"),
        git: match option_env!("PLC_GIT_HASH") {
            Some(g) => g,
            None => "unknown",
        },
        uid: embassy_stm32::uid::uid(),
    }
}

/// Opens LPUART1 and builds the service endpoint in its static.
pub fn open(s: pins::Service) -> (ServicePort, SharedService) {
    static RX_RING: StaticCell<[u8; RING_BYTES]> = StaticCell::new();
    static SERVICE: StaticCell<ThreadModeMutex<RefCell<Service>>> = StaticCell::new();
    let port = common::open_port(
        s.lpuart,
        s.tx,
        s.rx,
        s.tx_dma,
        s.rx_dma,
        Irqs,
        RX_RING.init([0; RING_BYTES]),
        SERVICE_BAUD,
    );
    let svc = SERVICE.init(ThreadModeMutex::new(RefCell::new(Service::new(
        build_info(),
    ))));
    (port, svc)
}

/// The service on the application for one call of the pump.
struct Shared {
    svc: SharedService,
    app: SharedApp,
}

impl SharedEndpoint for Shared {
    type Endpoint<'a> = OnApp<'a, I2cEeprom>;
    fn with<R>(&self, f: impl for<'a> FnOnce(&mut OnApp<'a, I2cEeprom>) -> R) -> Option<R> {
        Some(shared::with(self.app, |app| {
            self.svc
                .lock(|s| f(&mut OnApp::new(&mut s.borrow_mut(), app)))
        }))
    }
}

/// Moves bytes between LPUART1 and the service endpoint.
#[embassy_executor::task]
pub async fn run(port: ServicePort, svc: SharedService, app: SharedApp) {
    common::run_task(port, Shared { svc, app }, &TASK).await
}

/// Wakes the service task (the application pass asks for it: `PassReport::service_due`).
pub fn kick() {
    TASK.kick();
}
