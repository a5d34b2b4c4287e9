//! The clock tree as the other models see it:
//! * the LSI (its frequency, a setting of the part, and whether it runs) forwarded to the
//!   IWDG;
//! * every change of HCLK (RCC) and every write to FLASH_ACR or PWR checked against the
//!   flash wait states and the voltage range RM0440 requires (§3.3.3 Table "Number of wait
//!   states according to CPU clock (HCLK) frequency"; §6.1.5 "Dynamic voltage scaling
//!   management": range 1 normal at most 150 MHz, boost at most 170 MHz, range 2 at most
//!   26 MHz);
//! * RM0440 §6.1.5's sequence into boost mode: "The system clock must be divided by 2 using
//!   the AHB prescaler before switching to a higher system frequency" and restored after
//!   1 µs; RM0440 §7.2.7 "System clock (SYSCLK) selection" gives the same transition for a
//!   switch to a clock above 80 MHz (ST's HAL `HAL_RCC_ClockConfig`: "target frequency
//!   above 80MHz"; the L5's RM0438 §9.3.9 words it the same): a switch of SYSCLK from at most
//!   80 MHz to above 80 MHz with HPRE = /1 in boost mode is reported.
//!
//! Findings are model diagnostics (`Diagnostic::Model`), one per distinct message.

use super::{Diagnostic, Soc};
use crate::periph::flash::{min_latency, Flash, VoltageRange};
use crate::periph::iwdg::Iwdg;
use crate::periph::pwr::Pwr;
use crate::periph::rcc::{ClockChange, Rcc};
use crate::time::Cycles;

/// Above this SYSCLK a switch in boost mode needs the AHB prescaler at /2 first (RM0440
/// §6.1.5).
const BOOST_STEP_HZ: u64 = 80_000_000;

impl Soc {
    /// This part's LSI frequency (DS12589: 29.5 to 34 kHz; the model's default 32 kHz).
    /// Survives resets.
    pub fn set_lsi_hz(&mut self, hz: u64) {
        let k = self.iwdg;
        if let Some(w) = self.model_mut::<Iwdg>(k) {
            w.set_lsi_hz(hz);
        }
        self.refresh(k);
    }

    /// After slot `k` changed at `t`: RCC's LSI to the IWDG, and the clock checks after a
    /// change of RCC, FLASH or PWR.
    pub(super) fn clock_tree_changed(&mut self, k: usize, t: Cycles) {
        let name = self.slots.get(k).map_or("", |s| s.name);
        if k == self.rcc {
            self.sync_lsi(t);
            let changes = self
                .model_mut::<Rcc>(k)
                .map(Rcc::take_clock_changes)
                .unwrap_or_default();
            for c in changes {
                self.check_clock_change(&c);
            }
        } else if matches!(name, "FLASH" | "PWR") {
            self.check_clock_limits();
        }
    }

    fn sync_lsi(&mut self, t: Cycles) {
        let on = self.rcc().lsi_ready();
        let k = self.iwdg;
        self.advance_slot(k, t);
        if let Some(w) = self.model_mut::<Iwdg>(k) {
            w.set_lsi_on(on, t);
        }
        self.refresh(k);
    }

    fn range_and_latency(&self) -> Option<(VoltageRange, u32)> {
        let range = self.pwr()?.range();
        let latency = self.flash_if().map(Flash::latency)?;
        Some((range, latency))
    }

    /// HCLK now against the latency and the range now.
    fn check_clock_limits(&mut self) {
        if let Some(hz) = self.rcc().hclk_hz() {
            self.check_hclk(hz);
        }
    }

    fn check_hclk(&mut self, hz: u64) {
        let Some((range, latency)) = self.range_and_latency() else {
            return;
        };
        let mhz = hz as f64 * 1e-6;
        let msg = match min_latency(hz, range) {
            None => Some(format!(
                "HCLK {mhz:.1} MHz is above what {range:?} allows (RM0440 §6.1.5)"
            )),
            Some(ws) if ws > latency => Some(format!(
                "HCLK {mhz:.1} MHz with FLASH_ACR.LATENCY = {latency} in {range:?}: RM0440 \
                 §3.3.3 requires at least {ws} wait states"
            )),
            _ => None,
        };
        if let Some(m) = msg {
            self.clock_report(m);
        }
    }

    fn check_clock_change(&mut self, c: &ClockChange) {
        if let Some(hz) = c.to_hz {
            self.check_hclk(hz);
        }
        let boost = self.pwr().is_some_and(Pwr::boost);
        let from = c.from_hz.unwrap_or(0);
        if let (true, true, Some(to)) = (c.switch, boost, c.to_hz) {
            if from <= BOOST_STEP_HZ && to > BOOST_STEP_HZ && !c.hpre_divides {
                self.clock_report(format!(
                    "HCLK jumps from {:.0} to {:.0} MHz in boost mode with the AHB prescaler \
                     at /1: RM0440 §6.1.5 asks for HPRE = /2 across the switch and 1 µs \
                     after it (review N9)",
                    from as f64 * 1e-6,
                    to as f64 * 1e-6
                ));
            }
        }
    }

    fn clock_report(&mut self, msg: String) {
        let mut h: u32 = 0x811C_9DC5;
        for b in msg.bytes() {
            h = (h ^ u32::from(b)).wrapping_mul(0x0100_0193);
        }
        self.report((h, false, 6), Diagnostic::Model(msg));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const RCC_CR: u32 = 0x4002_1000;
    const RCC_CFGR: u32 = 0x4002_1008;
    const RCC_PLLCFGR: u32 = 0x4002_100C;
    const RCC_APB1ENR1: u32 = 0x4002_1058;
    const FLASH_ACR: u32 = 0x4002_2000;
    const PWR_CR5: u32 = 0x4000_7080;
    const PLL_170: u32 = 2 | (3 << 4) | (85 << 8) | (1 << 24);

    fn soc() -> Soc {
        let mut s = Soc::new(Vec::new(), Box::new(crate::soc::BareBoard));
        s.bus_write(RCC_APB1ENR1, 4, 1 << 28);
        s
    }

    /// Runs the SoC's events up to `t`.
    fn run(s: &mut Soc, t: Cycles) {
        s.advance_to(t);
    }

    fn models(s: &Soc) -> Vec<String> {
        s.diagnostics()
            .iter()
            .filter_map(|d| match d {
                Diagnostic::Model(m) => Some(m.clone()),
                _ => None,
            })
            .collect()
    }

    /// embassy's sequence on the G4 as `vendor/README.md` describes it: boost, 4 wait states, PLL,
    /// switch with HPRE = /1. Latency and range are right; the missing /2 step is reported.
    #[test]
    fn embassy_like_switch_to_170_mhz_reports_only_the_missing_hpre_step() {
        let mut s = soc();
        s.bus_write(PWR_CR5, 4, 0);
        s.bus_write(FLASH_ACR, 4, 0x604);
        s.bus_write(RCC_PLLCFGR, 4, PLL_170);
        s.bus_write(RCC_CR, 4, (1 << 8) | (1 << 24));
        run(&mut s, 10_000);
        s.bus_write(RCC_CFGR, 4, 3);
        run(&mut s, 20_000);
        let m = models(&s);
        assert_eq!(m.len(), 1, "{m:?}");
        assert!(m[0].contains("N9"), "{m:?}");
    }

    #[test]
    fn too_few_wait_states_and_no_boost_are_reported() {
        let mut s = soc();
        // R1MODE = 1 (no boost), LATENCY = 1, HPRE = /2 across the switch.
        s.bus_write(FLASH_ACR, 4, 0x601);
        s.bus_write(RCC_PLLCFGR, 4, PLL_170);
        s.bus_write(RCC_CR, 4, (1 << 8) | (1 << 24));
        run(&mut s, 10_000);
        s.bus_write(RCC_CFGR, 4, (0b1000 << 4) | 3);
        run(&mut s, 20_000);
        let m = models(&s);
        assert!(
            m.iter().any(|x| x.contains("LATENCY = 1")),
            "85 MHz needs 2 wait states in range 1 normal: {m:?}"
        );
        s.bus_write(RCC_CFGR, 4, 3);
        let m = models(&s);
        assert!(
            m.iter()
                .any(|x| x.contains("above what Range1Normal allows")),
            "{m:?}"
        );
    }
}
