//! DBGMCU (RM0440 §47.16): the device ID and the freeze bits that stop peripherals while the
//! core is halted by a debugger. The SoC reads [`Dbgmcu::tim1_stop`] / [`Dbgmcu::iwdg_stop`]
//! when a test halts the core.

use crate::periph::{Peripheral, Write};
use crate::time::Cycles;

/// DBGMCU_IDCODE of the G431 (DEV_ID 0x468, revision Z = 0x2001).
pub const IDCODE: u32 = 0x2001_6468;

/// The debug MCU block.
#[derive(Debug, Clone, Default)]
pub struct Dbgmcu {
    cr: u32,
    apb1fzr1: u32,
    apb1fzr2: u32,
    apb2fzr: u32,
}

impl Dbgmcu {
    /// DBG_TIM1_STOP (APB2FZR bit 11): TIM1 stops, with its outputs disabled, while halted.
    pub fn tim1_stop(&self) -> bool {
        self.apb2fzr & (1 << 11) != 0
    }

    /// DBG_IWDG_STOP (APB1FZR1 bit 12).
    pub fn iwdg_stop(&self) -> bool {
        self.apb1fzr1 & (1 << 12) != 0
    }

    /// DBG_TIM4_STOP (APB1FZR1 bit 2): embassy's time base stops while halted.
    pub fn tim4_stop(&self) -> bool {
        self.apb1fzr1 & (1 << 2) != 0
    }
}

impl Peripheral for Dbgmcu {
    fn read(&mut self, offset: u32, _now: Cycles) -> Option<u32> {
        Some(match offset {
            0x00 => IDCODE,
            0x04 => self.cr,
            0x08 => self.apb1fzr1,
            0x0C => self.apb1fzr2,
            0x10 => self.apb2fzr,
            _ => return None,
        })
    }

    fn write(&mut self, w: Write, _now: Cycles) -> bool {
        match w.offset {
            0x04 => self.cr = w.merge(self.cr) & 0x27,
            0x08 => self.apb1fzr1 = w.merge(self.apb1fzr1) & 0x81E0_1C3F,
            0x0C => self.apb1fzr2 = w.merge(self.apb1fzr2) & 0x0000_0002,
            0x10 => self.apb2fzr = w.merge(self.apb2fzr) & 0x0017_2800,
            0x00 => {}
            _ => return false,
        }
        true
    }

    fn reset(&mut self) {
        // DBGMCU is reset by power-on only, not by a system reset (RM0440 §47.16).
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn freeze_bits() {
        let mut d = Dbgmcu::default();
        assert!(!d.tim1_stop());
        d.write(Write::word(0x10, 1 << 11), 0);
        d.write(Write::word(0x08, 1 << 12), 0);
        assert!(d.tim1_stop() && d.iwdg_stop());
        d.reset();
        assert!(d.tim1_stop(), "survives a system reset");
    }
}
