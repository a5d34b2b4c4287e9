//! The link UART (USART1, 8N1, TX and RX on DMA1 CH1/CH2, RX into a ring buffer) and the
//! task glue around the core's link pump (`shared_protocol::link::pump`). The PLC's
//! service port (LPUART1) runs on the same machinery: [`open_port`] opens any U(S)ART with
//! its DMA channels, and [`run_task`] pumps bytes for any [`SharedEndpoint`] with its own
//! [`Task`] (kick signal, watchdog bit, cycle figures).
//!
//! The task only does I/O: it waits for received bytes, the pump's deadline or a
//! [`kick`] (whichever comes first), hands the bytes to the pump, and writes what the pump
//! hands out. When to send, how much, when to wake, how errors are counted and how often
//! they are logged: all of that is the pump's, host-tested, and hil-sim runs the same
//! pump.
//!
//! Why one task per line:
//! * RX has the internal pull-up: with the peer unplugged or unpowered a floating RX pin
//!   would read a storm of framing and noise errors.
//! * A line error (framing, noise, overrun, parity) never stops reception. The link
//!   and the PLC's service port receive into DMA rings of their own
//!   ([`crate::link_rx`]) that a line error never stops.
//! * Errors are counted by the endpoint (`LinkStats::line_errors`) and logged at most
//!   once a second with the count (`Pump::line_error`).

use embassy_futures::select::{select, Either};
use embassy_stm32::interrupt::typelevel::{Binding, Interrupt};
use embassy_stm32::interrupt::typelevel::{Handler, DMA1_CHANNEL2, USART1};
use embassy_stm32::interrupt::InterruptExt;
use embassy_stm32::mode::Async;
use embassy_stm32::usart::{
    self, Config, DataBits, Parity, RxDma, StopBits, TxDma, Uart, UartRx, UartTx,
};
use embassy_stm32::{bind_interrupts, dma, peripherals, Peri};
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::signal::Signal;
use embassy_time::with_deadline;
use shared_protocol::link::pump::{frame_pieces, LinkEndpoint, Pump, MAX_IDLE_US};
use shared_protocol::link::MAX_WIRE_FRAME;
use shared_protocol::units::Micros;
use static_cell::StaticCell;

use crate::link_rx::{self, Link, RingRx, RxHw, Service, RING_BYTES};
use crate::supervisor;
use crate::time::{instant, now};

// The receiver's handlers first: they take the IDLE and half-transfer flags they use
// (`link_rx`); embassy's then find nothing of theirs (the link's RX is not embassy's).
bind_interrupts!(struct Irqs {
    USART1 => LinkIdle, usart::InterruptHandler<peripherals::USART1>;
    DMA1_CHANNEL1 => dma::InterruptHandler<peripherals::DMA1_CH1>;
    DMA1_CHANNEL2 => LinkHalf, dma::InterruptHandler<peripherals::DMA1_CH2>;
});

/// USART1's interrupt, before embassy's: the link ring's IDLE wake-up.
struct LinkIdle;

impl Handler<USART1> for LinkIdle {
    unsafe fn on_interrupt() {
        link_rx::on_idle::<Link>();
    }
}

/// DMA1 channel 2's interrupt, before embassy's: the link ring's half events.
struct LinkHalf;

impl Handler<DMA1_CHANNEL2> for LinkHalf {
    unsafe fn on_interrupt() {
        link_rx::on_half::<Link>();
    }
}

/// The link's peripherals (pins are the board's: `pins.rs`).
pub struct LinkPins<Tx, Rx> {
    pub usart: Peri<'static, peripherals::USART1>,
    pub tx: Tx,
    pub rx: Rx,
    pub tx_dma: Peri<'static, peripherals::DMA1_CH1>,
    pub rx_dma: Peri<'static, peripherals::DMA1_CH2>,
}

/// An opened port: embassy's DMA transmitter and a receiver `R`.
pub struct Port<R> {
    pub tx: UartTx<'static, Async>,
    pub rx: R,
    /// embassy's receiver half, never read: kept so that the USART's RX (RE, the pin, the
    /// DMA channel's ownership) stays as embassy set it up (dropped, it would turn RX off).
    _embassy_rx: Option<UartRx<'static, Async>>,
}

/// The link's port: its receiver is [`link_rx::RingRx`].
pub type LinkPort = Port<RingRx<Link>>;

/// The PLC's service port: the same ring receiver on its own U(S)ART and channel.
pub type ServicePort = Port<RingRx<Service>>;

/// Opens the link USART 8N1 at `baud` with the RX pull-up and starts its ring receiver
/// ([`link_rx`]).
pub fn open<Tx, Rx>(l: LinkPins<Peri<'static, Tx>, Peri<'static, Rx>>, baud: u32) -> LinkPort
where
    Tx: usart::TxPin<peripherals::USART1>,
    Rx: usart::RxPin<peripherals::USART1>,
{
    static RING: StaticCell<[u8; RING_BYTES]> = StaticCell::new();
    let request = usart::RxDma::<peripherals::USART1>::request(&*l.rx_dma);
    let (tx, rx) = open_uart(l.usart, l.tx, l.rx, l.tx_dma, l.rx_dma, Irqs, baud);
    Port {
        tx,
        rx: link_rx::start(RING.init([0; RING_BYTES]), request),
        _embassy_rx: Some(rx),
    }
}

/// Opens any U(S)ART `T` 8N1 at `baud` with the RX pull-up, TX and RX on the DMA channels
/// `D1`/`D2` (RX into the ring receiver [`Service`], whose handlers `irqs` binds before
/// embassy's, into `rx_ring`), and puts its interrupt and its DMA channels' below TIM1
/// ([`crate::boot::BACKGROUND`]). The PLC's service LPUART1 is opened here.
#[allow(clippy::too_many_arguments)]
pub fn open_port<T, D1, D2>(
    usart: Peri<'static, T>,
    tx: Peri<'static, impl usart::TxPin<T>>,
    rx: Peri<'static, impl usart::RxPin<T>>,
    tx_dma: Peri<'static, D1>,
    rx_dma: Peri<'static, D2>,
    irqs: impl Binding<T::Interrupt, usart::InterruptHandler<T>>
        + Binding<D1::Interrupt, dma::InterruptHandler<D1>>
        + Binding<D2::Interrupt, dma::InterruptHandler<D2>>
        + 'static,
    rx_ring: &'static mut [u8; RING_BYTES],
    baud: u32,
) -> ServicePort
where
    T: usart::Instance,
    D1: TxDma<T>,
    D2: RxDma<T>,
{
    let request = D2::request(&*rx_dma);
    let (tx, rx) = open_uart(usart, tx, rx, tx_dma, rx_dma, irqs, baud);
    Port {
        tx,
        rx: link_rx::start(rx_ring, request),
        _embassy_rx: Some(rx),
    }
}

/// embassy's UART `T` 8N1 at `baud`, RX pull-up, interrupts below TIM1.
fn open_uart<T, D1, D2>(
    usart: Peri<'static, T>,
    tx: Peri<'static, impl usart::TxPin<T>>,
    rx: Peri<'static, impl usart::RxPin<T>>,
    tx_dma: Peri<'static, D1>,
    rx_dma: Peri<'static, D2>,
    irqs: impl Binding<T::Interrupt, usart::InterruptHandler<T>>
        + Binding<D1::Interrupt, dma::InterruptHandler<D1>>
        + Binding<D2::Interrupt, dma::InterruptHandler<D2>>
        + 'static,
    baud: u32,
) -> (UartTx<'static, Async>, UartRx<'static, Async>)
where
    T: usart::Instance,
    D1: TxDma<T>,
    D2: RxDma<T>,
{
    let mut config = Config::default();
    config.baudrate = baud;
    config.data_bits = DataBits::DataBits8;
    config.parity = Parity::ParityNone;
    config.stop_bits = StopBits::STOP1;
    config.rx_pull = embassy_stm32::gpio::Pull::Up;
    let uart = match Uart::new(usart, rx, tx, tx_dma, rx_dma, irqs, config) {
        Ok(uart) => uart,
        Err(e) => defmt::panic!("USART config rejected: {}", e),
    };
    for irq in [T::Interrupt::IRQ, D1::Interrupt::IRQ, D2::Interrupt::IRQ] {
        irq.set_priority(crate::boot::BACKGROUND);
    }
    uart.split()
}

/// A receiver the pump task reads: waits for bytes or a line error.
#[allow(async_fn_in_trait)]
pub trait ByteRx {
    type Error: defmt::Format;
    /// Bytes into `buf` (at least one), or the error that was flagged (reception goes on).
    async fn read_bytes(&mut self, buf: &mut [u8]) -> Result<usize, Self::Error>;
}

impl<H: RxHw> ByteRx for RingRx<H> {
    type Error = link_rx::LineError;
    async fn read_bytes(&mut self, buf: &mut [u8]) -> Result<usize, Self::Error> {
        self.read(buf).await
    }
}

/// What distinguishes one pump task from another: its wake-up signal, its watchdog bit
/// and its cycle figures.
pub struct Task {
    /// In log lines.
    pub name: &'static str,
    /// The supervisor bit reported every pass (0: not supervised).
    pub alive: u32,
    /// Wakes the task for a pass now ([`Task::kick`]).
    pub kick: Signal<CriticalSectionRawMutex, ()>,
    /// Receive and transmit calls, measured with `dwt-cycles`.
    #[cfg(feature = "dwt-cycles")]
    pub rx_cycles: &'static crate::cycles::CycleStat,
    #[cfg(feature = "dwt-cycles")]
    pub tx_cycles: &'static crate::cycles::CycleStat,
}

impl Task {
    /// Wakes the task for a pass now (its endpoint has something due).
    pub fn kick(&self) {
        self.kick.signal(());
    }
}

/// The link task of both boards.
pub static LINK: Task = Task {
    name: "link",
    alive: supervisor::TASK_LINK,
    kick: Signal::new(),
    #[cfg(feature = "dwt-cycles")]
    rx_cycles: &crate::cycles::LINK_RX,
    #[cfg(feature = "dwt-cycles")]
    tx_cycles: &crate::cycles::LINK_TX,
};

/// Wakes the link task for a pass now (the application queued something to send).
/// Call it when `shared_protocol::link::pump::is_due` says the endpoint's deadline has
/// come: the task otherwise sleeps until the deadline it knew.
pub fn kick() {
    LINK.kick();
}

/// How the link task reaches the endpoint the board shares with its other tasks.
pub trait SharedEndpoint {
    /// The endpoint, possibly a view borrowing more than one shared object for one call
    /// (the PLC's service on its application).
    type Endpoint<'a>: LinkEndpoint;
    /// Runs `f` on the endpoint (inside whatever lock the board uses); `None` when it is
    /// not there yet.
    fn with<R>(&self, f: impl for<'a> FnOnce(&mut Self::Endpoint<'a>) -> R) -> Option<R>;
}

/// The link task's loop: never returns. Each board wraps it in its own
/// `#[embassy_executor::task]` (tasks cannot be generic).
///
/// The three parts of a pass (receive, transmit, the application's reaction) run in
/// separate calls of [`SharedEndpoint::with`], so that none holds the board's lock for
/// all (the drive's lock masks the PWM interrupt; `dwt-cycles` measures the first two),
/// and the reaction runs after the pass's frame was written.
pub async fn run<S: SharedEndpoint>(port: LinkPort, shared: S) -> ! {
    run_task(port, shared, &LINK).await
}

/// [`run`] for any pump task: the same loop with `task`'s kick signal, watchdog bit and
/// cycle figures.
pub async fn run_task<S: SharedEndpoint, R: ByteRx>(
    mut port: Port<R>,
    shared: S,
    task: &Task,
) -> ! {
    let mut pump = Pump::new(MAX_IDLE_US);
    let mut rx_buf = [0u8; 64];
    let mut wake = now();
    loop {
        supervisor::alive(task.alive);
        let read = with_deadline(instant(wake), port.rx.read_bytes(&mut rx_buf));
        let n = match select(read, task.kick.wait()).await {
            Either::First(Ok(Ok(n))) => n,
            Either::First(Ok(Err(e))) => {
                // Reception goes on with the next byte (see the module doc).
                let t = now();
                if let Some(Some(count)) = shared.with(|ep| pump.line_error(ep, t)) {
                    defmt::warn!(
                        "{=str}: {=u32} line error(s), the last {}",
                        task.name,
                        count,
                        e
                    );
                }
                0
            }
            Either::First(Err(_)) | Either::Second(()) => 0,
        };
        let rx = rx_buf.get(..n).unwrap_or(&[]);
        // One frame at most per call (one critical section on the drive).
        for piece in frame_pieces(rx) {
            let t = now();
            #[cfg(feature = "dwt-cycles")]
            let start = crate::cycles::now();
            shared.with(|ep| pump.receive(ep, piece, t));
            #[cfg(feature = "dwt-cycles")]
            task.rx_cycles.record(start);
        }
        let t = now();
        #[cfg(feature = "dwt-cycles")]
        let start = crate::cycles::now();
        // The transmitter is free here (the last write was awaited): a whole frame fits.
        let pass = shared.with(|ep| pump.transmit(ep, MAX_WIRE_FRAME, t));
        #[cfg(feature = "dwt-cycles")]
        task.tx_cycles.record(start);
        wake = pass.map_or(Micros(t.0 + MAX_IDLE_US), |p| p.wake_at);
        let tx = pump.tx();
        if !tx.is_empty() {
            if let Err(e) = port.tx.write(tx).await {
                defmt::warn!("{=str}: tx error {}", task.name, e);
            }
        }
        // The application's reaction to what arrived, once the frame (an acknowledgement,
        // say) is out: a slow one (the PLC's EEPROM fault log) never delays it.
        let t = now();
        if let Some(w) = shared.with(|ep| pump.service(ep, t)) {
            wake = w;
        }
    }
}
