//! I2C v2 master (I2C1, I2C2, I2C3) and the bus its devices sit on.
//!
//! Register model of RM0440's "Inter-integrated circuit (I2C) interface" chapter (sections
//! "I2C master mode", "Software reset", "I2C registers"), as embassy-stm32 0.6's blocking v2
//! driver uses it (`blocking_write`, `blocking_write_read`, `blocking_write_vectored` with
//! RELOAD), plus the documented behaviour around it that a later driver could rely on.
//!
//! # Timing
//! Everything is derived from TIMINGR at I2CCLK = 170 MHz (one CPU cycle per I2CCLK):
//! * SCL low  = max(SCLL + 1, SDADEL + SCLDEL + 1) x (PRESC + 1) + tSYNC1,
//! * SCL high = (SCLH + 1) x (PRESC + 1) + tSYNC2 + the board's SCL rise time
//!   ([`I2c::set_rise_time_ns`], 0 by default),
//! * tSYNC = analog filter delay (260 ns, the datasheet maximum, unless ANFOFF) + DNF +
//!   3 I2CCLK of synchronisation — RM0440 "I2C clock requirements"/"I2C timings".
//!
//! With embassy's 100 kHz TIMINGR (0x3045D3D3) the SCL period T is 1792 cycles (94.9 kHz).
//! A START (or repeated START) and a STOP condition each take one T, a byte takes 9 T (eight
//! bits and the acknowledge). Device calls happen when the wire would carry them: the
//! address and written bytes reach the device after their eighth bit, a read byte is asked
//! for at its first bit, STOP at the end of the STOP condition.
//!
//! # Flags (master)
//! * TXIS is set when the next data byte is needed and TXDR is empty (after the address'
//!   and each byte's ACK); SCL is stretched until TXDR is written. A byte written into an
//!   empty TXDR while a byte shifts (TXE=1) is copied at the next ACK without a TXIS.
//! * RXNE is set after the eighth bit of a received byte; if RXDR is still full then, SCL is
//!   stretched before the ACK bit until RXDR is read. The master ACKs every byte but the
//!   last of a transfer that ends (RELOAD=0), which it NACKs.
//! * After NBYTES: RELOAD=1 sets TCR (stretch until NBYTES is written non-zero); AUTOEND=1
//!   sends STOP; otherwise TC (stretch until START or STOP is set).
//! * A NACK (address or data) sets NACKF and the master sends STOP by itself; STOPF is set
//!   when the STOP condition is seen on the bus, which also clears BUSY and CR2.STOP.
//! * CR2.STOP set while the peripheral is not master (embassy 0.6's `master_stop` after an
//!   arbitration loss or a timeout) stays set until a STOP is seen or PE=0, so the next
//!   transfer stops after its address byte (no TXIS: the driver times out) — the silicon
//!   behaviour embassy PR #4634 describes for the NACK case.
//! * PE=0 is RM0440's software reset: CR2.START/STOP/NACK and ISR (BUSY, TXE=1, TXIS, RXNE,
//!   ADDR, NACKF, TCR, TC, STOPF, BERR, ARLO, OVR, PECERR, TIMEOUT, ALERT) back to reset, the
//!   lines released; the other registers keep their values.
//!
//! # The bus and stuck SDA
//! [`I2cBus`] holds the attached devices ([`I2cDevice`], shared as [`SharedDevice`] so the
//! host keeps its own handle). While every device is in step with the master, transfers are
//! byte-level (fast). When the master goes away in the middle of a byte (MCU reset, PE=0),
//! each addressed device is left where it was on the wire: a device that was shifting out a
//! 0 bit (or driving an ACK) keeps holding SDA low ([`I2cBus::sda_held_low`]) and from then
//! on is clocked bit by bit. A master START with SDA held low is not seen by anybody: the
//! master then runs bit by bit against those devices and loses arbitration at the first 1
//! bit it sends on a low SDA (ARLO), exactly what the silicon does. SCL pulses made by the
//! firmware with the pins as open-drain GPIO ([`I2c::gpio_scl`], [`I2c::gpio_sda`]) clock
//! the devices and make START/STOP conditions, so a 9-pulse + STOP recovery works as on the
//! board.
//!
//! # Injected faults
//! [`I2c::inject_fault`] arms a NACK, a clock stretch by the device, an arbitration loss or
//! a bus error (misplaced STOP) for one device address; it hits the last byte of the next
//! write chunk without RELOAD to that device, where embassy's blocking master waits for TC
//! or TXIS (module `faults`). The SCL-low timeout detector (TIMEOUTR.TIMOUTEN with
//! TIDLE = 0) acts on an injected stretch: TIMEOUT at tTIMEOUT.
//!
//! # Not modelled (reported or documented)
//! Slave mode (OAR1/OAR2 are plain registers; ADDR never sets), SMBus (PEC: PECR reads are
//! reported as unmodelled; ALERT; the bus-idle timeout TIDLE = 1 and the cumulative TEXTEN
//! timeout), 10-bit addressing (a START with ADD10=1 gets no ACK and is reported by
//! [`I2c::unsupported`]), clock stretching by devices other than an injected one, BERR other
//! than an injected one, GPIO activity while the master itself is transferring, wake-up
//! from Stop.

use crate::names;
use crate::periph::{DmaRequests, IrqLines, Peripheral, Write};
use crate::time::{ns_to_cycles, Cycles};

mod bus;
mod faults;

use bus::Abandon;
pub use bus::{BusCondition, I2cBus, I2cDevice, SharedDevice};
pub use faults::I2cFault;

// Register offsets (RM0440 "I2C register map").
const CR1: u32 = 0x00;
const CR2: u32 = 0x04;
const OAR1: u32 = 0x08;
const OAR2: u32 = 0x0C;
const TIMINGR: u32 = 0x10;
const TIMEOUTR: u32 = 0x14;
const ISR: u32 = 0x18;
const ICR: u32 = 0x1C;
const PECR: u32 = 0x20;
const RXDR: u32 = 0x24;
const TXDR: u32 = 0x28;

// CR1 bits.
const CR1_PE: u32 = 1 << 0;
const CR1_TXIE: u32 = 1 << 1;
const CR1_RXIE: u32 = 1 << 2;
const CR1_ADDRIE: u32 = 1 << 3;
const CR1_NACKIE: u32 = 1 << 4;
const CR1_STOPIE: u32 = 1 << 5;
const CR1_TCIE: u32 = 1 << 6;
const CR1_ERRIE: u32 = 1 << 7;
const CR1_DNF_SHIFT: u32 = 8;
const CR1_DNF: u32 = 0xF << CR1_DNF_SHIFT;
const CR1_ANFOFF: u32 = 1 << 12;
const CR1_TXDMAEN: u32 = 1 << 14;
const CR1_RXDMAEN: u32 = 1 << 15;
const CR1_NOSTRETCH: u32 = 1 << 17;
/// Every CR1 bit (bit 13 is reserved).
const CR1_MASK: u32 = 0x00FF_DFFF;

// CR2 bits.
const CR2_SADD: u32 = 0x3FF;
const CR2_RD_WRN: u32 = 1 << 10;
const CR2_ADD10: u32 = 1 << 11;
const CR2_START: u32 = 1 << 13;
const CR2_STOP: u32 = 1 << 14;
const CR2_NACK: u32 = 1 << 15;
const CR2_NBYTES_SHIFT: u32 = 16;
const CR2_NBYTES: u32 = 0xFF << CR2_NBYTES_SHIFT;
const CR2_RELOAD: u32 = 1 << 24;
const CR2_AUTOEND: u32 = 1 << 25;
const CR2_MASK: u32 = 0x07FF_FFFF;

// OAR1/OAR2 bits.
const OAR1_EN: u32 = 1 << 15;
const OAR1_MASK: u32 = 0x87FF;
const OAR2_EN: u32 = 1 << 15;
const OAR2_MASK: u32 = 0x87FE;

// TIMINGR / TIMEOUTR.
const TIMINGR_MASK: u32 = 0xF0FF_FFFF;
const TIMEOUTR_A: u32 = 0x1FFF; // TIMEOUTA + TIDLE
const TIMEOUTR_TIMOUTEN: u32 = 1 << 15;
const TIMEOUTR_B: u32 = 0x0FFF << 16;
const TIMEOUTR_TEXTEN: u32 = 1 << 31;
const TIMEOUTR_MASK: u32 = 0x8FFF_9FFF;

// ISR bits.
const TXE: u32 = 1 << 0;
const TXIS: u32 = 1 << 1;
const RXNE: u32 = 1 << 2;
const ADDR: u32 = 1 << 3;
const NACKF: u32 = 1 << 4;
const STOPF: u32 = 1 << 5;
const TC: u32 = 1 << 6;
const TCR: u32 = 1 << 7;
const BERR: u32 = 1 << 8;
const ARLO: u32 = 1 << 9;
const OVR: u32 = 1 << 10;
const PECERR: u32 = 1 << 11;
const TIMEOUT: u32 = 1 << 12;
const ALERT: u32 = 1 << 13;
const BUSY: u32 = 1 << 15;
/// Flags ICR clears (ADDRCF, NACKCF, STOPCF, BERRCF, ARLOCF, OVRCF, PECCF, TIMOUTCF,
/// ALERTCF sit on the bits of the flags they clear).
const ICR_MASK: u32 = ADDR | NACKF | STOPF | BERR | ARLO | OVR | PECERR | TIMEOUT | ALERT;
const ERROR_FLAGS: u32 = BERR | ARLO | OVR | PECERR | TIMEOUT | ALERT;

/// Analog filter delay added to each SCL edge's detection when ANFOFF=0: the datasheet's
/// maximum tAF (50..260 ns); the slow end, never kinder than the chip.
const ANALOG_FILTER_NS: u64 = 260;
/// SCL edge synchronisation to I2CCLK (RM0440: 2 to 3 I2CCLK periods).
const SYNC_I2CCLK: u64 = 3;
/// RM0440: "When cleared, PE must be kept low for at least 3 APB clock cycles".
const PE_LOW_MIN_CYCLES: Cycles = 3;

// ---------------------------------------------------------------------------------------
// The peripheral

/// Where the master engine is. Times are the start of the slot.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Phase {
    /// Not master.
    Idle,
    /// START requested, waiting for the bus (BUSY from another START, or SCL held low).
    WaitBus,
    /// (Repeated) START condition, one T.
    Start { at: Cycles },
    /// Address byte: `ack` is known after the eighth bit.
    Address { at: Cycles, ack: Option<bool> },
    /// Data byte out.
    Tx {
        at: Cycles,
        byte: u8,
        ack: Option<bool>,
    },
    /// Data byte in (eight bits).
    Rx { at: Cycles, byte: u8 },
    /// Eight bits in, RXDR still full: SCL stretched before the ACK bit.
    RxHold { byte: u8 },
    /// The master's ACK (`ack`) or NACK bit.
    RxAck { at: Cycles, ack: bool },
    /// TXIS: stretching until TXDR is written.
    WaitTx,
    /// TCR: stretching until NBYTES is written.
    Reload,
    /// TC: stretching until START or STOP.
    Complete,
    /// STOP condition, one T.
    Stop { at: Cycles },
    /// Arbitration lost at `at` (bit-level transfer against a device holding SDA).
    Lost { at: Cycles },
}

/// Counters a test of the real image can assert on (they survive resets).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct I2cStats {
    /// START conditions the master generated (including repeated STARTs).
    pub starts: u64,
    /// STARTs generated while SDA (or SCL) was held low: nobody saw them (D6).
    pub stuck_starts: u64,
    /// Address or data bytes not acknowledged.
    pub nacks: u64,
    /// Arbitration lost (ARLO set).
    pub arbitration_losses: u64,
    /// STOP conditions seen on the bus at the end of a master transfer.
    pub stops: u64,
    /// STOPs the master made that were not seen because a device held SDA low.
    pub lost_stops: u64,
    /// Transfers abandoned in the middle by PE=0 or a reset.
    pub abandoned: u64,
    /// PE set again less than 3 APB cycles after it was cleared.
    pub short_pe_resets: u64,
    pub bytes_written: u64,
    pub bytes_read: u64,
    /// Injected faults that fired ([`I2c::inject_fault`]).
    pub injected_faults: u64,
}

/// Which I2C: names its interrupts (`I2Cx_EV`, `I2Cx_ER`) and DMA requests.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum I2cInstance {
    I2c1,
    I2c2,
    I2c3,
}

/// One I2C instance (I2C1..I2C3) with its bus.
#[derive(Debug)]
pub struct I2c {
    name: &'static str,
    ev_irq: Option<u16>,
    er_irq: Option<u16>,
    tx_request: Option<u8>,
    rx_request: Option<u8>,
    cr1: u32,
    cr2: u32,
    oar1: u32,
    oar2: u32,
    timingr: u32,
    timeoutr: u32,
    /// ISR flags (BUSY included).
    isr: u32,
    rxdr: u8,
    txdr: u8,
    phase: Phase,
    /// Transfer latched at START.
    addr7: u8,
    read: bool,
    ten_bit: bool,
    /// NBYTES of the current chunk and bytes done in it.
    nbytes: u8,
    count: u8,
    /// The transfer runs bit by bit (a START nobody saw).
    bit_mode: bool,
    bus: I2cBus,
    now: Cycles,
    rise_time: Cycles,
    pe_cleared_at: Option<Cycles>,
    stats: I2cStats,
    unsupported: Option<&'static str>,
    /// A fault waiting for its byte (`faults`).
    armed: Option<faults::Armed>,
    /// The SCL-low timeout detector fires here (during an injected stretch).
    timeout_at: Option<Cycles>,
}

impl I2c {
    /// The instance at reset, with an empty bus.
    pub fn new(instance: I2cInstance) -> Self {
        let name = match instance {
            I2cInstance::I2c1 => "I2C1",
            I2cInstance::I2c2 => "I2C2",
            I2cInstance::I2c3 => "I2C3",
        };
        I2c {
            name,
            ev_irq: names::irq(&format!("{name}_EV")),
            er_irq: names::irq(&format!("{name}_ER")),
            tx_request: names::dma_request(name, "TX"),
            rx_request: names::dma_request(name, "RX"),
            cr1: 0,
            cr2: 0,
            oar1: 0,
            oar2: 0,
            timingr: 0,
            timeoutr: 0,
            isr: TXE,
            rxdr: 0,
            txdr: 0,
            phase: Phase::Idle,
            addr7: 0,
            read: false,
            ten_bit: false,
            nbytes: 0,
            count: 0,
            bit_mode: false,
            bus: I2cBus::default(),
            now: 0,
            rise_time: 0,
            pe_cleared_at: None,
            stats: I2cStats::default(),
            unsupported: None,
            armed: None,
            timeout_at: None,
        }
    }

    /// "I2C1".."I2C3".
    pub fn name(&self) -> &'static str {
        self.name
    }

    /// Attaches a device to this instance's bus.
    pub fn attach(&mut self, dev: SharedDevice) {
        self.bus.attach(dev);
    }

    /// The bus (levels, stuck SDA, GPIO pulse count).
    pub fn bus(&self) -> &I2cBus {
        &self.bus
    }

    /// A device on this bus holds SDA low.
    pub fn sda_held_low(&self) -> bool {
        self.bus.sda_held_low()
    }

    /// The firmware drives the SCL pin as open-drain GPIO (`low` = pulled down). Call after
    /// `advance(now)`. Clocks the devices; releasing SCL lets a waiting START go.
    pub fn gpio_scl(&mut self, low: bool, now: Cycles) {
        self.bus.drive_scl(low, now);
        if self.phase == Phase::WaitBus {
            self.try_start(now);
        }
    }

    /// The firmware drives the SDA pin as open-drain GPIO. START/STOP conditions it makes
    /// set/clear BUSY while PE=1 (the peripheral watches the pins).
    pub fn gpio_sda(&mut self, low: bool, now: Cycles) {
        match self.bus.drive_sda(low, now) {
            Some(BusCondition::Start) if self.enabled() => self.isr |= BUSY,
            Some(BusCondition::Stop) if self.enabled() => {
                self.isr &= !BUSY;
                if self.phase == Phase::WaitBus {
                    self.try_start(now);
                }
            }
            _ => {}
        }
    }

    /// `n` GPIO pulses on SCL at `now` (a recovery loop's clocks).
    pub fn gpio_pulse_scl(&mut self, n: u32, now: Cycles) {
        for _ in 0..n {
            self.gpio_scl(true, now);
            self.gpio_scl(false, now);
        }
    }

    /// SCL rise time of the board (pull-up x bus capacitance), added to each SCL period.
    pub fn set_rise_time_ns(&mut self, ns: u64) {
        self.rise_time = ns_to_cycles(ns);
    }

    /// (low, high) parts of the SCL period in cycles, from TIMINGR and CR1 (DNF, ANFOFF).
    pub fn scl_low_high(&self) -> (Cycles, Cycles) {
        let t = self.timingr;
        let presc = u64::from((t >> 28) & 0xF) + 1;
        let scldel = u64::from((t >> 20) & 0xF);
        let sdadel = u64::from((t >> 16) & 0xF);
        let sclh = u64::from((t >> 8) & 0xFF);
        let scll = u64::from(t & 0xFF);
        let dnf = u64::from((self.cr1 & CR1_DNF) >> CR1_DNF_SHIFT);
        let af = if self.cr1 & CR1_ANFOFF == 0 {
            ns_to_cycles(ANALOG_FILTER_NS)
        } else {
            0
        };
        let sync = af + dnf + SYNC_I2CCLK;
        let low = (scll + 1).max(sdadel + scldel + 1) * presc + sync;
        let high = (sclh + 1) * presc + sync + self.rise_time;
        (low, high)
    }

    /// The SCL period T in cycles: a bit; a byte with its ACK is 9 T.
    pub fn scl_period(&self) -> Cycles {
        let (l, h) = self.scl_low_high();
        l + h
    }

    /// Counters (NACKs, arbitration losses, stuck STARTs...).
    pub fn stats(&self) -> I2cStats {
        self.stats
    }

    /// The first unsupported feature the firmware used (e.g. 10-bit addressing), if any.
    pub fn unsupported(&self) -> Option<&'static str> {
        self.unsupported
    }

    fn enabled(&self) -> bool {
        self.cr1 & CR1_PE != 0
    }

    fn due(&self) -> Option<Cycles> {
        match (self.phase_due(), self.timeout_at) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        }
    }

    fn phase_due(&self) -> Option<Cycles> {
        let t = self.scl_period();
        match self.phase {
            Phase::Start { at } | Phase::Stop { at } | Phase::RxAck { at, .. } => Some(at + t),
            Phase::Address { at, ack: None } | Phase::Tx { at, ack: None, .. } => Some(at + 8 * t),
            Phase::Address { at, ack: Some(_) }
            | Phase::Tx {
                at, ack: Some(_), ..
            } => Some(at + 9 * t),
            Phase::Rx { at, .. } => Some(at + 8 * t),
            Phase::Lost { at } => Some(at),
            _ => None,
        }
    }

    fn step(&mut self, t: Cycles) {
        match self.phase {
            Phase::Start { .. } => self.begin_address(t),
            Phase::Address { at, ack: None } => {
                let ack = if self.ten_bit {
                    false
                } else {
                    self.bus.start(self.addr7, self.read, t)
                };
                self.phase = Phase::Address { at, ack: Some(ack) };
            }
            Phase::Address { ack: Some(ack), .. } => {
                self.cr2 &= !CR2_START;
                if ack {
                    self.count = 0;
                    self.begin_chunk(t);
                } else {
                    self.nack(t);
                }
            }
            Phase::Tx {
                at,
                byte,
                ack: None,
            } => match self.take_fault().map(|f| self.apply_fault(f, byte, t)) {
                None => {
                    let ack = self.bus.write(byte, t);
                    self.phase = Phase::Tx {
                        at,
                        byte,
                        ack: Some(ack),
                    };
                }
                Some(faults::Hit::Ack(ack)) => {
                    self.phase = Phase::Tx {
                        at,
                        byte,
                        ack: Some(ack),
                    };
                }
                Some(faults::Hit::Stretched { ack, cycles }) => {
                    self.phase = Phase::Tx {
                        at: at + cycles,
                        byte,
                        ack: Some(ack),
                    };
                }
                Some(faults::Hit::Abort { flag }) => self.abort_transfer(flag, t),
            },
            Phase::Tx { ack: Some(ack), .. } => {
                self.stats.bytes_written += 1;
                if ack {
                    self.count = self.count.wrapping_add(1);
                    self.need_tx(t);
                } else {
                    self.nack(t);
                }
            }
            Phase::Rx { byte, .. } => {
                if self.isr & RXNE == 0 {
                    self.rxdr = byte;
                    self.isr |= RXNE;
                    self.rx_ack(t);
                } else {
                    self.phase = Phase::RxHold { byte };
                }
            }
            Phase::RxAck { .. } => {
                self.stats.bytes_read += 1;
                self.count = self.count.wrapping_add(1);
                if self.count < self.nbytes {
                    if self.cr2 & CR2_STOP != 0 {
                        self.begin_stop(t);
                    } else {
                        self.begin_rx(t);
                    }
                } else {
                    self.end_of_chunk(t);
                }
            }
            Phase::Stop { .. } => self.finish_stop(t),
            Phase::Lost { .. } => {
                self.isr |= ARLO;
                self.cr2 &= !CR2_START;
                self.stats.arbitration_losses += 1;
                self.phase = Phase::Idle;
                self.bit_mode = false;
            }
            Phase::Idle
            | Phase::WaitBus
            | Phase::RxHold { .. }
            | Phase::WaitTx
            | Phase::Reload
            | Phase::Complete => {}
        }
    }

    /// Latches CR2 and starts (or waits for the bus).
    fn request_start(&mut self, now: Cycles, restart: bool) {
        self.addr7 = ((self.cr2 & CR2_SADD) >> 1) as u8 & 0x7F;
        self.read = self.cr2 & CR2_RD_WRN != 0;
        self.ten_bit = self.cr2 & CR2_ADD10 != 0;
        if self.ten_bit && self.unsupported.is_none() {
            self.unsupported = Some("I2C 10-bit addressing (CR2.ADD10): no device answers");
        }
        if restart {
            // The master releases SDA and makes one more SCL clock before the START.
            self.bus.clock_bit(true, now);
            self.begin_start(now);
        } else {
            self.phase = Phase::WaitBus;
            self.try_start(now);
        }
    }

    fn try_start(&mut self, now: Cycles) {
        // "START ... once the bus is free": no START seen without its STOP, SCL high.
        if self.isr & BUSY == 0 && self.bus.scl() {
            self.begin_start(now);
        }
    }

    fn begin_start(&mut self, now: Cycles) {
        self.stats.starts += 1;
        if self.bus.sda() && self.bus.scl() {
            // SDA falls while SCL is high: everybody sees the START.
            self.bit_mode = false;
            self.isr |= BUSY;
        } else {
            // SDA already low: no START on the bus, the master clocks bit by bit.
            self.bit_mode = true;
            self.stats.stuck_starts += 1;
            self.bus.deselect_all();
        }
        self.phase = Phase::Start { at: now };
    }

    fn addr_byte(&self) -> u8 {
        (self.addr7 << 1) | u8::from(self.read)
    }

    fn begin_address(&mut self, t: Cycles) {
        if self.bit_mode {
            let byte = self.addr_byte();
            self.phase = match self.bus.clock_out(byte, t) {
                Ok(ack) => Phase::Address {
                    at: t,
                    ack: Some(ack),
                },
                Err(bit) => Phase::Lost {
                    at: t + (u64::from(bit) + 1) * self.scl_period(),
                },
            };
        } else {
            self.phase = Phase::Address { at: t, ack: None };
        }
    }

    fn begin_chunk(&mut self, t: Cycles) {
        self.nbytes = ((self.cr2 & CR2_NBYTES) >> CR2_NBYTES_SHIFT) as u8;
        if self.read {
            if self.count < self.nbytes {
                self.begin_rx(t);
            } else {
                self.end_of_chunk(t);
            }
        } else {
            self.need_tx(t);
        }
    }

    fn need_tx(&mut self, t: Cycles) {
        if self.count >= self.nbytes {
            self.end_of_chunk(t);
        } else if self.cr2 & CR2_STOP != 0 {
            self.begin_stop(t);
        } else if self.isr & TXE == 0 {
            self.isr |= TXE;
            self.begin_tx(t, self.txdr);
        } else {
            self.isr |= TXIS;
            self.phase = Phase::WaitTx;
        }
    }

    fn begin_tx(&mut self, t: Cycles, byte: u8) {
        if self.bit_mode {
            self.phase = match self.bus.clock_out(byte, t) {
                Ok(ack) => Phase::Tx {
                    at: t,
                    byte,
                    ack: Some(ack),
                },
                Err(bit) => Phase::Lost {
                    at: t + (u64::from(bit) + 1) * self.scl_period(),
                },
            };
        } else {
            self.phase = Phase::Tx {
                at: t,
                byte,
                ack: None,
            };
        }
    }

    fn begin_rx(&mut self, t: Cycles) {
        let byte = if self.bit_mode {
            self.bus.clock_in(t)
        } else {
            self.bus.read(t)
        };
        self.phase = Phase::Rx { at: t, byte };
    }

    /// The master's ACK/NACK bit after a received byte (RXDR just took it).
    fn rx_ack(&mut self, t: Cycles) {
        let last = self.count.wrapping_add(1) >= self.nbytes && self.cr2 & CR2_RELOAD == 0;
        let ack = !last;
        if self.bit_mode {
            self.bus.clock_bit(!ack, t);
        }
        self.phase = Phase::RxAck { at: t, ack };
    }

    fn end_of_chunk(&mut self, t: Cycles) {
        if self.cr2 & CR2_RELOAD != 0 {
            self.isr |= TCR;
            self.phase = Phase::Reload;
        } else if self.cr2 & CR2_AUTOEND != 0 {
            self.begin_stop(t);
        } else if self.cr2 & CR2_START != 0 {
            self.request_start(t, true);
        } else if self.cr2 & CR2_STOP != 0 {
            self.begin_stop(t);
        } else {
            self.isr |= TC;
            self.phase = Phase::Complete;
        }
    }

    fn nack(&mut self, t: Cycles) {
        self.isr |= NACKF;
        self.stats.nacks += 1;
        self.begin_stop(t);
    }

    fn begin_stop(&mut self, t: Cycles) {
        // SCL clocks once more with SDA low; the STOP is SDA rising while SCL is high.
        self.bus.clock_bit(false, t);
        self.phase = Phase::Stop { at: t };
    }

    fn finish_stop(&mut self, t: Cycles) {
        self.cr2 &= !CR2_STOP;
        if self.bus.sda_free() {
            self.bus.stop(t);
            self.isr |= STOPF;
            self.isr &= !BUSY;
            self.stats.stops += 1;
        } else {
            self.stats.lost_stops += 1;
        }
        self.phase = Phase::Idle;
        self.bit_mode = false;
        if self.cr2 & CR2_START != 0 {
            self.request_start(t, false);
        }
    }

    /// The master goes away mid-transfer (PE=0 or reset at `now`): the lines are released
    /// and the devices stay where they were on the wire.
    fn abandon(&mut self, now: Cycles) {
        let t = self.scl_period().max(1);
        let (low, _) = self.scl_low_high();
        // Bit `k` of a slot starting at `at`, and whether SCL was high (its rising edge
        // already seen); otherwise the release makes that rising edge.
        let pos = |at: Cycles| {
            let e = now.saturating_sub(at);
            ((e / t).min(8) as u8, e % t >= low)
        };
        let sending = |byte: u8, at: Cycles, address: bool| {
            let (k, high) = pos(at);
            let k = k.min(7);
            // Bits before k as sent; bit k as sent if SCL was high, else the released 1.
            let before = if k == 0 { 0 } else { byte >> (8 - k) };
            let bit_k = if high { (byte >> (7 - k)) & 1 } else { 1 };
            Abandon::MasterSending {
                address,
                partial: (before << 1) | bit_k,
                bits: k + 1,
            }
        };
        let at = if self.bit_mode {
            None
        } else {
            match self.phase {
                Phase::Address { at, ack: None } => Some(sending(self.addr_byte(), at, true)),
                Phase::Address { ack: Some(_), .. } => Some(Abandon::SlaveAcking {
                    address: true,
                    read: self.read,
                }),
                Phase::Tx {
                    at,
                    byte,
                    ack: None,
                } => Some(sending(byte, at, false)),
                Phase::Tx { ack: Some(_), .. } => Some(Abandon::SlaveAcking {
                    address: false,
                    read: false,
                }),
                Phase::Rx { at, .. } => Some(Abandon::SlaveSending {
                    bit: pos(at).0.min(7),
                    master_ack: false,
                }),
                Phase::RxHold { .. } => Some(Abandon::SlaveSending {
                    bit: 8,
                    master_ack: false,
                }),
                Phase::RxAck { at, ack } => Some(Abandon::SlaveSending {
                    bit: 8,
                    master_ack: ack && pos(at).1,
                }),
                Phase::WaitTx => Some(Abandon::BetweenWriteBytes),
                Phase::Reload | Phase::Complete if !self.read => Some(Abandon::BetweenWriteBytes),
                Phase::Reload => Some(Abandon::BetweenReadBytesAcked),
                Phase::Complete => Some(Abandon::AfterNack),
                _ => None,
            }
        };
        if let Some(at) = at {
            self.stats.abandoned += 1;
            self.bus.abandon(at, now);
        }
        if let Phase::Stop { .. } = self.phase {
            // The release finishes the STOP (SDA rises while SCL is high).
            if self.bus.sda_free() {
                self.bus.stop(now);
            }
        }
        self.phase = Phase::Idle;
        self.bit_mode = false;
    }

    /// RM0440 "Software reset" (PE=0).
    fn software_reset(&mut self, now: Cycles) {
        self.abandon(now);
        self.timeout_at = None;
        self.cr2 &= !(CR2_START | CR2_STOP | CR2_NACK);
        self.isr = TXE;
        self.pe_cleared_at = Some(now);
    }

    fn read_isr(&self) -> u32 {
        self.isr
    }

    fn write_cr1(&mut self, w: Write, now: Cycles) {
        let old = self.cr1;
        let mut new = w.merge(old) & CR1_MASK;
        // "The filters can only be programmed when the I2C is disabled (PE = 0)".
        if old & CR1_PE != 0 && new & CR1_PE != 0 {
            new = (new & !(CR1_DNF | CR1_ANFOFF)) | (old & (CR1_DNF | CR1_ANFOFF));
        }
        self.cr1 = new;
        if old & CR1_PE != 0 && new & CR1_PE == 0 {
            self.software_reset(now);
        } else if old & CR1_PE == 0 && new & CR1_PE != 0 {
            if let Some(c) = self.pe_cleared_at {
                if now.saturating_sub(c) < PE_LOW_MIN_CYCLES {
                    self.stats.short_pe_resets += 1;
                }
            }
        }
    }

    fn write_cr2(&mut self, w: Write, now: Cycles) {
        let old = self.cr2;
        let written = w.value & w.mask;
        // START/STOP/NACK: writing 0 has no effect.
        let mut new = (w.merge(old) & CR2_MASK) | (old & (CR2_START | CR2_STOP | CR2_NACK));
        let pe = self.enabled();
        if !pe {
            // Cleared by hardware while PE=0.
            new &= !(CR2_START | CR2_STOP | CR2_NACK);
        }
        self.cr2 = new;
        if !pe {
            return;
        }
        let nbytes = (new & CR2_NBYTES) >> CR2_NBYTES_SHIFT;
        if w.mask & CR2_NBYTES != 0 && nbytes != 0 && self.phase == Phase::Reload {
            // TCR "is cleared by software when NBYTES is written to a non-zero value".
            self.isr &= !TCR;
            self.count = 0;
            self.begin_chunk(now);
        }
        if written & CR2_STOP != 0 && self.phase == Phase::Complete {
            self.isr &= !TC;
            self.begin_stop(now);
        }
        if written & CR2_START != 0 {
            match self.phase {
                Phase::Idle => self.request_start(now, false),
                Phase::Complete => {
                    self.isr &= !TC;
                    self.request_start(now, true);
                }
                // Otherwise a repeated START after this chunk (end_of_chunk), or a START
                // once the current STOP is done (finish_stop).
                _ => {}
            }
        }
    }

    fn write_txdr(&mut self, byte: u8, now: Cycles) {
        if self.isr & TXE == 0 {
            // "TXDATA can be written only when TXE=1".
            return;
        }
        self.txdr = byte;
        self.isr &= !TXIS;
        if self.phase == Phase::WaitTx {
            self.begin_tx(now, byte);
        } else {
            self.isr &= !TXE;
        }
    }

    fn read_rxdr(&mut self, now: Cycles) -> u8 {
        let v = self.rxdr;
        self.isr &= !RXNE;
        if let Phase::RxHold { byte } = self.phase {
            self.rxdr = byte;
            self.isr |= RXNE;
            self.rx_ack(now);
        }
        v
    }
}

impl Peripheral for I2c {
    /// The first unsupported use, named (repeated at each call: the SoC reports it once).
    fn take_reports(&mut self) -> Vec<String> {
        self.unsupported
            .map(|u| vec![format!("{}: {u}", self.name())])
            .unwrap_or_default()
    }

    fn read(&mut self, offset: u32, now: Cycles) -> Option<u32> {
        Some(match offset {
            CR1 => self.cr1,
            CR2 => self.cr2,
            OAR1 => self.oar1,
            OAR2 => self.oar2,
            TIMINGR => self.timingr,
            TIMEOUTR => self.timeoutr,
            ISR => self.read_isr(),
            ICR => 0,
            RXDR => u32::from(self.read_rxdr(now)),
            TXDR => u32::from(self.txdr),
            // PEC is not modelled: report the access rather than read a made-up 0.
            PECR => return None,
            _ => return None,
        })
    }

    fn write(&mut self, w: Write, now: Cycles) -> bool {
        match w.offset {
            CR1 => self.write_cr1(w, now),
            CR2 => self.write_cr2(w, now),
            OAR1 => {
                // OA1/OA1MODE can be written only when OA1EN=0.
                let keep = if self.oar1 & OAR1_EN != 0 { 0x7FF } else { 0 };
                self.oar1 = ((w.merge(self.oar1) & !keep) | (self.oar1 & keep)) & OAR1_MASK;
            }
            OAR2 => {
                let keep = if self.oar2 & OAR2_EN != 0 { 0x7FE } else { 0 };
                self.oar2 = ((w.merge(self.oar2) & !keep) | (self.oar2 & keep)) & OAR2_MASK;
            }
            TIMINGR => self.timingr = w.merge(self.timingr) & TIMINGR_MASK,
            TIMEOUTR => {
                let old = self.timeoutr;
                let mut keep = 0;
                if old & TIMEOUTR_TIMOUTEN != 0 {
                    keep |= TIMEOUTR_A;
                }
                if old & TIMEOUTR_TEXTEN != 0 {
                    keep |= TIMEOUTR_B;
                }
                self.timeoutr = ((w.merge(old) & !keep) | (old & keep)) & TIMEOUTR_MASK;
            }
            ISR => {
                let written = w.value & w.mask;
                if written & TXE != 0 {
                    // Flushes TXDR.
                    self.isr |= TXE;
                }
                if written & TXIS != 0 && self.cr1 & CR1_NOSTRETCH != 0 {
                    self.isr |= TXIS;
                }
            }
            ICR => {
                let clear = w.value & w.mask & ICR_MASK;
                self.isr &= !clear;
                if clear & ADDR != 0 && self.phase == Phase::WaitBus {
                    // ADDRCF also clears a START that has not gone out yet.
                    self.cr2 &= !CR2_START;
                    self.phase = Phase::Idle;
                }
            }
            TXDR => {
                if w.mask & 0xFF != 0 {
                    self.write_txdr(w.value as u8, now);
                }
            }
            // Read-only registers: the write is ignored, as on the chip.
            RXDR => {}
            PECR => return false,
            _ => return false,
        }
        true
    }

    fn next_event(&self) -> Option<Cycles> {
        self.due()
    }

    fn advance(&mut self, now: Cycles) {
        while let Some(t) = self.due() {
            if t > now {
                break;
            }
            if self.timeout_at == Some(t) {
                self.timeout_detected(t);
            } else {
                self.step(t);
            }
        }
        self.now = self.now.max(now);
    }

    fn irq_lines(&self, lines: &mut IrqLines) {
        let (c, i) = (self.cr1, self.isr);
        let ev = (c & CR1_TXIE != 0 && i & TXIS != 0)
            || (c & CR1_RXIE != 0 && i & RXNE != 0)
            || (c & CR1_ADDRIE != 0 && i & ADDR != 0)
            || (c & CR1_NACKIE != 0 && i & NACKF != 0)
            || (c & CR1_STOPIE != 0 && i & STOPF != 0)
            || (c & CR1_TCIE != 0 && i & (TC | TCR) != 0);
        let er = c & CR1_ERRIE != 0 && i & ERROR_FLAGS != 0;
        if let (true, Some(n)) = (ev, self.ev_irq) {
            lines.set(n);
        }
        if let (true, Some(n)) = (er, self.er_irq) {
            lines.set(n);
        }
    }

    fn dma_requests(&self, requests: &mut DmaRequests) {
        if self.cr1 & CR1_TXDMAEN != 0 && self.isr & TXIS != 0 {
            if let Some(r) = self.tx_request {
                requests.set(r);
            }
        }
        if self.cr1 & CR1_RXDMAEN != 0 && self.isr & RXNE != 0 {
            if let Some(r) = self.rx_request {
                requests.set(r);
            }
        }
    }

    fn reset(&mut self) {
        // The pins go to their reset state (analog): the devices stay where they were.
        let now = self.now;
        self.abandon(now);
        self.timeout_at = None;
        self.cr1 = 0;
        self.cr2 = 0;
        self.oar1 = 0;
        self.oar2 = 0;
        self.timingr = 0;
        self.timeoutr = 0;
        self.isr = TXE;
        self.rxdr = 0;
        self.txdr = 0;
        self.pe_cleared_at = None;
    }
}

#[cfg(test)]
pub(crate) mod embassy_driver;

#[cfg(test)]
mod tests;
