//! The backup domain across the models: PWR_CR1.DBP to RCC_BDCR, the RTC and TAMP; the
//! RTC clock RCC_BDCR selects (RTCSEL, RTCEN) from the board's LSE crystal or the LSI; a
//! backup-domain reset (BDRST) to the RTC and the backup registers. A system reset does
//! not reach the domain (RM0440 "Backup domain", "RTC clock").

use super::Soc;
use crate::periph::iwdg::Iwdg;
use crate::periph::rcc::{bdcr, Rcc};
use crate::periph::rtc::Rtc;
use crate::periph::tamp::Tamp;
use crate::time::Cycles;

impl Soc {
    /// After a change of RCC or PWR at `t` (or a system reset): DBP, RTCCLK and BDRST to the
    /// backup domain's models.
    pub(super) fn sync_backup_domain(&mut self, t: Cycles) {
        let dbp = self
            .pwr_slot()
            .and_then(|k| self.model::<crate::periph::pwr::Pwr>(k))
            .is_some_and(|p| p.dbp());
        let lse_hz = self.board.lse_hz();
        let lsi_hz = self.model::<Iwdg>(self.iwdg).map(Iwdg::lsi_hz);
        let k = self.rcc;
        let Some(rcc) = self.model_mut::<Rcc>(k) else {
            return;
        };
        rcc.set_backup_writable(dbp);
        let reset = rcc.take_backup_domain_reset();
        let b = rcc.bdcr();
        let lsi_on = rcc.lsi_ready();
        // RTCSEL: 01 LSE, 10 LSI, 11 HSE / 32 (no HSE crystal on either board).
        let rtcclk = match (b & bdcr::RTCEN != 0, (b >> bdcr::RTCSEL_SHIFT) & 3) {
            (true, 1) if b & bdcr::LSERDY != 0 => lse_hz,
            (true, 2) if lsi_on => lsi_hz,
            _ => None,
        };
        let (r, tp) = (self.wired.rtc, self.wired.tamp);
        if let Some(rtc) = self.model_mut::<Rtc>(r) {
            if reset {
                rtc.backup_domain_reset();
            }
            rtc.set_backup_writable(dbp);
            rtc.set_clock(rtcclk, t);
        }
        if let Some(tamp) = self.model_mut::<Tamp>(tp) {
            if reset {
                tamp.backup_domain_reset();
            }
            tamp.set_backup_writable(dbp);
        }
        self.refresh(r);
    }

    /// A power-on: the boards have no battery on VBAT (the NUCLEO-G431RB's and the ESC1's
    /// documents show none), so the backup domain is lost with VDD (RM0440 "Backup domain
    /// reset": VDD or VBAT power-on when both were off). RCC_BDCR is reset by the RCC's
    /// own power-on reset.
    pub(super) fn backup_domain_power_on(&mut self) {
        let (r, tp) = (self.wired.rtc, self.wired.tamp);
        if let Some(rtc) = self.model_mut::<Rtc>(r) {
            rtc.backup_domain_reset();
        }
        if let Some(tamp) = self.model_mut::<Tamp>(tp) {
            tamp.backup_domain_reset();
        }
    }

    /// The RTC model (for the host and tests: the calendar the image set).
    pub fn rtc(&self) -> Option<&Rtc> {
        self.model::<Rtc>(self.wired.rtc)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::periph::gpio::PinReader;
    use crate::soc::{BareBoard, Board};
    use crate::time::HCLK_HZ;

    /// A board with the NUCLEO-G431RB's 32.768 kHz crystal X2.
    struct WithLse;

    impl PinReader for WithLse {}

    impl Board for WithLse {
        fn lse_hz(&self) -> Option<u64> {
            Some(32_768)
        }
    }

    const APB1ENR1: u32 = 0x4002_1058;
    const PWR_CR1: u32 = 0x4000_7000;
    const BDCR: u32 = 0x4002_1090;
    const RTC_TR: u32 = 0x4000_2800;
    const RTC_DR: u32 = 0x4000_2804;
    const RTC_ICSR: u32 = 0x4000_280C;
    const RTC_WPR: u32 = 0x4000_2824;
    const TAMP_BKP0R: u32 = 0x4000_2500;

    /// PWREN and PWR_CR1.DBP: backup-domain writes allowed.
    fn allow_backup_writes(s: &mut Soc) {
        let enr = s.bus_read(APB1ENR1, 4);
        s.bus_write(APB1ENR1, 4, enr | (1 << 28));
        let cr1 = s.bus_read(PWR_CR1, 4);
        s.bus_write(PWR_CR1, 4, cr1 | (1 << 8));
    }

    /// RM0440's sequence from reset: PWREN, DBP, LSEON, wait LSERDY, RTCSEL = LSE, RTCEN,
    /// unlock, INIT, wait INITF, TR, DR, INIT = 0, wait RSF. Returns the cycle it ends at.
    fn start_calendar(s: &mut Soc) -> Option<Cycles> {
        allow_backup_writes(s);
        s.bus_write(BDCR, 4, bdcr::LSEON);
        let until = s.now + 3 * HCLK_HZ;
        while s.bus_read(BDCR, 4) & bdcr::LSERDY == 0 {
            let t = s.next_event().filter(|t| *t <= until)?;
            s.advance_to(t);
        }
        s.bus_write(
            BDCR,
            4,
            bdcr::LSEON | (1 << bdcr::RTCSEL_SHIFT) | bdcr::RTCEN,
        );
        s.bus_write(RTC_WPR, 4, 0xCA);
        s.bus_write(RTC_WPR, 4, 0x53);
        s.bus_write(RTC_ICSR, 4, 1 << 7);
        while s.bus_read(RTC_ICSR, 4) & (1 << 6) == 0 {
            let t = s.next_event()?;
            s.advance_to(t);
        }
        s.bus_write(RTC_TR, 4, 0x0007_3000);
        s.bus_write(RTC_DR, 4, 0x0026_C815);
        s.bus_write(RTC_ICSR, 4, 0);
        while s.bus_read(RTC_ICSR, 4) & (1 << 5) == 0 {
            let t = s.next_event()?;
            s.advance_to(t);
        }
        Some(s.now)
    }

    #[test]
    fn the_calendar_runs_on_the_lse_and_survives_a_system_reset() {
        let mut s = Soc::new(vec![0xFF; 16], Box::new(WithLse));
        let start = start_calendar(&mut s).expect("LSERDY, INITF and RSF set");
        assert!(start >= 2 * HCLK_HZ, "LSERDY after the LSE's start-up time");
        s.bus_write(TAMP_BKP0R, 4, 0xC0FF_EE00);
        s.system_reset(crate::periph::rcc::ResetKind::Software);
        s.advance_to(start + 10 * HCLK_HZ);
        // 07:30:00 + 10 s, Saturday 15 August 2026; the backup register and BDCR kept.
        assert_eq!(s.bus_read(RTC_TR, 4), 0x0007_3010);
        assert_eq!(s.bus_read(RTC_DR, 4), 0x0026_C815);
        assert_eq!(s.bus_read(TAMP_BKP0R, 4), 0xC0FF_EE00);
        assert_ne!(s.bus_read(BDCR, 4) & bdcr::RTCEN, 0);
        // After the reset DBP is 0 again: the backup domain ignores writes.
        s.bus_write(TAMP_BKP0R, 4, 1);
        assert_eq!(s.bus_read(TAMP_BKP0R, 4), 0xC0FF_EE00);
        // BDRST: the whole domain back to reset.
        allow_backup_writes(&mut s);
        s.bus_write(BDCR, 4, bdcr::BDRST);
        s.bus_write(BDCR, 4, 0);
        assert_eq!(s.bus_read(TAMP_BKP0R, 4), 0);
        assert_eq!(s.bus_read(RTC_DR, 4), 0x0000_2101);
    }

    #[test]
    fn a_power_on_loses_the_backup_domain() {
        let mut s = Soc::new(vec![0xFF; 16], Box::new(WithLse));
        let start = start_calendar(&mut s).expect("LSERDY, INITF and RSF set");
        s.bus_write(TAMP_BKP0R, 4, 0xC0FF_EE00);
        s.system_reset(crate::periph::rcc::ResetKind::PowerOn);
        s.advance_to(start + HCLK_HZ);
        assert_eq!(s.bus_read(TAMP_BKP0R, 4), 0);
        assert_eq!(s.bus_read(BDCR, 4), 0);
        assert_eq!(
            s.bus_read(RTC_ICSR, 4) & (1 << 4),
            0,
            "INITS: never initialized"
        );
    }

    #[test]
    fn without_a_crystal_lserdy_never_sets() {
        let mut s = Soc::new(vec![0xFF; 16], Box::new(BareBoard));
        assert_eq!(start_calendar(&mut s), None);
        assert_eq!(s.bus_read(BDCR, 4) & bdcr::LSERDY, 0);
    }
}
