//! PWR (RM0440 §6.4): plain registers with the reset values, and VOSF in SR2 following a
//! voltage-scaling change after the regulator's settling time. embassy-stm32 writes CR5.R1MODE
//! (boost) and CR3.UCPD1_DBDIS; the images never enter low-power modes.

use crate::periph::{Peripheral, Write};
use crate::time::{Cycles, CYCLES_PER_US};

/// Regulator settling after a VOS change (DS12589: tens of µs; 20 µs here).
const VOS_SETTLE: Cycles = 20 * CYCLES_PER_US;

/// The PWR block.
#[derive(Debug, Clone)]
pub struct Pwr {
    /// CR1..CR5 at 0x00, 0x04, 0x08, 0x0C, 0x80.
    cr: [u32; 4],
    cr5: u32,
    sr1: u32,
    sr2: u32,
    /// PUCRA..PDCRG (0x20..0x5C): stored only (standby pulls).
    pucr: [u32; 16],
    vosf_until: Option<Cycles>,
}

impl Default for Pwr {
    fn default() -> Self {
        Pwr::new()
    }
}

impl Pwr {
    pub fn new() -> Self {
        Pwr {
            // CR1: VOS = range 1; CR3: EIWUL (RM0440 reset 0x0000_8000).
            cr: [0x0000_0200, 0, 0x0000_8000, 0],
            // CR5: R1MODE = 1 (boost off).
            cr5: 0x0000_0100,
            sr1: 0,
            sr2: 0,
            pucr: [0; 16],
            vosf_until: None,
        }
    }

    /// Boost mode (range 1 boost) is on: CR5.R1MODE = 0.
    pub fn boost(&self) -> bool {
        self.cr5 & (1 << 8) == 0
    }
}

impl Peripheral for Pwr {
    fn read(&mut self, offset: u32, _now: Cycles) -> Option<u32> {
        Some(match offset {
            0x00..=0x0C => self.cr.get((offset / 4) as usize).copied()?,
            0x10 => self.sr1,
            0x14 => self.sr2 | (u32::from(self.vosf_until.is_some()) << 10),
            0x18 => 0,
            0x20..=0x5C => self.pucr.get(((offset - 0x20) / 4) as usize).copied()?,
            0x80 => self.cr5,
            _ => return None,
        })
    }

    fn write(&mut self, w: Write, now: Cycles) -> bool {
        match w.offset {
            0x00..=0x0C => {
                let Some(r) = self.cr.get_mut((w.offset / 4) as usize) else {
                    return false;
                };
                let old = *r;
                *r = w.merge(old);
                if w.offset == 0 && (old ^ *r) & (3 << 9) != 0 {
                    self.vosf_until = Some(now + VOS_SETTLE);
                }
            }
            0x18 => self.sr1 = w.clear_w1(self.sr1),
            0x20..=0x5C => {
                if let Some(r) = self.pucr.get_mut(((w.offset - 0x20) / 4) as usize) {
                    *r = w.merge(*r);
                }
            }
            0x80 => {
                let old = self.cr5;
                self.cr5 = w.merge(old) & (1 << 8);
                if old != self.cr5 {
                    self.vosf_until = Some(now + VOS_SETTLE);
                }
            }
            _ => return false,
        }
        true
    }

    fn next_event(&self) -> Option<Cycles> {
        self.vosf_until
    }

    fn advance(&mut self, now: Cycles) {
        if self.vosf_until.is_some_and(|t| t <= now) {
            self.vosf_until = None;
        }
    }

    fn reset(&mut self) {
        *self = Pwr::new();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn boost_and_vosf() {
        let mut p = Pwr::new();
        assert!(!p.boost());
        p.write(Write::word(0x80, 0), 100);
        assert!(p.boost());
        assert_ne!(
            p.read(0x14, 100).unwrap_or(0) & (1 << 10),
            0,
            "VOSF while settling"
        );
        p.advance(100 + VOS_SETTLE);
        assert_eq!(p.read(0x14, 0).unwrap_or(0) & (1 << 10), 0);
    }
}
