//! FLASH interface (RM0440 §3.7): ACR (latency, caches) reads back what was written, as the
//! wait-state change the images wait on completes at once on the G4; OPTR reports the factory
//! option bytes (nSWBOOT0 = 1, nBOOT0 = 1, so BOOT0 is taken from the PB8 pin); the
//! programming registers are not modelled (the images never write flash).

use crate::periph::{Peripheral, Write};
use crate::time::Cycles;

/// Factory OPTR of the G431 (RM0440 §3.7.8 reset value as delivered).
pub const OPTR_FACTORY: u32 = 0xFFEF_F8AA;
/// OPTR.nSWBOOT0: BOOT0 comes from the nBOOT0 option bit instead of the PB8 pin.
pub const OPTR_NSWBOOT0: u32 = 1 << 26;

/// The flash interface.
#[derive(Debug, Clone)]
pub struct Flash {
    acr: u32,
    optr: u32,
    sr: u32,
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
        }
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
            0x20 => self.optr,
            _ => return None,
        })
    }

    fn write(&mut self, w: Write, _now: Cycles) -> bool {
        match w.offset {
            // ICRST/DCRST (bits 11, 12) are write-only pulses.
            0x00 => self.acr = w.merge(self.acr) & 0x0000_E70F,
            0x10 => self.sr = w.clear_w1(self.sr),
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
}
