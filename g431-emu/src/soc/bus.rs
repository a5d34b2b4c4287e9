//! The bus: every CPU or DMA access routed to memory, to the private peripheral bus (SCS,
//! DBGMCU) or to the register model at that address, with the clock gate, the byte lanes
//! and the reports of accesses nothing answers.

use super::diagnostics::is_stored_only;
use super::scheduler::Poll;
use super::{Diagnostic, Soc, FLASH_BASE, FLASH_BYTES, RAM_BASE, RAM_BYTES};
use crate::names;
use crate::periph::Write;

/// DBGMCU, in the private peripheral bus (RM0440 §47.16).
pub(super) const DBGMCU_BASE: u32 = 0xE004_2000;

impl Soc {
    /// A read of `size` bytes at `addr` by the CPU or the DMA.
    pub fn bus_read(&mut self, addr: u32, size: usize) -> u32 {
        let aligned = addr & !3;
        let shift = 8 * (addr & 3);
        let word = self.read_word(aligned);
        let v = word >> shift;
        let v = match size {
            1 => v & 0xFF,
            2 => v & 0xFFFF,
            _ => v,
        };
        self.track_poll(aligned, word);
        v
    }

    pub(super) fn read_word(&mut self, addr: u32) -> u32 {
        if (0xE000_0000..0xE010_0000).contains(&addr) {
            return self.ppb_read(addr);
        }
        let Some(k) = self.find(addr) else {
            self.report_missing(addr, false);
            return 0;
        };
        if !self.clocked(k) {
            let what = names::describe(addr);
            self.report(
                (addr, false, 1),
                Diagnostic::Unclocked { what, write: false },
            );
            return 0;
        }
        let now = self.now;
        let Some(off) = self.slots.get(k).map(|s| addr - s.base) else {
            return 0;
        };
        self.advance_slot(k, now);
        let gpio_port = self.gpio.iter().position(|g| *g == k);
        let value = match gpio_port {
            Some(port) if off == 0x10 => self.read_idr(port as u8, k),
            _ => self.slots.get_mut(k).and_then(|s| s.model.read(off, now)),
        };
        self.refresh(k);
        if self.dma_related(k) {
            self.service_dma();
        }
        match value {
            Some(v) => v,
            None => {
                let what = names::describe(addr);
                self.report(
                    (addr, false, 2),
                    Diagnostic::Unmodelled { what, write: false },
                );
                0
            }
        }
    }

    /// A write of `size` bytes of `value` at `addr` by the CPU or the DMA.
    pub fn bus_write(&mut self, addr: u32, size: usize, value: u32) {
        self.poll = Poll::default();
        self.write_raw(addr, size, value);
    }

    /// A write by the CPU or the DMA (without the polling-loop bookkeeping).
    pub(super) fn write_raw(&mut self, addr: u32, size: usize, value: u32) {
        let aligned = addr & !3;
        let shift = 8 * (addr & 3);
        let mask = match size {
            1 => 0xFFu32 << shift,
            2 => 0xFFFFu32 << shift,
            _ => !0,
        };
        let w = Write {
            offset: 0,
            value: value << shift,
            mask,
        };
        if (0xE000_0000..0xE010_0000).contains(&aligned) {
            self.ppb_write(aligned, w);
            return;
        }
        let Some(k) = self.find(aligned) else {
            self.report_missing(aligned, true);
            return;
        };
        if !self.clocked(k) {
            let what = names::describe(aligned);
            self.report(
                (aligned, true, 1),
                Diagnostic::Unclocked { what, write: true },
            );
            return;
        }
        let now = self.now;
        self.advance_slot(k, now);
        let stored_only = self
            .slots
            .get(k)
            .is_some_and(|s| is_stored_only(s.name, aligned - s.base));
        let before = match self.slots.get_mut(k) {
            Some(s) if stored_only => s.model.read(aligned - s.base, now),
            _ => None,
        };
        let ok = match self.slots.get_mut(k) {
            Some(s) => s.model.write(
                Write {
                    offset: aligned - s.base,
                    ..w
                },
                now,
            ),
            None => false,
        };
        if let Some(before) = before {
            let after = self
                .slots
                .get_mut(k)
                .and_then(|s| s.model.read(aligned - s.base, now));
            if after.is_some_and(|a| a != before) {
                self.report(
                    (aligned, true, 6),
                    Diagnostic::StoredOnly {
                        what: names::describe(aligned),
                        value: after.unwrap_or(0),
                    },
                );
            }
        }
        if !ok {
            let what = names::describe(aligned);
            self.report(
                (aligned, true, 2),
                Diagnostic::Unmodelled { what, write: true },
            );
        }
        self.refresh(k);
        self.after_event(k, now);
        if let Some(port) = self.gpio.iter().position(|g| *g == k) {
            self.gpio_changed(port);
            self.i2c_gpio();
        }
    }

    pub(super) fn ppb_read(&mut self, addr: u32) -> u32 {
        if (DBGMCU_BASE..DBGMCU_BASE + 0x400).contains(&addr) {
            let k = self.dbgmcu;
            let now = self.now;
            let v = self
                .slots
                .get_mut(k)
                .and_then(|s| s.model.read(addr - DBGMCU_BASE, now));
            return v.unwrap_or_else(|| {
                self.report_unmodelled_dbgmcu(addr, false);
                0
            });
        }
        let (now, ipsr) = (self.now, self.ipsr);
        match self.scs.read(addr, now, ipsr) {
            Some(v) => v,
            None => {
                self.report(
                    (addr, false, 2),
                    Diagnostic::Unmodelled {
                        what: format!("{addr:#010x} (PPB)"),
                        write: false,
                    },
                );
                0
            }
        }
    }

    pub(super) fn ppb_write(&mut self, addr: u32, w: Write) {
        if (DBGMCU_BASE..DBGMCU_BASE + 0x400).contains(&addr) {
            let k = self.dbgmcu;
            let now = self.now;
            let ok = self.slots.get_mut(k).is_some_and(|s| {
                s.model.write(
                    Write {
                        offset: addr - DBGMCU_BASE,
                        ..w
                    },
                    now,
                )
            });
            if !ok {
                self.report_unmodelled_dbgmcu(addr, true);
            }
            return;
        }
        let now = self.now;
        match self.scs.write(addr, w, now) {
            Some(fx) => {
                if fx.system_reset {
                    self.stop.system_reset = true;
                }
                self.stop.irq = true;
            }
            None => self.report(
                (addr, true, 2),
                Diagnostic::Unmodelled {
                    what: format!("{addr:#010x} (PPB)"),
                    write: true,
                },
            ),
        }
    }

    pub(super) fn dma_read(&mut self, addr: u32, size: u8) -> Option<u32> {
        if (RAM_BASE..RAM_BASE + RAM_BYTES as u32).contains(&addr)
            || (FLASH_BASE..FLASH_BASE + FLASH_BYTES as u32).contains(&addr)
        {
            let aligned = addr & !3;
            let w = self.mem_word(aligned)?;
            let v = w >> (8 * (addr & 3));
            return Some(match size {
                1 => v & 0xFF,
                2 => v & 0xFFFF,
                _ => v,
            });
        }
        if (0x4000_0000..0x6000_0000).contains(&addr) {
            let aligned = addr & !3;
            let word = self.read_word(aligned);
            return Some(word >> (8 * (addr & 3)));
        }
        None
    }

    pub(super) fn dma_write(&mut self, addr: u32, size: u8, value: u32) -> bool {
        if (RAM_BASE..RAM_BASE + RAM_BYTES as u32).contains(&addr) {
            let o = (addr - RAM_BASE) as usize;
            let bytes = value.to_le_bytes();
            let n = usize::from(size.clamp(1, 4));
            return match self.ram.get_mut(o..o + n) {
                Some(dst) => {
                    dst.copy_from_slice(&bytes[..n]);
                    true
                }
                None => false,
            };
        }
        if (0x4000_0000..0x6000_0000).contains(&addr) {
            self.write_raw(addr, usize::from(size), value);
            return true;
        }
        false
    }

    /// RAM as a slice (for the DMA, RTT and tests).
    pub fn ram(&self) -> &[u8] {
        &self.ram
    }

    /// Reads a little-endian word of RAM or flash (`None` elsewhere).
    pub fn mem_word(&self, addr: u32) -> Option<u32> {
        let (mem, base): (&[u8], u32) = if addr >= RAM_BASE {
            (&self.ram, RAM_BASE)
        } else {
            (&self.flash, FLASH_BASE)
        };
        let o = addr.checked_sub(base)? as usize;
        let b = mem.get(o..o + 4)?;
        Some(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }

    /// Writes a little-endian word of RAM.
    pub fn set_ram_word(&mut self, addr: u32, v: u32) -> bool {
        let Some(o) = addr.checked_sub(RAM_BASE) else {
            return false;
        };
        match self.ram.get_mut(o as usize..o as usize + 4) {
            Some(b) => {
                b.copy_from_slice(&v.to_le_bytes());
                true
            }
            None => false,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::BareBoard;
    use super::*;

    fn soc() -> Soc {
        Soc::new(vec![0xFF; 16], Box::new(BareBoard))
    }

    #[test]
    fn unclocked_peripherals_read_zero_and_are_reported() {
        let mut s = soc();
        // GPIOB is not clocked out of reset: MODER reads 0, not its reset value.
        assert_eq!(s.bus_read(0x4800_0400, 4), 0);
        assert!(matches!(
            s.diagnostics().first(),
            Some(Diagnostic::Unclocked { what, .. }) if what == "GPIOB.MODER"
        ));
        // AHB2ENR bit 1: GPIOBEN.
        s.bus_write(0x4002_104C, 4, 1 << 1);
        assert_eq!(s.bus_read(0x4800_0400, 4), 0xFFFF_FEBF);
    }

    #[test]
    fn unmodelled_registers_are_named() {
        let mut s = soc();
        s.bus_read(0x4002_1024, 4);
        assert!(s.diagnostics().iter().any(|d| matches!(
            d, Diagnostic::Unmodelled { what, write: false } if what.starts_with("0x40021024")
        )));
    }

    #[test]
    fn byte_and_halfword_accesses_reach_the_right_bits() {
        let mut s = soc();
        s.bus_write(0x4002_104C, 4, 1);
        s.bus_write(0x4800_0014, 1, 0xA5);
        assert_eq!(s.bus_read(0x4800_0014, 4), 0xA5);
        s.bus_write(0x4800_0015, 1, 0x5A);
        assert_eq!(s.bus_read(0x4800_0014, 4), 0x5AA5);
        assert_eq!(s.bus_read(0x4800_0015, 1), 0x5A);
    }

    #[test]
    fn dbgmcu_offsets_without_a_register_are_reported() {
        let mut s = soc();
        assert_eq!(s.bus_read(DBGMCU_BASE, 4), crate::periph::dbgmcu::IDCODE);
        s.bus_write(DBGMCU_BASE + 0x10, 4, 1 << 11);
        assert!(s.dbgmcu().tim1_stop());
        assert!(s.diagnostics().is_empty(), "{:?}", s.diagnostics());
        s.bus_read(DBGMCU_BASE + 0x20, 4);
        s.bus_write(DBGMCU_BASE + 0x24, 4, 1);
        let what: Vec<String> = s.diagnostics().iter().map(|d| d.to_string()).collect();
        assert_eq!(
            what,
            [
                "read of unmodelled register DBGMCU+0x20",
                "write to unmodelled register DBGMCU+0x24"
            ]
        );
    }
}
