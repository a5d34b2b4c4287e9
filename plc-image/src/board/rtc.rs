//! The RTC of the backup domain on the NUCLEO-G431RB's 32.768 kHz crystal X2 (LSE, PC14/
//! PC15, UM2505), bound to the core's wall clock (`firmware_plc::clock`): read when the
//! core asks (the first pass, then every minute), written when the core hands over a time
//! set from the service port. The core decides what the time is; this module moves it in
//! and out of RM0440's registers (RTC_TR/DR in BCD through
//! `firmware_plc::clock::rtc_format`). Synchronous, from the application task's pass: the
//! waits are RM0440's few RTCCLK periods, bounded.
//!
//! The backup domain (RCC_BDCR, the RTC, TAMP_BKPxR) survives every reset and is lost with
//! the supply (the NUCLEO has no battery on VBAT). A set clock is told by [`MARKER`] in
//! TAMP_BKP0R, written after the calendar; anything else reads as unset.
//!
//! RCC_BDCR holds one configuration, [`BDCR`] (the LSE oscillator at [`DRIVE`], the RTC on
//! it), set by [`prepare`] before embassy's clock set-up. embassy compares RCC_BDCR with
//! its `LsConfig` and resets the backup domain when they differ, then waits for LSERDY;
//! given [`LS`], the same configuration, it finds RCC_BDCR as it wants it and neither
//! resets the domain nor waits for the crystal (tSU(LSE) is 2 s typical, with no maximum,
//! DS12589 table 41). The calendar is written only once LSERDY is set: a time set before
//! stays due (the core's clock runs on the uptime meanwhile).

use embassy_stm32::pac;
use embassy_stm32::pac::rcc::vals::Rtcsel;
use embassy_stm32::rcc::{LsConfig, LseConfig, LseDrive, LseMode};
use embassy_stm32::time::Hertz;
use firmware_plc::clock::rtc_format;
use shared_protocol::units::Micros;

use super::shared::App;

/// TAMP_BKP0R after a complete set of the calendar by this firmware.
pub const MARKER: u32 = 0x504C_4331;
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
/// Register polls for INITF and RSF (each sets within a few RTCCLK periods, 30.5 us each;
/// this bound is well over 1 ms at 170 MHz).
const SYNC_POLLS: u32 = 50_000;

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

/// Polls `done` at most [`SYNC_POLLS`] times.
fn sync(done: impl Fn() -> bool) -> bool {
    (0..SYNC_POLLS).any(|_| done())
}

/// The calendar when a set one runs: seconds since 2000, and the second's elapsed
/// fraction (RTC_SSR, PREDIV_S at its reset value 255: 3906 us a count) in microseconds.
#[inline(never)]
fn read() -> Option<(u32, u64)> {
    // After a system reset the shadow registers hold their reset values until RSF.
    if pac::TAMP.bkpr(0).read().bkp() != MARKER || !sync(|| pac::RTC.icsr().read().rsf()) {
        return None;
    }
    let ss = u64::from(pac::RTC.ssr().read().ss() & 0xFF);
    let tr = pac::RTC.tr().read().0;
    let dr = pac::RTC.dr().read().0;
    Some((rtc_format::seconds(tr, dr)?, (255 - ss) * 3_906))
}

/// Writes the core's time into the calendar (RM0440 "Calendar initialization and
/// configuration"), PRER at its reset value (1 Hz from 32.768 kHz), 24-hour format.
#[inline(never)]
fn write(app: &mut App, now: Micros) {
    pac::TAMP.bkpr(0).write(|w| w.set_bkp(0));
    let rtc = pac::RTC;
    rtc.wpr().write_value(pac::rtc::regs::Wpr(0xCA));
    rtc.wpr().write_value(pac::rtc::regs::Wpr(0x53));
    rtc.icsr().modify(|w| w.set_init(true));
    // Without INITF the time stays due: written at a later pass.
    let seconds = if sync(|| rtc.icsr().read().initf()) {
        app.take_rtc_write(now)
    } else {
        None
    };
    if let Some(s) = seconds {
        let (tr, dr) = rtc_format::registers(s);
        rtc.tr().write_value(pac::rtc::regs::Tr(tr));
        rtc.dr().write_value(pac::rtc::regs::Dr(dr));
    }
    rtc.icsr().modify(|w| w.set_init(false));
    rtc.wpr().write_value(pac::rtc::regs::Wpr(0xFF));
    if let Some(s) = seconds {
        pac::TAMP.bkpr(0).write(|w| w.set_bkp(MARKER));
        defmt::info!("rtc: set to {=u32} s since 2000 UTC", s);
    }
}

/// The application task's share after each pass: the write the core asks for once the
/// LSE runs, else the read it asks for.
#[inline(never)]
pub fn pass(app: &mut App, now: Micros) {
    if app.rtc_write_due() {
        if pac::RCC.bdcr().read().lserdy() {
            write(app, now);
        }
    } else if app.rtc_read_due(now) {
        match read() {
            Some((s, elapsed_us)) => {
                app.rtc_read(Some(s), Micros(now.0.saturating_sub(elapsed_us)))
            }
            None => app.rtc_read(None, now),
        }
    }
}
