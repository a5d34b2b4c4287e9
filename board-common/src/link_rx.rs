//! A U(S)ART receiver into a DMA ring that never stops, register bindings only (review
//! N13): the link's (USART1 RX on DMA1 channel 2, both images, [`Link`]) and the PLC's
//! service port's (LPUART1 RX on DMA1 channel 4, [`Service`]). Each is an [`RxHw`]: the
//! peripheral, the channel and the state its interrupts share with its task.
//!
//! Why not embassy's `RingBufferedUartRx`: after a line error it stops the channel (EN = 0)
//! and restarts it by setting EN again without reprogramming CNDTR/CMAR, which RM0440
//! ("DMA channel state and disabling a channel") does not support; g431-emu models that
//! and the link (and the service port) was lost. Here the USART keeps CR3.DDRE = 0 (its
//! reset value, which embassy never changes; RM0440 USART CR3 "DDRE": "DMA is not disabled
//! in case of reception error. The corresponding error flag is set but RXNE is kept 0 ...
//! the erroneous data is not transferred, but next correct received data is transferred"),
//! and CR3.EIE = 0, so a line error never interrupts and never stops anything: the task
//! reads the error flags (FE, NE, ORE, PE) when it polls the ring and clears them.
//!
//! What it decides is core code with host tests: where the new bytes are and whether the
//! DMA lapped the reader (`shared_protocol::link::rx_ring`); how errors are counted and
//! logged (the pump). The task is woken by the USART's IDLE interrupt (a frame's end) and
//! the channel's half-transfer and transfer-complete interrupts (a long burst), both
//! handled here ([`on_idle`], [`on_half`], called from handlers bound before embassy's,
//! which find nothing left to do).
//!
//! LPUART1's ISR, ICR, RDR, CR1 (IDLEIE) and CR3 (EIE, DMAR) have USART1's offsets and
//! bits (RM0440 LPUART and USART register maps), so both are driven through the USART
//! register block.

use core::future::poll_fn;
use core::marker::PhantomData;
use core::sync::atomic::{compiler_fence, AtomicU32, Ordering};
use core::task::Poll;

use embassy_stm32::pac;
use embassy_stm32::pac::bdma::vals::{Dir, Size};
use embassy_stm32::pac::usart::Usart;
use embassy_sync::waitqueue::AtomicWaker;
use shared_protocol::link::rx_ring::{RingRead, RingReader};

/// Ring size: 22 ms of line time at 115200 baud, more than a frame's write (the task
/// awaits it) plus a pass. Even (the half events split it).
pub const RING_BYTES: usize = 256;

/// USART ISR/ICR bits: PE, FE, NE, ORE (RM0440 USART ISR, ICR: the clear bits are at the
/// same positions).
const PE: u32 = 1 << 0;
const FE: u32 = 1 << 1;
const NE: u32 = 1 << 2;
const ORE: u32 = 1 << 3;
const IDLE: u32 = 1 << 4;

/// What a receiver's interrupts share with its task.
pub struct RxState {
    /// Half events (half transfer, transfer complete) the channel's interrupt counted.
    halves: AtomicU32,
    /// The task waiting for bytes.
    waker: AtomicWaker,
}

impl RxState {
    const fn new() -> Self {
        RxState {
            halves: AtomicU32::new(0),
            waker: AtomicWaker::new(),
        }
    }
}

/// One receiver's hardware: its U(S)ART, its DMA1 channel and its shared state (a type,
/// so each receiver's code is built with its constants).
pub trait RxHw: 'static {
    /// The U(S)ART's register block.
    const USART: Usart;
    /// DMA1 channel index (channel n is index n - 1); DMA1's channels 1-6 are DMAMUX1's
    /// channels 0-5 (RM0440 "DMAMUX mapping"), so it is also the DMAMUX channel.
    const CH: usize;
    /// What its interrupts share with its task.
    fn state() -> &'static RxState;
}

/// The link: USART1 RX on DMA1 channel 2.
pub struct Link;

impl RxHw for Link {
    const USART: Usart = pac::USART1;
    const CH: usize = 1;
    fn state() -> &'static RxState {
        static STATE: RxState = RxState::new();
        &STATE
    }
}

/// The PLC's service port: LPUART1 RX on DMA1 channel 4 (same register layout as
/// USART1's for what is used here, see the module doc).
pub struct Service;

impl RxHw for Service {
    // SAFETY: LPUART1's address; only registers with USART1's offsets and bits are used.
    const USART: Usart = unsafe { Usart::from_ptr(pac::LPUART1.as_ptr()) };
    const CH: usize = 3;
    fn state() -> &'static RxState {
        static STATE: RxState = RxState::new();
        &STATE
    }
}

/// A line error the USART flagged (the first of the flags set, in this order).
#[derive(Debug, Clone, Copy, PartialEq, Eq, defmt::Format)]
pub enum LineError {
    Framing,
    Noise,
    Overrun,
    Parity,
    /// The DMA came round to bytes not yet read (the task was late by a ring's time).
    RingOverrun,
}

/// The receiver: the ring and the reader's position.
pub struct RingRx<H: RxHw> {
    ring: *const u8,
    reader: RingReader,
    _hw: PhantomData<H>,
}

/// Programs the channel (circular, peripheral to memory, bytes, half and complete
/// interrupts) of `H` into `ring` on `request` (DMAMUX request of its U(S)ART's RX), then
/// enables the U(S)ART's DMA request and IDLE interrupt. Called once per receiver, after
/// embassy opened the U(S)ART (RE, baud, pin).
pub fn start<H: RxHw>(ring: &'static mut [u8; RING_BYTES], request: u8) -> RingRx<H> {
    let ring = ring.as_mut_ptr();
    let usart = H::USART;
    let ch = pac::DMA1.ch(H::CH);
    // RM0440 "Channel configuration procedure": addresses, count, request, then CCR with EN.
    ch.cr().write(|w| w.set_en(false));
    ch.par().write_value(usart.rdr().as_ptr() as u32);
    ch.mar().write_value(ring as u32);
    ch.ndtr().write(|w| w.set_ndt(RING_BYTES as u16));
    pac::DMAMUX1.ccr(H::CH).write(|w| w.set_dmareq_id(request));
    ch.cr().write(|w| {
        w.set_dir(Dir::FROM_PERIPHERAL);
        w.set_minc(true);
        w.set_circ(true);
        w.set_psize(Size::BITS8);
        w.set_msize(Size::BITS8);
        w.set_htie(true);
        w.set_tcie(true);
        w.set_en(true);
    });
    // Flags from before the start (bytes on a floating line) are not this ring's.
    usart.icr().write(|w| w.0 = PE | FE | NE | ORE | IDLE);
    usart.cr1().modify(|w| w.set_idleie(true));
    usart.cr3().modify(|w| {
        w.set_eie(false);
        w.set_dmar(true);
    });
    RingRx {
        ring,
        reader: RingReader::new(RING_BYTES as u16),
        _hw: PhantomData,
    }
}

impl<H: RxHw> RingRx<H> {
    /// Waits until bytes arrived or a line error was flagged; the bytes into `buf` (as
    /// many as fit; the rest stay for the next call).
    pub async fn read(&mut self, buf: &mut [u8]) -> Result<usize, LineError> {
        poll_fn(|cx| {
            H::state().waker.register(cx.waker());
            match self.poll(buf) {
                Ok(0) => Poll::Pending,
                r => Poll::Ready(r),
            }
        })
        .await
    }

    /// Error flags first (read and cleared), then the new bytes.
    fn poll(&mut self, buf: &mut [u8]) -> Result<usize, LineError> {
        let usart = H::USART;
        let flags = usart.isr().read().0 & (PE | FE | NE | ORE);
        if flags != 0 {
            usart.icr().write(|w| w.0 = flags);
            return Err(if flags & FE != 0 {
                LineError::Framing
            } else if flags & NE != 0 {
                LineError::Noise
            } else if flags & ORE != 0 {
                LineError::Overrun
            } else {
                LineError::Parity
            });
        }
        // The count and the position read as a pair: again if an event came in between.
        let (remaining, halves) = loop {
            let halves = H::state().halves.load(Ordering::Acquire);
            let remaining = pac::DMA1.ch(H::CH).ndtr().read().ndt();
            if H::state().halves.load(Ordering::Acquire) == halves {
                break (remaining, halves);
            }
        };
        let (first, second) = match self.reader.poll(remaining, halves, buf.len()) {
            RingRead::Overrun => return Err(LineError::RingOverrun),
            RingRead::Bytes { first, second } => (first, second),
        };
        compiler_fence(Ordering::Acquire);
        let mut n = 0;
        for (i, slot) in first.chain(second).zip(buf.iter_mut()) {
            // SAFETY: `i` < RING_BYTES (the reader's ranges are inside the ring); the DMA
            // writes bytes the reader has not been given, never these.
            *slot = unsafe { core::ptr::read_volatile(self.ring.add(i)) };
            n += 1;
        }
        Ok(n)
    }
}

/// The U(S)ART's interrupt, before embassy's: the IDLE flag (a frame's end) wakes the
/// task.
pub fn on_idle<H: RxHw>() {
    if H::USART.isr().read().0 & IDLE != 0 {
        H::USART.icr().write(|w| w.0 = IDLE);
        H::state().waker.wake();
    }
}

/// The DMA channel's interrupt, before embassy's: counts the half events and wakes the
/// task.
pub fn on_half<H: RxHw>() {
    let dma = pac::DMA1;
    let isr = dma.isr().read();
    let (ht, tc) = (isr.htif(H::CH), isr.tcif(H::CH));
    if ht || tc {
        dma.ifcr().write(|w| {
            w.set_htif(H::CH, ht);
            w.set_tcif(H::CH, tc);
        });
        H::state()
            .halves
            .fetch_add(u32::from(ht) + u32::from(tc), Ordering::Release);
        H::state().waker.wake();
    }
}
