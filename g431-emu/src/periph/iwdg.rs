//! Independent watchdog (RM0440 §42): KR keys (0x5555 unlock, 0xCCCC start, 0xAAAA reload),
//! PR/RLR/WINR with their busy flags PVU/RVU/WVU, and the down-counter on LSI / (4·2^PR).
//! When the counter reaches 0 the IWDG requests a system reset ([`Iwdg::expired`]); the SoC
//! performs it and RCC_CSR shows IWDGRSTF. It can be frozen while the core is halted by a
//! debugger (DBGMCU_APB1FZR1.DBG_IWDG_STOP, the SoC calls [`Iwdg::set_frozen`]).

use crate::periph::{Peripheral, Write};
use crate::time::{cycles_for, Cycles};

/// LSI frequency (DS12589: 32 kHz typical; 29.5-34 kHz over the spread).
pub const LSI_HZ: u64 = 32_000;
/// A register update crosses into the LSI domain in about 5 LSI periods (RM0440 §42.4.4:
/// "can take up to 5 RC 40 kHz cycles").
const UPDATE_LSI_CLOCKS: u64 = 5;

/// The independent watchdog.
#[derive(Debug, Clone)]
pub struct Iwdg {
    unlocked: bool,
    pr: u32,
    rlr: u32,
    winr: u32,
    running: bool,
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
            running: false,
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
        cycles_for(div, LSI_HZ)
    }

    /// The watchdog counts.
    pub fn running(&self) -> bool {
        self.running
    }

    /// The counter reached 0: the SoC must reset the MCU.
    pub fn expired(&self) -> bool {
        self.expired
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
        let update = now + cycles_for(UPDATE_LSI_CLOCKS, LSI_HZ);
        match w.offset {
            0x00 => match v & 0xFFFF {
                0x5555 => self.unlocked = true,
                0xCCCC => {
                    if !self.running {
                        self.running = true;
                        self.reload(now);
                    }
                    self.unlocked = false;
                }
                0xAAAA => {
                    self.unlocked = false;
                    if self.running {
                        self.reload(now);
                    }
                }
                _ => self.unlocked = false,
            },
            0x04 if self.unlocked => {
                self.pr = v & 7;
                self.pvu_until = Some(update);
            }
            0x08 if self.unlocked => {
                self.rlr = v & 0xFFF;
                self.rvu_until = Some(update);
            }
            0x10 if self.unlocked => {
                self.winr = v & 0xFFF;
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
        .min()
    }

    fn advance(&mut self, now: Cycles) {
        for t in [
            &mut self.pvu_until,
            &mut self.rvu_until,
            &mut self.wvu_until,
        ] {
            if t.is_some_and(|t| t <= now) {
                *t = None;
            }
        }
        if self.expiry().is_some_and(|e| e <= now) {
            self.expired = true;
        }
    }

    fn reset(&mut self) {
        // The IWDG is reset with the system (it must be started again by software).
        *self = Iwdg::new();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// embassy's `IndependentWatchdog::new(100 ms)` then `unleash()`: PR = /4... RLR 799.
    fn start_100ms(w: &mut Iwdg, now: Cycles) {
        w.write(Write::word(0x00, 0x5555), now);
        w.write(Write::word(0x04, 0), now);
        w.write(Write::word(0x08, 799), now);
        w.write(Write::word(0x00, 0xCCCC), now);
    }

    #[test]
    fn expires_after_the_timeout_unless_fed() {
        let mut w = Iwdg::new();
        start_100ms(&mut w, 0);
        // 800 ticks of 4 / 32 kHz = 100 ms.
        assert_eq!(w.timeout(), 17_000_000);
        w.advance(16_999_999);
        assert!(!w.expired());
        w.write(Write::word(0x00, 0xAAAA), 10_000_000);
        w.advance(26_999_999);
        assert!(!w.expired());
        w.advance(27_000_000);
        assert!(w.expired());
        assert_eq!(w.longest_gap, 10_000_000);
    }

    #[test]
    fn protected_registers_need_the_unlock_key_and_show_busy() {
        let mut w = Iwdg::new();
        w.write(Write::word(0x08, 5), 0);
        assert_eq!(w.read(0x08, 0), Some(0xFFF));
        w.write(Write::word(0x00, 0x5555), 0);
        w.write(Write::word(0x08, 5), 0);
        assert_eq!(
            w.read(0x0C, 1),
            Some(0b10),
            "RVU while the value crosses domains"
        );
        w.advance(1_000_000);
        assert_eq!(w.read(0x0C, 1_000_000), Some(0));
    }

    #[test]
    fn frozen_while_halted() {
        let mut w = Iwdg::new();
        start_100ms(&mut w, 0);
        w.set_frozen(true, 1_000_000);
        w.advance(100_000_000);
        assert!(!w.expired());
        w.set_frozen(false, 100_000_000);
        w.advance(100_000_000 + 15_999_999);
        assert!(!w.expired());
        w.advance(100_000_000 + 16_000_000);
        assert!(w.expired());
    }
}
