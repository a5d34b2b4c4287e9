//! 24C256 serial EEPROM (256 Kbit = 32 KiB), from the Microchip 24AA256/24LC256 and
//! Atmel/Microchip AT24C256C datasheets, as an [`I2cDevice`].
//!
//! * Address 0b1010_A2A1A0 (0x50 with A2..A0 low). Every write starts with two address
//!   bytes, high byte first; the top bit of the high byte is "don't care" (15-bit address).
//! * Byte and page write: data bytes go to the 64-byte page of the address, the low 6 bits
//!   wrapping **inside the page** ("roll over ... previously received data will be
//!   overwritten"). The internal write cycle tWR starts at the STOP that follows at least
//!   one complete data byte (5 ms max by default, [`Eeprom24c256::with_write_cycle`]);
//!   during it the chip ACKs nothing, its address included: ACK polling. A STOP after only
//!   the address bytes writes nothing (it sets the address counter: a random read's dummy
//!   write). A START before the STOP aborts the page write.
//! * Reads: current-address read (the counter keeps the last address accessed + 1),
//!   random read (dummy write + repeated START + read), sequential read rolling over from
//!   0x7FFF to 0x0000.
//! * Contents: the host loads/saves the raw 32 KiB image ([`contents`], [`load`]), the
//!   simulator's EEPROM image format.
//! * Power cut during a write cycle ([`power_cut`]): modelled as [`TornWrite`]; the default
//!   (what this model documents as the chip's behaviour) is that every byte already latched
//!   in the page buffer is written ([`TornWrite::Written`]); a test of the firmware's
//!   storage can choose the pessimistic outcomes (old data kept, or the bytes erased).
//!
//! A STOP in the middle of a data byte (the datasheets do not say what it does) is taken as
//! a STOP after the last complete byte: the latched bytes are written.
//!
//! Writes are applied to the memory at the STOP (the NACKs of the write cycle keep the
//! firmware from reading them early); the page's old bytes are kept until tWR ends so that a
//! power cut can undo them.
//!
//! Counters: [`writes`] (write cycles started), [`nacked_polls`] (addressings NACKed
//! because a write cycle was running), [`aborted_writes`].
//!
//! [`contents`]: Eeprom24c256::contents
//! [`load`]: Eeprom24c256::load
//! [`power_cut`]: Eeprom24c256::power_cut
//! [`writes`]: Eeprom24c256::writes
//! [`nacked_polls`]: Eeprom24c256::nacked_polls
//! [`aborted_writes`]: Eeprom24c256::aborted_writes

use crate::periph::i2c::I2cDevice;
use crate::time::{Cycles, CYCLES_PER_US};

/// Size of the memory.
pub const BYTES: usize = 32 * 1024;
/// Page size.
pub const PAGE: usize = 64;
/// Address with A2..A0 low.
pub const DEFAULT_ADDRESS: u8 = 0x50;
/// Datasheet maximum of the write cycle tWR (5 ms).
pub const DEFAULT_WRITE_CYCLE: Cycles = 5_000 * CYCLES_PER_US;

const ADDR_MASK: u16 = (BYTES - 1) as u16;
const PAGE_MASK: u16 = !((PAGE - 1) as u16) & ADDR_MASK;

/// What a power cut during the write cycle leaves in the bytes being written.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum TornWrite {
    /// The latched bytes are written (the default).
    #[default]
    Written,
    /// The page keeps its old bytes.
    NotWritten,
    /// The latched bytes read 0xFF (erased, not programmed).
    Erased,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum State {
    /// Not addressed.
    Idle,
    /// Addressed for a write: waiting for the address high byte.
    AddrHigh,
    /// Waiting for the address low byte.
    AddrLow { high: u8 },
    /// Taking data bytes into the page buffer (`latched` complete bytes so far).
    Data { latched: u32 },
    /// Addressed for a read.
    Reading,
}

/// The write cycle in progress: the page's bytes before it, to undo on a power cut.
#[derive(Debug, Clone)]
struct Cycle {
    ends: Cycles,
    page: u16,
    old: [u8; PAGE],
    mask: u64,
}

/// A 24C256 on the bus.
#[derive(Debug, Clone)]
pub struct Eeprom24c256 {
    address: u8,
    mem: Box<[u8; BYTES]>,
    /// Internal address counter.
    pointer: u16,
    state: State,
    /// Page buffer: page base, bytes, which offsets were written.
    page: u16,
    buffer: [u8; PAGE],
    mask: u64,
    write_cycle: Cycles,
    cycle: Option<Cycle>,
    torn: TornWrite,
    epoch: u32,
    writes: u64,
    nacked_polls: u64,
    aborted_writes: u64,
}

impl Default for Eeprom24c256 {
    fn default() -> Self {
        Self::new(DEFAULT_ADDRESS)
    }
}

impl Eeprom24c256 {
    /// An erased chip (all 0xFF, as delivered) at `address` (0x50..=0x57).
    pub fn new(address: u8) -> Self {
        Eeprom24c256 {
            address,
            mem: Box::new([0xFF; BYTES]),
            pointer: 0,
            state: State::Idle,
            page: 0,
            buffer: [0xFF; PAGE],
            mask: 0,
            write_cycle: DEFAULT_WRITE_CYCLE,
            cycle: None,
            torn: TornWrite::default(),
            epoch: 0,
            writes: 0,
            nacked_polls: 0,
            aborted_writes: 0,
        }
    }

    /// tWR of this part (the datasheet gives a maximum; real parts are often faster).
    pub fn with_write_cycle(mut self, cycles: Cycles) -> Self {
        self.write_cycle = cycles;
        self
    }

    /// What a power cut during a write cycle does ([`TornWrite`]).
    pub fn set_torn_write(&mut self, torn: TornWrite) {
        self.torn = torn;
    }

    /// The memory as the chip holds it (a running write cycle counted as written).
    pub fn contents(&self) -> &[u8; BYTES] {
        &self.mem
    }

    /// Loads a raw image (exactly 32 KiB).
    pub fn load(&mut self, image: &[u8]) -> Result<(), ImageSizeError> {
        if image.len() != BYTES {
            return Err(ImageSizeError { len: image.len() });
        }
        self.mem.copy_from_slice(image);
        self.cycle = None;
        Ok(())
    }

    /// Whether a write cycle runs at `now` (the chip NACKs its address).
    pub fn is_writing(&self, now: Cycles) -> bool {
        self.cycle.as_ref().is_some_and(|c| now < c.ends)
    }

    /// End of the running (or last) write cycle.
    pub fn write_cycle_end(&self) -> Option<Cycles> {
        self.cycle.as_ref().map(|c| c.ends)
    }

    /// The internal address counter.
    pub fn pointer(&self) -> u16 {
        self.pointer
    }

    /// Write cycles started (page or byte writes).
    pub fn writes(&self) -> u64 {
        self.writes
    }

    /// Addressings NACKed because a write cycle was running (ACK polling).
    pub fn nacked_polls(&self) -> u64 {
        self.nacked_polls
    }

    /// Page writes abandoned by a START before their STOP.
    pub fn aborted_writes(&self) -> u64 {
        self.aborted_writes
    }

    /// The supply goes away at `now` and comes back: a write cycle in progress ends as
    /// [`TornWrite`] says, the address counter and the bus interface restart from 0/idle.
    pub fn power_cut(&mut self, now: Cycles) {
        if let Some(c) = self.cycle.take() {
            if now < c.ends {
                for (i, old) in c.old.iter().enumerate() {
                    if c.mask & (1 << i) == 0 {
                        continue;
                    }
                    let at = usize::from(c.page) + i;
                    if let Some(cell) = self.mem.get_mut(at) {
                        match self.torn {
                            TornWrite::Written => {}
                            TornWrite::NotWritten => *cell = *old,
                            TornWrite::Erased => *cell = 0xFF,
                        }
                    }
                }
            }
        }
        self.state = State::Idle;
        self.pointer = 0;
        self.mask = 0;
        self.epoch = self.epoch.wrapping_add(1);
    }

    fn settle(&mut self, now: Cycles) {
        if self.cycle.as_ref().is_some_and(|c| now >= c.ends) {
            self.cycle = None;
        }
    }

    fn abort_page(&mut self) {
        if let State::Data { latched } = self.state {
            if latched > 0 {
                self.aborted_writes += 1;
            }
        }
        self.state = State::Idle;
        self.mask = 0;
    }
}

/// [`Eeprom24c256::load`] got an image of the wrong size.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ImageSizeError {
    pub len: usize,
}

impl std::fmt::Display for ImageSizeError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "24C256 image is {} bytes, not {}", self.len, BYTES)
    }
}

impl std::error::Error for ImageSizeError {}

impl I2cDevice for Eeprom24c256 {
    fn address(&self) -> u8 {
        self.address
    }

    fn start(&mut self, address: u8, read: bool, now: Cycles) -> bool {
        self.settle(now);
        self.abort_page();
        if address != self.address {
            return false;
        }
        if self.is_writing(now) {
            self.nacked_polls += 1;
            return false;
        }
        self.state = if read {
            State::Reading
        } else {
            State::AddrHigh
        };
        true
    }

    fn write(&mut self, byte: u8, _now: Cycles) -> bool {
        match self.state {
            State::AddrHigh => {
                self.state = State::AddrLow { high: byte & 0x7F };
                true
            }
            State::AddrLow { high } => {
                self.pointer = (u16::from(high) << 8 | u16::from(byte)) & ADDR_MASK;
                self.page = self.pointer & PAGE_MASK;
                self.mask = 0;
                self.state = State::Data { latched: 0 };
                true
            }
            State::Data { latched } => {
                let off = usize::from(self.pointer & !PAGE_MASK & ADDR_MASK);
                if let Some(b) = self.buffer.get_mut(off) {
                    *b = byte;
                }
                self.mask |= 1 << off;
                // The low six bits roll over inside the page.
                self.pointer = self.page | ((self.pointer + 1) & !PAGE_MASK & ADDR_MASK);
                self.state = State::Data {
                    latched: latched + 1,
                };
                true
            }
            State::Idle | State::Reading => false,
        }
    }

    fn read(&mut self, _now: Cycles) -> u8 {
        if self.state != State::Reading {
            return 0xFF;
        }
        let v = self
            .mem
            .get(usize::from(self.pointer))
            .copied()
            .unwrap_or(0xFF);
        self.pointer = (self.pointer + 1) & ADDR_MASK;
        v
    }

    fn stop(&mut self, now: Cycles) {
        self.settle(now);
        if let State::Data { latched } = self.state {
            if latched > 0 {
                let mut old = [0xFF; PAGE];
                let base = usize::from(self.page);
                for (i, o) in old.iter_mut().enumerate() {
                    if self.mask & (1 << i) == 0 {
                        continue;
                    }
                    if let Some(cell) = self.mem.get_mut(base + i) {
                        *o = *cell;
                        *cell = self.buffer[i];
                    }
                }
                self.cycle = Some(Cycle {
                    ends: now + self.write_cycle,
                    page: self.page,
                    old,
                    mask: self.mask,
                });
                self.writes += 1;
            }
        }
        self.state = State::Idle;
        self.mask = 0;
    }

    fn start_condition(&mut self, now: Cycles) {
        self.settle(now);
        self.abort_page();
    }

    fn power_epoch(&self) -> u32 {
        self.epoch
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const US: Cycles = CYCLES_PER_US;

    /// A byte-level page write: START+W, address, data, STOP.
    fn write(e: &mut Eeprom24c256, addr: u16, data: &[u8], now: Cycles) -> bool {
        if !e.start(0x50, false, now) {
            return false;
        }
        let [hi, lo] = addr.to_be_bytes();
        assert!(e.write(hi, now) && e.write(lo, now));
        for b in data {
            assert!(e.write(*b, now));
        }
        e.stop(now);
        true
    }

    fn random_read(e: &mut Eeprom24c256, addr: u16, n: usize, now: Cycles) -> Vec<u8> {
        assert!(e.start(0x50, false, now));
        let [hi, lo] = addr.to_be_bytes();
        assert!(e.write(hi, now) && e.write(lo, now));
        assert!(e.start(0x50, true, now));
        let v = (0..n).map(|_| e.read(now)).collect();
        e.stop(now);
        v
    }

    #[test]
    fn page_write_wraps_inside_the_page() {
        let mut e = Eeprom24c256::default();
        // Start 3 bytes before the end of page 2 (0x80..0xBF) and write 5.
        assert!(write(&mut e, 0x00BD, &[1, 2, 3, 4, 5], 0));
        let m = e.contents();
        assert_eq!(&m[0xBD..0xC0], &[1, 2, 3]);
        assert_eq!(
            &m[0x80..0x82],
            &[4, 5],
            "bytes 4 and 5 wrap to the page start"
        );
        assert_eq!(m[0xC0], 0xFF, "the next page is untouched");
        assert_eq!(e.writes(), 1);
    }

    #[test]
    fn more_than_a_page_overwrites_the_first_bytes() {
        let mut e = Eeprom24c256::default();
        let data: Vec<u8> = (0..66).collect();
        assert!(write(&mut e, 0x0100, &data, 0));
        assert_eq!(e.contents()[0x100], 64);
        assert_eq!(e.contents()[0x101], 65);
        assert_eq!(e.contents()[0x102], 2);
        assert_eq!(e.contents()[0x13F], 63);
    }

    #[test]
    fn write_cycle_nacks_until_twr_has_elapsed() {
        let mut e = Eeprom24c256::default();
        assert!(write(&mut e, 0x0000, &[0xAB], 1000));
        let end = 1000 + DEFAULT_WRITE_CYCLE;
        assert_eq!(e.write_cycle_end(), Some(end));
        // Reads and writes alike are NACKed at the address.
        assert!(!e.start(0x50, false, 1001));
        assert!(!e.start(0x50, true, end - 1));
        assert_eq!(e.nacked_polls(), 2);
        assert!(e.start(0x50, false, end));
        e.stop(end);
        // A STOP after the address byte alone starts no write cycle.
        assert_eq!(e.writes(), 1);
        assert!(!e.is_writing(end + 1));
    }

    #[test]
    fn address_only_write_sets_the_pointer_and_writes_nothing() {
        let mut e = Eeprom24c256::default();
        assert!(write(&mut e, 0x1234, &[], 0));
        assert_eq!(e.writes(), 0);
        assert_eq!(e.pointer(), 0x1234);
        assert!(
            e.start(0x50, false, 1),
            "no write cycle: the chip answers at once"
        );
    }

    #[test]
    fn top_address_bit_is_ignored() {
        let mut e = Eeprom24c256::default();
        assert!(write(&mut e, 0x8010, &[7], 0));
        assert_eq!(e.contents()[0x0010], 7);
    }

    #[test]
    fn sequential_read_rolls_over_the_whole_memory() {
        let mut e = Eeprom24c256::default();
        let mut img = vec![0u8; BYTES];
        img[0x7FFE] = 0x11;
        img[0x7FFF] = 0x22;
        img[0x0000] = 0x33;
        img[0x0001] = 0x44;
        e.load(&img).unwrap();
        assert_eq!(
            random_read(&mut e, 0x7FFE, 4, 0),
            vec![0x11, 0x22, 0x33, 0x44]
        );
        // Current-address read continues after the last byte read.
        assert!(e.start(0x50, true, 0));
        assert_eq!(e.read(0), img[2]);
        e.stop(0);
        assert_eq!(e.pointer(), 3);
    }

    #[test]
    fn current_address_after_a_page_write_is_the_next_byte_in_the_page() {
        let mut e = Eeprom24c256::default();
        assert!(write(&mut e, 0x003F, &[9], 0));
        // 0x3F + 1 rolls over inside page 0 during a write.
        assert_eq!(e.pointer(), 0x0000);
    }

    #[test]
    fn start_before_stop_aborts_the_page_write() {
        let mut e = Eeprom24c256::default();
        assert!(e.start(0x50, false, 0));
        assert!(e.write(0x00, 0) && e.write(0x20, 0) && e.write(0x55, 0));
        // Repeated START (to another device or this one) before the STOP.
        assert!(!e.start(0x27, false, 0));
        e.stop(0);
        assert_eq!(e.contents()[0x20], 0xFF);
        assert_eq!(e.writes(), 0);
        assert_eq!(e.aborted_writes(), 1);
    }

    #[test]
    fn other_addresses_are_not_acknowledged() {
        let mut e = Eeprom24c256::new(0x51);
        assert!(!e.start(0x50, false, 0));
        assert!(e.start(0x51, false, 0));
    }

    #[test]
    fn power_cut_during_the_write_cycle() {
        for (torn, want) in [
            (TornWrite::Written, 0xA5),
            (TornWrite::NotWritten, 0x00),
            (TornWrite::Erased, 0xFF),
        ] {
            let mut e = Eeprom24c256::default();
            e.load(&[0u8; BYTES]).unwrap();
            e.set_torn_write(torn);
            assert!(write(&mut e, 0x0040, &[0xA5], 0));
            e.power_cut(DEFAULT_WRITE_CYCLE / 2);
            assert_eq!(e.contents()[0x40], want, "{torn:?}");
            assert_eq!(
                e.contents()[0x41],
                0x00,
                "bytes not latched keep their value"
            );
            assert!(
                e.start(0x50, true, DEFAULT_WRITE_CYCLE / 2 + 1),
                "chip answers after power-up"
            );
        }
        // After tWR a power cut changes nothing.
        let mut e = Eeprom24c256::default();
        e.set_torn_write(TornWrite::Erased);
        e.load(&[0u8; BYTES]).unwrap();
        assert!(write(&mut e, 0x0040, &[0xA5], 0));
        e.power_cut(DEFAULT_WRITE_CYCLE);
        assert_eq!(e.contents()[0x40], 0xA5);
    }

    #[test]
    fn image_size_is_checked() {
        let mut e = Eeprom24c256::default();
        assert_eq!(e.load(&[0; 100]), Err(ImageSizeError { len: 100 }));
    }

    #[test]
    fn write_cycle_is_a_parameter() {
        let mut e = Eeprom24c256::default().with_write_cycle(3_000 * US);
        assert!(write(&mut e, 0, &[1], 0));
        assert!(!e.start(0x50, false, 3_000 * US - 1));
        assert!(e.start(0x50, false, 3_000 * US));
    }
}
