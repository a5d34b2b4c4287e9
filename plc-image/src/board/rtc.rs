//! The RTC of the backup domain on the NUCLEO-G431RB's 32.768 kHz crystal X2 (LSE, PC14/
//! PC15, UM2505), bound to the core's wall clock: the RTC port of
//! `firmware_plc::clock::rtc_sync`, whose `pass` (the task body, after each application
//! pass) decides when to read, when to write and what a read means. This module moves words
//! in and out of RM0440's registers and waits RM0440's few RTCCLK periods, bounded.
//! Synchronous, from the application task.
//!
//! The backup domain (RCC_BDCR, the RTC, TAMP_BKPxR) survives every reset and is lost with
//! the supply (the NUCLEO has no battery on VBAT).
//!
//! RCC_BDCR holds one configuration, [`BDCR`] (the LSE oscillator at [`DRIVE`], the RTC on
//! it), set by [`prepare`] before embassy's clock set-up. embassy compares RCC_BDCR with
//! its `LsConfig` and resets the backup domain when they differ, then waits for LSERDY;
//! given [`LS`], the same configuration, it finds RCC_BDCR as it wants it and neither
//! resets the domain nor waits for the crystal (tSU(LSE) is 2 s typical, with no maximum,
//! DS12589 table 41).

use embassy_stm32::pac;
use embassy_stm32::pac::rcc::vals::Rtcsel;
use embassy_stm32::rcc::{LsConfig, LseConfig, LseDrive, LseMode};
use embassy_stm32::time::Hertz;
use firmware_plc::clock::rtc_sync::{Calendar, RtcEvent, RtcPort};
use shared_protocol::units::Micros;

use super::shared::App;
/// The crystal's drive (RCC_BDCR.LSEDRV): embassy's `default_lse`; UM2505 as reached does
/// not name one.
const DRIVE: LseDrive = LseDrive::MediumHigh;
/// RCC_BDCR's LSEON, LSEBYP, LSEDRV, RTCSEL and RTCEN as this firmware runs them.
const BDCR: u32 = 1 | (DRIVE as u32) << 3 | 1 << 8 | 1 << 15;
/// The bits of RCC_BDCR that [`BDCR`] sets (LSERDY, LSECSSON/LSECSSD, LSCO and BDRST
/// aside).
const BDCR_CONFIG: u32 = 0b1_1101 | 0b11 << 8 | 1 << 15;
/// embassy's view of [`BDCR`].
pub const LS: LsConfig = {
    let mut ls = LsConfig::off();
    ls.rtc = Rtcsel::LSE;
    ls.lse = Some(LseConfig {
        frequency: Hertz(32_768),
        mode: LseMode::Oscillator(DRIVE),
    });
    ls
};
/// Before embassy's set-up: the RTC's bus clock, and RCC_BDCR to [`BDCR`]. After a
/// power-on it is 0: the LSE starts and the RTC is selected at once (it counts once the
/// LSE runs; the calendar is written only after LSERDY). RTCSEL changes only through a
/// backup-domain reset (RM0440 RCC_BDCR), which any other configuration gets first. Backup-domain writes stay allowed after it: embassy's set-up
/// resets PWR (DBP = 0) and sets DBP again.
#[inline(never)]
pub fn prepare() {
    pac::RCC.apb1enr1().modify(|w| {
        w.set_pwren(true);
        w.set_rtcapben(true);
    });
    // RM0440 "Peripheral clock enable registers": the clock runs 2 cycles after the write.
    pac::RCC.apb1enr1().read();
    pac::PWR.cr1().modify(|w| w.set_dbp(true));
    let bdcr = pac::RCC.bdcr();
    if bdcr.read().0 & BDCR_CONFIG != BDCR {
        bdcr.write_value(pac::rcc::regs::Bdcr(1 << 16));
        bdcr.write_value(pac::rcc::regs::Bdcr(0));
        bdcr.write_value(pac::rcc::regs::Bdcr(BDCR));
    }
}

/// Register polls for INITF and RSF (each sets within a few RTCCLK periods, 30.5 us each;
/// this bound is well over 1 ms at 170 MHz).
const SYNC_POLLS: u32 = 50_000;

/// Polls `done` at most [`SYNC_POLLS`] times.
fn sync(done: impl Fn() -> bool) -> bool {
    (0..SYNC_POLLS).any(|_| done())
}

/// RM0440's RTC, TAMP_BKP0R and RCC_BDCR.LSERDY.
struct Registers;

impl RtcPort for Registers {
    fn crystal_ready(&mut self) -> bool {
        pac::RCC.bdcr().read().lserdy()
    }

    fn marker(&mut self) -> u32 {
        pac::TAMP.bkpr(0).read().bkp()
    }

    fn set_marker(&mut self, value: u32) {
        pac::TAMP.bkpr(0).write(|w| w.set_bkp(value));
    }

    /// After a system reset the shadow registers hold their reset values until RSF.
    fn read_calendar(&mut self) -> Option<Calendar> {
        if !sync(|| pac::RTC.icsr().read().rsf()) {
            return None;
        }
        Some(Calendar {
            ssr: pac::RTC.ssr().read().ss(),
            tr: pac::RTC.tr().read().0,
            dr: pac::RTC.dr().read().0,
        })
    }

    fn enter_init(&mut self) -> bool {
        let rtc = pac::RTC;
        rtc.wpr().write_value(pac::rtc::regs::Wpr(0xCA));
        rtc.wpr().write_value(pac::rtc::regs::Wpr(0x53));
        rtc.icsr().modify(|w| w.set_init(true));
        sync(|| rtc.icsr().read().initf())
    }

    fn write_calendar(&mut self, tr: u32, dr: u32) {
        pac::RTC.tr().write_value(pac::rtc::regs::Tr(tr));
        pac::RTC.dr().write_value(pac::rtc::regs::Dr(dr));
    }

    fn exit_init(&mut self) {
        pac::RTC.icsr().modify(|w| w.set_init(false));
        pac::RTC.wpr().write_value(pac::rtc::regs::Wpr(0xFF));
    }
}

/// The application task's share after each pass.
#[inline(never)]
pub fn pass(app: &mut App, now: Micros) {
    if let Some(RtcEvent::Set { seconds }) = app.rtc_pass(&mut Registers, now) {
        defmt::info!("rtc: set to {=u32} s since 2000 UTC", seconds);
    }
}
