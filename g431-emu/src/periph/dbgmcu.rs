//! DBGMCU (RM0440 §47.16): the device ID and the freeze bits that stop peripherals while the
//! core is halted by a debugger. The SoC reads [`Dbgmcu::tim1_stop`] / [`Dbgmcu::iwdg_stop`]
//! / [`Dbgmcu::tim4_stop`] when a test halts the core.
//!
//! DBGMCU_CR's DBG_SLEEP/DBG_STOP/DBG_STANDBY keep the clocks of a debugger running in the
//! low-power modes: nothing the software can observe (embassy sets them at init). Every
//! other freeze bit (TIM2/3/8, I2C timeouts, ...) and TRACE_IOEN are stored but do nothing
//! here: setting one is reported ([`Dbgmcu::take_reports`]), as is a write to the
//! read-only IDCODE (the silicon ignores it).

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
    reports: Vec<String>,
}

/// The freeze bits the SoC applies: APB1FZR1 DBG_TIM4_STOP and DBG_IWDG_STOP.
const APB1FZR1_MODELLED: u32 = (1 << 2) | (1 << 12);
/// APB2FZR DBG_TIM1_STOP.
const APB2FZR_MODELLED: u32 = 1 << 11;
/// CR: DBG_SLEEP, DBG_STOP, DBG_STANDBY (no software-visible effect).
const CR_MODELLED: u32 = 0x07;

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

    /// Reports the bits of `reg` (named `name`) newly set outside `modelled`.
    fn check(&mut self, name: &str, old: u32, new: u32, modelled: u32) {
        let fresh = new & !old & !modelled;
        if fresh != 0 {
            self.reports.push(format!(
                "DBGMCU.{name}: bits {fresh:#010x} set, which this model stores but does not apply"
            ));
        }
    }
}

impl Peripheral for Dbgmcu {
    /// What the software turned on that this model does not do, since the last call.
    fn take_reports(&mut self) -> Vec<String> {
        std::mem::take(&mut self.reports)
    }

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
            0x04 => {
                let old = self.cr;
                self.cr = w.merge(old) & 0x27;
                self.check("CR", old, self.cr, CR_MODELLED);
            }
            0x08 => {
                let old = self.apb1fzr1;
                self.apb1fzr1 = w.merge(old) & 0x81E0_1C3F;
                self.check("APB1FZR1", old, self.apb1fzr1, APB1FZR1_MODELLED);
            }
            0x0C => {
                let old = self.apb1fzr2;
                self.apb1fzr2 = w.merge(old) & 0x0000_0002;
                self.check("APB1FZR2", old, self.apb1fzr2, 0);
            }
            0x10 => {
                let old = self.apb2fzr;
                self.apb2fzr = w.merge(old) & 0x0017_2800;
                self.check("APB2FZR", old, self.apb2fzr, APB2FZR_MODELLED);
            }
            0x00 => self
                .reports
                .push("DBGMCU.IDCODE is read-only: write ignored".to_string()),
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
        assert!(
            d.take_reports().is_empty(),
            "TIM1 and IWDG freezes are modelled"
        );
    }

    #[test]
    fn freeze_bits_without_an_effect_here_are_reported() {
        let mut d = Dbgmcu::default();
        // embassy's init: DBG_SLEEP | DBG_STOP | DBG_STANDBY.
        d.write(Write::word(0x04, 0x07), 0);
        assert!(d.take_reports().is_empty());
        // DBG_TIM2_STOP is stored, not applied.
        d.write(Write::word(0x08, 1), 0);
        let r = d.take_reports();
        assert!(r.len() == 1 && r[0].contains("APB1FZR1"), "{r:?}");
        d.write(Write::word(0x08, 1), 0);
        assert!(d.take_reports().is_empty(), "reported when it turns on");
        d.write(Write::word(0x00, 0), 0);
        assert_eq!(d.take_reports().len(), 1);
        assert_eq!(d.read(0x00, 0), Some(IDCODE));
        assert!(!d.write(Write::word(0x14, 0), 0), "no register there");
    }
}
