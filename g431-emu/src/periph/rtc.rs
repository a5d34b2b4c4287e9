//! RTC: the calendar (time, date, sub-seconds) of the backup domain, clocked by RTCCLK, with
//! its write protection and initialization sequence (RM0440 "Real-time clock (RTC)").
//!
//! Modelled, from RM0440's RTC chapter:
//! * RTC_TR, RTC_DR in BCD (24-hour or 12-hour format, FMT is stored), RTC_SSR (the
//!   synchronous prescaler's down-counter: second fraction = (PREDIV_S - SS) / (PREDIV_S +
//!   1)), RTC_PRER (PREDIV_A, PREDIV_S; reset 0x007F_00FF: 1 Hz from a 32.768 kHz LSE);
//!   the calendar counts days per month and the leap years of 2000-2099 (year % 4 == 0);
//!   the week day counts 1 (Monday) to 7;
//! * write protection: after a backup-domain reset every protected register ignores writes
//!   until RTC_WPR receives 0xCA then 0x53; any other key locks it again; and the whole
//!   backup domain ignores writes while PWR_CR1.DBP = 0 (RM0440 "RTC register write
//!   protection", PWR "Backup domain access");
//! * initialization: ICSR.INIT = 1 stops the calendar; INITF sets 2 RTCCLK periods later
//!   and only then do TR, DR and PRER take writes (earlier ones are ignored and reported);
//!   INIT = 0 restarts the counters 4 RTCCLK periods later; RSF clears in initialization
//!   mode or by software and sets again when the shadow registers are next copied (every
//!   2 RTCCLK periods); INITS is set while the year is not 0;
//! * reading RTC_SSR or RTC_TR locks the higher-order shadow registers until RTC_DR is read.
//!
//! Not modelled (reported when used): alarms, wake-up timer, time stamp, smooth
//! calibration, shift, bypass of the shadow registers (BYPSHAD: stored only), RTC_OUT. The
//! shadow registers are not copies of their own: a read returns the calendar at the access,
//! not at the last copy (at most 2 RTCCLK periods older on the silicon); a read while RSF
//! is 0 (after INIT or a clear of RSF), which the silicon answers with stale values, is
//! reported instead.
//!
//! The backup domain (this model, TAMP's backup registers and RCC_BDCR) is reset only by
//! power-on and by RCC_BDCR.BDRST: a system reset ([`Peripheral::reset`]) keeps the
//! calendar running ([`Rtc::backup_domain_reset`] is the other).

use super::reports::DistinctReports;
use super::{Peripheral, Write};
use crate::time::{Cycles, HCLK_HZ};

const TR: u32 = 0x00;
const DR: u32 = 0x04;
const SSR: u32 = 0x08;
const ICSR: u32 = 0x0C;
const PRER: u32 = 0x10;
const CR: u32 = 0x18;
const WPR: u32 = 0x24;
const SR: u32 = 0x50;
const MISR: u32 = 0x54;
const SCR: u32 = 0x5C;

/// ICSR bits (RM0440 RTC_ICSR).
pub mod icsr {
    pub const INITS: u32 = 1 << 4;
    pub const RSF: u32 = 1 << 5;
    pub const INITF: u32 = 1 << 6;
    pub const INIT: u32 = 1 << 7;
}

/// CR bits the model applies or stores: FMT (12-hour format, bit 6), BYPSHAD (bit 5).
const CR_STORED: u32 = (1 << 6) | (1 << 5);
/// TR's defined bits (SU ST MNU MNT HU HT PM).
const TR_MASK: u32 = 0x007F_7F7F;
/// DR's defined bits (DU DT MU MT WDU YU YT).
const DR_MASK: u32 = 0x00FF_FF3F;
/// PRER: PREDIV_S (14:0), PREDIV_A (22:16).
const PRER_MASK: u32 = 0x007F_7FFF;
/// RM0440 reset values.
const DR_RESET: u32 = 0x0000_2101;
const PRER_RESET: u32 = 0x007F_00FF;

/// RTCCLK periods from INIT = 1 to INITF = 1, from INIT = 0 to the counters running, and
/// between two shadow-register copies (RM0440 "Calendar initialization and
/// configuration", "Reading the calendar").
const INITF_PERIODS: u64 = 2;
const RESTART_PERIODS: u64 = 4;
const COPY_PERIODS: u64 = 2;

const SECONDS_PER_DAY: u64 = 86_400;

/// The calendar as counters: seconds since 2000-01-01 00:00:00 and the week day (1..=7,
/// kept apart: the RTC counts the day written, whatever the date).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Calendar {
    secs: u64,
    weekday: u8,
}

fn bcd(v: u32) -> u32 {
    ((v / 10) << 4) | (v % 10)
}

fn from_bcd(v: u32) -> u32 {
    (v >> 4) * 10 + (v & 0xF)
}

fn leap(year: u32) -> bool {
    year.is_multiple_of(4)
}

fn days_in_month(year: u32, month: u32) -> u32 {
    match month {
        2 if leap(year) => 29,
        2 => 28,
        4 | 6 | 9 | 11 => 30,
        _ => 31,
    }
}

impl Calendar {
    /// (year 0..=99, month 1..=12, day 1..=31) of the day `secs` falls in.
    fn date(&self) -> (u32, u32, u32) {
        let mut days = (self.secs / SECONDS_PER_DAY) as u32;
        let mut year = 0;
        loop {
            let n = if leap(year) { 366 } else { 365 };
            if days < n || year == 99 {
                break;
            }
            days -= n;
            year += 1;
        }
        let mut month = 1;
        while month < 12 && days >= days_in_month(year, month) {
            days -= days_in_month(year, month);
            month += 1;
        }
        (year, month, days + 1)
    }

    fn tr(&self, twelve_hour: bool) -> u32 {
        let s = (self.secs % SECONDS_PER_DAY) as u32;
        let (h, m, sec) = (s / 3600, s / 60 % 60, s % 60);
        let (h, pm) = if twelve_hour {
            (if h % 12 == 0 { 12 } else { h % 12 }, h >= 12)
        } else {
            (h, false)
        };
        bcd(sec) | bcd(m) << 8 | bcd(h) << 16 | u32::from(pm) << 22
    }

    fn dr(&self) -> u32 {
        let (y, mo, d) = self.date();
        bcd(d) | bcd(mo) << 8 | u32::from(self.weekday) << 13 | bcd(y) << 16
    }

    /// The calendar a TR and DR write sets (fields out of range are taken as written, as
    /// the silicon does not check them; they are reported by the caller).
    fn from_registers(tr: u32, dr: u32, twelve_hour: bool) -> Calendar {
        let year = from_bcd(dr >> 16 & 0xFF).min(99);
        let month = from_bcd(dr >> 8 & 0x1F).clamp(1, 12);
        let day = from_bcd(dr & 0x3F).clamp(1, 31);
        let mut days: u64 = (0..year)
            .map(|y| if leap(y) { 366 } else { 365 })
            .sum::<u64>();
        days += (1..month)
            .map(|m| u64::from(days_in_month(year, m)))
            .sum::<u64>();
        days += u64::from(day - 1);
        let mut hour = from_bcd(tr >> 16 & 0x3F);
        if twelve_hour {
            hour = hour % 12 + if tr & (1 << 22) != 0 { 12 } else { 0 };
        }
        let secs = u64::from(hour) * 3600
            + u64::from(from_bcd(tr >> 8 & 0x7F)) * 60
            + u64::from(from_bcd(tr & 0x7F));
        Calendar {
            secs: days * SECONDS_PER_DAY + secs,
            weekday: (dr >> 13 & 7) as u8,
        }
    }

    fn add_seconds(&mut self, n: u64) {
        let day_before = self.secs / SECONDS_PER_DAY;
        // RM0440 RTC_DR: "The calendar is frozen when reaching the maximum value, and can't
        // roll over" (2099-12-31 23:59:59: the year counter has two digits).
        const CENTURY: u64 = 36_525 * SECONDS_PER_DAY;
        self.secs = self.secs.saturating_add(n).min(CENTURY - 1);
        let days = (self.secs / SECONDS_PER_DAY).wrapping_sub(day_before) % 7;
        if self.weekday != 0 {
            self.weekday = ((u64::from(self.weekday) - 1 + days) % 7 + 1) as u8;
        }
    }
}

/// The RTC.
#[derive(Debug, Clone)]
pub struct Rtc {
    cal: Calendar,
    /// ck_apre periods elapsed in the present second (SS = PREDIV_S - this).
    sub_ticks: u32,
    /// RTCCLK periods elapsed in the present ck_apre period.
    apre_ticks: u32,
    /// RTCCLK in Hz (`None`: RTCEN = 0, or no running source selected).
    clock_hz: Option<u64>,
    /// RTCCLK periods times HCLK_HZ not yet counted (the fraction of a period).
    remainder: u128,
    last: Cycles,
    prer: u32,
    cr: u32,
    /// INIT as written.
    init: bool,
    /// INITF sets at this cycle (INIT = 1, waiting for the synchronisation).
    initf_at: Option<Cycles>,
    initf: bool,
    /// The counters run again from this cycle (INIT = 0 written).
    restart_at: Option<Cycles>,
    rsf: bool,
    rsf_at: Option<Cycles>,
    /// WPR: 0 locked, 1 after 0xCA, 2 unlocked.
    key_stage: u8,
    /// PWR_CR1.DBP: the backup domain takes writes.
    writable: bool,
    /// DR (and TR) locked by a read of SSR or TR, until DR is read.
    locked_dr: Option<u32>,
    locked_tr: Option<u32>,
    /// A system reset put the shadow registers back to their reset values: reads give
    /// those until the next copy (RM0440 "Reading the calendar", "Resetting the RTC").
    shadow_reset: bool,
    /// A system reset cleared RSF: the next copy is scheduled when RTCCLK is next given
    /// ([`Rtc::set_clock`], right after the reset).
    copy_after_reset: bool,
    reports: DistinctReports,
}

impl Default for Rtc {
    fn default() -> Self {
        Rtc::new()
    }
}

impl Rtc {
    /// The RTC after a power-on (backup-domain) reset: 2000-01-01, Monday, 00:00:00,
    /// stopped, write-protected.
    pub fn new() -> Self {
        Rtc {
            cal: Calendar::from_registers(0, DR_RESET, false),
            sub_ticks: 0,
            apre_ticks: 0,
            clock_hz: None,
            remainder: 0,
            last: 0,
            prer: PRER_RESET,
            cr: 0,
            init: false,
            initf_at: None,
            initf: false,
            restart_at: None,
            rsf: false,
            rsf_at: None,
            key_stage: 0,
            writable: false,
            locked_dr: None,
            locked_tr: None,
            shadow_reset: false,
            copy_after_reset: false,
            reports: DistinctReports::default(),
        }
    }

    /// RCC_BDCR.BDRST: the backup domain back to its reset state (the RTCCLK input and
    /// DBP are the RCC's and PWR's and stay).
    pub fn backup_domain_reset(&mut self) {
        let (clock_hz, writable, last) = (self.clock_hz, self.writable, self.last);
        *self = Rtc::new();
        self.clock_hz = clock_hz;
        self.writable = writable;
        self.last = last;
    }

    /// RTCCLK from `now` on (the source RCC_BDCR selects and enables, if it runs).
    pub fn set_clock(&mut self, hz: Option<u64>, now: Cycles) {
        self.advance(now);
        if hz != self.clock_hz {
            self.clock_hz = hz;
            self.remainder = 0;
        }
        if self.copy_after_reset && self.running() {
            self.copy_after_reset = false;
            self.rsf_at = self.periods(COPY_PERIODS, now);
        }
    }

    /// PWR_CR1.DBP.
    pub fn set_backup_writable(&mut self, writable: bool) {
        self.writable = writable;
    }

    /// RTCCLK periods as CPU cycles (rounded up: never earlier than the silicon).
    fn periods(&self, n: u64, now: Cycles) -> Option<Cycles> {
        let hz = self.clock_hz?;
        Some(now + (u128::from(n) * u128::from(HCLK_HZ)).div_ceil(u128::from(hz)) as u64)
    }

    fn running(&self) -> bool {
        self.clock_hz.is_some() && !self.init && self.restart_at.is_none()
    }

    fn twelve_hour(&self) -> bool {
        self.cr & (1 << 6) != 0
    }

    fn prediv_s(&self) -> u32 {
        self.prer & 0x7FFF
    }

    fn prediv_a(&self) -> u32 {
        self.prer >> 16 & 0x7F
    }

    /// Counts the RTCCLK periods from `self.last` to `now`.
    fn count(&mut self, now: Cycles) {
        let Some(hz) = self.clock_hz else {
            return;
        };
        let elapsed = u128::from(now.saturating_sub(self.last)) * u128::from(hz) + self.remainder;
        let periods = elapsed / u128::from(HCLK_HZ);
        self.remainder = elapsed % u128::from(HCLK_HZ);
        if !self.running() {
            return;
        }
        let a = u128::from(self.prediv_a()) + 1;
        let s = u128::from(self.prediv_s()) + 1;
        let apre = u128::from(self.apre_ticks) + periods;
        self.apre_ticks = (apre % a) as u32;
        let sub = u128::from(self.sub_ticks) + apre / a;
        self.sub_ticks = (sub % s) as u32;
        self.cal.add_seconds((sub / s) as u64);
    }

    fn protected(&mut self, what: &str) -> bool {
        if !self.writable {
            self.reports.once(format!(
                "RTC.{what} written while PWR_CR1.DBP = 0: the backup domain ignores it"
            ));
            return true;
        }
        if self.key_stage < 2 {
            self.reports.once(format!(
                "RTC.{what} written while write-protected (RTC_WPR 0xCA, 0x53 first): ignored"
            ));
            return true;
        }
        false
    }

    fn icsr(&self) -> u32 {
        // ALRAWF, ALRBWF, WUTWF: set while the alarms and the wake-up timer are disabled
        // (they are not modelled: CR enabling them is reported), cleared in initialization
        // mode (backup-domain reset value 0x0000_0007).
        let mut v = if self.initf { 0 } else { 0b111 };
        if self.cal.secs >= 366 * SECONDS_PER_DAY {
            v |= icsr::INITS;
        }
        if self.rsf {
            v |= icsr::RSF;
        }
        if self.initf {
            v |= icsr::INITF;
        }
        if self.init {
            v |= icsr::INIT;
        }
        v
    }

    fn write_icsr(&mut self, v: u32, now: Cycles) {
        if v & icsr::RSF == 0 {
            // rc_w0: software clears RSF; it sets again at the next copy.
            self.rsf = false;
            if self.running() {
                self.rsf_at = self.periods(COPY_PERIODS, now);
            }
        }
        let init = v & icsr::INIT != 0;
        if init && !self.init {
            self.init = true;
            self.rsf = false;
            self.rsf_at = None;
            self.restart_at = None;
            self.initf_at = self.periods(INITF_PERIODS, now);
        } else if !init && self.init {
            self.init = false;
            self.initf = false;
            self.initf_at = None;
            self.restart_at = self.periods(RESTART_PERIODS, now);
        }
    }

    fn check_in_init(&mut self, what: &str) -> bool {
        if !self.initf {
            self.reports.once(format!(
                "RTC.{what} written outside initialization mode (INITF = 0): ignored"
            ));
        }
        self.initf
    }

    fn read_calendar_early(&mut self, what: &str) {
        if !self.rsf && self.cr & (1 << 5) == 0 {
            self.reports.once(format!(
                "RTC.{what} read while ICSR.RSF = 0: the silicon returns the shadow \
                 registers' stale values"
            ));
        }
    }
}

impl Peripheral for Rtc {
    fn read(&mut self, offset: u32, now: Cycles) -> Option<u32> {
        self.advance(now);
        let prediv_s = self.prediv_s();
        Some(match offset {
            TR | DR | SSR if self.shadow_reset => {
                self.read_calendar_early("TR/DR/SSR");
                match offset {
                    DR => DR_RESET,
                    _ => 0,
                }
            }
            TR => {
                self.read_calendar_early("TR");
                let tr = self
                    .locked_tr
                    .take()
                    .unwrap_or(self.cal.tr(self.twelve_hour()));
                self.locked_dr.get_or_insert(self.cal.dr());
                tr
            }
            DR => {
                self.read_calendar_early("DR");
                self.locked_tr = None;
                self.locked_dr.take().unwrap_or(self.cal.dr())
            }
            SSR => {
                self.read_calendar_early("SSR");
                self.locked_tr
                    .get_or_insert(self.cal.tr(self.twelve_hour()));
                self.locked_dr.get_or_insert(self.cal.dr());
                prediv_s.saturating_sub(self.sub_ticks)
            }
            ICSR => self.icsr(),
            PRER => self.prer,
            CR => self.cr,
            SR | MISR => 0,
            _ => return None,
        })
    }

    fn write(&mut self, w: Write, now: Cycles) -> bool {
        self.advance(now);
        match w.offset {
            WPR => {
                if self.writable {
                    self.key_stage = match (self.key_stage, w.value & 0xFF) {
                        (0, 0xCA) => 1,
                        (1, 0x53) => 2,
                        _ => 0,
                    };
                }
            }
            ICSR => {
                if !self.protected("ICSR") {
                    let v = w.merge(self.icsr());
                    self.write_icsr(v, now);
                }
            }
            TR | DR => {
                let what = if w.offset == TR { "TR" } else { "DR" };
                if !self.protected(what) && self.check_in_init(what) {
                    let twelve = self.twelve_hour();
                    let (tr, dr) = (self.cal.tr(twelve), self.cal.dr());
                    let (tr, dr) = if w.offset == TR {
                        (w.merge(tr) & TR_MASK, dr)
                    } else {
                        (tr, w.merge(dr) & DR_MASK)
                    };
                    self.cal = Calendar::from_registers(tr, dr, twelve);
                    self.sub_ticks = 0;
                    self.apre_ticks = 0;
                }
            }
            PRER => {
                if !self.protected("PRER") && self.check_in_init("PRER") {
                    self.prer = w.merge(self.prer) & PRER_MASK;
                }
            }
            CR => {
                if !self.protected("CR") {
                    let v = w.merge(self.cr);
                    if v & !CR_STORED != 0 {
                        self.reports.once(format!(
                            "RTC.CR = {v:#010x}: alarms, wake-up, time stamp and outputs \
                             are not modelled"
                        ));
                    }
                    self.cr = v;
                }
            }
            SCR => {}
            _ => return false,
        }
        true
    }

    fn next_event(&self) -> Option<Cycles> {
        [self.initf_at, self.restart_at, self.rsf_at]
            .into_iter()
            .flatten()
            .min()
    }

    fn advance(&mut self, now: Cycles) {
        if now < self.last {
            return;
        }
        // The counters stop and start at the INITF / restart instants, in time order.
        loop {
            let due = self.next_event().filter(|t| *t <= now);
            let Some(t) = due else {
                break;
            };
            self.count(t);
            self.last = t;
            if self.initf_at == Some(t) {
                self.initf_at = None;
                self.initf = true;
            }
            if self.restart_at == Some(t) {
                self.restart_at = None;
                self.rsf_at = self.periods(COPY_PERIODS, t);
            }
            if self.rsf_at == Some(t) {
                self.rsf_at = None;
                self.rsf = true;
                self.shadow_reset = false;
            }
        }
        self.count(now);
        self.last = now;
    }

    fn take_reports(&mut self) -> Vec<String> {
        self.reports.take()
    }

    /// A system reset does not reach the backup domain: the calendar runs on (and a
    /// calendar in initialization mode restarts). It clears INIT, INITF and RSF and resets
    /// the shadow registers (RM0440 RTC_ICSR "System reset value", "Resetting the RTC"):
    /// reads give the reset values until the next copy sets RSF again.
    fn reset(&mut self) {
        let now = self.last;
        if self.init {
            self.init = false;
            self.initf = false;
            self.initf_at = None;
            self.restart_at = self.periods(RESTART_PERIODS, now);
        }
        self.rsf = false;
        self.rsf_at = None;
        self.locked_dr = None;
        self.locked_tr = None;
        self.shadow_reset = true;
        self.copy_after_reset = true;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const LSE_HZ: u64 = 32_768;

    /// An RTC on the LSE with DBP set, as after the RCC and PWR steps of the init.
    fn clocked() -> Rtc {
        let mut r = Rtc::new();
        r.set_backup_writable(true);
        r.set_clock(Some(LSE_HZ), 0);
        r
    }

    fn cycles(secs_num: u64, secs_den: u64) -> Cycles {
        HCLK_HZ * secs_num / secs_den
    }

    fn unlock(r: &mut Rtc, now: Cycles) {
        assert!(r.write(Write::word(WPR, 0xCA), now));
        assert!(r.write(Write::word(WPR, 0x53), now));
    }

    /// RM0440's sequence: unlock, INIT, wait INITF, PRER, TR, DR, INIT = 0, wait RSF.
    fn set_calendar(r: &mut Rtc, tr: u32, dr: u32, now: &mut Cycles) {
        unlock(r, *now);
        r.write(Write::word(ICSR, icsr::INIT), *now);
        while r.read(ICSR, *now).unwrap() & icsr::INITF == 0 {
            *now = r.next_event().expect("INITF is pending");
        }
        r.write(Write::word(PRER, PRER_RESET), *now);
        r.write(Write::word(TR, tr), *now);
        r.write(Write::word(DR, dr), *now);
        r.write(Write::word(ICSR, 0), *now);
        r.write(Write::word(WPR, 0xFF), *now);
        while r.read(ICSR, *now).unwrap() & icsr::RSF == 0 {
            *now = r.next_event().expect("RSF is pending");
        }
    }

    #[test]
    fn reset_values_are_rm0440s() {
        let mut r = Rtc::new();
        assert_eq!(r.read(DR, 0), Some(DR_RESET));
        assert_eq!(r.read(TR, 0), Some(0));
        assert_eq!(r.read(PRER, 0), Some(PRER_RESET));
        assert_eq!(r.read(ICSR, 0), Some(0x0000_0007));
        assert_eq!(
            r.read(0x40, 0),
            None,
            "an unmodelled register is not read as 0"
        );
    }

    #[test]
    fn the_register_map_is_the_metadatas() {
        assert_eq!(crate::names::base("RTC"), Some(0x4000_2800));
        for (offset, name) in [(TR, "TR"), (DR, "DR"), (SSR, "SSR"), (ICSR, "ICSR")]
            .into_iter()
            .chain([(PRER, "PRER"), (CR, "CR"), (WPR, "WPR"), (SCR, "SCR")])
        {
            assert_eq!(
                crate::names::describe(0x4000_2800 + offset),
                format!("RTC.{name}")
            );
        }
    }

    #[test]
    fn writes_are_ignored_until_the_wpr_keys_and_without_dbp() {
        let mut r = clocked();
        r.write(Write::word(ICSR, icsr::INIT), 0);
        assert_eq!(r.read(ICSR, 0).unwrap() & icsr::INIT, 0, "locked");
        // A wrong second key locks again.
        r.write(Write::word(WPR, 0xCA), 0);
        r.write(Write::word(WPR, 0x54), 0);
        r.write(Write::word(ICSR, icsr::INIT), 0);
        assert_eq!(r.read(ICSR, 0).unwrap() & icsr::INIT, 0);
        unlock(&mut r, 0);
        r.write(Write::word(ICSR, icsr::INIT), 0);
        assert_eq!(r.read(ICSR, 0).unwrap() & icsr::INIT, icsr::INIT);
        let reports = r.take_reports();
        assert!(
            reports.iter().any(|m| m.contains("write-protected")),
            "{reports:?}"
        );
        // Without DBP even the keys are ignored.
        let mut r = Rtc::new();
        r.set_clock(Some(LSE_HZ), 0);
        unlock(&mut r, 0);
        r.write(Write::word(ICSR, icsr::INIT), 0);
        assert_eq!(r.read(ICSR, 0).unwrap() & icsr::INIT, 0);
        assert!(r.take_reports().iter().any(|m| m.contains("DBP")));
    }

    #[test]
    fn initf_follows_init_after_two_rtcclk_periods_and_only_then_tr_is_writable() {
        let mut r = clocked();
        unlock(&mut r, 0);
        r.write(Write::word(ICSR, icsr::INIT), 0);
        r.write(Write::word(TR, 0x0012_3456), 0);
        assert_eq!(r.read(TR, 0), Some(0), "TR ignored before INITF");
        let initf_at = r.next_event().unwrap();
        assert_eq!(initf_at, (2 * HCLK_HZ).div_ceil(LSE_HZ));
        assert_eq!(r.read(ICSR, initf_at - 1).unwrap() & icsr::INITF, 0);
        assert_ne!(r.read(ICSR, initf_at).unwrap() & icsr::INITF, 0);
        r.write(Write::word(TR, 0x0012_3456), initf_at);
        assert_eq!(r.read(TR, initf_at), Some(0x0012_3456));
        // Without RTCCLK INITF never sets.
        let mut r = Rtc::new();
        r.set_backup_writable(true);
        unlock(&mut r, 0);
        r.write(Write::word(ICSR, icsr::INIT), 0);
        assert_eq!(r.next_event(), None);
    }

    #[test]
    fn the_calendar_counts_seconds_days_months_and_leap_years() {
        let mut r = clocked();
        let mut now = 0;
        // 2024-02-28 (Wednesday = 3), 23:59:58.
        set_calendar(&mut r, 0x0023_5958, 0x0024_6228, &mut now);
        let start = now;
        assert_eq!(r.read(TR, now), Some(0x0023_5958));
        assert_eq!(r.read(DR, now), Some(0x0024_6228));
        // The counters restarted 4 RTCCLK periods after INIT = 0; 2 s later it is the 29th
        // (2024 is a leap year), Thursday.
        let t = start + cycles(2, 1);
        assert_eq!(r.read(TR, t), Some(0));
        assert_eq!(r.read(DR, t), Some(0x0024_8229));
        // One more day: 1 March, Friday.
        let t = t + cycles(SECONDS_PER_DAY, 1);
        assert_eq!(r.read(TR, t), Some(0));
        assert_eq!(r.read(DR, t), Some(0x0024_A301));
    }

    #[test]
    fn the_sub_second_register_counts_down_from_prediv_s() {
        let mut r = clocked();
        let mut now = 0;
        set_calendar(&mut r, 0x0010_0000, 0x0025_2101, &mut now);
        let s0 = r.read(SSR, now).unwrap();
        // A quarter of a second later SS is 64 lower (PREDIV_S = 255, ck_spre = 1 Hz).
        let t = now + cycles(1, 4);
        let s1 = r.read(SSR, t).unwrap();
        assert_eq!(s0.wrapping_sub(s1) % 256, 64, "{s0} -> {s1}");
        assert!(s1 <= 255);
        r.read(DR, t);
    }

    #[test]
    fn reading_tr_locks_dr_until_dr_is_read() {
        let mut r = clocked();
        let mut now = 0;
        // 2025-01-01 23:59:59, Wednesday.
        set_calendar(&mut r, 0x0023_5959, 0x0025_6101, &mut now);
        assert_eq!(r.read(TR, now), Some(0x0023_5959));
        // Midnight passes between the TR and the DR read: DR still gives the locked date.
        let t = now + cycles(2, 1);
        assert_eq!(r.read(DR, t), Some(0x0025_6101));
        assert_eq!(r.read(DR, t), Some(0x0025_8102), "unlocked by the DR read");
    }

    #[test]
    fn a_system_reset_keeps_the_calendar_and_bdrst_clears_it() {
        let mut r = clocked();
        let mut now = 0;
        set_calendar(&mut r, 0x0008_0000, 0x0026_2315, &mut now);
        let t = now + cycles(3, 1);
        r.advance(t);
        r.reset();
        // As the SoC does after every reset: RTCCLK (still the LSE) given again.
        r.set_clock(Some(LSE_HZ), t);
        // INIT, INITF and RSF cleared; the shadow registers at their reset values until
        // the next copy (reported: software must wait for RSF).
        assert_eq!(
            r.read(ICSR, t).unwrap() & (icsr::INIT | icsr::INITF | icsr::RSF),
            0
        );
        assert_eq!(r.read(TR, t), Some(0));
        assert_eq!(r.read(DR, t), Some(DR_RESET));
        assert!(r.take_reports().iter().any(|m| m.contains("RSF = 0")));
        let copy = r.next_event().expect("the next copy is due");
        assert_eq!(copy, t + (2 * HCLK_HZ).div_ceil(LSE_HZ));
        assert_ne!(r.read(ICSR, copy).unwrap() & icsr::RSF, 0);
        assert_eq!(
            r.read(TR, copy),
            Some(0x0008_0003),
            "ran on through the reset"
        );
        assert_eq!(r.read(DR, copy), Some(0x0026_2315));
        assert_ne!(r.read(ICSR, copy).unwrap() & icsr::INITS, 0);
        r.backup_domain_reset();
        assert_eq!(r.read(DR, copy), Some(DR_RESET));
        // The reset calendar counts on from 00:00:00 while RTCCLK is there (the SoC's BDRST
        // also clears RCC_BDCR.RTCEN, which stops it).
        assert_eq!(r.read(TR, copy + cycles(5, 1)), Some(0x0000_0005));
    }

    #[test]
    fn a_reset_in_initialization_mode_restarts_the_counters() {
        let mut r = clocked();
        unlock(&mut r, 0);
        r.write(Write::word(ICSR, icsr::INIT), 0);
        let initf = r.next_event().unwrap();
        assert_eq!(
            r.read(ICSR, initf).unwrap() & 0b111,
            0,
            "write flags clear in init"
        );
        r.reset();
        r.set_clock(Some(LSE_HZ), initf);
        assert_eq!(r.read(ICSR, initf).unwrap() & icsr::INIT, 0);
        let t = initf + cycles(2, 1);
        assert_eq!(r.read(TR, t), Some(0x0000_0001), "counting again");
    }

    #[test]
    fn the_calendar_freezes_at_its_last_second() {
        let mut r = clocked();
        let mut now = 0;
        // 2099-12-31 23:59:58, Thursday.
        set_calendar(&mut r, 0x0023_5958, 0x0099_9231, &mut now);
        let t = now + cycles(5, 1);
        assert_eq!(r.read(TR, t), Some(0x0023_5959));
        assert_eq!(r.read(DR, t), Some(0x0099_9231));
    }

    #[test]
    fn rsf_clears_by_software_and_sets_at_the_next_copy() {
        let mut r = clocked();
        let mut now = 0;
        set_calendar(&mut r, 0, 0x0025_2101, &mut now);
        unlock(&mut r, now);
        r.write(Write::word(ICSR, !icsr::RSF & !icsr::INIT), now);
        assert_eq!(r.read(ICSR, now).unwrap() & icsr::RSF, 0);
        let _ = r.read(TR, now);
        assert!(r.take_reports().iter().any(|m| m.contains("RSF = 0")));
        let at = r.next_event().unwrap();
        assert_eq!(at, now + (2 * HCLK_HZ).div_ceil(LSE_HZ));
        assert_ne!(r.read(ICSR, at).unwrap() & icsr::RSF, 0);
    }
}
