//! FLASH interface (RM0440 §3.7): ACR (latency, caches) reads back what was written, as the
//! wait-state change the images wait on completes at once on the G4; OPTR reports the factory
//! option bytes (nSWBOOT0 = 1, nBOOT0 = 1, so BOOT0 is taken from the PB8 pin); the
//! programming registers are not modelled (the images never write flash).
//!
//! ECC (RM0440 §3.3.4 "Error code correction (ECC)" and FLASH_ECCR): a double error found
//! by a read sets ECCR.ECCD with the failing double word's address in ADDR_ECC (SYSF_ECC for
//! system flash) and raises the NMI; ECCD is cleared by writing 1. A single error is
//! corrected: ECCC, and the flash interrupt if ECCCIE. Errors are injected by the host
//! ([`Flash::inject_ecc`]); the SoC raises the NMI and, while ECCD is set and
//! SYSCFG_CFGR2.ECCL routes it, TIM1's system break ([`Flash::double_ecc`]). How long the
//! ECC signal to the break lasts is not in RM0440; the model holds it until ECCD is
//! cleared (the longer choice: a handler must clear the flag to end it).
//!
//! Option bytes: [`Flash::sram_parity_checked`] reads OPTR.SRAM_PE (bit 24, 0 = parity
//! check on); the factory value has it at 1, so a factory-fresh G431 detects no SRAM parity
//! error at all.

use crate::periph::{Peripheral, Write};
use crate::time::Cycles;

/// Factory OPTR of the G431 (RM0440 §3.7.8 reset value as delivered).
pub const OPTR_FACTORY: u32 = 0xFFEF_F8AA;
/// OPTR.nSWBOOT0: BOOT0 comes from the nBOOT0 option bit instead of the PB8 pin.
pub const OPTR_NSWBOOT0: u32 = 1 << 26;
/// OPTR.SRAM_PE: 0 = SRAM1 and CCM SRAM parity check enabled, 1 = disabled (RM0440 FLASH_OPTR).
pub const OPTR_SRAM_PE: u32 = 1 << 24;

/// FLASH_ECCR bits (RM0440 "Flash ECC register (FLASH_ECCR)").
pub mod eccr {
    /// Address of the failing double word (bits 18:0).
    pub const ADDR_ECC: u32 = 0x0007_FFFF;
    /// The error was in system flash.
    pub const SYSF_ECC: u32 = 1 << 22;
    /// Interrupt on a corrected error.
    pub const ECCCIE: u32 = 1 << 24;
    /// A single error was corrected (rc_w1).
    pub const ECCC: u32 = 1 << 30;
    /// A double error was detected: NMI (rc_w1).
    pub const ECCD: u32 = 1 << 31;
}

/// The voltage range the core runs in (PWR_CR1.VOS, PWR_CR5.R1MODE).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum VoltageRange {
    /// Range 1 boost mode (R1MODE = 0): up to 170 MHz.
    Range1Boost,
    /// Range 1 normal mode: up to 150 MHz.
    Range1Normal,
    /// Range 2: up to 26 MHz.
    Range2,
}

/// The fewest flash wait states (ACR.LATENCY) for HCLK at `hz` in `range`, or `None` when
/// the range does not allow that frequency at all (RM0440 §3.3.3 "Read access latency",
/// Table "Number of wait states according to CPU clock (HCLK) frequency").
pub fn min_latency(hz: u64, range: VoltageRange) -> Option<u32> {
    let mhz_per_ws: &[u64] = match range {
        VoltageRange::Range1Boost => &[34, 68, 102, 136, 170],
        VoltageRange::Range1Normal => &[30, 60, 90, 120, 150],
        VoltageRange::Range2 => &[12, 24, 26],
    };
    mhz_per_ws
        .iter()
        .position(|max| hz <= max * 1_000_000)
        .map(|ws| ws as u32)
}

/// Which ECC error a read found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EccError {
    /// Corrected (ECCC).
    Single,
    /// Detected, not corrected (ECCD, NMI).
    Double,
}

/// The flash interface.
#[derive(Debug, Clone)]
pub struct Flash {
    acr: u32,
    optr: u32,
    sr: u32,
    eccr: u32,
}

impl Default for Flash {
    fn default() -> Self {
        Flash::new(OPTR_FACTORY)
    }
}

impl Flash {
    /// With the option bytes `optr`.
    pub fn new(optr: u32) -> Self {
        Flash {
            // LATENCY 0, PRFTEN 0, ICEN 1, DCEN 1 (RM0440 reset 0x0000_0600).
            acr: 0x0000_0600,
            optr,
            sr: 0,
            eccr: 0,
        }
    }

    /// A read of the double word at `addr` (a flash or system-memory address) found an ECC
    /// error. ECCR keeps the first error until its flag is cleared (the address of a second
    /// one is lost, as on the chip: ADDR_ECC is "updated only if the flags are cleared").
    pub fn inject_ecc(&mut self, addr: u32, kind: EccError) {
        if self.eccr & (eccr::ECCC | eccr::ECCD) == 0 {
            let sys = if (0x1FFF_0000..0x2000_0000).contains(&addr) {
                eccr::SYSF_ECC
            } else {
                0
            };
            self.eccr = (self.eccr & eccr::ECCCIE) | sys | (addr & eccr::ADDR_ECC);
        }
        self.eccr |= match kind {
            EccError::Single => eccr::ECCC,
            EccError::Double => eccr::ECCD,
        };
    }

    /// ECCR.ECCD: a double ECC error is flagged (the NMI source and, with ECCL, a system
    /// break).
    pub fn double_ecc(&self) -> bool {
        self.eccr & eccr::ECCD != 0
    }

    /// OPTR.SRAM_PE = 0: SRAM parity errors are detected.
    pub fn sram_parity_checked(&self) -> bool {
        self.optr & OPTR_SRAM_PE == 0
    }

    /// Wait states programmed.
    pub fn latency(&self) -> u32 {
        self.acr & 0xF
    }

    /// ACR as programmed (the cycle model reads LATENCY, PRFTEN, ICEN, DCEN).
    pub fn acr(&self) -> u32 {
        self.acr
    }

    /// The option bytes as loaded.
    pub fn optr(&self) -> u32 {
        self.optr
    }
}

impl Peripheral for Flash {
    fn read(&mut self, offset: u32, _now: Cycles) -> Option<u32> {
        Some(match offset {
            0x00 => self.acr,
            0x10 => self.sr,
            // CR: LOCK and OPTLOCK set.
            0x14 => 0xC000_0000,
            0x18 => self.eccr,
            0x20 => self.optr,
            _ => return None,
        })
    }

    fn write(&mut self, w: Write, _now: Cycles) -> bool {
        match w.offset {
            // ICRST/DCRST (bits 11, 12) are write-only pulses.
            0x00 => self.acr = w.merge(self.acr) & 0x0000_E70F,
            0x10 => self.sr = w.clear_w1(self.sr),
            0x18 => {
                let flags = eccr::ECCC | eccr::ECCD;
                let cleared = w.clear_w1(self.eccr) & flags;
                let cie = w.merge(self.eccr) & eccr::ECCCIE;
                self.eccr = (self.eccr & !(flags | eccr::ECCCIE)) | cleared | cie;
            }
            _ => return false,
        }
        true
    }

    fn reset(&mut self) {
        *self = Flash::new(self.optr);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn latency_reads_back_at_once() {
        let mut f = Flash::default();
        f.write(Write::word(0, 0x604), 0);
        assert_eq!(f.read(0, 0), Some(0x604));
        assert_eq!(f.latency(), 4);
    }

    #[test]
    fn factory_option_bytes_take_boot0_from_the_pin() {
        assert_eq!(Flash::default().optr() & OPTR_NSWBOOT0, OPTR_NSWBOOT0);
    }

    #[test]
    fn wait_states_per_range() {
        use VoltageRange::*;
        assert_eq!(min_latency(170_000_000, Range1Boost), Some(4));
        assert_eq!(min_latency(16_000_000, Range1Boost), Some(0));
        assert_eq!(
            min_latency(170_000_000, Range1Normal),
            None,
            "150 MHz at most"
        );
        assert_eq!(min_latency(150_000_000, Range1Normal), Some(4));
        assert_eq!(min_latency(16_000_000, Range2), Some(1));
        assert_eq!(min_latency(30_000_000, Range2), None);
    }

    #[test]
    fn factory_option_bytes_leave_the_sram_parity_check_off() {
        assert!(!Flash::default().sram_parity_checked());
        assert!(Flash::new(OPTR_FACTORY & !OPTR_SRAM_PE).sram_parity_checked());
    }

    #[test]
    fn double_ecc_sets_eccd_with_the_address_until_written_1() {
        let mut f = Flash::default();
        f.inject_ecc(0x0800_1238, EccError::Double);
        assert!(f.double_ecc());
        let r = f.read(0x18, 0).unwrap_or(0);
        assert_eq!(r & eccr::ADDR_ECC, 0x1238);
        assert_ne!(r & eccr::ECCD, 0);
        // A second error keeps the first address.
        f.inject_ecc(0x0800_4000, EccError::Double);
        assert_eq!(f.read(0x18, 0).unwrap_or(0) & eccr::ADDR_ECC, 0x1238);
        // Writing 0 does nothing; writing ECCD clears it.
        f.write(Write::word(0x18, 0), 0);
        assert!(f.double_ecc());
        f.write(Write::word(0x18, eccr::ECCD), 0);
        assert!(!f.double_ecc());
    }
}
