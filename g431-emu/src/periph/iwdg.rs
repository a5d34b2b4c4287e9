//! Independent watchdog (RM0440 §42): KR keys (0x5555 unlock, 0xCCCC start, 0xAAAA reload),
//! PR/RLR/WINR with their busy flags PVU/RVU/WVU, and the down-counter on LSI / (4·2^PR).
//! When the counter reaches 0 the IWDG requests a system reset ([`Iwdg::expired`]); the SoC
//! performs it and RCC_CSR shows IWDGRSTF. It can be frozen while the core is halted by a
//! debugger (DBGMCU_APB1FZR1.DBG_IWDG_STOP, the SoC calls [`Iwdg::set_frozen`]).
//!
//! As RM0440 §42.3 describes it:
//! * the LSI frequency is a setting ([`Iwdg::set_lsi_hz`], 32 kHz typical; the datasheet
//!   DS12589 gives 29.5 to 34 kHz over the operating conditions, so embassy's 100 ms
//!   (PR = 0, RLR = 799) lasts 94.1 to 108.5 ms);
//! * a PR/RLR/WINR write reaches the counter's (LSI) domain only while the LSI runs: the busy
//!   flag stays set and the old value stays in effect until 5 LSI clocks after the LSI runs
//!   (RCC_CSR.LSION/LSIRDY, which the SoC forwards, or the IWDG's own start, which forces the
//!   LSI on after its start-up time); reads of PR/RLR/WINR return the value in effect
//!   (RM0440: "valid only when the PVU bit ... is reset");
//! * the start key loads the counter with 0xFFF (RM0440 §42.3.2: "the counter starts
//!   counting down from the reset value of 0xFFF"), not with RLR;
//! * the window: a reload while the counter is above WINR resets the MCU (RM0440 §42.3.5).

use crate::periph::{Peripheral, Write};
use crate::time::{cycles_for, Cycles};

/// LSI frequency (DS12589: 32 kHz typical; 29.5-34 kHz over the spread).
pub const LSI_HZ: u64 = 32_000;
/// A register update crosses into the LSI domain in about 5 LSI periods (RM0440 §42.4.4:
/// "can take up to 5 RC 40 kHz cycles").
const UPDATE_LSI_CLOCKS: u64 = 5;
/// LSI start-up when the IWDG's start key forces it on (DS12589 tsu(LSI) 130 µs max).
const LSI_STARTUP: Cycles = 130 * crate::time::CYCLES_PER_US;
/// A pending update waiting for the LSI.
const WAITING_FOR_LSI: Cycles = Cycles::MAX;
/// The counter's value at start and at reset.
const COUNTER_RESET: u32 = 0xFFF;

/// The independent watchdog.
#[derive(Debug, Clone)]
pub struct Iwdg {
    unlocked: bool,
    /// The values in effect (the LSI domain's).
    pr: u32,
    rlr: u32,
    winr: u32,
    /// Values written and not yet in effect.
    pr_pending: u32,
    rlr_pending: u32,
    winr_pending: u32,
    running: bool,
    /// LSI frequency, Hz (survives resets: the part's).
    lsi_hz: u64,
    /// The LSI runs (RCC), or will once started by the IWDG at this cycle.
    lsi_on: bool,
    lsi_on_at: Option<Cycles>,
    /// A reload happened outside the window (WINR): the reset is due.
    window_violation: bool,
    /// Cycle at which the counter was last reloaded, and the value loaded.
    reload_at: Cycles,
    reload_value: u32,
    /// Busy flags clear at these cycles.
    pvu_until: Option<Cycles>,
    rvu_until: Option<Cycles>,
    wvu_until: Option<Cycles>,
    expired: bool,
    /// While frozen, the counter holds its value (`frozen_left` cycles to expiry).
    frozen_left: Option<Cycles>,
    /// Cycles between the last reloads, for the "longest gap" figure.
    pub longest_gap: Cycles,
    last_feed: Option<Cycles>,
    /// Number of reloads (feeds) since start.
    pub feeds: u64,
}

impl Default for Iwdg {
    fn default() -> Self {
        Iwdg::new()
    }
}

impl Iwdg {
    pub fn new() -> Self {
        Iwdg {
            unlocked: false,
            pr: 0,
            rlr: 0xFFF,
            winr: 0xFFF,
            pr_pending: 0,
            rlr_pending: 0xFFF,
            winr_pending: 0xFFF,
            running: false,
            lsi_hz: LSI_HZ,
            lsi_on: false,
            lsi_on_at: None,
            window_violation: false,
            reload_at: 0,
            reload_value: 0xFFF,
            pvu_until: None,
            rvu_until: None,
            wvu_until: None,
            expired: false,
            frozen_left: None,
            longest_gap: 0,
            last_feed: None,
            feeds: 0,
        }
    }

    /// Cycles per counter decrement with prescaler `pr`.
    fn tick(&self) -> Cycles {
        let div = 4u64 << self.pr.min(6);
        cycles_for(div, self.lsi_hz)
    }

    /// This part's LSI frequency (a scenario setting; survives resets).
    pub fn set_lsi_hz(&mut self, hz: u64) {
        self.lsi_hz = hz.max(1);
    }

    /// The LSI frequency in use.
    pub fn lsi_hz(&self) -> u64 {
        self.lsi_hz
    }

    /// The LSI runs (RCC_CSR.LSIRDY), or stopped, from `now` (the SoC forwards RCC's
    /// state). Pending register updates complete 5 LSI clocks after it runs.
    pub fn set_lsi_on(&mut self, on: bool, now: Cycles) {
        if on && !self.lsi_running(now) {
            self.lsi_on = true;
            self.lsi_on_at = Some(now);
            self.schedule_pending(now);
        } else if !on && !self.running {
            // The started IWDG keeps the LSI on whatever RCC says.
            self.lsi_on = false;
            self.lsi_on_at = None;
        }
    }

    fn lsi_running(&self, now: Cycles) -> bool {
        self.lsi_on && self.lsi_on_at.is_some_and(|t| t <= now)
    }

    /// When an update written at `now` reaches the LSI domain.
    fn update_done(&self, now: Cycles) -> Cycles {
        let five = cycles_for(UPDATE_LSI_CLOCKS, self.lsi_hz);
        match self.lsi_on_at {
            Some(t) if self.lsi_on => t.max(now) + five,
            _ => WAITING_FOR_LSI,
        }
    }

    /// Updates waiting for the LSI get their completion time.
    fn schedule_pending(&mut self, now: Cycles) {
        let done = self.update_done(now);
        for t in [
            &mut self.pvu_until,
            &mut self.rvu_until,
            &mut self.wvu_until,
        ] {
            if *t == Some(WAITING_FOR_LSI) {
                *t = Some(done);
            }
        }
    }

    /// The counter's value at `now` (running and not frozen).
    fn counter(&self, now: Cycles) -> u32 {
        let ticks = now.saturating_sub(self.reload_at) / self.tick().max(1);
        u32::try_from(u64::from(self.reload_value).saturating_sub(ticks)).unwrap_or(0)
    }

    /// The watchdog counts.
    pub fn running(&self) -> bool {
        self.running
    }

    /// The counter reached 0, or a reload came outside the window: the SoC must reset
    /// the MCU.
    pub fn expired(&self) -> bool {
        self.expired
    }

    /// The reset was caused by a reload above the window (WINR).
    pub fn window_violation(&self) -> bool {
        self.window_violation
    }

    /// Timeout of a full reload with the current PR/RLR, in cycles.
    pub fn timeout(&self) -> Cycles {
        self.tick() * (u64::from(self.rlr) + 1)
    }

    fn expiry(&self) -> Option<Cycles> {
        if !self.running || self.expired || self.frozen_left.is_some() {
            return None;
        }
        Some(self.reload_at + self.tick() * (u64::from(self.reload_value) + 1))
    }

    fn reload(&mut self, now: Cycles) {
        if let Some(last) = self.last_feed {
            self.longest_gap = self.longest_gap.max(now - last);
        }
        self.last_feed = Some(now);
        self.feeds += 1;
        self.reload_at = now;
        self.reload_value = self.rlr;
    }

    /// The core is halted by a debugger with DBG_IWDG_STOP set (`frozen`), or resumed.
    pub fn set_frozen(&mut self, frozen: bool, now: Cycles) {
        match (frozen, self.frozen_left) {
            (true, None) => {
                if let Some(e) = self.expiry() {
                    self.frozen_left = Some(e.saturating_sub(now));
                }
            }
            (false, Some(left)) => {
                self.frozen_left = None;
                let full = self.tick() * (u64::from(self.reload_value) + 1);
                self.reload_at = (now + left).saturating_sub(full);
            }
            _ => {}
        }
    }
}

impl Peripheral for Iwdg {
    fn read(&mut self, offset: u32, now: Cycles) -> Option<u32> {
        Some(match offset {
            0x00 => 0,
            0x04 => self.pr,
            0x08 => self.rlr,
            0x0C => {
                let busy = |t: Option<Cycles>| t.is_some_and(|t| t > now);
                u32::from(busy(self.pvu_until))
                    | (u32::from(busy(self.rvu_until)) << 1)
                    | (u32::from(busy(self.wvu_until)) << 2)
            }
            0x10 => self.winr,
            _ => return None,
        })
    }

    fn write(&mut self, w: Write, now: Cycles) -> bool {
        let v = w.value & w.mask;
        let update = self.update_done(now);
        match w.offset {
            0x00 => match v & 0xFFFF {
                0x5555 => self.unlocked = true,
                0xCCCC => {
                    if !self.running {
                        self.running = true;
                        if !self.lsi_on {
                            // The start forces the LSI on (RM0440 §42.3.2).
                            self.lsi_on = true;
                            self.lsi_on_at = Some(now + LSI_STARTUP);
                            self.schedule_pending(now);
                        }
                        self.reload(now);
                        self.reload_value = COUNTER_RESET;
                        self.reload_at = self.lsi_on_at.map_or(now, |t| t.max(now));
                    }
                    self.unlocked = false;
                }
                0xAAAA => {
                    self.unlocked = false;
                    if self.running {
                        if self.winr < COUNTER_RESET
                            && self.frozen_left.is_none()
                            && self.counter(now) > self.winr
                        {
                            // RM0440 §42.3.5: a reload above the window resets the MCU.
                            self.window_violation = true;
                            self.expired = true;
                        }
                        self.reload(now);
                    }
                }
                _ => self.unlocked = false,
            },
            0x04 if self.unlocked => {
                self.pr_pending = v & 7;
                self.pvu_until = Some(update);
            }
            0x08 if self.unlocked => {
                self.rlr_pending = v & 0xFFF;
                self.rvu_until = Some(update);
            }
            0x10 if self.unlocked => {
                self.winr_pending = v & 0xFFF;
                self.wvu_until = Some(update);
                // Writing WINR also reloads (RM0440 §42.3.5).
                if self.running {
                    self.reload(now);
                }
            }
            // Protected registers ignore writes while locked.
            0x04 | 0x08 | 0x10 => {}
            _ => return false,
        }
        true
    }

    fn next_event(&self) -> Option<Cycles> {
        [
            self.expiry(),
            self.pvu_until,
            self.rvu_until,
            self.wvu_until,
        ]
        .into_iter()
        .flatten()
        .filter(|t| *t != WAITING_FOR_LSI)
        .min()
    }

    fn advance(&mut self, now: Cycles) {
        if self.pvu_until.is_some_and(|t| t <= now) {
            self.pvu_until = None;
            // The counter keeps its count; its tick changes from here.
            if self.running && self.frozen_left.is_none() {
                let left = self.counter(now);
                self.pr = self.pr_pending;
                self.reload_at = now;
                self.reload_value = left;
            } else {
                self.pr = self.pr_pending;
            }
        }
        if self.rvu_until.is_some_and(|t| t <= now) {
            self.rvu_until = None;
            self.rlr = self.rlr_pending;
        }
        if self.wvu_until.is_some_and(|t| t <= now) {
            self.wvu_until = None;
            self.winr = self.winr_pending;
        }
        if self.expiry().is_some_and(|e| e <= now) {
            self.expired = true;
        }
    }

    fn reset(&mut self) {
        // The IWDG is reset with the system (it must be started again by software); the
        // LSI's frequency is the part's. RCC stops the LSI at reset.
        let hz = self.lsi_hz;
        *self = Iwdg::new();
        self.lsi_hz = hz;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// embassy's `IndependentWatchdog::new(100 ms)` then `unleash()`: PR = /4, RLR 799.
    fn start_100ms(w: &mut Iwdg, now: Cycles) {
        w.write(Write::word(0x00, 0x5555), now);
        w.write(Write::word(0x04, 0), now);
        w.write(Write::word(0x08, 799), now);
        w.write(Write::word(0x00, 0xCCCC), now);
    }

    /// The LSI on (embassy's RCC set-up starts it at boot) and the 100 ms watchdog started
    /// at 0, with PR/RLR in effect after 5 LSI clocks.
    fn running_100ms() -> Iwdg {
        let mut w = Iwdg::new();
        w.set_lsi_on(true, 0);
        start_100ms(&mut w, 0);
        w.advance(100_000);
        w
    }

    #[test]
    fn expires_after_the_timeout_unless_fed() {
        let mut w = running_100ms();
        // 800 ticks of 4 / 32 kHz = 100 ms.
        assert_eq!(w.timeout(), 17_000_000);
        // The first period counts down from 0xFFF (RM0440 §42.3.2): 4096 ticks, 512 ms.
        w.advance(86_000_000);
        assert!(!w.expired());
        w.write(Write::word(0x00, 0xAAAA), 86_000_000);
        w.advance(102_999_999);
        assert!(!w.expired());
        w.advance(103_000_000);
        assert!(w.expired());
        assert_eq!(w.longest_gap, 86_000_000);
    }

    #[test]
    fn the_timeout_follows_the_lsi_at_both_datasheet_extremes() {
        for (hz, ms) in [(29_500u64, 108.47), (34_000, 94.12)] {
            let mut w = Iwdg::new();
            w.set_lsi_hz(hz);
            w.reset();
            assert_eq!(w.lsi_hz(), hz, "survives a reset");
            w.set_lsi_on(true, 0);
            start_100ms(&mut w, 0);
            w.advance(1_000_000);
            let got = crate::time::cycles_to_ns(w.timeout()) as f64 * 1e-6;
            assert!((got - ms).abs() < 0.05, "{hz} Hz: {got} ms");
        }
    }

    #[test]
    fn busy_flags_need_the_lsi() {
        let mut w = Iwdg::new();
        w.write(Write::word(0x08, 5), 0);
        assert_eq!(w.read(0x08, 0), Some(0xFFF), "locked");
        w.write(Write::word(0x00, 0x5555), 0);
        w.write(Write::word(0x08, 5), 0);
        // LSI off: RVU stays set, the old value stays in effect.
        w.advance(10_000_000);
        assert_eq!(w.read(0x0C, 10_000_000), Some(0b10));
        assert_eq!(w.read(0x08, 10_000_000), Some(0xFFF));
        assert_eq!(w.next_event(), None, "nothing will happen");
        // The LSI starts: 5 LSI clocks later the value is in effect.
        w.set_lsi_on(true, 10_000_000);
        let done = 10_000_000 + cycles_for(5, LSI_HZ);
        w.advance(done - 1);
        assert_eq!(w.read(0x0C, done - 1), Some(0b10));
        w.advance(done);
        assert_eq!(w.read(0x0C, done), Some(0));
        assert_eq!(w.read(0x08, done), Some(5));
    }

    #[test]
    fn the_start_key_forces_the_lsi_on() {
        let mut w = Iwdg::new();
        start_100ms(&mut w, 0);
        assert_eq!(w.read(0x0C, 1), Some(0b11), "PVU and RVU");
        let done = LSI_STARTUP + cycles_for(5, LSI_HZ);
        w.advance(done);
        assert_eq!(w.read(0x0C, done), Some(0));
        assert_eq!(w.timeout(), 17_000_000);
    }

    #[test]
    fn a_reload_above_the_window_resets() {
        let mut w = running_100ms();
        // WINR = 400: reloads only once the counter is at or below 400.
        w.write(Write::word(0x00, 0x5555), 200_000);
        w.write(Write::word(0x10, 400), 200_000);
        // Writing WINR reloads the counter with RLR = 799 (RM0440 §42.3.5); 300 ticks later
        // it is at 499, above the window: the reload is too early.
        let tick = cycles_for(4, LSI_HZ);
        w.advance(200_000 + 300 * tick);
        w.write(Write::word(0x00, 0xAAAA), 200_000 + 300 * tick);
        assert!(w.expired() && w.window_violation());
        // Inside the window (counter 399) it is a plain reload.
        let mut w = running_100ms();
        w.write(Write::word(0x00, 0x5555), 200_000);
        w.write(Write::word(0x10, 400), 200_000);
        w.advance(200_000 + 401 * tick);
        w.write(Write::word(0x00, 0xAAAA), 200_000 + 401 * tick);
        assert!(!w.expired() && !w.window_violation());
    }

    #[test]
    fn frozen_while_halted() {
        let mut w = running_100ms();
        // A feed loads RLR: 100 ms from 1 000 000.
        w.write(Write::word(0x00, 0xAAAA), 1_000_000);
        w.set_frozen(true, 2_000_000);
        w.advance(100_000_000);
        assert!(!w.expired());
        w.set_frozen(false, 100_000_000);
        w.advance(100_000_000 + 15_999_999);
        assert!(!w.expired());
        w.advance(100_000_000 + 16_000_000);
        assert!(w.expired());
    }
}
