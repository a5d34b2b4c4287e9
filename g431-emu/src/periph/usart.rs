//! USART1-3, UART4 and LPUART1: the "usart_v4" register set of RM0440 §37 (USART/UART) and
//! §38 (LPUART), as embassy-stm32 0.6 drives it (`usart/mod.rs`, `usart/ringbuffered.rs`).
//!
//! What the images rely on, and therefore what this model does exactly:
//! * embassy's `configure` always sets FIFOEN (usart_v4), so FIFO mode is the normal case:
//!   an 8-deep TXFIFO in front of the shift register, and an RXFIFO of 8 behind RDR (RXFF is
//!   "RXFIFO full + 1 data in RDR", RM0440 USART_ISR.RXFF). Without FIFOEN, TDR and RDR are
//!   single registers.
//! * Timing in CPU cycles from BRR, PRESC, OVER8 and the kernel clock RCC selects
//!   ([`Usart::set_kernel_clock_hz`]). At the images' 170 MHz PCLK a USART bit is
//!   `BRR·presc` cycles, `USARTDIV·presc/2` with OVER8 (USARTDIV is even there: `BRR[2:0]`
//!   holds `USARTDIV[3:1]`), and an LPUART bit `BRR·presc/256` cycles. Line times are kept
//!   in 1/512 cycle so that back-to-back LPUART frames at a fractional bit time do not
//!   drift.
//! * TX: a word written to TDR moves to the shift register as soon as it is free (TXE/TXFNF
//!   sets again then) and is on the wire for one frame (start + word + stop bits); TC sets
//!   when a data frame ends with nothing left to send. Setting TE (with UE) first sends an
//!   idle frame (preamble), as RM0440 §37 "Character transmission" describes.
//! * RX: bytes arrive from outside ([`Usart::push_rx`]) with the cycle their stop bit ends;
//!   RXNE/RXFNE sets then. A byte completing while RDR (FIFO mode: RDR and RXFIFO) is full is
//!   lost and sets ORE, unless OVRDIS (then RDR is overwritten and the FIFO bypassed). IDLE
//!   sets one idle frame after the last byte (not again until a new byte). FE/NE come with a
//!   byte the outside marks; PE is computed from the received word. In FIFO mode the error
//!   flags belong to the word in RDR, so they set when that word reaches RDR. With DMAR set
//!   and DDRE clear, an erroneous word sets its flag but is discarded (RXNE kept 0), as the
//!   DDRE description says.
//! * Interrupt (level) per RM0440's USART interrupt table; the error interrupt follows the
//!   flag descriptions: FE and ORE with EIE, NE with EIE only in multibuffer (DMAR)
//!   communication, ORE also with RXNEIE.
//! * DMA requests (level): RX while RXNE/RXFNE and DMAR (masked by an error flag when DDRE);
//!   TX while TXE/TXFNF, DMAT and TE. Both drop while UE = 0.
//!
//! Not modelled, and reported through [`Usart::take_reports`] when software turns them on:
//! synchronous/SPI mode, LIN, IrDA, smartcard, half-duplex, RS-485 driver enable, hardware
//! flow control, mute mode, character match, receiver timeout, auto baud rate, break
//! transmission, pin swap and signal/data inversion, MSB first, wake-up from Stop.

use std::collections::VecDeque;

use super::reports::DistinctReports;
use super::{DmaRequests, IrqLines, Peripheral, Write};
use crate::names;
use crate::time::{Cycles, HCLK_HZ};

/// Line times are counted in 1/`SUB` CPU cycle: an LPUART bit is a multiple of 1/256 cycle
/// (BRR·presc/256), and a 0.5 or 1.5 stop bit halves a bit.
pub const SUB: u64 = 512;

/// Depth of the TXFIFO and RXFIFO (RM0440 §37.3 / §38.3: 8 data).
const FIFO_DEPTH: usize = 8;

// Register offsets (RM0440 USART/LPUART register maps).
const CR1: u32 = 0x00;
const CR2: u32 = 0x04;
const CR3: u32 = 0x08;
const BRR: u32 = 0x0c;
const GTPR: u32 = 0x10;
const RTOR: u32 = 0x14;
const RQR: u32 = 0x18;
const ISR: u32 = 0x1c;
const ICR: u32 = 0x20;
const RDR: u32 = 0x24;
const TDR: u32 = 0x28;
const PRESC: u32 = 0x2c;

// CR1
const CR1_UE: u32 = 1 << 0;
const CR1_RE: u32 = 1 << 2;
const CR1_TE: u32 = 1 << 3;
const CR1_IDLEIE: u32 = 1 << 4;
const CR1_RXNEIE: u32 = 1 << 5;
const CR1_TCIE: u32 = 1 << 6;
const CR1_TXEIE: u32 = 1 << 7;
const CR1_PEIE: u32 = 1 << 8;
const CR1_PS: u32 = 1 << 9;
const CR1_PCE: u32 = 1 << 10;
const CR1_M0: u32 = 1 << 12;
const CR1_MME: u32 = 1 << 13;
const CR1_CMIE: u32 = 1 << 14;
const CR1_OVER8: u32 = 1 << 15;
const CR1_RTOIE: u32 = 1 << 26;
const CR1_EOBIE: u32 = 1 << 27;
const CR1_M1: u32 = 1 << 28;
const CR1_FIFOEN: u32 = 1 << 29;
const CR1_TXFEIE: u32 = 1 << 30;
const CR1_RXFFIE: u32 = 1 << 31;
/// CR1 fields RM0440 allows to be written only while UE = 0: PS, PCE, WAKE, M0, OVER8, DEDT,
/// DEAT, M1, FIFOEN.
const CR1_UE0_ONLY: u32 = 0x33ff_9e00;
const CR1_VALID_USART: u32 = 0xffff_ffff;
/// LPUART1 has no OVER8, RTOIE, EOBIE.
const CR1_VALID_LPUART: u32 = !(CR1_OVER8 | CR1_RTOIE | CR1_EOBIE);

// CR2
const CR2_SLVEN: u32 = 1 << 0;
const CR2_LBDIE: u32 = 1 << 6;
const CR2_CLKEN: u32 = 1 << 11;
const CR2_STOP_SHIFT: u32 = 12;
const CR2_LINEN: u32 = 1 << 14;
const CR2_SWAP: u32 = 1 << 15;
const CR2_RXINV: u32 = 1 << 16;
const CR2_TXINV: u32 = 1 << 17;
const CR2_DATAINV: u32 = 1 << 18;
const CR2_MSBFIRST: u32 = 1 << 19;
const CR2_ABREN: u32 = 1 << 20;
const CR2_RTOEN: u32 = 1 << 23;
const CR2_VALID_USART: u32 = 0xffff_ff79;
/// LPUART1: ADDM7, STOP, SWAP, RXINV, TXINV, DATAINV, MSBFIRST, ADD.
const CR2_VALID_LPUART: u32 = 0xff0f_b010;
/// CR2 fields writable at any time (LBDIE, ABREN, RTOEN); the rest only while UE = 0.
const CR2_ANY_TIME: u32 = CR2_LBDIE | CR2_ABREN | CR2_RTOEN;

// CR3
const CR3_EIE: u32 = 1 << 0;
const CR3_IREN: u32 = 1 << 1;
const CR3_HDSEL: u32 = 1 << 3;
const CR3_SCEN: u32 = 1 << 5;
const CR3_DMAR: u32 = 1 << 6;
const CR3_DMAT: u32 = 1 << 7;
const CR3_RTSE: u32 = 1 << 8;
const CR3_CTSE: u32 = 1 << 9;
const CR3_CTSIE: u32 = 1 << 10;
const CR3_ONEBIT: u32 = 1 << 11;
const CR3_OVRDIS: u32 = 1 << 12;
const CR3_DDRE: u32 = 1 << 13;
const CR3_DEM: u32 = 1 << 14;
const CR3_WUFIE: u32 = 1 << 22;
const CR3_TXFTIE: u32 = 1 << 23;
const CR3_TCBGTIE: u32 = 1 << 24;
const CR3_RXFTCFG_SHIFT: u32 = 25;
const CR3_RXFTIE: u32 = 1 << 28;
const CR3_TXFTCFG_SHIFT: u32 = 29;
const CR3_VALID_USART: u32 = 0xfffe_ffff;
/// LPUART1: no IREN, IRLP, NACK, SCEN, ONEBIT, SCARCNT, TCBGTIE.
const CR3_VALID_LPUART: u32 = 0xfef0_f7c9;
/// CR3 fields RM0440 allows to be written only while UE = 0: IREN, IRLP, HDSEL, NACK,
/// SCEN, RTSE, CTSE, ONEBIT, OVRDIS, DDRE, DEM, DEP, SCARCNT, WUS.
const CR3_UE0_ONLY: u32 = 0x003e_fb3e;

// ISR / ICR
const ISR_PE: u32 = 1 << 0;
const ISR_FE: u32 = 1 << 1;
const ISR_NE: u32 = 1 << 2;
const ISR_ORE: u32 = 1 << 3;
const ISR_IDLE: u32 = 1 << 4;
const ISR_RXNE: u32 = 1 << 5;
const ISR_TC: u32 = 1 << 6;
const ISR_TXE: u32 = 1 << 7;
const ISR_BUSY: u32 = 1 << 16;
const ISR_TEACK: u32 = 1 << 21;
const ISR_REACK: u32 = 1 << 22;
const ISR_TXFE: u32 = 1 << 23;
const ISR_RXFF: u32 = 1 << 24;
const ISR_RXFT: u32 = 1 << 26;
const ISR_TXFT: u32 = 1 << 27;
/// ICR bit 5 clears TXFE (TXFECF), bit 6 TC (TCCF); 0-4 clear PE, FE, NE, ORE, IDLE.
const ICR_TXFECF: u32 = 1 << 5;

// RQR
const RQR_ABRRQ: u32 = 1 << 0;
const RQR_SBKRQ: u32 = 1 << 1;
const RQR_MMRQ: u32 = 1 << 2;
const RQR_RXFRQ: u32 = 1 << 3;
const RQR_TXFRQ: u32 = 1 << 4;

/// One of the G431's U(S)ARTs. All use the same register block; LPUART1 has a 20-bit BRR
/// in 1/256 of the kernel clock and lacks the synchronous, smartcard, IrDA and LIN fields.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum UsartInstance {
    Usart1,
    Usart2,
    Usart3,
    Uart4,
    Lpuart1,
}

impl UsartInstance {
    /// Peripheral name in the STM32 metadata (`"USART2"`).
    pub fn name(self) -> &'static str {
        match self {
            UsartInstance::Usart1 => "USART1",
            UsartInstance::Usart2 => "USART2",
            UsartInstance::Usart3 => "USART3",
            UsartInstance::Uart4 => "UART4",
            UsartInstance::Lpuart1 => "LPUART1",
        }
    }

    pub fn is_lpuart(self) -> bool {
        self == UsartInstance::Lpuart1
    }

    /// Base address from the metadata.
    pub fn base(self) -> Option<u32> {
        names::base(self.name())
    }
}

/// Parity as programmed (PCE, PS).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Parity {
    None,
    Even,
    Odd,
}

/// The character format and bit time a USART is programmed for, so that whoever wires two
/// of them can check that both ends agree (RM0440 §37 "USART character description").
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LineConfig {
    /// One bit on the line, in 1/[`SUB`] CPU cycle.
    pub bit_time_sub: u64,
    /// Bits between the start bit and the stop bits, parity included (7, 8 or 9).
    pub word_bits: u8,
    pub parity: Parity,
    /// Stop bits in half bits: 1 = 0.5, 2 = 1, 3 = 1.5, 4 = 2.
    pub stop_half_bits: u8,
}

impl LineConfig {
    /// The baud rate this bit time gives (CPU cycles at 170 MHz).
    pub fn baud_hz(&self) -> f64 {
        (HCLK_HZ as f64) * (SUB as f64) / (self.bit_time_sub.max(1) as f64)
    }

    /// One frame (start + word + stop bits) in 1/[`SUB`] cycle.
    pub fn frame_sub(&self) -> u64 {
        let half_bits = 2 * (1 + u64::from(self.word_bits)) + u64::from(self.stop_half_bits);
        self.bit_time_sub * half_bits / 2
    }

    /// One frame in whole cycles (rounded up).
    pub fn frame_cycles(&self) -> Cycles {
        self.frame_sub().div_ceil(SUB)
    }
}

/// A character arriving on RX. `data` is the whole word (parity bit included, as it was on
/// the line); FE and NE cannot be derived from a word, so the outside marks them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RxByte {
    pub data: u16,
    /// The stop bit was sampled low (de-synchronisation, break, a floating line).
    pub framing_error: bool,
    /// The samples of a bit disagreed (ignored when ONEBIT is set).
    pub noise: bool,
}

impl RxByte {
    pub fn clean(data: u16) -> Self {
        RxByte {
            data,
            framing_error: false,
            noise: false,
        }
    }
}

/// A character on the TX line: its start bit begins at `start`, its last stop bit ends at
/// `end` (both in cycles, rounded up), `data` is the word as on the line (parity included).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TxFrame {
    pub start: Cycles,
    pub end: Cycles,
    pub data: u16,
}

/// What occupies the transmit shift register.
#[derive(Debug, Clone, Copy)]
struct Shift {
    end_sub: u64,
    /// `None`: the idle frame (preamble) sent after TE is set.
    data: Option<u16>,
}

/// A received word in RDR or the RXFIFO, with the errors it arrived with.
#[derive(Debug, Clone, Copy)]
struct RxEntry {
    data: u16,
    pe: bool,
    fe: bool,
    ne: bool,
}

/// The register model of one U(S)ART.
#[derive(Debug)]
pub struct Usart {
    instance: UsartInstance,
    /// The kernel clock RCC selects for this instance (RCC_CCIPR and the APB prescaler),
    /// Hz; `None`: a source the emulator does not model (LSE), nothing is timed.
    kernel_hz: Option<u64>,
    irq: Option<u16>,
    rx_request: Option<u8>,
    tx_request: Option<u8>,
    cr1: u32,
    cr2: u32,
    cr3: u32,
    brr: u32,
    gtpr: u32,
    rtor: u32,
    presc: u32,
    tdr: u16,
    rdr: u16,
    // Latched ISR flags (the others are computed from the state).
    pe: bool,
    fe: bool,
    ne: bool,
    ore: bool,
    idle: bool,
    tc: bool,
    txfe: bool,
    /// TDR (no FIFO) or TXFIFO contents, oldest first.
    tx_queue: VecDeque<u16>,
    shift: Option<Shift>,
    /// TE went 0 → 1 while a frame was on the line: the preamble follows it.
    preamble_pending: bool,
    /// Frames that have started on the line and not yet been taken by the SoC.
    tx_started: VecDeque<TxFrame>,
    /// RDR (head) and RXFIFO.
    rx_store: VecDeque<RxEntry>,
    /// Characters on their way, by the cycle their stop bit ends.
    rx_incoming: VecDeque<(Cycles, RxByte)>,
    /// Cycle since which the receiver has been enabled (UE and RE), if it is.
    rx_enabled_at: Option<Cycles>,
    /// When IDLE will set if no start bit comes first.
    idle_at: Option<Cycles>,
    /// When IDLE last set (to notice a character pushed too late to cancel it).
    idle_set_at: Option<Cycles>,
    now: Cycles,
    reports: DistinctReports,
}

impl Usart {
    /// The USART at reset, with its NVIC line and DMAMUX request IDs from the metadata.
    pub fn new(instance: UsartInstance) -> Self {
        let name = instance.name();
        Usart {
            instance,
            kernel_hz: Some(HCLK_HZ),
            irq: names::irq(name),
            rx_request: names::dma_request(name, "RX"),
            tx_request: names::dma_request(name, "TX"),
            cr1: 0,
            cr2: 0,
            cr3: 0,
            brr: 0,
            gtpr: 0,
            rtor: 0,
            presc: 0,
            tdr: 0,
            rdr: 0,
            pe: false,
            fe: false,
            ne: false,
            ore: false,
            idle: false,
            tc: true,
            txfe: true,
            tx_queue: VecDeque::new(),
            shift: None,
            preamble_pending: false,
            tx_started: VecDeque::new(),
            rx_store: VecDeque::new(),
            rx_incoming: VecDeque::new(),
            rx_enabled_at: None,
            idle_at: None,
            idle_set_at: None,
            now: 0,
            reports: DistinctReports::default(),
        }
    }

    pub fn instance(&self) -> UsartInstance {
        self.instance
    }

    /// NVIC line of this instance.
    pub fn irq(&self) -> Option<u16> {
        self.irq
    }

    /// DMAMUX request IDs (RX, TX).
    pub fn dma_request_ids(&self) -> (Option<u8>, Option<u8>) {
        (self.rx_request, self.tx_request)
    }

    /// The next frame that has started on the TX line, oldest first. A frame is handed out
    /// when its start bit begins, with the cycle its stop bit will end: the receiving end
    /// needs it that early for BUSY and for IDLE (a start bit within the idle frame cancels
    /// the idle detection). Feed it to the peer with `push_rx(frame.end, ..)`.
    pub fn take_tx(&mut self) -> Option<TxFrame> {
        self.tx_started.pop_front()
    }

    /// A character whose stop bit ends at cycle `at` (now or later). Characters must be
    /// pushed before the model is advanced past `at - frame` for BUSY and IDLE to be exact;
    /// one pushed for a past cycle is still received, at the next `advance`.
    pub fn push_rx(&mut self, at: Cycles, byte: RxByte) {
        if at < self.now {
            self.reports.once(format!(
                "{}: RX character pushed for a cycle the model has passed (received late)",
                self.instance.name()
            ));
        }
        let frame = self.line_config().map_or(0, |c| c.frame_cycles());
        if self
            .idle_set_at
            .is_some_and(|i| at.saturating_sub(frame) <= i && i < at)
        {
            self.reports.once(format!(
                "{}: RX character pushed after IDLE was set although its start bit came \
                 first (push characters at their start bit)",
                self.instance.name()
            ));
        }
        let pos = self
            .rx_incoming
            .iter()
            .position(|(t, _)| *t > at)
            .unwrap_or(self.rx_incoming.len());
        self.rx_incoming.insert(pos, (at, byte));
    }

    /// The cycle at which the receiver will detect an idle line (one idle frame after the
    /// last character) unless a start bit comes first, if it is waiting for one. A
    /// co-simulation runs the sending side up to this cycle before this side passes it, so
    /// that a start bit inside the idle frame cancels the detection as on the line.
    pub fn idle_deadline(&self) -> Option<Cycles> {
        self.idle_at
    }

    /// Bit time and character format as programmed, or `None` while BRR is below the minimum
    /// RM0440 allows (16, or 0x300 for LPUART1), in which case nothing is transmitted.
    pub fn line_config(&self) -> Option<LineConfig> {
        let presc: u64 = match self.presc & 0xf {
            0 => 1,
            1 => 2,
            2 => 4,
            3 => 6,
            4 => 8,
            5 => 10,
            6 => 12,
            7 => 16,
            8 => 32,
            9 => 64,
            10 => 128,
            _ => 256,
        };
        // A bit in kernel clock periods, as a fraction `ticks / per`.
        let (ticks, per): (u64, u64) = if self.instance.is_lpuart() {
            let brr = u64::from(self.brr & 0xf_ffff);
            if brr < 0x300 {
                return None;
            }
            (brr * presc, 256)
        } else if self.cr1 & CR1_OVER8 != 0 {
            let brr = u64::from(self.brr & 0xffff);
            let usartdiv = (brr & 0xfff0) | ((brr & 0x7) << 1);
            if usartdiv < 16 {
                return None;
            }
            (usartdiv * presc, 2)
        } else {
            let brr = u64::from(self.brr & 0xffff);
            if brr < 16 {
                return None;
            }
            (brr * presc, 1)
        };
        // In 1/SUB CPU cycle: exact at the 170 MHz kernel clock, rounded to the nearest
        // 1/SUB cycle for another (HSI16: 10.625 CPU cycles per kernel period, exact too).
        let kernel = u128::from(self.kernel_hz?.max(1));
        let num = u128::from(ticks) * u128::from(SUB) * u128::from(HCLK_HZ);
        let den = u128::from(per) * kernel;
        let bit_time_sub = u64::try_from((num + den / 2) / den).unwrap_or(u64::MAX);
        let word_bits = match (self.cr1 & CR1_M1 != 0, self.cr1 & CR1_M0 != 0) {
            (false, false) => 8,
            (false, true) => 9,
            (true, false) => 7,
            // Reserved; reported when written.
            (true, true) => 8,
        };
        let parity = match (self.cr1 & CR1_PCE != 0, self.cr1 & CR1_PS != 0) {
            (false, _) => Parity::None,
            (true, false) => Parity::Even,
            (true, true) => Parity::Odd,
        };
        let stop_half_bits = match (self.cr2 >> CR2_STOP_SHIFT) & 3 {
            0 => 2,
            1 if !self.instance.is_lpuart() => 1,
            2 => 4,
            3 if !self.instance.is_lpuart() => 3,
            // LPUART1 reserved codes; reported when written.
            _ => 2,
        };
        Some(LineConfig {
            bit_time_sub,
            word_bits,
            parity,
            stop_half_bits,
        })
    }

    /// The kernel clock RCC gives this instance (RCC_CCIPR's selection, the APB
    /// prescaler: [`crate::periph::rcc::Rcc::usart_kernel_hz`]); `None` for a source the
    /// emulator does not model, which is reported and stops the line (nothing is timed
    /// against a clock the silicon would not have at that rate).
    pub fn set_kernel_clock_hz(&mut self, hz: Option<u64>, source: &str) {
        if hz.is_none() {
            self.reports.once(format!(
                "{}: kernel clock {source} is not modelled (the line stops)",
                self.instance.name()
            ));
        }
        self.kernel_hz = hz;
    }

    /// The kernel clock in Hz (`None`: not modelled).
    pub fn kernel_clock_hz(&self) -> Option<u64> {
        self.kernel_hz
    }

    fn ue(&self) -> bool {
        self.cr1 & CR1_UE != 0
    }

    fn fifo(&self) -> bool {
        self.cr1 & CR1_FIFOEN != 0
    }

    fn tx_on(&self) -> bool {
        self.cr1 & (CR1_UE | CR1_TE) == CR1_UE | CR1_TE
    }

    fn rx_on(&self) -> bool {
        self.cr1 & (CR1_UE | CR1_RE) == CR1_UE | CR1_RE
    }

    fn tx_capacity(&self) -> usize {
        if self.fifo() {
            FIFO_DEPTH
        } else {
            1
        }
    }

    /// RDR alone, or RDR + RXFIFO in FIFO mode; OVRDIS bypasses the FIFO.
    fn rx_capacity(&self) -> usize {
        if self.fifo() && self.cr3 & CR3_OVRDIS == 0 {
            FIFO_DEPTH + 1
        } else {
            1
        }
    }

    /// TXE (no FIFO) / TXFNF (FIFO mode).
    fn txe(&self) -> bool {
        self.tx_queue.len() < self.tx_capacity()
    }

    fn rxne(&self) -> bool {
        !self.rx_store.is_empty()
    }

    fn any_rx_error(&self) -> bool {
        self.pe || self.fe || self.ne || self.ore
    }

    /// FIFO threshold in entries for a TXFTCFG/RXFTCFG code (1/8 .. 7/8, full/empty).
    fn threshold(code: u32) -> usize {
        match code & 7 {
            0 => 1,
            1 => 2,
            2 => 4,
            3 => 6,
            4 => 7,
            _ => 8,
        }
    }

    fn word_mask(bits: u8) -> u16 {
        ((1u32 << bits) - 1) as u16
    }

    fn parity_bit(data: u16, parity: Parity) -> u16 {
        let ones = data.count_ones() as u16 & 1;
        match parity {
            Parity::Odd => ones ^ 1,
            _ => ones,
        }
    }

    /// The word as it goes on the line: with PCE, the MSB of the word is replaced by the
    /// computed parity bit (RM0440 §37 "Parity control").
    fn line_word(&self, cfg: &LineConfig, written: u16) -> u16 {
        match cfg.parity {
            Parity::None => written & Self::word_mask(cfg.word_bits),
            p => {
                let data = written & Self::word_mask(cfg.word_bits - 1);
                data | (Self::parity_bit(data, p) << (cfg.word_bits - 1))
            }
        }
    }

    /// The BUSY flag: a start bit has been seen and the character is not complete.
    fn busy(&self, now: Cycles) -> bool {
        if !self.rx_on() {
            return false;
        }
        let Some(cfg) = self.line_config() else {
            return false;
        };
        let frame = cfg.frame_cycles();
        self.rx_incoming
            .iter()
            .any(|(at, _)| at.saturating_sub(frame) <= now && now < *at)
    }

    fn isr(&self) -> u32 {
        let mut v = 0;
        let flag = |b: bool, bit: u32| if b { bit } else { 0 };
        v |= flag(self.pe, ISR_PE);
        v |= flag(self.fe, ISR_FE);
        v |= flag(self.ne, ISR_NE);
        v |= flag(self.ore, ISR_ORE);
        v |= flag(self.idle, ISR_IDLE);
        v |= flag(self.rxne(), ISR_RXNE);
        v |= flag(self.tc, ISR_TC);
        v |= flag(self.txe(), ISR_TXE);
        v |= flag(self.busy(self.now), ISR_BUSY);
        v |= flag(self.tx_on(), ISR_TEACK);
        v |= flag(self.rx_on(), ISR_REACK);
        if self.fifo() {
            v |= flag(self.txfe, ISR_TXFE);
            v |= flag(self.rx_store.len() >= self.rx_capacity(), ISR_RXFF);
            let rx_thr = Self::threshold(self.cr3 >> CR3_RXFTCFG_SHIFT);
            v |= flag(self.rx_store.len() >= rx_thr, ISR_RXFT);
            let tx_thr = Self::threshold(self.cr3 >> CR3_TXFTCFG_SHIFT);
            v |= flag(FIFO_DEPTH - self.tx_queue.len() >= tx_thr, ISR_TXFT);
        }
        v
    }

    /// Loads the shift register at `at_sub` if it is free: the pending preamble, else the
    /// oldest word of TDR/TXFIFO.
    fn load_tx(&mut self, at_sub: u64) {
        if self.shift.is_some() || !self.tx_on() {
            return;
        }
        if !self.preamble_pending && self.tx_queue.is_empty() {
            return;
        }
        let Some(cfg) = self.line_config() else {
            self.reports.once(format!(
                "{}: transmitter enabled with BRR {:#x} below RM0440's minimum: nothing is sent",
                self.instance.name(),
                self.brr
            ));
            return;
        };
        let end_sub = at_sub + cfg.frame_sub();
        if self.preamble_pending {
            self.preamble_pending = false;
            self.shift = Some(Shift {
                end_sub,
                data: None,
            });
            return;
        }
        if let Some(written) = self.tx_queue.pop_front() {
            let data = self.line_word(&cfg, written);
            self.shift = Some(Shift {
                end_sub,
                data: Some(data),
            });
            self.tx_started.push_back(TxFrame {
                start: at_sub.div_ceil(SUB),
                end: end_sub.div_ceil(SUB),
                data,
            });
            if self.tx_queue.is_empty() {
                self.txfe = true;
            }
        }
    }

    fn advance_tx(&mut self, now: Cycles) {
        while let Some(s) = self.shift {
            if s.end_sub.div_ceil(SUB) > now {
                break;
            }
            self.shift = None;
            // TC: a frame containing data is complete and TXE/TXFNF... with nothing left.
            if s.data.is_some() && self.tx_queue.is_empty() {
                self.tc = true;
            }
            self.load_tx(s.end_sub);
            if self.shift.is_none() && !self.tx_on() {
                // TE = 0 and no transmission going on: TC is set.
                self.tc = true;
            }
        }
    }

    fn advance_rx(&mut self, now: Cycles) {
        loop {
            let next = self.rx_incoming.front().map(|(at, _)| *at);
            let frame = self.line_config().map(|c| c.frame_cycles()).unwrap_or(0);
            match (next, self.idle_at) {
                (Some(at), idle) if at <= now && idle.is_none_or(|i| at <= i) => {
                    if let Some((at, byte)) = self.rx_incoming.pop_front() {
                        self.receive(at, byte);
                    }
                }
                (next, Some(i)) if i <= now => {
                    self.idle_at = None;
                    // A start bit inside the idle frame: no idle line.
                    let cancelled = next.is_some_and(|at| at.saturating_sub(frame) <= i);
                    if !cancelled && self.rx_on() {
                        self.idle = true;
                        self.idle_set_at = Some(i);
                    }
                }
                _ => break,
            }
        }
    }

    /// A character completes at `at` (its stop bit ends).
    fn receive(&mut self, at: Cycles, byte: RxByte) {
        if !self.rx_on() {
            return;
        }
        let Some(cfg) = self.line_config() else {
            self.reports.once(format!(
                "{}: character received with BRR {:#x} below RM0440's minimum: dropped",
                self.instance.name(),
                self.brr
            ));
            return;
        };
        let frame = cfg.frame_cycles();
        if self
            .rx_enabled_at
            .is_some_and(|en| at.saturating_sub(frame) < en)
        {
            self.reports.once(format!(
                "{}: character started before the receiver was enabled: dropped (the \
                 silicon may take a data edge for a start bit)",
                self.instance.name()
            ));
            return;
        }
        self.idle_at = Some(at + frame);
        let data = byte.data & Self::word_mask(cfg.word_bits);
        let entry = RxEntry {
            data,
            pe: cfg.parity != Parity::None
                && Self::parity_bit(data & Self::word_mask(cfg.word_bits - 1), cfg.parity)
                    != (data >> (cfg.word_bits - 1)) & 1,
            fe: byte.framing_error,
            ne: byte.noise && (self.instance.is_lpuart() || self.cr3 & CR3_ONEBIT == 0),
        };
        if self.rx_store.len() >= self.rx_capacity() {
            if self.cr3 & CR3_OVRDIS != 0 {
                // No overrun detection: the new word overwrites RDR.
                self.rx_store.clear();
            } else {
                // The shift register is overwritten; RDR/RXFIFO keep their content.
                self.ore = true;
                return;
            }
        }
        if (entry.pe || entry.fe || entry.ne)
            && self.cr3 & CR3_DMAR != 0
            && self.cr3 & CR3_DDRE == 0
        {
            // DDRE = 0: the error flag is set but RXNE is kept 0, the word is not transferred.
            self.set_entry_flags(entry);
            return;
        }
        self.rx_store.push_back(entry);
        if self.rx_store.len() == 1 {
            self.set_entry_flags(entry);
        }
    }

    fn set_entry_flags(&mut self, e: RxEntry) {
        self.pe |= e.pe;
        self.fe |= e.fe;
        self.ne |= e.ne;
    }

    /// UE cleared: prescalers and outputs stop, current operations are discarded and the
    /// ISR flags go back to their reset values (RM0440 USART_CR1.UE).
    fn disable(&mut self, now: Cycles) {
        if let Some(Shift {
            data: Some(_),
            end_sub,
        }) = self.shift
        {
            if end_sub.div_ceil(SUB) > now {
                self.reports.once(format!(
                    "{}: UE cleared during a transmission: the frame is cut on the line (the \
                     model has already handed it out whole)",
                    self.instance.name()
                ));
            }
        }
        self.shift = None;
        self.preamble_pending = false;
        self.tx_queue.clear();
        self.rx_store.clear();
        self.pe = false;
        self.fe = false;
        self.ne = false;
        self.ore = false;
        self.idle = false;
        self.tc = true;
        self.txfe = true;
        self.idle_at = None;
    }

    fn valid_masks(&self) -> (u32, u32, u32) {
        if self.instance.is_lpuart() {
            (CR1_VALID_LPUART, CR2_VALID_LPUART, CR3_VALID_LPUART)
        } else {
            (CR1_VALID_USART, CR2_VALID_USART, CR3_VALID_USART)
        }
    }

    /// A write to a register whose `protected` bits RM0440 allows only while UE = 0: while
    /// UE = 1 those bits keep their value, and a change is reported.
    fn guarded(&mut self, reg: &str, old: u32, new: u32, protected: u32) -> u32 {
        if self.ue() && (old ^ new) & protected != 0 {
            self.reports.once(format!(
                "{}.{reg}: bits {:#010x} written while UE = 1 (RM0440: only while UE = 0): ignored",
                self.instance.name(),
                (old ^ new) & protected
            ));
            (new & !protected) | (old & protected)
        } else {
            new
        }
    }

    fn unmodelled(&mut self, reg: &str, value: u32, bits: &[(u32, &str)]) {
        for &(bit, what) in bits {
            if value & bit != 0 {
                self.reports.once(format!(
                    "{}.{reg}: {what} is not modelled",
                    self.instance.name()
                ));
            }
        }
    }

    fn write_cr1(&mut self, w: Write, now: Cycles) {
        let old = self.cr1;
        let (valid, _, _) = self.valid_masks();
        let new = self.guarded("CR1", old, w.merge(old) & valid, CR1_UE0_ONLY);
        let was_tx_on = self.tx_on();
        let was_rx_on = self.rx_on();
        self.cr1 = new;
        if old & CR1_UE != 0 && new & CR1_UE == 0 {
            self.disable(now);
        }
        if !was_tx_on && self.tx_on() {
            // TE set: an idle frame goes out first (after the current frame, if any).
            self.preamble_pending = true;
            self.load_tx(now * SUB);
        } else if was_tx_on && !self.tx_on() {
            // The current frame completes; with none on the line TC sets at once.
            self.preamble_pending = false;
            if self.shift.is_none() {
                self.tc = true;
            }
        }
        if !was_rx_on && self.rx_on() {
            self.rx_enabled_at = Some(now);
        } else if was_rx_on && !self.rx_on() {
            // A character being received is lost.
            self.rx_enabled_at = None;
            self.idle_at = None;
        }
        if new & (CR1_M0 | CR1_M1) == CR1_M0 | CR1_M1 {
            self.reports.once(format!(
                "{}.CR1: M1:M0 = 11 is reserved",
                self.instance.name()
            ));
        }
        self.unmodelled(
            "CR1",
            new,
            &[
                (CR1_MME, "mute mode (MME)"),
                (CR1_CMIE, "character match (CMIE)"),
                (CR1_RTOIE, "receiver timeout interrupt (RTOIE)"),
                (CR1_EOBIE, "end of block interrupt (EOBIE)"),
            ],
        );
    }

    fn write_cr2(&mut self, w: Write) {
        let old = self.cr2;
        let (_, valid, _) = self.valid_masks();
        let new = self.guarded("CR2", old, w.merge(old) & valid, valid & !CR2_ANY_TIME);
        self.cr2 = new;
        let stop = (new >> CR2_STOP_SHIFT) & 3;
        if self.instance.is_lpuart() && (stop == 1 || stop == 3) {
            self.reports.once(format!(
                "{}.CR2: STOP = {stop:#b} is reserved on LPUART1",
                self.instance.name()
            ));
        }
        self.unmodelled(
            "CR2",
            new,
            &[
                (CR2_SLVEN, "SPI slave mode (SLVEN)"),
                (CR2_LBDIE, "LIN break detection (LBDIE)"),
                (CR2_CLKEN, "synchronous mode (CLKEN)"),
                (CR2_LINEN, "LIN mode (LINEN)"),
                (CR2_SWAP, "TX/RX pin swap (SWAP)"),
                (CR2_RXINV, "RX level inversion (RXINV)"),
                (CR2_TXINV, "TX level inversion (TXINV)"),
                (CR2_DATAINV, "data inversion (DATAINV)"),
                (CR2_MSBFIRST, "MSB first (MSBFIRST)"),
                (CR2_ABREN, "auto baud rate (ABREN)"),
                (CR2_RTOEN, "receiver timeout (RTOEN)"),
            ],
        );
    }

    fn write_cr3(&mut self, w: Write) {
        let old = self.cr3;
        let (_, _, valid) = self.valid_masks();
        let new = self.guarded("CR3", old, w.merge(old) & valid, CR3_UE0_ONLY);
        self.cr3 = new;
        self.unmodelled(
            "CR3",
            new,
            &[
                (CR3_IREN, "IrDA mode (IREN)"),
                (CR3_HDSEL, "half-duplex mode (HDSEL)"),
                (CR3_SCEN, "smartcard mode (SCEN)"),
                (CR3_RTSE, "RTS flow control (RTSE)"),
                (CR3_CTSE, "CTS flow control (CTSE)"),
                (CR3_CTSIE, "CTS interrupt (CTSIE)"),
                (CR3_DEM, "RS-485 driver enable (DEM)"),
                (CR3_WUFIE, "wake-up from Stop (WUFIE)"),
                (CR3_TCBGTIE, "smartcard guard time (TCBGTIE)"),
            ],
        );
    }

    fn write_tdr(&mut self, w: Write, now: Cycles) {
        let data = (w.value & w.mask & 0x1ff) as u16;
        self.tdr = data;
        if !self.ue() {
            self.reports.once(format!(
                "{}.TDR written while UE = 0: ignored",
                self.instance.name()
            ));
            return;
        }
        // TC is cleared by a write to TDR.
        self.tc = false;
        if self.tx_queue.len() >= self.tx_capacity() {
            self.reports.once(format!(
                "{}.TDR written while TXE/TXFNF = 0: the word is lost",
                self.instance.name()
            ));
            if !self.fifo() {
                // Without FIFO the write replaces the word waiting in TDR.
                self.tx_queue.clear();
                self.tx_queue.push_back(data);
            }
        } else {
            self.tx_queue.push_back(data);
        }
        self.txfe = false;
        self.load_tx(now * SUB);
    }

    fn read_rdr(&mut self) -> u32 {
        if let Some(e) = self.rx_store.pop_front() {
            self.rdr = e.data;
            if let Some(head) = self.rx_store.front().copied() {
                // The next word reaches RDR with its error flags.
                self.set_entry_flags(head);
            }
        }
        u32::from(self.rdr)
    }

    fn write_icr(&mut self, v: u32) {
        if v & ISR_PE != 0 {
            self.pe = false;
        }
        if v & ISR_FE != 0 {
            self.fe = false;
        }
        if v & ISR_NE != 0 {
            self.ne = false;
        }
        if v & ISR_ORE != 0 {
            self.ore = false;
        }
        if v & ISR_IDLE != 0 {
            self.idle = false;
        }
        if v & ICR_TXFECF != 0 {
            self.txfe = false;
        }
        if v & ISR_TC != 0 {
            self.tc = false;
        }
        // The other clear bits (TCBGT, LBD, CTS, RTO, EOB, UDR, CM, WU) belong to flags this
        // model never sets.
    }

    fn write_rqr(&mut self, v: u32) {
        if v & RQR_RXFRQ != 0 {
            // Flush: RDR/RXFIFO emptied, RXNE/RXFNE cleared.
            self.rx_store.clear();
        }
        if v & RQR_TXFRQ != 0 {
            self.tx_queue.clear();
            self.txfe = true;
        }
        self.unmodelled(
            "RQR",
            v,
            &[
                (RQR_ABRRQ, "auto baud rate request (ABRRQ)"),
                (RQR_SBKRQ, "send break request (SBKRQ)"),
                (RQR_MMRQ, "mute mode request (MMRQ)"),
            ],
        );
    }
}

impl Peripheral for Usart {
    /// Uses of features this model does not implement (or of values RM0440 forbids), each
    /// reported once, since the last call.
    fn take_reports(&mut self) -> Vec<String> {
        self.reports.take()
    }

    fn read(&mut self, offset: u32, _now: Cycles) -> Option<u32> {
        let lp = self.instance.is_lpuart();
        match offset {
            CR1 => Some(self.cr1),
            CR2 => Some(self.cr2),
            CR3 => Some(self.cr3),
            BRR => Some(self.brr),
            GTPR if !lp => Some(self.gtpr),
            RTOR if !lp => Some(self.rtor),
            RQR | ICR => Some(0),
            ISR => Some(self.isr()),
            RDR => Some(self.read_rdr()),
            TDR => Some(u32::from(self.tdr)),
            PRESC => Some(self.presc),
            _ => None,
        }
    }

    fn write(&mut self, w: Write, now: Cycles) -> bool {
        let lp = self.instance.is_lpuart();
        match w.offset {
            CR1 => self.write_cr1(w, now),
            CR2 => self.write_cr2(w),
            CR3 => self.write_cr3(w),
            BRR => {
                let mask = if lp { 0xf_ffff } else { 0xffff };
                let old = self.brr;
                self.brr = self.guarded("BRR", old, w.merge(old) & mask, mask);
                if !lp && self.cr1 & CR1_OVER8 != 0 && self.brr & 0x8 != 0 {
                    self.reports.once(format!(
                        "{}.BRR: bit 3 set with OVER8 (RM0440: must be kept cleared)",
                        self.instance.name()
                    ));
                }
            }
            GTPR if !lp => {
                let old = self.gtpr;
                self.gtpr = self.guarded("GTPR", old, w.merge(old) & 0xffff, 0xffff);
            }
            RTOR if !lp => self.rtor = w.merge(self.rtor),
            RQR => self.write_rqr(w.value & w.mask),
            ICR => self.write_icr(w.value & w.mask),
            TDR => self.write_tdr(w, now),
            PRESC => {
                let old = self.presc;
                self.presc = self.guarded("PRESC", old, w.merge(old) & 0xf, 0xf);
                if self.presc >= 12 {
                    self.reports.once(format!(
                        "{}.PRESC: {} is reserved",
                        self.instance.name(),
                        self.presc
                    ));
                }
            }
            // ISR, RDR: read-only.
            ISR | RDR => {}
            _ => return false,
        }
        true
    }

    fn next_event(&self) -> Option<Cycles> {
        let tx = self.shift.map(|s| s.end_sub.div_ceil(SUB));
        // The next character: BUSY rises at its start bit (so that a poll of ISR sees it),
        // RXNE at its end.
        let rx = self.rx_incoming.front().map(|(at, _)| {
            let frame = self.line_config().map_or(0, |c| c.frame_cycles());
            let start = at.saturating_sub(frame);
            if self.rx_on() && start > self.now {
                start
            } else {
                *at
            }
        });
        [tx, rx, self.idle_at].into_iter().flatten().min()
    }

    fn advance(&mut self, now: Cycles) {
        if now < self.now {
            return;
        }
        self.now = now;
        self.advance_tx(now);
        self.advance_rx(now);
    }

    fn irq_lines(&self, lines: &mut IrqLines) {
        let Some(irq) = self.irq else {
            return;
        };
        let cr1 = self.cr1;
        let cr3 = self.cr3;
        let on = |bit: u32| cr1 & bit != 0;
        let rxne = self.rxne();
        let mut level = (self.txe() && on(CR1_TXEIE))
            || (self.tc && on(CR1_TCIE))
            || ((rxne || self.ore) && on(CR1_RXNEIE))
            || (self.idle && on(CR1_IDLEIE))
            || (self.pe && on(CR1_PEIE))
            || (cr3 & CR3_EIE != 0 && (self.fe || self.ore || (self.ne && cr3 & CR3_DMAR != 0)));
        if self.fifo() {
            let isr = self.isr();
            level |= (isr & ISR_TXFE != 0 && on(CR1_TXFEIE))
                || (isr & ISR_RXFF != 0 && on(CR1_RXFFIE))
                || (isr & ISR_TXFT != 0 && cr3 & CR3_TXFTIE != 0)
                || (isr & ISR_RXFT != 0 && cr3 & CR3_RXFTIE != 0);
        }
        if level {
            lines.set(irq);
        }
    }

    fn dma_requests(&self, requests: &mut DmaRequests) {
        if !self.ue() {
            return;
        }
        if let Some(id) = self.rx_request {
            let masked = self.cr3 & CR3_DDRE != 0 && self.any_rx_error();
            if self.cr3 & CR3_DMAR != 0 && self.rxne() && !masked {
                requests.set(id);
            }
        }
        if let Some(id) = self.tx_request {
            if self.cr3 & CR3_DMAT != 0 && self.cr1 & CR1_TE != 0 && self.txe() {
                requests.set(id);
            }
        }
    }

    fn reset(&mut self) {
        let now = self.now;
        let reports = std::mem::take(&mut self.reports);
        // The kernel clock is RCC's, not the peripheral's: a peripheral reset keeps it.
        let kernel_hz = self.kernel_hz;
        *self = Usart::new(self.instance);
        self.kernel_hz = kernel_hz;
        self.now = now;
        self.reports = reports;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 115200 baud from 170 MHz as embassy computes it: 170e6 / 115200 = 1475.69 → 1476.
    const BRR_115200: u32 = 1476;
    /// One 8N1 frame at BRR 1476: 10 bits of 1476 cycles.
    const FRAME: Cycles = 14_760;

    fn rd(u: &mut Usart, off: u32, now: Cycles) -> u32 {
        u.advance(now);
        u.read(off, now).unwrap_or(0xdead_beef)
    }

    fn wr(u: &mut Usart, off: u32, value: u32, now: Cycles) {
        u.advance(now);
        assert!(u.write(Write::word(off, value), now));
    }

    fn modify(u: &mut Usart, off: u32, now: Cycles, f: impl FnOnce(u32) -> u32) {
        let v = rd(u, off, now);
        wr(u, off, f(v), now);
    }

    /// embassy-stm32 0.6 `Uart::new` → `enable_and_configure` → `configure` (usart/mod.rs),
    /// 8N1, with `assume_noise_free` as given; FIFOEN is always set on usart_v4.
    fn embassy_configure(u: &mut Usart, brr: u32, onebit: bool, now: Cycles) {
        wr(u, CR3, 0, now); // cr3().write(rtse, ctse, dem = false)
        modify(u, CR1, now, |v| v & !CR1_UE);
        wr(u, BRR, brr, now);
        wr(u, PRESC, 0, now);
        wr(u, CR2, 0, now); // STOP1, no inversion, no swap
        modify(u, CR3, now, |v| {
            (v & !(CR3_ONEBIT | CR3_HDSEL)) | if onebit { CR3_ONEBIT } else { 0 }
        });
        wr(u, CR1, CR1_UE | CR1_TE | CR1_RE | CR1_FIFOEN, now);
    }

    fn isr(u: &mut Usart, now: Cycles) -> u32 {
        rd(u, ISR, now)
    }

    fn irq(u: &Usart) -> bool {
        let mut l = IrqLines::default();
        u.irq_lines(&mut l);
        u.irq().is_some_and(|n| l.get(n))
    }

    fn requests(u: &Usart) -> (bool, bool) {
        let mut r = DmaRequests::default();
        u.dma_requests(&mut r);
        let (rx, tx) = u.dma_request_ids();
        (
            rx.is_some_and(|id| r.get(id)),
            tx.is_some_and(|id| r.get(id)),
        )
    }

    /// A USART2 as the images open it, with the preamble already sent (at `FRAME`).
    fn ready(fifo: bool) -> Usart {
        let mut u = Usart::new(UsartInstance::Usart2);
        embassy_configure(&mut u, BRR_115200, false, 0);
        if !fifo {
            wr(&mut u, CR1, CR1_TE | CR1_RE, 0);
            wr(&mut u, CR1, CR1_UE | CR1_TE | CR1_RE, 0);
        }
        u.advance(FRAME);
        assert!(u.take_tx().is_none(), "the preamble is not a frame");
        u
    }

    #[test]
    fn instance_wiring_comes_from_the_metadata() {
        let u = Usart::new(UsartInstance::Usart1);
        assert_eq!(u.irq(), Some(37));
        assert_eq!(u.dma_request_ids(), (Some(24), Some(25)));
        let lp = Usart::new(UsartInstance::Lpuart1);
        assert_eq!(lp.irq(), Some(91));
        assert_eq!(UsartInstance::Usart2.base(), Some(0x4000_4400));
    }

    #[test]
    fn reset_values() {
        let mut u = Usart::new(UsartInstance::Usart2);
        assert_eq!(
            isr(&mut u, 0),
            ISR_TXE | ISR_TC,
            "RM0440: USART_ISR resets to 0xC0"
        );
        for off in [CR1, CR2, CR3, BRR, PRESC] {
            assert_eq!(rd(&mut u, off, 0), 0);
        }
        assert_eq!(u.line_config(), None, "BRR 0 is below the minimum");
    }

    #[test]
    fn brr_at_115200_and_1_mbaud() {
        let mut u = Usart::new(UsartInstance::Usart1);
        embassy_configure(&mut u, BRR_115200, false, 0);
        let c = u.line_config().unwrap_or_else(|| panic!("config"));
        assert_eq!(c.bit_time_sub, 1476 * SUB);
        assert_eq!(c.frame_cycles(), FRAME);
        assert!((c.baud_hz() - 115_176.15).abs() < 0.01, "{}", c.baud_hz());
        // 1 Mbaud: 170e6 / 1e6 = 170.
        embassy_configure(&mut u, 170, false, 1);
        let c = u.line_config().unwrap_or_else(|| panic!("config"));
        assert_eq!(c.frame_cycles(), 1700);
        assert!((c.baud_hz() - 1e6).abs() < 1e-6);
    }

    #[test]
    fn over8_brr_as_embassy_writes_it() {
        // 12 Mbaud: USARTDIV 170/12 = 14 < 16, so embassy uses OVER8 with USARTDIV 28:
        // BRR = (28 & !0xf) | (14 & 7) = 0x16, i.e. a bit of 28/2 = 14 cycles.
        let mut u = Usart::new(UsartInstance::Usart1);
        wr(&mut u, BRR, 0x16, 0);
        wr(&mut u, CR1, CR1_UE | CR1_TE | CR1_OVER8, 0);
        let c = u.line_config().unwrap_or_else(|| panic!("config"));
        assert_eq!(c.bit_time_sub, 14 * SUB);
        assert_eq!(c.frame_cycles(), 140);
        // BRR[2:0] holds USARTDIV[3:1]: BRR 0x17 is USARTDIV 0x10 | 0b1110 = 30, 15 cycles.
        let mut u = Usart::new(UsartInstance::Usart1);
        wr(&mut u, BRR, 0x17, 0);
        wr(&mut u, CR1, CR1_OVER8, 0);
        let c = u.line_config().unwrap_or_else(|| panic!("config"));
        assert_eq!(c.bit_time_sub, 15 * SUB);
        assert_eq!(c.frame_cycles(), 150);
    }

    #[test]
    fn lpuart_brr_is_256_f_over_baud_and_frames_do_not_drift() {
        // embassy: 256 * 170e6 / 115200 = 377777.8 → 377778 (≥ 0x300, < 0x100000, PRESC 1).
        let mut u = Usart::new(UsartInstance::Lpuart1);
        embassy_configure(&mut u, 377_778, false, 0);
        let c = u.line_config().unwrap_or_else(|| panic!("config"));
        assert_eq!(c.bit_time_sub, 377_778 * 2);
        assert!((c.baud_hz() - 115_200.0).abs() < 0.1, "{}", c.baud_hz());
        // 10 bits of 1475.695 cycles: 14756.95 → 14757.
        assert_eq!(c.frame_cycles(), 14_757);
        // 30 back-to-back frames after the preamble, the TXFIFO topped up whenever it has
        // room: frame k ends at (k + 1) * 7555560 / 512 cycles, rounded up once. Rounding
        // each frame to whole cycles would add 0.047 cycles per frame.
        let mut sent = 0u32;
        let mut now = 1;
        while sent < 30 {
            while sent < 30 && isr(&mut u, now) & ISR_TXE != 0 {
                wr(&mut u, TDR, sent, now);
                sent += 1;
            }
            now = u.next_event().unwrap_or(now + 1);
        }
        u.advance(1_000_000);
        let ends: Vec<Cycles> = std::iter::from_fn(|| u.take_tx()).map(|f| f.end).collect();
        let exact = |n: u64| (n * 7_555_560).div_ceil(SUB);
        assert_eq!(ends, (2..=31).map(exact).collect::<Vec<_>>());
        assert_eq!(ends.last(), Some(&457_466));
        assert_ne!(exact(31), 31 * 14_757, "per-frame rounding would drift");
        // LPUART1 has no GTPR/RTOR and a 20-bit BRR; OVER8 does not exist.
        assert_eq!(u.read(GTPR, 300_000), None);
        assert!(!u.write(Write::word(RTOR, 1), 300_000));
        let mut lp = Usart::new(UsartInstance::Lpuart1);
        wr(&mut lp, BRR, 0xfff_ffff, 0);
        assert_eq!(rd(&mut lp, BRR, 0), 0xf_ffff);
        wr(&mut lp, CR1, CR1_OVER8, 0);
        assert_eq!(rd(&mut lp, CR1, 0), 0);
        wr(&mut lp, BRR, 0x2ff, 0);
        assert_eq!(lp.line_config(), None, "LPUARTDIV below 0x300 is forbidden");
    }

    #[test]
    fn the_lpuart_is_timed_by_its_kernel_clock_not_by_the_cpu_clock() {
        // RM0440 §38.4.7: baud = 256 · f_lpuart_ker_ck / LPUARTDIV. The BRR embassy writes
        // for 115200 at PCLK1 = 170 MHz gives 10 842 baud on HSI16 (CCIPR LPUART1SEL = 10):
        // an image that selected HSI16 but computed BRR for 170 MHz talks at the wrong rate.
        let mut u = Usart::new(UsartInstance::Lpuart1);
        u.set_kernel_clock_hz(Some(16_000_000), "HSI16");
        embassy_configure(&mut u, 377_778, false, 0);
        let c = u.line_config().unwrap_or_else(|| panic!("config"));
        assert!((c.baud_hz() - 10_842.35).abs() < 0.1, "{}", c.baud_hz());
        // The BRR for HSI16 (256 · 16e6 / 115200 = 35 555.6 → 35 556) gives 115200 again.
        let mut u = Usart::new(UsartInstance::Lpuart1);
        u.set_kernel_clock_hz(Some(16_000_000), "HSI16");
        embassy_configure(&mut u, 35_556, false, 0);
        let c = u.line_config().unwrap_or_else(|| panic!("config"));
        assert!((c.baud_hz() - 115_198.56).abs() < 0.1, "{}", c.baud_hz());
        // A peripheral reset keeps RCC's selection; an unmodelled source stops the line.
        u.reset();
        assert_eq!(u.kernel_clock_hz(), Some(16_000_000));
        u.set_kernel_clock_hz(None, "LSE");
        embassy_configure(&mut u, 0x300, false, 0);
        assert_eq!(u.line_config(), None);
        assert!(u.take_reports().iter().any(|r| r.contains("LSE")));
        // USART2 on PCLK1 / 2 (PPRE1 = 100): the same BRR is half the rate.
        let mut u = Usart::new(UsartInstance::Usart2);
        u.set_kernel_clock_hz(Some(85_000_000), "PCLK1");
        embassy_configure(&mut u, BRR_115200, false, 0);
        let c = u.line_config().unwrap_or_else(|| panic!("config"));
        assert_eq!(c.bit_time_sub, 2 * 1476 * SUB);
    }

    #[test]
    fn te_sends_an_idle_frame_first() {
        let mut u = Usart::new(UsartInstance::Usart2);
        embassy_configure(&mut u, BRR_115200, false, 100);
        // Written during the preamble: waits in the TXFIFO.
        wr(&mut u, TDR, u32::from(b'A'), 200);
        assert_eq!(isr(&mut u, 200) & ISR_TC, 0, "a TDR write clears TC");
        assert_eq!(u.take_tx(), None);
        assert_eq!(u.next_event(), Some(100 + FRAME));
        u.advance(100 + FRAME);
        assert_eq!(
            u.take_tx(),
            Some(TxFrame {
                start: 100 + FRAME,
                end: 100 + 2 * FRAME,
                data: u16::from(b'A'),
            })
        );
    }

    #[test]
    fn one_byte_without_dma_is_one_frame_on_the_wire() {
        for fifo in [false, true] {
            let mut u = ready(fifo);
            let t = 20_000;
            assert_ne!(isr(&mut u, t) & ISR_TXE, 0);
            wr(&mut u, TDR, 0x55, t);
            // It went straight to the shift register: TXE is set again, TC is not.
            let s = isr(&mut u, t);
            assert_ne!(s & ISR_TXE, 0, "fifo {fifo}");
            assert_eq!(s & ISR_TC, 0);
            assert_eq!(
                u.take_tx(),
                Some(TxFrame {
                    start: t,
                    end: t + FRAME,
                    data: 0x55
                })
            );
            assert_eq!(u.next_event(), Some(t + FRAME));
            assert_eq!(isr(&mut u, t + FRAME - 1) & ISR_TC, 0);
            assert_ne!(
                isr(&mut u, t + FRAME) & ISR_TC,
                0,
                "TC when the stop bit ends"
            );
            assert_eq!(u.next_event(), None);
        }
    }

    #[test]
    fn back_to_back_bytes_without_fifo() {
        let mut u = ready(false);
        let t = 30_000;
        wr(&mut u, TDR, 1, t);
        wr(&mut u, TDR, 2, t + 1);
        // The second waits in TDR: TXE clear until the first leaves the shift register.
        assert_eq!(isr(&mut u, t + 1) & ISR_TXE, 0);
        assert!(!requests(&u).1, "DMAT not set: no request");
        assert_eq!(isr(&mut u, t + FRAME - 1) & ISR_TXE, 0);
        assert_ne!(isr(&mut u, t + FRAME) & ISR_TXE, 0);
        assert_eq!(isr(&mut u, t + FRAME) & ISR_TC, 0, "data still on the wire");
        let frames: Vec<TxFrame> = std::iter::from_fn(|| u.take_tx()).collect();
        assert_eq!(
            frames,
            vec![
                TxFrame {
                    start: t,
                    end: t + FRAME,
                    data: 1
                },
                TxFrame {
                    start: t + FRAME,
                    end: t + 2 * FRAME,
                    data: 2
                },
            ]
        );
        assert_eq!(isr(&mut u, t + 2 * FRAME - 1) & ISR_TC, 0);
        assert_ne!(isr(&mut u, t + 2 * FRAME) & ISR_TC, 0);
    }

    #[test]
    fn txfifo_holds_eight_behind_the_shift_register() {
        let mut u = ready(true);
        let t = 20_000;
        for b in 0..9u32 {
            assert_ne!(isr(&mut u, t) & ISR_TXE, 0, "TXFNF before word {b}");
            wr(&mut u, TDR, b, t);
        }
        let s = isr(&mut u, t);
        assert_eq!(
            s & ISR_TXE,
            0,
            "1 in the shift register + 8 in the TXFIFO: full"
        );
        assert_eq!(s & ISR_TXFE, 0);
        wr(&mut u, TDR, 99, t);
        assert_eq!(
            u.take_reports().len(),
            1,
            "a write to a full TXFIFO is reported"
        );
        u.advance(t + 9 * FRAME);
        let frames: Vec<TxFrame> = std::iter::from_fn(|| u.take_tx()).collect();
        assert_eq!(frames.len(), 9);
        for (k, f) in frames.iter().enumerate() {
            assert_eq!(f.data, k as u16);
            assert_eq!(f.start, t + k as u64 * FRAME);
        }
        let s = isr(&mut u, t + 9 * FRAME);
        assert_ne!(s & ISR_TC, 0);
        assert_ne!(s & ISR_TXFE, 0);
    }

    #[test]
    fn tc_is_cleared_by_tccf_and_set_when_te_is_cleared() {
        let mut u = ready(true);
        assert_ne!(isr(&mut u, FRAME) & ISR_TC, 0);
        wr(&mut u, ICR, ISR_TC, FRAME);
        assert_eq!(isr(&mut u, FRAME) & ISR_TC, 0);
        // TE = 0 with nothing on the line: TC sets at once.
        modify(&mut u, CR1, FRAME + 1, |v| v & !CR1_TE);
        assert_ne!(isr(&mut u, FRAME + 1) & ISR_TC, 0);
    }

    #[test]
    fn teack_and_reack_follow_te_and_re() {
        let mut u = Usart::new(UsartInstance::Usart1);
        wr(&mut u, BRR, BRR_115200, 0);
        wr(&mut u, CR1, CR1_TE | CR1_RE, 0);
        assert_eq!(isr(&mut u, 0) & (ISR_TEACK | ISR_REACK), 0, "UE = 0");
        wr(&mut u, CR1, CR1_UE | CR1_TE, 1);
        assert_eq!(isr(&mut u, 1) & (ISR_TEACK | ISR_REACK), ISR_TEACK);
        wr(&mut u, CR1, CR1_UE | CR1_RE, 2);
        assert_eq!(isr(&mut u, 2) & (ISR_TEACK | ISR_REACK), ISR_REACK);
        wr(&mut u, CR1, CR1_UE | CR1_RE | CR1_TE, 3);
        assert_eq!(
            isr(&mut u, 3) & (ISR_TEACK | ISR_REACK),
            ISR_TEACK | ISR_REACK
        );
    }

    #[test]
    fn rxne_sets_when_the_stop_bit_ends() {
        for fifo in [false, true] {
            let mut u = ready(fifo);
            let at = 40_000;
            u.push_rx(at, RxByte::clean(0xa5));
            assert_eq!(
                u.next_event(),
                Some(at - FRAME),
                "BUSY rises at the start bit"
            );
            assert_eq!(isr(&mut u, at - FRAME - 1) & ISR_BUSY, 0);
            assert_ne!(isr(&mut u, at - FRAME) & ISR_BUSY, 0);
            assert_eq!(u.next_event(), Some(at));
            let s = isr(&mut u, at - 1);
            assert_eq!(s & ISR_RXNE, 0);
            assert_ne!(s & ISR_BUSY, 0, "start bit seen");
            let s = isr(&mut u, at);
            assert_ne!(s & ISR_RXNE, 0);
            assert_eq!(s & ISR_BUSY, 0);
            assert_eq!(rd(&mut u, RDR, at), 0xa5);
            assert_eq!(isr(&mut u, at) & ISR_RXNE, 0, "reading RDR clears RXNE");
            assert_eq!(rd(&mut u, RDR, at), 0xa5, "RDR keeps the last word");
        }
    }

    #[test]
    fn overrun_without_fifo_loses_the_new_byte() {
        let mut u = ready(false);
        u.push_rx(40_000, RxByte::clean(1));
        u.push_rx(40_000 + FRAME, RxByte::clean(2));
        assert_eq!(isr(&mut u, 40_000 + FRAME - 1) & ISR_ORE, 0);
        let s = isr(&mut u, 40_000 + FRAME);
        assert_ne!(s & ISR_ORE, 0);
        assert!(!irq(&u), "no ORE interrupt without RXNEIE or EIE");
        modify(&mut u, CR1, 40_000 + FRAME, |v| v | CR1_RXNEIE);
        assert!(irq(&u));
        assert_eq!(rd(&mut u, RDR, 40_000 + FRAME), 1, "RDR is not lost");
        assert_eq!(
            isr(&mut u, 40_000 + FRAME) & ISR_RXNE,
            0,
            "the second byte is"
        );
        // OVRDIS (only while UE = 0): the new byte overwrites RDR, no ORE.
        let mut u = ready(false);
        modify(&mut u, CR1, FRAME, |v| v & !CR1_UE);
        modify(&mut u, CR3, FRAME, |v| v | CR3_OVRDIS);
        modify(&mut u, CR1, FRAME, |v| v | CR1_UE);
        u.push_rx(40_000, RxByte::clean(1));
        u.push_rx(40_000 + FRAME, RxByte::clean(2));
        assert_eq!(isr(&mut u, 40_000 + FRAME) & ISR_ORE, 0);
        assert_eq!(rd(&mut u, RDR, 40_000 + FRAME), 2);
    }

    #[test]
    fn overrun_in_fifo_mode_after_rdr_and_eight_in_the_rxfifo() {
        let mut u = ready(true);
        let t0 = 40_000;
        for k in 0..10u64 {
            u.push_rx(t0 + k * FRAME, RxByte::clean(k as u16));
        }
        let s = isr(&mut u, t0 + 8 * FRAME);
        assert_ne!(s & ISR_RXFF, 0, "RXFIFO full + 1 in RDR");
        assert_eq!(s & ISR_ORE, 0);
        assert_ne!(isr(&mut u, t0 + 9 * FRAME) & ISR_ORE, 0);
        let got: Vec<u32> = (0..9).map(|_| rd(&mut u, RDR, t0 + 9 * FRAME)).collect();
        assert_eq!(got, (0..9).collect::<Vec<u32>>());
        assert_eq!(isr(&mut u, t0 + 9 * FRAME) & ISR_RXNE, 0);
    }

    #[test]
    fn idle_sets_one_idle_frame_after_the_last_byte() {
        let mut u = ready(true);
        assert_eq!(isr(&mut u, 100_000) & ISR_IDLE, 0, "no activity: no IDLE");
        let at = 120_000;
        u.push_rx(at, RxByte::clean(1));
        // A second byte right behind the first: its start bit cancels the idle frame.
        u.push_rx(at + FRAME, RxByte::clean(2));
        assert_eq!(isr(&mut u, at + FRAME) & ISR_IDLE, 0);
        let last = at + FRAME;
        assert_eq!(u.next_event(), Some(last + FRAME));
        assert_eq!(isr(&mut u, last + FRAME - 1) & ISR_IDLE, 0);
        assert_ne!(isr(&mut u, last + FRAME) & ISR_IDLE, 0);
        modify(&mut u, CR1, last + FRAME, |v| v | CR1_IDLEIE);
        assert!(irq(&u));
        wr(&mut u, ICR, ISR_IDLE, last + FRAME);
        assert!(!irq(&u) || rd(&mut u, ISR, last + FRAME) & ISR_RXNE != 0);
        // Not set again until a new byte has been received.
        assert_eq!(isr(&mut u, last + 10 * FRAME) & ISR_IDLE, 0);
        assert_eq!(u.next_event(), None);
        // A gap shorter than a frame does not make an idle line.
        let t = last + 20 * FRAME;
        u.push_rx(t, RxByte::clean(3));
        u.push_rx(t + FRAME + FRAME / 2, RxByte::clean(4));
        assert_eq!(isr(&mut u, t + FRAME + FRAME / 2) & ISR_IDLE, 0);
        assert_ne!(isr(&mut u, t + 2 * FRAME + FRAME / 2) & ISR_IDLE, 0);
        assert!(u.take_reports().is_empty());
        // A wire that pushes a character only when it ends, after the receiver has passed
        // the idle frame its start bit would have cancelled: reported.
        let idle = t + 2 * FRAME + FRAME / 2;
        u.push_rx(idle + FRAME / 2, RxByte::clean(5));
        assert_eq!(u.take_reports().len(), 1);
    }

    #[test]
    fn icr_clears_only_the_flags_written_as_one() {
        let mut u = ready(false);
        let t = 40_000;
        u.push_rx(t, RxByte::clean(0x100 | 1)); // fits in 8 bits: 0x01
        u.push_rx(
            t + FRAME,
            RxByte {
                data: 2,
                framing_error: true,
                noise: true,
            },
        );
        u.advance(t + 2 * FRAME);
        // RXNE still set from byte 1: byte 2 overran (and its errors are lost with it).
        let s = isr(&mut u, t + 2 * FRAME);
        assert_eq!(
            s & (ISR_ORE | ISR_IDLE | ISR_FE | ISR_NE),
            ISR_ORE | ISR_IDLE
        );
        assert_eq!(rd(&mut u, RDR, t + 2 * FRAME), 1);
        wr(&mut u, ICR, 0, t + 2 * FRAME);
        assert_eq!(
            isr(&mut u, t + 2 * FRAME) & (ISR_ORE | ISR_IDLE),
            ISR_ORE | ISR_IDLE
        );
        wr(&mut u, ICR, ISR_IDLE, t + 2 * FRAME);
        assert_eq!(isr(&mut u, t + 2 * FRAME) & (ISR_ORE | ISR_IDLE), ISR_ORE);
        // A byte-wide write of the low byte clears ORE.
        u.write(
            Write {
                offset: ICR,
                value: ISR_ORE,
                mask: 0xff,
            },
            t + 2 * FRAME,
        );
        assert_eq!(isr(&mut u, t + 2 * FRAME) & ISR_ORE, 0);
        // ISR is read-only.
        wr(&mut u, ISR, 0, t + 2 * FRAME);
        assert_ne!(isr(&mut u, t + 2 * FRAME) & ISR_TXE, 0);
    }

    #[test]
    fn framing_and_noise_errors_and_the_error_interrupt() {
        let mut u = ready(false);
        let t = 40_000;
        let fe = RxByte {
            data: 7,
            framing_error: true,
            noise: false,
        };
        u.push_rx(t, fe);
        let s = isr(&mut u, t);
        assert_eq!(
            s & (ISR_FE | ISR_RXNE),
            ISR_FE | ISR_RXNE,
            "no DMAR: the word is kept"
        );
        assert!(!irq(&u));
        modify(&mut u, CR3, t, |v| v | CR3_EIE);
        assert!(irq(&u), "FE with EIE");
        wr(&mut u, ICR, ISR_FE, t);
        assert!(!irq(&u));
        rd(&mut u, RDR, t);
        // NE raises the error interrupt only in multibuffer (DMAR) communication.
        let ne = RxByte {
            data: 8,
            framing_error: false,
            noise: true,
        };
        u.push_rx(t + FRAME, ne);
        assert_ne!(isr(&mut u, t + FRAME) & ISR_NE, 0);
        assert!(!irq(&u), "NE with EIE but without DMAR");
        modify(&mut u, CR3, t + FRAME, |v| v | CR3_DMAR);
        assert!(irq(&u), "NE with EIE and DMAR");
        // DMAR with DDRE = 0: the word stays in RDR (it arrived before DMAR was set).
        assert!(requests(&u).0);
    }

    #[test]
    fn with_dmar_and_ddre_clear_an_erroneous_word_is_not_transferred() {
        let mut u = ready(true);
        let t = 40_000;
        modify(&mut u, CR3, 0, |v| v | CR3_DMAR | CR3_EIE);
        u.push_rx(
            t,
            RxByte {
                data: 9,
                framing_error: true,
                noise: false,
            },
        );
        let s = isr(&mut u, t);
        assert_eq!(s & (ISR_FE | ISR_RXNE), ISR_FE, "RXNE kept 0");
        assert!(irq(&u));
        assert_eq!(requests(&u), (false, false));
        // DDRE = 1 (only while UE = 0): the word is kept and the request masked until the
        // flag is cleared.
        modify(&mut u, CR1, t, |v| v & !CR1_UE);
        modify(&mut u, CR3, t, |v| v | CR3_DDRE);
        modify(&mut u, CR1, t, |v| v | CR1_UE);
        u.push_rx(
            t + 2 * FRAME,
            RxByte {
                data: 9,
                framing_error: true,
                noise: false,
            },
        );
        let s = isr(&mut u, t + 2 * FRAME);
        assert_eq!(s & (ISR_FE | ISR_RXNE), ISR_FE | ISR_RXNE);
        assert!(!requests(&u).0, "masked by FE");
        wr(&mut u, ICR, ISR_FE, t + 2 * FRAME);
        assert!(requests(&u).0);
    }

    #[test]
    fn onebit_disables_noise_detection() {
        let mut u = Usart::new(UsartInstance::Usart1);
        embassy_configure(&mut u, BRR_115200, true, 0);
        u.push_rx(
            40_000,
            RxByte {
                data: 1,
                framing_error: false,
                noise: true,
            },
        );
        assert_eq!(isr(&mut u, 40_000) & (ISR_NE | ISR_RXNE), ISR_RXNE);
    }

    #[test]
    fn in_fifo_mode_error_flags_come_with_the_word_in_rdr() {
        let mut u = ready(true);
        let t = 40_000;
        u.push_rx(t, RxByte::clean(1));
        u.push_rx(
            t + FRAME,
            RxByte {
                data: 2,
                framing_error: true,
                noise: false,
            },
        );
        assert_eq!(isr(&mut u, t + FRAME) & ISR_FE, 0, "still behind word 1");
        assert_eq!(rd(&mut u, RDR, t + FRAME), 1);
        assert_ne!(isr(&mut u, t + FRAME) & ISR_FE, 0);
        assert_eq!(rd(&mut u, RDR, t + FRAME), 2);
    }

    #[test]
    fn parity_is_computed_on_both_sides() {
        // 8 data bits + even parity: M0 = 1 (9-bit word), PCE.
        let mut u = Usart::new(UsartInstance::Usart1);
        wr(&mut u, BRR, BRR_115200, 0);
        wr(&mut u, CR1, CR1_UE | CR1_TE | CR1_RE | CR1_M0 | CR1_PCE, 0);
        let c = u.line_config().unwrap_or_else(|| panic!("config"));
        assert_eq!((c.word_bits, c.parity), (9, Parity::Even));
        assert_eq!(c.frame_cycles(), 11 * 1476);
        u.advance(c.frame_cycles());
        wr(&mut u, TDR, 0x07, c.frame_cycles());
        let f = u.take_tx().unwrap_or_else(|| panic!("frame"));
        assert_eq!(f.data, 0x107, "three ones: the parity bit makes them even");
        // Receive it back, then a corrupted copy.
        u.push_rx(100_000, RxByte::clean(f.data));
        assert_eq!(isr(&mut u, 100_000) & ISR_PE, 0);
        assert_eq!(
            rd(&mut u, RDR, 100_000),
            0x107,
            "RDR holds the parity bit too"
        );
        u.push_rx(200_000, RxByte::clean(f.data ^ 1));
        assert_ne!(isr(&mut u, 200_000) & ISR_PE, 0);
        modify(&mut u, CR1, 200_000, |v| v | CR1_PEIE);
        assert!(irq(&u));
    }

    #[test]
    fn dma_request_lines() {
        let mut u = ready(true);
        assert_eq!(requests(&u), (false, false));
        modify(&mut u, CR3, FRAME, |v| v | CR3_DMAT);
        assert_eq!(requests(&u), (false, true), "TXFNF and DMAT");
        modify(&mut u, CR3, FRAME, |v| v | CR3_DMAR);
        assert_eq!(requests(&u), (false, true));
        u.push_rx(40_000, RxByte::clean(1));
        u.advance(40_000);
        assert_eq!(requests(&u), (true, true));
        rd(&mut u, RDR, 40_000);
        assert_eq!(requests(&u), (false, true), "RDR read drops the RX request");
        modify(&mut u, CR1, 40_000, |v| v & !CR1_TE);
        assert_eq!(requests(&u), (false, false), "no TX request without TE");
        modify(&mut u, CR1, 40_000, |v| v & !CR1_UE);
        u.push_rx(60_000, RxByte::clean(1));
        u.advance(60_000);
        assert_eq!(requests(&u), (false, false));
    }

    #[test]
    fn clearing_ue_discards_everything_and_resets_the_flags() {
        let mut u = ready(true);
        let t = 40_000;
        u.push_rx(t, RxByte::clean(1));
        u.advance(t);
        wr(&mut u, TDR, 5, t);
        wr(&mut u, TDR, 6, t);
        assert_ne!(isr(&mut u, t) & (ISR_RXNE | ISR_TEACK | ISR_REACK), 0);
        modify(&mut u, CR1, t + 10, |v| v & !CR1_UE);
        assert_eq!(
            isr(&mut u, t + 10) & !(ISR_TXFE | ISR_TXFT),
            ISR_TXE | ISR_TC
        );
        assert_eq!(
            u.take_reports().len(),
            1,
            "a frame cut on the line is reported"
        );
        u.advance(t + 10 * FRAME);
        assert_eq!(
            std::iter::from_fn(|| u.take_tx()).count(),
            1,
            "only the first started"
        );
    }

    #[test]
    fn configuration_bits_are_locked_while_ue_is_set() {
        let mut u = ready(true);
        let before = rd(&mut u, CR1, FRAME);
        wr(&mut u, CR1, before | CR1_M0 | CR1_PCE, FRAME);
        assert_eq!(rd(&mut u, CR1, FRAME), before);
        wr(&mut u, BRR, 170, FRAME);
        assert_eq!(rd(&mut u, BRR, FRAME), BRR_115200);
        modify(&mut u, CR3, FRAME, |v| v | CR3_ONEBIT | CR3_DMAR | CR3_EIE);
        assert_eq!(
            rd(&mut u, CR3, FRAME),
            CR3_DMAR | CR3_EIE,
            "DMAR/EIE any time"
        );
        assert_eq!(u.take_reports().len(), 3);
    }

    #[test]
    fn unmodelled_features_are_reported() {
        let mut u = Usart::new(UsartInstance::Usart3);
        wr(&mut u, CR3, CR3_HDSEL, 0);
        wr(&mut u, CR2, CR2_SWAP, 0);
        wr(&mut u, RQR, RQR_SBKRQ, 0);
        wr(&mut u, CR1, CR1_M0 | CR1_M1, 0);
        let r = u.take_reports();
        assert_eq!(r.len(), 4, "{r:?}");
        assert!(r.iter().all(|m| m.starts_with("USART3")));
    }

    #[test]
    fn flush_requests() {
        let mut u = ready(true);
        u.push_rx(40_000, RxByte::clean(1));
        u.push_rx(40_000 + FRAME, RxByte::clean(2));
        u.advance(40_000 + FRAME);
        wr(&mut u, RQR, RQR_RXFRQ, 40_000 + FRAME);
        assert_eq!(isr(&mut u, 40_000 + FRAME) & ISR_RXNE, 0);
        // TXFRQ empties the TXFIFO; the word in the shift register still goes out.
        let t = 100_000;
        for b in 0..4 {
            wr(&mut u, TDR, b, t);
        }
        wr(&mut u, RQR, RQR_TXFRQ, t);
        assert_ne!(isr(&mut u, t) & ISR_TXFE, 0);
        u.advance(t + 5 * FRAME);
        assert_eq!(std::iter::from_fn(|| u.take_tx()).count(), 1);
    }

    #[test]
    fn a_byte_started_before_the_receiver_was_enabled_is_dropped() {
        let mut u = Usart::new(UsartInstance::Usart2);
        embassy_configure(&mut u, BRR_115200, false, 10_000);
        u.push_rx(10_000 + FRAME - 1, RxByte::clean(1));
        u.push_rx(10_000 + 2 * FRAME, RxByte::clean(2));
        u.advance(10_000 + 2 * FRAME);
        assert_eq!(rd(&mut u, RDR, 10_000 + 2 * FRAME), 2);
        assert_eq!(isr(&mut u, 10_000 + 2 * FRAME) & (ISR_RXNE | ISR_ORE), 0);
        assert_eq!(u.take_reports().len(), 1);
    }
}
