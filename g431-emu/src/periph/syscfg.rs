//! SYSCFG (RM0440 §10.2), the part outside COMP/OPAMP/VREFBUF (those have their own models
//! at SYSCFG+0x030/0x200/0x300): memory remap, EXTI port selection (the SoC's EXTI model
//! reads [`Syscfg::exti_port`]) and CFGR2, whose lock bits route LOCKUP (CLL), SRAM parity
//! (SPL), PVD (PVDL) and flash ECC (ECCL) to the timers' system break (RM0440 Table 271). The
//! lock bits are set-only until a system reset.
//!
//! SRAM parity (RM0440 "Memory and bus architecture", embedded SRAM: "Parity check"; the
//! same wording across the STM32 families with SRAM parity, and SYSCFG_CFGR2.SPF): with the
//! check enabled by the option bit FLASH_OPTR.SRAM_PE = 0, a parity error on a read sets
//! CFGR2.SPF (cleared by writing 1) and raises the NMI; with SPL it is also a system break. Errors are injected by the host through the SoC
//! ([`Syscfg::set_parity_error`]), which checks the option bit and raises the NMI. The break
//! signal is held while SPF is set (RM0440 does not give its length; the longer choice).

use crate::periph::{Peripheral, Write};
use crate::time::Cycles;

/// SYSCFG_CFGR2 bits.
pub mod cfgr2 {
    /// Cortex-M4 LOCKUP to the timers' break.
    pub const CLL: u32 = 1 << 0;
    /// SRAM parity error to the break.
    pub const SPL: u32 = 1 << 1;
    /// PVD to the break.
    pub const PVDL: u32 = 1 << 2;
    /// Flash double-ECC error to the break.
    pub const ECCL: u32 = 1 << 3;
    /// SRAM parity error flag (rc_w1).
    pub const SPF: u32 = 1 << 8;
}

/// SYSCFG.
#[derive(Debug, Clone, Default)]
pub struct Syscfg {
    memrmp: u32,
    cfgr1: u32,
    exticr: [u32; 4],
    scsr: u32,
    cfgr2: u32,
    swpr: u32,
}

impl Syscfg {
    /// CFGR2 (lock bits).
    pub fn cfgr2(&self) -> u32 {
        self.cfgr2
    }

    /// An SRAM parity error was detected: SPF set (the SoC checks that parity checking is
    /// on, raises the NMI and re-evaluates the system break).
    pub fn set_parity_error(&mut self) {
        self.cfgr2 |= cfgr2::SPF;
    }

    /// CFGR2.SPF.
    pub fn parity_error(&self) -> bool {
        self.cfgr2 & cfgr2::SPF != 0
    }

    /// Port (0 = A) selected for EXTI line `line` (0..16).
    pub fn exti_port(&self, line: u8) -> u8 {
        let reg = self.exticr.get(usize::from(line / 4)).copied().unwrap_or(0);
        ((reg >> (4 * u32::from(line % 4))) & 0xF) as u8
    }
}

impl Peripheral for Syscfg {
    fn read(&mut self, offset: u32, _now: Cycles) -> Option<u32> {
        Some(match offset {
            0x00 => self.memrmp,
            0x04 => self.cfgr1,
            0x08..=0x14 => self.exticr.get(((offset - 0x08) / 4) as usize).copied()?,
            0x18 => self.scsr,
            0x1C => self.cfgr2,
            0x20 => self.swpr,
            _ => return None,
        })
    }

    fn write(&mut self, w: Write, _now: Cycles) -> bool {
        match w.offset {
            0x00 => self.memrmp = w.merge(self.memrmp) & 0x107,
            0x04 => self.cfgr1 = w.merge(self.cfgr1),
            0x08..=0x14 => {
                if let Some(r) = self.exticr.get_mut(((w.offset - 0x08) / 4) as usize) {
                    *r = w.merge(*r) & 0xFFFF;
                }
            }
            0x18 => self.scsr = w.merge(self.scsr) & 1,
            // Lock bits: set-only. SPF (bit 8, parity error flag) is rc_w1.
            0x1C => {
                let v = w.value & w.mask;
                self.cfgr2 = (self.cfgr2 | (v & 0xF)) & !(v & cfgr2::SPF);
            }
            0x20 => self.swpr = w.merge(self.swpr),
            0x24 => {}
            _ => return false,
        }
        true
    }

    fn reset(&mut self) {
        *self = Syscfg::default();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cfgr2_lock_bits_are_set_only() {
        let mut s = Syscfg::default();
        s.write(Write::word(0x1C, cfgr2::CLL | cfgr2::PVDL), 0);
        s.write(Write::word(0x1C, 0), 0);
        assert_eq!(s.cfgr2() & 0xF, cfgr2::CLL | cfgr2::PVDL);
        s.reset();
        assert_eq!(s.cfgr2(), 0);
    }

    #[test]
    fn spf_is_set_by_a_parity_error_and_cleared_by_writing_1() {
        let mut s = Syscfg::default();
        s.write(Write::word(0x1C, cfgr2::SPL), 0);
        s.set_parity_error();
        assert!(s.parity_error());
        assert_eq!(s.read(0x1C, 0), Some(cfgr2::SPL | cfgr2::SPF));
        s.write(Write::word(0x1C, 0), 0);
        assert!(s.parity_error(), "writing 0 leaves SPF");
        s.write(Write::word(0x1C, cfgr2::SPF), 0);
        assert!(!s.parity_error());
        assert_eq!(s.cfgr2(), cfgr2::SPL, "the lock bit stays");
    }

    #[test]
    fn exti_port_selection() {
        let mut s = Syscfg::default();
        // EXTI5 on port B: EXTICR2 bits 7:4 = 1.
        s.write(Write::word(0x0C, 1 << 4), 0);
        assert_eq!(s.exti_port(5), 1);
        assert_eq!(s.exti_port(4), 0);
    }
}
