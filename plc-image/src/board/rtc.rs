//! The RTC of the backup domain on the NUCLEO-G431RB's 32.768 kHz crystal X2 (LSE, PC14/
//! PC15, UM2505), bound to the core's wall clock (`firmware_plc::clock`): read when the
//! core asks (the first pass, then every minute), written when the core hands over a time
//! set from the service port. The core decides what the time is; this module moves it in
//! and out of RM0440's registers (RTC_TR/DR in BCD through
//! `firmware_plc::clock::rtc_format`). Synchronous, from the application task's pass: the
//! waits are RM0440's few RTCCLK periods, bounded.
//!
//! The backup domain (RCC_BDCR, the RTC, TAMP_BKPxR) survives every reset and is lost with
//! the supply (the NUCLEO has no battery on VBAT). A set clock is told by RTCSEL = LSE,
//! RTCEN and [`MARKER`] in TAMP_BKP0R, written after the calendar; anything else reads as
//! unset.
//!
//! embassy's clock set-up resets the backup domain when RCC_BDCR differs from its
//! `LsConfig`, and waits for LSERDY when that config has the LSE: [`keep_backup_domain`]
//! hands it the configuration BDCR already holds, so it never resets the domain nor waits
//! for the crystal (tSU(LSE) is 2 s typical, with no maximum, DS12589 table 41). After a
//! power-on [`open`] starts the LSE; a time set before LSERDY stays due (the core's clock
//! runs on the uptime meanwhile) and is written at the first pass after it.

use embassy_stm32::pac;
use embassy_stm32::pac::rcc::vals::{Lsedrv, Rtcsel};
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
/// Register polls for INITF and RSF (each sets within a few RTCCLK periods, 30.5 us each;
/// this bound is well over 1 ms at 170 MHz).
const SYNC_POLLS: u32 = 50_000;

/// embassy's `LsConfig` matching RCC_BDCR as the last run left it: the LSE with the RTC on
/// it, the LSE alone (started, never set), or off (power-on).
#[inline(never)]
pub fn keep_backup_domain() -> LsConfig {
    let b = pac::RCC.bdcr().read();
    let mut ls = LsConfig::off();
    if b.lseon() && !b.lsebyp() && b.lsedrv() == Lsedrv::from(DRIVE) {
        ls.lse = Some(LseConfig {
            frequency: Hertz(32_768),
            mode: LseMode::Oscillator(DRIVE),
        });
        if b.rtcen() && b.rtcsel() == Rtcsel::LSE {
            ls.rtc = Rtcsel::LSE;
        }
    }
    ls
}

/// After embassy's set-up: the RTC's bus clock, backup-domain writes, and the LSE started
/// when it is off.
#[inline(never)]
pub fn open() {
    pac::RCC.apb1enr1().modify(|w| {
        w.set_rtcapben(true);
        w.set_pwren(true);
    });
    pac::PWR.cr1().modify(|w| w.set_dbp(true));
    if !pac::RCC.bdcr().read().lseon() {
        pac::RCC.bdcr().modify(|w| {
            w.set_lsedrv(DRIVE.into());
            w.set_lseon(true);
        });
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
    let b = pac::RCC.bdcr().read();
    // After a system reset the shadow registers hold their reset values until RSF.
    if !(b.rtcen() && b.rtcsel() == Rtcsel::LSE && pac::TAMP.bkpr(0).read().bkp() == MARKER)
        || !sync(|| pac::RTC.icsr().read().rsf())
    {
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
fn write(app: &mut App, now: Micros) -> Option<u32> {
    pac::RCC.bdcr().modify(|w| {
        w.set_rtcsel(Rtcsel::LSE);
        w.set_rtcen(true);
    });
    pac::TAMP.bkpr(0).write(|w| w.set_bkp(0));
    let rtc = pac::RTC;
    rtc.wpr().write_value(pac::rtc::regs::Wpr(0xCA));
    rtc.wpr().write_value(pac::rtc::regs::Wpr(0x53));
    rtc.icsr().modify(|w| w.set_init(true));
    let ready = sync(|| rtc.icsr().read().initf());
    let seconds = app.take_rtc_write(now).filter(|_| ready);
    if let Some(s) = seconds {
        let (tr, dr) = rtc_format::registers(s);
        rtc.tr().write_value(pac::rtc::regs::Tr(tr));
        rtc.dr().write_value(pac::rtc::regs::Dr(dr));
    }
    rtc.icsr().modify(|w| w.set_init(false));
    rtc.wpr().write_value(pac::rtc::regs::Wpr(0xFF));
    if seconds.is_some() {
        pac::TAMP.bkpr(0).write(|w| w.set_bkp(MARKER));
    }
    seconds
}

/// The application task's share after each pass: the write the core asks for once the
/// LSE runs, else the read it asks for.
#[inline(never)]
pub fn pass(app: &mut App, now: Micros) {
    if app.rtc_write_due() {
        if pac::RCC.bdcr().read().lserdy() {
            let written = write(app, now);
            defmt::info!("rtc: set to {=?} s since 2000 UTC", written);
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
