//! The PLC link: USART1, 115200 8N1, TX and RX on DMA (RX into a ring buffer so no byte is
//! lost while the task is busy).

use embassy_stm32::mode::Async;
use embassy_stm32::usart::{
    self, Config, DataBits, Parity, RingBufferedUartRx, StopBits, Uart, UartTx,
};
use embassy_stm32::{bind_interrupts, dma, peripherals};
use embassy_time::{with_timeout, Duration};
use static_cell::StaticCell;

use shared_protocol::link::MAX_WIRE_FRAME;

use super::{shared, supervisor};
use crate::pins::Link;

/// RX ring size: 22 ms of line time at 115200 baud, far more than one task period.
const RX_RING_BYTES: usize = 256;
/// Longest wait for bytes: the endpoint's transmit queue needs a poll every millisecond.
const POLL: Duration = Duration::from_millis(1);

bind_interrupts!(struct Irqs {
    USART1 => usart::InterruptHandler<peripherals::USART1>;
    DMA1_CHANNEL1 => dma::InterruptHandler<peripherals::DMA1_CH1>;
    DMA1_CHANNEL2 => dma::InterruptHandler<peripherals::DMA1_CH2>;
});

/// Opened link halves.
pub struct LinkPort {
    pub tx: UartTx<'static, Async>,
    pub rx: RingBufferedUartRx<'static>,
}

/// Opens the USART 8N1 at the link configuration's baud rate (115200 by default).
pub fn open(l: Link, baud: u32) -> LinkPort {
    static RX_RING: StaticCell<[u8; RX_RING_BYTES]> = StaticCell::new();
    let mut config = Config::default();
    config.baudrate = baud;
    config.data_bits = DataBits::DataBits8;
    config.parity = Parity::ParityNone;
    config.stop_bits = StopBits::STOP1;
    let uart = match Uart::new(l.usart, l.rx, l.tx, l.tx_dma, l.rx_dma, Irqs, config) {
        Ok(uart) => uart,
        Err(e) => defmt::panic!("link USART config rejected: {}", e),
    };
    let (tx, rx) = uart.split();
    LinkPort {
        tx,
        rx: rx.into_ring_buffered(RX_RING.init([0; RX_RING_BYTES])),
    }
}

/// Moves bytes between the USART and the application's link endpoint: received bytes go in
/// as they arrive (commands reach the core at once), and the endpoint is polled for frames
/// at least every millisecond. Link events are logged by the control task.
#[embassy_executor::task]
pub async fn run(mut port: LinkPort) {
    let mut rx_buf = [0u8; 64];
    let mut frame = [0u8; MAX_WIRE_FRAME];
    loop {
        supervisor::alive(supervisor::TASK_LINK);
        match with_timeout(POLL, port.rx.read(&mut rx_buf)).await {
            Ok(Ok(n)) => {
                let bytes = rx_buf.get(..n).unwrap_or(&[]);
                shared::with(|s| s.app.on_rx(bytes, shared::now()));
            }
            Ok(Err(e)) => defmt::warn!("link: rx error {}", e),
            Err(_timeout) => {}
        }
        // At most one frame per pass, then RX again (the PLC's link task had a whole
        // window's worth of line time between two reads: see the PLC's board/link.rs).
        let n = shared::with(|s| s.app.poll_tx(shared::now(), &mut frame)).unwrap_or(0);
        if let Some(bytes) = frame.get(..n).filter(|b| !b.is_empty()) {
            if let Err(e) = port.tx.write(bytes).await {
                defmt::warn!("link: tx error {}", e);
            }
        }
    }
}
