//! Faults of the silicon that cross models: the timers' system break and the NMI.
//!
//! RM0440 §29.3.18 ("Using the break function") and SYSCFG_CFGR2 (RM0440 Table "TIMx break
//! interconnect"): the system break input `tim_sys_brk` of TIM1 and TIM8 is the OR of the
//! sources whose lock bit is set in SYSCFG_CFGR2:
//! * CLL: the Cortex-M4 LOCKUP output (the CPU calls [`Soc::lockup`]);
//! * PVDL: the PVD output PWR_SR2.PVDO (the host sets the supply, [`Soc::set_vdd_mv`]);
//! * SPL: an SRAM parity error, SYSCFG_CFGR2.SPF ([`Soc::inject_sram_parity_error`]);
//! * ECCL: a flash double ECC error, FLASH_ECCR.ECCD ([`Soc::inject_flash_ecc_error`]).
//!
//! The level is re-evaluated after every change of a source and every write to PWR, SYSCFG
//! or FLASH (the flags are cleared there). A parity error and a double ECC error also raise
//! the NMI, whatever the lock bits say (RM0440 FLASH_ECCR.ECCD: "When this bit is set, a NMI
//! is generated"; the SRAM parity check likewise).

use super::Soc;
use crate::periph::flash::{EccError, Flash};
use crate::periph::pwr::Pwr;
use crate::periph::syscfg::{cfgr2, Syscfg};
use crate::periph::tim_adv::TimAdv;
use crate::scs::exc;

/// The system-break state the SoC keeps between events.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct SystemFaults {
    /// The core is locked up (LOCKUP output high).
    pub(super) locked_up: bool,
    /// The level last given to the timers.
    level: bool,
}

/// Which source held the system break (for tests and reports).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SystemBreakSources {
    pub lockup: bool,
    pub pvd: bool,
    pub sram_parity: bool,
    pub flash_ecc: bool,
}

impl SystemBreakSources {
    pub fn any(&self) -> bool {
        self.lockup || self.pvd || self.sram_parity || self.flash_ecc
    }
}

impl Soc {
    pub(super) fn pwr_slot(&self) -> Option<usize> {
        self.slot_of("PWR")
    }

    fn flash_slot(&self) -> Option<usize> {
        self.slot_of("FLASH")
    }

    /// The PWR model.
    pub fn pwr(&self) -> Option<&Pwr> {
        self.model::<Pwr>(self.pwr_slot()?)
    }

    /// The FLASH interface model.
    pub fn flash_if(&self) -> Option<&Flash> {
        self.model::<Flash>(self.flash_slot()?)
    }

    /// A write to slot `k` may have changed a system-break source (a flag cleared, a lock
    /// bit set, the PVD configured).
    pub(super) fn is_system_fault_slot(&self, k: usize) -> bool {
        self.slots
            .get(k)
            .is_some_and(|s| matches!(s.name, "PWR" | "SYSCFG" | "FLASH"))
    }

    /// The supply of this MCU is now `mv` millivolts (the host's scenario): the PVD follows.
    pub fn set_vdd_mv(&mut self, mv: u32) {
        let now = self.now;
        if let Some(k) = self.pwr_slot() {
            self.advance_slot(k, now);
            if let Some(p) = self.model_mut::<Pwr>(k) {
                p.set_vdd_mv(mv);
            }
            self.refresh(k);
        }
        self.update_system_break();
    }

    /// A read of SRAM found a parity error now. Only detected with the parity check on
    /// (option bit FLASH_OPTR.SRAM_PE = 0; the factory value has it off): then SPF is set
    /// and the NMI raised. Returns whether the error was detected.
    pub fn inject_sram_parity_error(&mut self) -> bool {
        if !self.flash_if().is_some_and(Flash::sram_parity_checked) {
            return false;
        }
        let k = self.syscfg;
        if let Some(s) = self.model_mut::<Syscfg>(k) {
            s.set_parity_error();
        }
        self.raise_nmi();
        self.update_system_break();
        true
    }

    /// A read of the flash double word at `addr` found a double ECC error now: ECCD set,
    /// the NMI raised.
    pub fn inject_flash_ecc_error(&mut self, addr: u32) {
        if let Some(k) = self.flash_slot() {
            if let Some(f) = self.model_mut::<Flash>(k) {
                f.inject_ecc(addr, EccError::Double);
            }
        }
        self.raise_nmi();
        self.update_system_break();
    }

    /// NMI pending: the CPU takes it at its next instruction boundary (it preempts
    /// everything but a HardFault's lockup).
    fn raise_nmi(&mut self) {
        self.pend_exception(exc::NMI);
    }

    /// Exception `n` (`scs::exc`) pended now, as a debugger writing ICSR's NMIPENDSET or
    /// PENDSVSET would (tests of the images' handlers); taken at the next instruction
    /// boundary its priority allows.
    pub fn pend_exception(&mut self, n: u16) {
        self.scs.set_pending(n);
        self.stop.irq = true;
    }

    /// The sources holding the system break now (lock bit set and source active).
    pub fn system_break_sources(&self) -> SystemBreakSources {
        let cfg = self.syscfg().cfgr2();
        SystemBreakSources {
            lockup: cfg & cfgr2::CLL != 0 && self.sys_faults.locked_up,
            pvd: cfg & cfgr2::PVDL != 0 && self.pwr().is_some_and(Pwr::pvdo),
            sram_parity: cfg & cfgr2::SPL != 0 && self.syscfg().parity_error(),
            flash_ecc: cfg & cfgr2::ECCL != 0 && self.flash_if().is_some_and(Flash::double_ecc),
        }
    }

    /// Re-evaluates `tim_sys_brk` and gives it to TIM1 and TIM8 when it changed. Also
    /// applies PVDL's lock of PWR_CR2.
    pub(super) fn update_system_break(&mut self) {
        let now = self.now;
        if self.syscfg().cfgr2() & cfgr2::PVDL != 0 {
            if let Some(k) = self.pwr_slot() {
                if let Some(p) = self.model_mut::<Pwr>(k) {
                    p.lock_pvd();
                }
            }
        }
        let level = self.system_break_sources().any();
        if level == self.sys_faults.level {
            return;
        }
        self.sys_faults.level = level;
        for k in [self.wired.tim1, self.wired.tim8] {
            self.advance_slot(k, now);
            if let Some(tim) = self.model_mut::<TimAdv>(k) {
                tim.set_system_break(level, now);
            }
            self.refresh(k);
            self.after_event(k, now);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::periph::flash::OPTR_SRAM_PE;

    const PWR_CR2: u32 = 0x4000_7004;
    const SYSCFG_CFGR2: u32 = 0x4001_001C;
    const FLASH_ECCR: u32 = 0x4002_2018;
    const TIM1_SR: u32 = 0x4001_2C10;
    const TIM1_BDTR: u32 = 0x4001_2C44;
    const RCC_APB2ENR: u32 = 0x4002_1060;
    const RCC_APB1ENR1: u32 = 0x4002_1058;
    const SBIF: u32 = 1 << 13;
    const BIF: u32 = 1 << 7;
    const BKE: u32 = 1 << 12;
    const MOE: u32 = 1 << 15;
    /// BKIN (not wired, low) active high: inactive.
    const BKP: u32 = 1 << 13;

    /// The drive's set-up: TIM1, SYSCFG and PWR clocked, BKE and MOE, PVD at 2.75 V and
    /// every source routed (power_stage::route_system_faults_to_break).
    fn routed() -> Soc {
        let mut s = Soc::new(Vec::new(), Box::new(crate::soc::BareBoard));
        s.bus_write(RCC_APB2ENR, 4, (1 << 11) | 1);
        s.bus_write(RCC_APB1ENR1, 4, 1 << 28);
        s.bus_write(TIM1_BDTR, 4, BKE | BKP | MOE);
        s.bus_write(PWR_CR2, 4, (0b101 << 1) | 1);
        s.bus_write(SYSCFG_CFGR2, 4, 0xF);
        s
    }

    fn moe(s: &mut Soc) -> bool {
        s.bus_read(TIM1_BDTR, 4) & MOE != 0
    }

    #[test]
    fn a_pvd_dip_is_a_system_break_with_sbif_only() {
        let mut s = routed();
        assert!(moe(&mut s));
        s.set_vdd_mv(2600);
        assert!(s.system_break_sources().pvd);
        assert!(!moe(&mut s), "the system break cleared MOE");
        assert_eq!(s.bus_read(TIM1_SR, 4) & (SBIF | BIF), SBIF);
        // The supply back: SBIF can be cleared, MOE set again.
        s.set_vdd_mv(3300);
        s.bus_write(TIM1_SR, 4, !SBIF);
        assert_eq!(s.bus_read(TIM1_SR, 4) & SBIF, 0);
        s.bus_write(TIM1_BDTR, 4, BKE | BKP | MOE);
        assert!(moe(&mut s));
    }

    #[test]
    fn pvdl_locks_the_pvd_configuration() {
        let mut s = routed();
        s.bus_write(PWR_CR2, 4, 0);
        assert_eq!(s.bus_read(PWR_CR2, 4), (0b101 << 1) | 1);
    }

    #[test]
    fn flash_double_ecc_raises_the_nmi_and_breaks_until_eccd_is_cleared() {
        let mut s = routed();
        s.inject_flash_ecc_error(0x0800_0100);
        assert!(s.scs.pending(exc::NMI));
        assert!(s.system_break_sources().flash_ecc);
        assert!(!moe(&mut s));
        s.bus_write(FLASH_ECCR, 4, 1 << 31);
        assert!(!s.system_break_sources().any());
        s.bus_write(TIM1_SR, 4, !SBIF);
        assert_eq!(s.bus_read(TIM1_SR, 4) & SBIF, 0);
    }

    #[test]
    fn sram_parity_is_detected_only_with_the_option_bit() {
        let mut s = routed();
        assert!(
            !s.inject_sram_parity_error(),
            "factory option bytes: no check"
        );
        assert!(!s.scs.pending(exc::NMI));
        assert!(moe(&mut s));
        // Option bytes with SRAM_PE = 0.
        let k = s.flash_slot().expect("FLASH");
        if let Some(f) = s.model_mut::<Flash>(k) {
            *f = Flash::new(crate::periph::flash::OPTR_FACTORY & !OPTR_SRAM_PE);
        }
        assert!(s.inject_sram_parity_error());
        assert!(s.scs.pending(exc::NMI));
        assert!(s.system_break_sources().sram_parity);
        assert!(!moe(&mut s));
        s.bus_write(SYSCFG_CFGR2, 4, 1 << 8);
        assert!(!s.system_break_sources().any());
    }

    #[test]
    fn without_the_lock_bits_no_source_breaks() {
        let mut s = Soc::new(Vec::new(), Box::new(crate::soc::BareBoard));
        s.bus_write(RCC_APB2ENR, 4, (1 << 11) | 1);
        s.bus_write(RCC_APB1ENR1, 4, 1 << 28);
        s.bus_write(TIM1_BDTR, 4, BKE | BKP | MOE);
        s.bus_write(PWR_CR2, 4, (0b101 << 1) | 1);
        s.set_vdd_mv(2000);
        s.inject_flash_ecc_error(0x0800_0000);
        assert!(moe(&mut s), "no CFGR2 bit: the timers see nothing");
        assert!(s.scs.pending(exc::NMI), "the NMI does not need ECCL");
    }
}
