//! EXTI (RM0440 §15): configurable lines with rising/falling edge selection, software
//! trigger and the pending register (rc_w1), lines 0-15 from the GPIO pins SYSCFG selects, and
//! the direct lines of the comparators (COMP1 = 21, COMP2 = 22, COMP3 = 29, COMP4 = 30). The
//! SoC feeds line levels with [`Exti::set_line`]; the NVIC lines are EXTI0..EXTI4,
//! EXTI9_5, EXTI15_10, COMP1_2_3, COMP4.

use crate::names;
use crate::periph::{IrqLines, Peripheral, Write};
use crate::time::Cycles;

/// EXTI line of each comparator output (RM0440 Table 102).
pub const COMP_LINES: [u8; 4] = [21, 22, 29, 30];

/// The EXTI controller.
#[derive(Debug, Clone)]
pub struct Exti {
    imr: [u32; 2],
    emr: [u32; 2],
    rtsr: [u32; 2],
    ftsr: [u32; 2],
    pr: [u32; 2],
    levels: [u32; 2],
    irq: [Option<u16>; 9],
}

impl Default for Exti {
    fn default() -> Self {
        Exti::new()
    }
}

impl Exti {
    pub fn new() -> Self {
        let irq = [
            "EXTI0",
            "EXTI1",
            "EXTI2",
            "EXTI3",
            "EXTI4",
            "EXTI9_5",
            "EXTI15_10",
            "COMP1_2_3",
            "COMP4",
        ]
        .map(names::irq);
        Exti {
            // IMR1 reset: the direct lines (not configurable) are unmasked (0xFF82_0000).
            imr: [0xFF82_0000, 0x0000_0087],
            emr: [0; 2],
            rtsr: [0; 2],
            ftsr: [0; 2],
            pr: [0; 2],
            levels: [0; 2],
            irq,
        }
    }

    /// Line `line` (0..=42) changes to `level`; a selected edge sets its pending bit.
    pub fn set_line(&mut self, line: u8, level: bool) {
        let (k, b) = (usize::from(line / 32), u32::from(line % 32));
        let (Some(lv), Some(rt), Some(ft), Some(pr)) = (
            self.levels.get_mut(k),
            self.rtsr.get(k),
            self.ftsr.get(k),
            self.pr.get_mut(k),
        ) else {
            return;
        };
        let was = *lv & (1 << b) != 0;
        if level == was {
            return;
        }
        if level {
            *lv |= 1 << b;
        } else {
            *lv &= !(1 << b);
        }
        let edge = if level { rt } else { ft };
        if edge & (1 << b) != 0 {
            *pr |= 1 << b;
        }
    }

    fn active(&self, line: u8) -> bool {
        let (k, b) = (usize::from(line / 32), line % 32);
        let pr = self.pr.get(k).copied().unwrap_or(0);
        let imr = self.imr.get(k).copied().unwrap_or(0);
        pr & imr & (1 << b) != 0
    }
}

impl Peripheral for Exti {
    fn read(&mut self, offset: u32, _now: Cycles) -> Option<u32> {
        let k = usize::from(offset >= 0x20);
        Some(match offset & 0x1F {
            0x00 => self.imr[k],
            0x04 => self.emr[k],
            0x08 => self.rtsr[k],
            0x0C => self.ftsr[k],
            0x10 => 0,
            0x14 => self.pr[k],
            _ => return None,
        })
    }

    fn write(&mut self, w: Write, _now: Cycles) -> bool {
        if w.offset >= 0x38 {
            return false;
        }
        let k = usize::from(w.offset >= 0x20);
        match w.offset & 0x1F {
            0x00 => self.imr[k] = w.merge(self.imr[k]),
            0x04 => self.emr[k] = w.merge(self.emr[k]),
            0x08 => self.rtsr[k] = w.merge(self.rtsr[k]),
            0x0C => self.ftsr[k] = w.merge(self.ftsr[k]),
            0x10 => self.pr[k] |= w.value & w.mask,
            0x14 => self.pr[k] = w.clear_w1(self.pr[k]),
            _ => return false,
        }
        true
    }

    fn irq_lines(&self, lines: &mut IrqLines) {
        let groups: [&[u8]; 9] = [
            &[0],
            &[1],
            &[2],
            &[3],
            &[4],
            &[5, 6, 7, 8, 9],
            &[10, 11, 12, 13, 14, 15],
            &[21, 22, 29],
            &[30],
        ];
        for (g, irq) in groups.iter().zip(self.irq) {
            if let Some(irq) = irq {
                if g.iter().any(|l| self.active(*l)) {
                    lines.set(irq);
                }
            }
        }
    }

    fn reset(&mut self) {
        *self = Exti::new();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rising_edge_pends_and_rc_w1_clears() {
        let mut e = Exti::new();
        e.write(Write::word(0x00, 1 << 5), 0);
        e.write(Write::word(0x08, 1 << 5), 0);
        e.set_line(5, true);
        let mut l = IrqLines::default();
        e.irq_lines(&mut l);
        assert!(l.get(names::irq("EXTI9_5").unwrap_or(0)));
        e.set_line(5, false);
        e.write(Write::word(0x14, 1 << 5), 0);
        let mut l = IrqLines::default();
        e.irq_lines(&mut l);
        assert!(l.is_empty());
    }
}
