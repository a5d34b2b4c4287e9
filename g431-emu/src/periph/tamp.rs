//! TAMP's backup registers (RM0440 "Tamper and backup registers (TAMP)"): TAMP_BKP0R to
//! TAMP_BKP31R at 0x100, 32 words of the backup domain that survive a system reset and are
//! cleared by a backup-domain reset (RCC_BDCR.BDRST) or a power-on. They take writes only
//! while PWR_CR1.DBP = 1.
//!
//! Not modelled: the tamper inputs and their erase of the backup registers, the monotonic
//! counter; their registers read as unmodelled.

use super::reports::DistinctReports;
use super::{Peripheral, Write};
use crate::time::Cycles;

/// Offset of TAMP_BKP0R.
const BKP0R: u32 = 0x100;
/// Backup registers on the G431.
pub const BACKUP_REGISTERS: usize = 32;

/// The backup registers of TAMP.
#[derive(Debug, Clone, Default)]
pub struct Tamp {
    bkp: [u32; BACKUP_REGISTERS],
    /// PWR_CR1.DBP.
    writable: bool,
    reports: DistinctReports,
}

impl Tamp {
    pub fn new() -> Self {
        Tamp::default()
    }

    /// RCC_BDCR.BDRST: every backup register back to 0.
    pub fn backup_domain_reset(&mut self) {
        self.bkp = [0; BACKUP_REGISTERS];
    }

    /// PWR_CR1.DBP.
    pub fn set_backup_writable(&mut self, writable: bool) {
        self.writable = writable;
    }

    fn index(offset: u32) -> Option<usize> {
        let k = usize::try_from(offset.checked_sub(BKP0R)? / 4).ok()?;
        (k < BACKUP_REGISTERS).then_some(k)
    }
}

impl Peripheral for Tamp {
    fn read(&mut self, offset: u32, _now: Cycles) -> Option<u32> {
        self.bkp.get(Tamp::index(offset)?).copied()
    }

    fn write(&mut self, w: Write, _now: Cycles) -> bool {
        let Some(k) = Tamp::index(w.offset) else {
            return false;
        };
        if !self.writable {
            self.reports.once(format!(
                "TAMP.BKP{k}R written while PWR_CR1.DBP = 0: the backup domain ignores it"
            ));
            return true;
        }
        if let Some(r) = self.bkp.get_mut(k) {
            *r = w.merge(*r);
        }
        true
    }

    fn take_reports(&mut self) -> Vec<String> {
        self.reports.take()
    }

    /// A system reset does not reach the backup domain.
    fn reset(&mut self) {}
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn backup_registers_need_dbp_survive_a_reset_and_clear_on_bdrst() {
        let mut t = Tamp::new();
        assert!(t.write(Write::word(0x104, 0x1234_5678), 0));
        assert_eq!(t.read(0x104, 0), Some(0), "DBP = 0: ignored");
        assert!(t.take_reports()[0].contains("BKP1R"));
        t.set_backup_writable(true);
        t.write(Write::word(0x104, 0x1234_5678), 0);
        t.write(Write::word(0x17C, 7), 0);
        t.reset();
        assert_eq!(t.read(0x104, 0), Some(0x1234_5678));
        assert_eq!(t.read(0x17C, 0), Some(7));
        t.backup_domain_reset();
        assert_eq!(t.read(0x104, 0), Some(0));
        assert_eq!(t.read(0x180, 0), None, "32 registers only");
        assert_eq!(t.read(0x00, 0), None, "tamper control is not modelled");
    }

    #[test]
    fn the_register_map_is_the_metadatas() {
        assert_eq!(crate::names::base("TAMP"), Some(0x4000_2400));
        assert_eq!(crate::names::describe(0x4000_2400 + BKP0R), "TAMP.BKPR[0]");
    }
}
