//! Register models of the G431's peripherals, one module each, behind one contract:
//! [`Peripheral`].
//!
//! The SoC (one per emulated MCU) owns every model, maps it at its base address, and keeps
//! its state in step with the CPU:
//! * before a register access at cycle `now` it calls [`Peripheral::advance`]`(now)`, so a
//!   model only ever answers for the present;
//! * whenever the earliest [`Peripheral::next_event`] of any model is due, it stops the CPU
//!   there and calls `advance` at that cycle;
//! * after every access and every `advance` it samples [`Peripheral::irq_lines`] (NVIC lines
//!   are level-sensitive, as on the chip) and [`Peripheral::dma_requests`] (the DMA then
//!   performs the transfer as ordinary register accesses, so a DMA read of a data register
//!   has the same side effects as a CPU read).
//!
//! Cross-peripheral wiring (TIM1 TRGO2 to the ADC, comparators to the TIM1 break, a USART's
//! TX to the other board's RX, I2C to the devices) is done by the SoC: a model's outputs come
//! out of [`Peripheral::take_signals`], its inputs go in through its own typed methods,
//! documented in its module. What a model finds wrong with the software's use of it comes
//! out of [`Peripheral::take_reports`] ([`reports`] keeps each finding once).
//!
//! Rules for every model (tests and reviewers hold them to these):
//! * Reset values and bit behaviour as RM0440 documents them: rc_w0 flags clear only where
//!   0 is written, rc_w1/ICR flags only where 1 is written, read-only bits ignore writes,
//!   reserved bits read 0.
//! * Never kinder than the silicon: a flag the hardware sets after a delay (ready bits,
//!   conversions, transmissions) is set after that delay, not at once.
//! * A register the model does not implement answers `None`/`false`: the SoC reports the
//!   access by register name. Silently reading 0 hides bugs.

use crate::time::Cycles;

pub mod adc;
pub mod analog_errors;
pub mod comp;
pub mod dac;
pub mod dbgmcu;
pub mod dma;
pub mod dmamux;
pub mod exti;
pub mod flash;
pub mod gpio;
pub mod i2c;
pub mod iwdg;
pub mod opamp;
pub mod pwr;
pub mod rcc;
pub mod reports;
pub mod rtc;
pub mod syscfg;
pub mod tamp;
pub mod tim_adv;
pub mod tim_gp;
pub mod usart;

/// One register write as the bus delivers it: the 32-bit register at `offset`, with the
/// written bytes in place and `mask` covering them (a byte write to bits 8-15 of a register
/// has `mask = 0x0000_ff00`, a word write `mask = !0`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Write {
    /// Byte offset of the 32-bit register in the peripheral (a multiple of 4).
    pub offset: u32,
    /// The written bits, already shifted into their position in the register.
    pub value: u32,
    /// Which bits the access wrote.
    pub mask: u32,
}

impl Write {
    /// A full 32-bit write (what most drivers and the tests do).
    pub fn word(offset: u32, value: u32) -> Self {
        Write {
            offset,
            value,
            mask: !0,
        }
    }

    /// The register after this write if it is plain read/write memory: the written bytes
    /// replace those of `old`, the others keep their value.
    pub fn merge(&self, old: u32) -> u32 {
        (old & !self.mask) | (self.value & self.mask)
    }

    /// An rc_w0 status register after this write: a flag clears only where a 0 was written
    /// (bytes the access did not cover count as 1, i.e. untouched).
    pub fn clear_w0(&self, old: u32) -> u32 {
        old & (self.value | !self.mask)
    }

    /// A flag register with write-1-to-clear semantics (ICR/IFCR/rc_w1) after this write.
    pub fn clear_w1(&self, old: u32) -> u32 {
        old & !(self.value & self.mask)
    }
}

/// NVIC interrupt lines (the G431 has 102), one bit per line.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct IrqLines(pub [u32; 4]);

impl IrqLines {
    /// Asserts line `irq` (ignored beyond the 128 the set holds).
    pub fn set(&mut self, irq: u16) {
        if let Some(w) = self.0.get_mut(usize::from(irq / 32)) {
            *w |= 1 << (irq % 32);
        }
    }

    pub fn get(&self, irq: u16) -> bool {
        self.0
            .get(usize::from(irq / 32))
            .is_some_and(|w| w & (1 << (irq % 32)) != 0)
    }

    pub fn is_empty(&self) -> bool {
        self.0.iter().all(|w| *w == 0)
    }
}

/// DMAMUX request lines (request IDs of RM0440's DMAMUX table, 1..=115), one bit per ID.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct DmaRequests(pub [u32; 4]);

impl DmaRequests {
    /// Asserts request `id`.
    pub fn set(&mut self, id: u8) {
        if let Some(w) = self.0.get_mut(usize::from(id / 32)) {
            *w |= 1 << (id % 32);
        }
    }

    pub fn get(&self, id: u8) -> bool {
        self.0
            .get(usize::from(id / 32))
            .is_some_and(|w| w & (1 << (id % 32)) != 0)
    }
}

/// An output of a model that the SoC's wiring carries to other models or to the board.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Signal {
    /// An advanced timer's event: its trigger outputs, the OC5 blanking window, an output
    /// change for the power stage.
    Timer(tim_adv::TimEvent),
    /// A comparator's output changed.
    Comparator(comp::CompEdge),
}

/// What every register model offers the SoC. See the module documentation for the calling
/// rules.
pub trait Peripheral {
    /// The 32-bit register at `offset` (a multiple of 4), read at cycle `now` (after
    /// `advance(now)`). Reads may have side effects (a data-register read clears its flag).
    /// `None`: the model has no such register; the SoC reports the access and reads 0.
    fn read(&mut self, offset: u32, now: Cycles) -> Option<u32>;

    /// A write at cycle `now` (after `advance(now)`). `false`: the model has no such
    /// register; the SoC reports the access and ignores it.
    fn write(&mut self, w: Write, now: Cycles) -> bool;

    /// The next cycle at which the model changes by itself (a flag set after a delay, a
    /// counter match, a byte finishing on a wire), or `None` while nothing is pending.
    fn next_event(&self) -> Option<Cycles> {
        None
    }

    /// Brings the model to cycle `now`: everything due at or before `now` happens, in time
    /// order. Called with non-decreasing `now`; calling it twice with the same `now` is a
    /// no-op.
    fn advance(&mut self, _now: Cycles) {}

    /// Asserts the NVIC lines this model drives high now.
    fn irq_lines(&self, _lines: &mut IrqLines) {}

    /// Asserts the DMAMUX request lines this model drives high now.
    fn dma_requests(&self, _requests: &mut DmaRequests) {}

    /// Back to the reset state (system reset, or the peripheral's RCC reset bit).
    fn reset(&mut self);

    /// Appends the output signals the model raised since the last call, in time order
    /// (a model with no output to other models has none).
    fn take_signals(&mut self, _out: &mut Vec<Signal>) {}

    /// Misuse and unsupported-feature findings since the last call, each reported once
    /// (the SoC turns them into `Diagnostic::Model`).
    fn take_reports(&mut self) -> Vec<String> {
        Vec::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn byte_write_merges_only_its_byte() {
        let w = Write {
            offset: 0,
            value: 0x0000_ab00,
            mask: 0x0000_ff00,
        };
        assert_eq!(w.merge(0x1234_5678), 0x1234_ab78);
    }

    #[test]
    fn rc_w0_clears_only_written_zeros() {
        // Writing !UIF (all ones but bit 0) clears UIF and nothing else.
        let w = Write::word(0x10, !1);
        assert_eq!(w.clear_w0(0b1011), 0b1010);
        // A byte write of 0 to byte 1 clears only that byte's flags.
        let b = Write {
            offset: 0x10,
            value: 0,
            mask: 0xff00,
        };
        assert_eq!(b.clear_w0(0xffff), 0x00ff);
    }

    #[test]
    fn w1c_clears_only_written_ones() {
        assert_eq!(Write::word(0x20, 0b0100).clear_w1(0b0110), 0b0010);
    }

    #[test]
    fn irq_and_request_sets() {
        let mut l = IrqLines::default();
        assert!(l.is_empty());
        l.set(25);
        l.set(101);
        assert!(l.get(25) && l.get(101) && !l.get(24));
        let mut r = DmaRequests::default();
        r.set(26);
        assert!(r.get(26) && !r.get(27));
    }
}
