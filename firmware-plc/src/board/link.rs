//! The drive link: USART1, 115200 8N1, TX and RX on DMA (RX into a ring buffer so no byte is
//! lost while the task is busy).

use embassy_stm32::mode::Async;
use embassy_stm32::usart::{
    self, Config, DataBits, Parity, RingBufferedUartRx, StopBits, Uart, UartTx,
};
use embassy_stm32::{bind_interrupts, dma, peripherals};
use embassy_time::{with_timeout, Duration};
use static_cell::StaticCell;

use super::supervisor;
use crate::pins::Link;

/// Default link baud rate (link.md: 115200 by default, must also work at 1 Mbaud).
pub const BAUD: u32 = 115_200;
/// RX ring size: 22 ms of line time at 115200 baud, far more than one task period.
const RX_RING_BYTES: usize = 256;
/// Longest wait for bytes before the task reports alive anyway.
const IDLE_POLL: Duration = Duration::from_millis(5);

bind_interrupts!(struct Irqs {
    USART1 => usart::InterruptHandler<peripherals::USART1>;
    DMA1_CHANNEL1 => dma::InterruptHandler<peripherals::DMA1_CH1>;
    DMA1_CHANNEL2 => dma::InterruptHandler<peripherals::DMA1_CH2>;
});

/// Opened link halves.
#[allow(dead_code)] // TX carries the endpoint's frames once the application is bound (issue 8)
pub struct LinkPort {
    pub tx: UartTx<'static, Async>,
    pub rx: RingBufferedUartRx<'static>,
}

/// Opens the USART at [`BAUD`] 8N1.
pub fn open(l: Link) -> LinkPort {
    static RX_RING: StaticCell<[u8; RX_RING_BYTES]> = StaticCell::new();
    let mut config = Config::default();
    config.baudrate = BAUD;
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

/// Moves bytes between the USART and the PLC link endpoint.
#[embassy_executor::task]
pub async fn run(mut port: LinkPort) {
    let mut buf = [0u8; 64];
    let mut received: u32 = 0;
    loop {
        supervisor::alive(supervisor::TASK_LINK);
        match with_timeout(IDLE_POLL, port.rx.read(&mut buf)).await {
            Ok(Ok(n)) => {
                received = received.wrapping_add(n as u32);
                // Call site of the PLC link endpoint (issue 8): feed `buf[..n]` to the
                // decoder, send its replies through `port.tx`.
                defmt::trace!("link: {} bytes ({} total)", n, received);
            }
            Ok(Err(e)) => defmt::warn!("link: rx error {}", e),
            Err(_timeout) => {}
        }
    }
}
