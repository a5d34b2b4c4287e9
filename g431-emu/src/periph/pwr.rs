//! PWR (RM0440 §6.4): plain registers with the reset values, and VOSF in SR2 following a
//! voltage-scaling change after the regulator's settling time. embassy-stm32 writes CR5.R1MODE
//! (boost) and CR3.UCPD1_DBDIS; the images never enter low-power modes.
//!
//! The programmable voltage detector (RM0440 §6.2.2 "Programmable voltage detector (PVD)"):
//! CR2.PVDE enables it, CR2.PLS\[2:0\] picks the threshold, and SR2.PVDO reads 1 while VDD is
//! below it. The supply is the host's ([`Pwr::set_vdd_mv`], 3.3 V by default); the
//! thresholds and their hysteresis are [`PVD_FALLING_MV`]/[`PVD_RISING_MV`]. PVDO is what
//! SYSCFG_CFGR2.PVDL routes to the timers' system break (the SoC reads [`Pwr::pvdo`]); with
//! PVDL set, PVDE and PLS are locked until a system reset (RM0440 SYSCFG_CFGR2.PVDL: "enable
//! and lock the PVD connection ... as well as the PVDE and PLS\[2:0\] in the PWR_CR2
//! register"): the SoC calls [`Pwr::lock_pvd`]. PLS = 111 (PVD_IN pin) compares the pin
//! with VREFINT; it is not modelled and reported. The PVD's EXTI line 16 is not wired (no
//! image uses it).

use crate::periph::{Peripheral, Write};
use crate::time::{Cycles, CYCLES_PER_US};

/// Regulator settling after a VOS change (DS12589: tens of µs; 20 µs here).
const VOS_SETTLE: Cycles = 20 * CYCLES_PER_US;

/// VDD at power-up, mV (both boards regulate 3.3 V: UM2516, UM2505).
pub const VDD_NOMINAL_MV: u32 = 3300;

/// PVD falling thresholds VPVD0..VPVD6 for PLS = 000..110, mV: the typical values of the
/// STM32G431 datasheet (DS12589, "Programmable voltage detector characteristics"). PVDO sets
/// when VDD falls below the selected one.
pub const PVD_FALLING_MV: [u32; 7] = [2000, 2150, 2310, 2450, 2590, 2750, 2850];
/// The rising thresholds (same table): PVDO clears when VDD rises above the selected one
/// (about 100 mV of hysteresis).
pub const PVD_RISING_MV: [u32; 7] = [2100, 2260, 2410, 2560, 2690, 2850, 2960];

/// CR2 bits.
const CR2_PVDE: u32 = 1 << 0;
const CR2_PLS_SHIFT: u32 = 1;
const CR2_PLS: u32 = 0b111 << CR2_PLS_SHIFT;
/// SR2.PVDO.
const SR2_PVDO: u32 = 1 << 11;

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
    /// The supply, mV (the host's).
    vdd_mv: u32,
    /// The PVD output (PVDO), with its hysteresis.
    pvdo: bool,
    /// SYSCFG_CFGR2.PVDL: PVDE and PLS are read-only until a system reset.
    pvd_locked: bool,
    /// Diagnostics for the SoC (PLS = 111, writes to locked bits).
    reports: Vec<String>,
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
            vdd_mv: VDD_NOMINAL_MV,
            pvdo: false,
            pvd_locked: false,
            reports: Vec::new(),
        }
    }

    /// The supply voltage changed (the host's scenario). Returns whether PVDO changed.
    pub fn set_vdd_mv(&mut self, mv: u32) -> bool {
        self.vdd_mv = mv;
        self.update_pvd()
    }

    /// The supply voltage, mV.
    pub fn vdd_mv(&self) -> u32 {
        self.vdd_mv
    }

    /// SR2.PVDO: the PVD is enabled and VDD is below its threshold.
    pub fn pvdo(&self) -> bool {
        self.pvdo
    }

    /// SYSCFG_CFGR2.PVDL was set: CR2.PVDE and PLS are locked until a system reset.
    pub fn lock_pvd(&mut self) {
        self.pvd_locked = true;
    }

    /// Re-evaluates PVDO after a change of VDD or CR2; returns whether it changed.
    fn update_pvd(&mut self) -> bool {
        let cr2 = self.cr[1];
        let old = self.pvdo;
        let pls = ((cr2 & CR2_PLS) >> CR2_PLS_SHIFT) as usize;
        self.pvdo = if cr2 & CR2_PVDE == 0 {
            false
        } else if let (Some(&fall), Some(&rise)) = (PVD_FALLING_MV.get(pls), PVD_RISING_MV.get(pls))
        {
            // Hysteresis: below the falling threshold sets, above the rising one clears.
            if old {
                self.vdd_mv < rise
            } else {
                self.vdd_mv < fall
            }
        } else {
            // PLS = 111: PVD_IN against VREFINT; not modelled (the pin's level is unknown).
            false
        };
        old != self.pvdo
    }

    /// CR1.DBP: the backup domain (RCC_BDCR, RTC, TAMP's backup registers) takes writes.
    pub fn dbp(&self) -> bool {
        self.cr[0] & (1 << 8) != 0
    }

    /// Boost mode (range 1 boost) is on: CR5.R1MODE = 0.
    pub fn boost(&self) -> bool {
        self.cr5 & (1 << 8) == 0
    }

    /// The voltage range in effect (CR1.VOS: 01 range 1, 10 range 2; R1MODE in range 1).
    /// While VOSF is set after a change the regulator is still settling: the lower of the
    /// two ranges is the one to trust, which the SoC's check does not model (reported
    /// separately if an image switches the clock while VOSF is set).
    pub fn range(&self) -> crate::periph::flash::VoltageRange {
        use crate::periph::flash::VoltageRange;
        match (self.cr[0] >> 9) & 3 {
            2 => VoltageRange::Range2,
            _ if self.boost() => VoltageRange::Range1Boost,
            _ => VoltageRange::Range1Normal,
        }
    }
}

impl Peripheral for Pwr {
    /// Diagnostics since the last call.
    fn take_reports(&mut self) -> Vec<String> {
        std::mem::take(&mut self.reports)
    }

    fn read(&mut self, offset: u32, _now: Cycles) -> Option<u32> {
        Some(match offset {
            0x00..=0x0C => self.cr.get((offset / 4) as usize).copied()?,
            0x10 => self.sr1,
            0x14 => {
                self.sr2
                    | (u32::from(self.vosf_until.is_some()) << 10)
                    | if self.pvdo { SR2_PVDO } else { 0 }
            }
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
                let mut new = w.merge(old);
                if w.offset == 0x04 {
                    let pvd_bits = CR2_PVDE | CR2_PLS;
                    if self.pvd_locked && (new ^ old) & pvd_bits != 0 {
                        new = (new & !pvd_bits) | (old & pvd_bits);
                        self.reports.push(
                            "PWR_CR2 PVDE/PLS written while SYSCFG_CFGR2.PVDL locks them: ignored"
                                .into(),
                        );
                    }
                    if (new & CR2_PLS) == CR2_PLS && new & CR2_PVDE != 0 {
                        self.reports.push(
                            "PWR_CR2 PLS = 111 (PVD_IN pin) is not modelled: PVDO stays 0".into(),
                        );
                    }
                }
                *r = new;
                if w.offset == 0 && (old ^ *r) & (3 << 9) != 0 {
                    self.vosf_until = Some(now + VOS_SETTLE);
                }
                if w.offset == 0x04 {
                    self.update_pvd();
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
        // The supply is the outside world's and survives the reset; PVDL's lock does not.
        let vdd = self.vdd_mv;
        *self = Pwr::new();
        self.vdd_mv = vdd;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The drive's `route_system_faults_to_break`: PLS = 101, PVDE.
    fn pvd_2v75(p: &mut Pwr) {
        p.write(Write::word(0x04, (0b101 << 1) | 1), 0);
    }

    #[test]
    fn pvdo_follows_vdd_with_hysteresis() {
        let mut p = Pwr::new();
        pvd_2v75(&mut p);
        assert_eq!(p.read(0x14, 0).unwrap_or(0) & SR2_PVDO, 0, "3.3 V: above");
        assert!(p.set_vdd_mv(2700));
        assert!(p.pvdo());
        assert_ne!(p.read(0x14, 0).unwrap_or(0) & SR2_PVDO, 0);
        // Between the thresholds: stays below until VDD rises above the rising one.
        assert!(!p.set_vdd_mv(2800));
        assert!(p.pvdo());
        assert!(p.set_vdd_mv(2900));
        assert!(!p.pvdo());
    }

    #[test]
    fn pvd_needs_pvde_and_a_low_supply_alone_does_nothing() {
        let mut p = Pwr::new();
        p.set_vdd_mv(2000);
        assert!(!p.pvdo(), "PVDE = 0 at reset");
        p.write(Write::word(0x04, 0b101 << 1), 0);
        assert!(!p.pvdo());
    }

    #[test]
    fn pvdl_locks_pvde_and_pls_until_reset() {
        let mut p = Pwr::new();
        pvd_2v75(&mut p);
        p.lock_pvd();
        p.write(Write::word(0x04, 0), 0);
        assert_eq!(p.read(0x04, 0), Some((0b101 << 1) | 1));
        assert_eq!(p.take_reports().len(), 1);
        p.set_vdd_mv(2500);
        p.reset();
        assert_eq!(p.read(0x04, 0), Some(0), "reset clears CR2 and the lock");
        assert_eq!(p.vdd_mv(), 2500, "the supply is the outside world's");
        assert!(!p.pvdo());
    }

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
