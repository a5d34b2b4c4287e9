//! RCC (RM0440 §7.4): oscillator and PLL ready flags that follow their enables after the
//! datasheet's start-up times, SWS following SW, the clock-enable and reset registers (the
//! SoC gates and resets the other models with them), and the reset flags in CSR.
//!
//! The clock tree is computed, not run: every model still counts time at 170 MHz (see
//! `crate::time`), but the RCC knows the frequencies the configuration gives
//! ([`Rcc::sysclk_hz`], [`Rcc::hclk_hz`], [`Rcc::adc12_kernel_hz`]) and records each change
//! of HCLK ([`Rcc::take_clock_changes`]) for the SoC to check against the flash latency and
//! the voltage range. [`Rcc::sysclk_is_pll`] lets the SoC report an image that
//! runs the PLL-dependent peripherals without switching to the PLL.
//!
//! A system-clock switch completes only once its source is ready (RM0440 §7.4.3 RCC_CFGR.SW:
//! the switch happens when the selected clock is ready; SWS shows it): SW = PLL with the PLL
//! not locked leaves SWS where it was until PLLRDY, and a source that never becomes ready
//! (PLL off, or HSE: no crystal on either board) is reported.

use crate::periph::usart::UsartInstance;
use crate::periph::{Peripheral, Write};
use crate::time::{Cycles, CYCLES_PER_US, HCLK_HZ};

/// HSI16 start-up time, maximum (DS12589 tsu(HSI16), rounded up).
const HSI_STARTUP: Cycles = 4 * CYCLES_PER_US;
/// PLL lock time, maximum (DS12589 tLOCK 40 µs).
const PLL_LOCK: Cycles = 40 * CYCLES_PER_US;
/// LSI start-up time, maximum (DS12589 tsu(LSI) 130 µs).
const LSI_STARTUP: Cycles = 130 * CYCLES_PER_US;
/// HSI48 start-up time, maximum (DS12589 tsu(HSI48) 6 µs).
const HSI48_STARTUP: Cycles = 6 * CYCLES_PER_US;
/// LSE start-up time with a 32.768 kHz crystal (DS12589 "LSE oscillator characteristics",
/// tSU(LSE): 2 s typical; no maximum is given, and the start-up "can vary significantly with
/// the crystal").
pub const LSE_STARTUP: Cycles = 2 * crate::time::HCLK_HZ;
/// A system-clock switch takes effect after a few cycles of both clocks.
const SWITCH: Cycles = 16;

const CR: u32 = 0x00;
const ICSCR: u32 = 0x04;
const CFGR: u32 = 0x08;
const PLLCFGR: u32 = 0x0C;
const CIER: u32 = 0x18;
const CIFR: u32 = 0x1C;
const CICR: u32 = 0x20;
const CCIPR: u32 = 0x88;
const CSR: u32 = 0x94;
const CRRCR: u32 = 0x98;
/// RCC_BDCR, in the backup domain (RM0440 "RCC backup domain control register").
const BDCR: u32 = 0x90;

/// RCC_BDCR bits.
pub mod bdcr {
    pub const LSEON: u32 = 1 << 0;
    pub const LSERDY: u32 = 1 << 1;
    pub const RTCSEL_SHIFT: u32 = 8;
    pub const RTCSEL: u32 = 0b11 << RTCSEL_SHIFT;
    pub const RTCEN: u32 = 1 << 15;
    pub const BDRST: u32 = 1 << 16;
    /// Read-only: LSERDY, LSECSSD (6), LSESYSRDY (11).
    pub const READ_ONLY: u32 = LSERDY | (1 << 6) | (1 << 11);
}

/// Why the MCU last reset, as RCC_CSR reports it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ResetKind {
    /// Power-on (BOR) reset: BORRSTF and PINRSTF.
    PowerOn,
    /// Independent watchdog: IWDGRSTF and PINRSTF (every internal reset also drives NRST).
    Watchdog,
    /// AIRCR.SYSRESETREQ: SFTRSTF and PINRSTF.
    Software,
    /// The NRST pin (e.g. a probe's reset): PINRSTF.
    Pin,
}

/// A pending ready-flag change.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Settle {
    at: Cycles,
    /// Bit of CR (or CSR for LSI) that becomes `value`.
    reg: u32,
    bit: u32,
    value: bool,
}

/// The RCC.
#[derive(Debug, Clone)]
pub struct Rcc {
    cr: u32,
    icscr: u32,
    cfgr: u32,
    pllcfgr: u32,
    cier: u32,
    cifr: u32,
    /// Every other register (RSTR, ENR, SMENR, CCIPR, BDCR, CRRCR, CCIPR2): plain storage,
    /// indexed by offset / 4.
    regs: [u32; 0xA0 / 4],
    csr: u32,
    settle: heapless_settle::Queue,
    /// SWS catches up with SW at this cycle.
    sws_at: Option<Cycles>,
    /// Reset bits newly set by a write, for the SoC to reset those models.
    resets_asserted: Vec<(u32, u32)>,
    /// HCLK changes since the SoC last looked.
    clock_changes: Vec<ClockChange>,
    /// Diagnostics for the SoC.
    reports: Vec<String>,
    /// A 32.768 kHz crystal is fitted on the board (LSERDY can set).
    lse_fitted: bool,
    /// PWR_CR1.DBP: BDCR takes writes.
    backup_writable: bool,
    /// A write set BDRST: the SoC resets the backup domain's models.
    backup_domain_reset: bool,
}

/// One change of HCLK (a system-clock switch or an AHB prescaler write).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ClockChange {
    pub at: Cycles,
    /// HCLK before and after, Hz (`None`: a source the model cannot know, HSE).
    pub from_hz: Option<u64>,
    pub to_hz: Option<u64>,
    /// SYSCLK switched (SWS changed); otherwise HPRE changed.
    pub switch: bool,
    /// The AHB prescaler divides (HPRE != /1) at the moment of the change.
    pub hpre_divides: bool,
}

/// A tiny fixed queue without allocation in the hot path.
mod heapless_settle {
    use super::Settle;

    #[derive(Debug, Clone, Default)]
    pub struct Queue(Vec<Settle>);

    impl Queue {
        pub fn push(&mut self, s: Settle) {
            // A newer request for the same bit replaces the older one.
            self.0.retain(|o| !(o.reg == s.reg && o.bit == s.bit));
            self.0.push(s);
        }
        /// When `bit` of `reg` becomes 1, if that is pending.
        pub fn ready_at(&self, reg: u32, bit: u32) -> Option<super::Cycles> {
            self.0
                .iter()
                .find(|s| s.reg == reg && s.bit == bit && s.value)
                .map(|s| s.at)
        }
        pub fn cancel(&mut self, reg: u32, bit: u32) {
            self.0.retain(|o| !(o.reg == reg && o.bit == bit));
        }
        pub fn next(&self) -> Option<super::Cycles> {
            self.0.iter().map(|s| s.at).min()
        }
        pub fn take_due(&mut self, now: super::Cycles) -> Vec<Settle> {
            let (due, rest): (Vec<_>, Vec<_>) = self.0.drain(..).partition(|s| s.at <= now);
            self.0 = rest;
            due
        }
        pub fn clear(&mut self) {
            self.0.clear();
        }
    }
}

/// The AHB prescaler's division (RM0440 RCC_CFGR.HPRE, bits 7:4: 0xxx = 1, 1000 = 2 ...
/// 1011 = 16, 1100 = 64 ... 1111 = 512).
fn hpre_div(cfgr: u32) -> u64 {
    let h = (cfgr >> 4) & 0xF;
    match h {
        0..=7 => 1,
        8..=11 => 2 << (h - 8),
        _ => 64 << (h - 12),
    }
}

/// Reset values of the storage registers (RM0440 §7.4).
fn storage_reset() -> [u32; 0xA0 / 4] {
    let mut r = [0u32; 0xA0 / 4];
    // AHB1ENR: FLASHEN.
    r[0x48 / 4] = 0x0000_0100;
    // APB1ENR1: RTCAPBEN.
    r[0x58 / 4] = 0x0000_0400;
    // AHB1SMENR..APB2SMENR: clocks stay on in Sleep mode.
    r[0x68 / 4] = 0x0000_130F;
    r[0x6C / 4] = 0x050F_667F;
    r[0x70 / 4] = 0x0000_0101;
    r[0x78 / 4] = 0xD2FE_CD3F;
    r[0x7C / 4] = 0x0000_0103;
    r[0x80 / 4] = 0x0437_F801;
    r
}

impl Default for Rcc {
    fn default() -> Self {
        Rcc::new(ResetKind::PowerOn)
    }
}

impl Rcc {
    /// The RCC just after a reset of kind `why`.
    pub fn new(why: ResetKind) -> Self {
        let mut r = Rcc {
            cr: 0,
            icscr: 0,
            cfgr: 0,
            pllcfgr: 0,
            cier: 0,
            cifr: 0,
            regs: storage_reset(),
            csr: 0,
            settle: heapless_settle::Queue::default(),
            sws_at: None,
            resets_asserted: Vec::new(),
            clock_changes: Vec::new(),
            reports: Vec::new(),
            lse_fitted: false,
            backup_writable: false,
            backup_domain_reset: false,
        };
        r.reset_to(why);
        r
    }

    /// SYSCLK in Hz as SWS selects it now (`None`: HSE, whose frequency no board gives).
    pub fn sysclk_hz(&self) -> Option<u64> {
        self.source_hz((self.cfgr >> 2) & 3)
    }

    /// HCLK in Hz: SYSCLK through the AHB prescaler (RM0440 RCC_CFGR.HPRE).
    pub fn hclk_hz(&self) -> Option<u64> {
        Some(self.sysclk_hz()? / hpre_div(self.cfgr))
    }

    /// The frequency of system-clock source `sw` (RM0440 RCC_CFGR.SW: 01 HSI16, 10 HSE,
    /// 11 PLL "R" output).
    fn source_hz(&self, sw: u32) -> Option<u64> {
        match sw {
            1 => Some(16_000_000),
            3 => {
                let p = self.pllcfgr;
                let vco = self.pll_vco_hz()?;
                // PLLR (bits 26:25): /2, /4, /6, /8.
                let r = 2 * (u64::from((p >> 25) & 3) + 1);
                Some(vco / r)
            }
            _ => None,
        }
    }

    /// The PLL's VCO (RM0440 RCC_PLLCFGR: PLLSRC, PLLM, PLLN), Hz.
    fn pll_vco_hz(&self) -> Option<u64> {
        let p = self.pllcfgr;
        let input = match p & 3 {
            2 => 16_000_000u64,
            _ => return None,
        };
        let m = u64::from((p >> 4) & 0xF) + 1;
        let n = u64::from((p >> 8) & 0x7F);
        Some(input / m * n)
    }

    /// The ADC1/ADC2 kernel clock RCC_CCIPR.ADC12SEL selects (RM0440 §7.4.26: 00 none, 01
    /// PLL "P", 10 SYSCLK), Hz; `None` with no clock, or with the PLL "P" output off.
    pub fn adc12_kernel_hz(&self) -> Option<u64> {
        let ccipr = self.regs.get((CCIPR / 4) as usize).copied().unwrap_or(0);
        match (ccipr >> 28) & 3 {
            1 => {
                let p = self.pllcfgr;
                if p & (1 << 16) == 0 || self.cr & (1 << 25) == 0 {
                    return None;
                }
                // PLLPDIV (bits 31:27) if not 0, else PLLP (bit 17): /7 or /17.
                let pdiv = u64::from(p >> 27);
                let div = if pdiv >= 2 {
                    pdiv
                } else if p & (1 << 17) != 0 {
                    17
                } else {
                    7
                };
                Some(self.pll_vco_hz()? / div)
            }
            2 => self.sysclk_hz(),
            _ => None,
        }
    }

    /// HCLK changes since the last call.
    pub fn take_clock_changes(&mut self) -> Vec<ClockChange> {
        std::mem::take(&mut self.clock_changes)
    }

    /// The ready flag of system-clock source `sw` (bit of CR), if it has one.
    fn ready_bit(sw: u32) -> Option<u32> {
        match sw {
            1 => Some(10),
            2 => Some(17),
            3 => Some(25),
            _ => None,
        }
    }

    fn reset_to(&mut self, why: ResetKind) {
        // HSI16 on and ready, HSI selected (RM0440: CR reset 0x0000_0500, CFGR 0x0000_0005).
        self.cr = 0x0000_0500;
        self.icscr = 0x4000_0000;
        self.cfgr = 0x0000_0005;
        self.pllcfgr = 0x0000_1000;
        self.cier = 0;
        self.cifr = 0;
        // BDCR is in the backup domain: only a power-on resets it, and a starting LSE goes
        // on starting.
        let bdcr = self.reg(BDCR);
        let lse_ready_at = self.settle.ready_at(BDCR, 1);
        self.regs = storage_reset();
        if why != ResetKind::PowerOn {
            *self.reg_mut(BDCR) = bdcr;
        }
        // CSR keeps the reset flags of earlier resets until RMVF (they live in the
        // backup/always-on domain); LSI stops.
        let keep = self.csr & 0xFE80_0000;
        let flag = match why {
            ResetKind::PowerOn => (1 << 27) | (1 << 26),
            ResetKind::Watchdog => (1 << 29) | (1 << 26),
            ResetKind::Software => (1 << 28) | (1 << 26),
            ResetKind::Pin => 1 << 26,
        };
        self.csr = if why == ResetKind::PowerOn {
            flag
        } else {
            keep | flag
        };
        self.settle.clear();
        if let (Some(at), true) = (lse_ready_at, why != ResetKind::PowerOn) {
            self.settle.push(Settle {
                at,
                reg: BDCR,
                bit: 1,
                value: true,
            });
        }
        self.backup_writable = false;
        self.sws_at = None;
        self.resets_asserted.clear();
        self.clock_changes.clear();
    }

    /// Whether the board has a 32.768 kHz crystal on OSC32_IN/OUT (a board's property).
    pub fn set_lse_fitted(&mut self, fitted: bool) {
        self.lse_fitted = fitted;
    }

    /// PWR_CR1.DBP (the SoC passes it on after each PWR write).
    pub fn set_backup_writable(&mut self, writable: bool) {
        self.backup_writable = writable;
    }

    /// RCC_BDCR now.
    pub fn bdcr(&self) -> u32 {
        self.reg(BDCR)
    }

    /// A write set BDRST since the last call: the backup domain's models go back to reset.
    pub fn take_backup_domain_reset(&mut self) -> bool {
        core::mem::take(&mut self.backup_domain_reset)
    }

    fn write_bdcr(&mut self, w: Write, now: Cycles) {
        if !self.backup_writable {
            self.reports.push(
                "RCC.BDCR written while PWR_CR1.DBP = 0: the backup domain ignores it".into(),
            );
            return;
        }
        let old = self.reg(BDCR);
        let v = w.merge(old);
        if v & bdcr::BDRST != 0 {
            // The whole backup domain resets, BDCR with it (BDRST stays as written).
            *self.reg_mut(BDCR) = bdcr::BDRST;
            self.settle.cancel(BDCR, 1);
            self.backup_domain_reset = true;
            return;
        }
        // RM0440 RCC_BDCR.RTCSEL: "Once the RTC clock source has been selected, it cannot
        // be changed anymore unless the RTC domain is reset, or unless a failure is
        // detected on LSE (LSECSSD is set)" (the LSE's CSS is not modelled): a selection
        // holds until BDRST or a power-on, later writes of the field are ignored, silently
        // as on the silicon (embassy's clock set-up writes its mux's RTCSEL at every boot).
        let keep = if old & bdcr::RTCSEL != 0 {
            bdcr::READ_ONLY | bdcr::RTCSEL
        } else {
            bdcr::READ_ONLY
        };
        *self.reg_mut(BDCR) = (v & !keep) | (old & keep);
        let on = v & bdcr::LSEON != 0;
        if !on {
            *self.reg_mut(BDCR) &= !bdcr::LSERDY;
        }
        // Without a crystal LSERDY never sets (the board documents none on the ESC1).
        self.request(now, BDCR, 1, on && self.lse_fitted, LSE_STARTUP);
    }

    /// A system reset of kind `why` (the RCC itself resets with everything else).
    pub fn system_reset(&mut self, why: ResetKind) {
        self.reset_to(why);
    }

    /// The clock-enable bit `bit` of register `offset` is set (see
    /// `crate::names::rcc_enable`).
    pub fn enabled(&self, offset: u32, bit: u32) -> bool {
        self.regs
            .get((offset / 4) as usize)
            .is_some_and(|r| r & (1 << bit) != 0)
    }

    /// Reset bits that a write set since the last call: (register offset, bit). The SoC
    /// resets those peripherals (they stay in reset while the bit is 1).
    pub fn take_resets(&mut self) -> Vec<(u32, u32)> {
        core::mem::take(&mut self.resets_asserted)
    }

    /// The kernel clock of `usart` (RM0440 §7.4.26 RCC_CCIPR USARTxSEL/LPUART1SEL, §7.4.3
    /// CFGR PPRE1/PPRE2) in Hz, with the source's name; `None` for LSE, which the
    /// emulator does not model. PCLK is HCLK divided by its APB prescaler (USART1 is on
    /// APB2, the others on APB1); SYSCLK is the 170 MHz every model assumes.
    pub fn usart_kernel_hz(&self, usart: UsartInstance) -> (Option<u64>, &'static str) {
        let shift = match usart {
            UsartInstance::Usart1 => 0,
            UsartInstance::Usart2 => 2,
            UsartInstance::Usart3 => 4,
            UsartInstance::Uart4 => 6,
            UsartInstance::Lpuart1 => 10,
        };
        let ccipr = self.regs.get((CCIPR / 4) as usize).copied().unwrap_or(0);
        match (ccipr >> shift) & 3 {
            0 => {
                let (ppre, name) = if usart == UsartInstance::Usart1 {
                    ((self.cfgr >> 11) & 7, "PCLK2")
                } else {
                    ((self.cfgr >> 8) & 7, "PCLK1")
                };
                // 0xx: not divided; 100..111: 2, 4, 8, 16.
                let div = if ppre < 4 { 1 } else { 2u64 << (ppre - 4) };
                (Some(HCLK_HZ / div), name)
            }
            1 => (Some(HCLK_HZ), "SYSCLK"),
            2 => (Some(16_000_000), "HSI16"),
            _ => (None, "LSE"),
        }
    }

    /// The system clock is the PLL (SWS = 3).
    pub fn sysclk_is_pll(&self) -> bool {
        (self.cfgr >> 2) & 3 == 3
    }

    /// The LSI oscillator runs (the IWDG starts it itself, RM0440 §42.3.2).
    pub fn lsi_ready(&self) -> bool {
        self.csr & 0b10 != 0
    }

    /// The register a settle applies to (CR, CSR or CRRCR).
    fn reg(&self, reg: u32) -> u32 {
        match reg {
            CSR => self.csr,
            CRRCR | BDCR => self.regs.get((reg / 4) as usize).copied().unwrap_or(0),
            _ => self.cr,
        }
    }

    fn reg_mut(&mut self, reg: u32) -> &mut u32 {
        match reg {
            CSR => &mut self.csr,
            CRRCR | BDCR => match self.regs.get_mut((reg / 4) as usize) {
                Some(r) => r,
                None => &mut self.cr,
            },
            _ => &mut self.cr,
        }
    }

    fn request(&mut self, now: Cycles, reg: u32, bit: u32, value: bool, delay: Cycles) {
        let cur = self.reg(reg) & (1 << bit) != 0;
        if cur == value {
            // Already there: a pending opposite change is cancelled.
            self.settle.cancel(reg, bit);
            return;
        }
        self.settle.push(Settle {
            at: now + delay,
            reg,
            bit,
            value,
        });
    }
}

impl Peripheral for Rcc {
    /// Diagnostics since the last call.
    fn take_reports(&mut self) -> Vec<String> {
        std::mem::take(&mut self.reports)
    }

    fn read(&mut self, offset: u32, _now: Cycles) -> Option<u32> {
        Some(match offset {
            CR => self.cr,
            ICSCR => self.icscr,
            CFGR => self.cfgr,
            PLLCFGR => self.pllcfgr,
            CIER => self.cier,
            CIFR => self.cifr,
            CICR => 0,
            CSR => self.csr,
            0x24 | 0x34 | 0x44 | 0x54 | 0x64 | 0x74 | 0x84 => return None,
            o if o < 0xA0 => self.regs.get((o / 4) as usize).copied()?,
            _ => return None,
        })
    }

    fn write(&mut self, w: Write, now: Cycles) -> bool {
        match w.offset {
            CR => {
                let old = self.cr;
                // Writable: HSION(8) HSIKERON(9) HSEON(16) HSEBYP(18) CSSON(19) PLLON(24).
                let writable = (1 << 8) | (1 << 9) | (1 << 16) | (1 << 18) | (1 << 19) | (1 << 24);
                self.cr = (old & !writable) | (w.merge(old) & writable);
                let cr = self.cr;
                let on = |b: u32| cr & (1 << b) != 0;
                // No crystal is fitted on either board: HSERDY only follows a bypass clock.
                let (hsi, pll, hse) = (on(8), on(24), on(16) && on(18));
                self.request(now, CR, 10, hsi, HSI_STARTUP);
                self.request(now, CR, 25, pll, PLL_LOCK);
                self.request(now, CR, 17, hse, HSI_STARTUP);
            }
            ICSCR => self.icscr = (self.icscr & 0xFF) | (w.merge(self.icscr) & 0x7F00_0000),
            CFGR => {
                let old = self.cfgr;
                let hclk_before = self.hclk_hz();
                // SWS (bits 3:2) is read-only.
                self.cfgr = (w.merge(old) & !0xC) | (old & 0xC);
                if (self.cfgr & 3) != ((old >> 2) & 3) {
                    self.sws_at = Some(now + SWITCH);
                }
                if hpre_div(old) != hpre_div(self.cfgr) {
                    self.clock_changes.push(ClockChange {
                        at: now,
                        from_hz: hclk_before,
                        to_hz: self.hclk_hz(),
                        switch: false,
                        hpre_divides: hpre_div(self.cfgr) != 1,
                    });
                }
            }
            PLLCFGR => self.pllcfgr = w.merge(self.pllcfgr),
            CIER => self.cier = w.merge(self.cier) & 0x7FF,
            CICR => self.cifr = w.clear_w1(self.cifr),
            CSR => {
                let old = self.csr;
                let v = w.merge(old);
                // RMVF clears every reset flag.
                let mut csr = (old & !1) | (v & 1);
                if v & (1 << 23) != 0 {
                    csr &= !0xFE00_0000;
                }
                self.csr = csr;
                let lsion = csr & 1 != 0;
                self.request(now, CSR, 1, lsion, LSI_STARTUP);
            }
            BDCR => self.write_bdcr(w, now),
            CRRCR => {
                let Some(r) = self.regs.get_mut((CRRCR / 4) as usize) else {
                    return false;
                };
                // HSI48ON is writable, HSI48RDY and HSI48CAL are read-only.
                *r = (*r & !1) | (w.merge(*r) & 1);
                let on = *r & 1 != 0;
                self.request(now, CRRCR, 1, on, HSI48_STARTUP);
            }
            o if o < 0xA0 && !matches!(o, 0x24 | 0x34 | 0x44 | 0x54 | 0x64 | 0x74 | 0x84) => {
                let Some(slot) = self.regs.get_mut((o / 4) as usize) else {
                    return false;
                };
                let old = *slot;
                *slot = w.merge(old);
                let set = *slot & !old;
                // RSTR registers: AHB1 0x28, AHB2 0x2C, AHB3 0x30, APB1 0x38/0x3C, APB2 0x40.
                if matches!(o, 0x28 | 0x2C | 0x30 | 0x38 | 0x3C | 0x40) && set != 0 {
                    for bit in 0..32 {
                        if set & (1 << bit) != 0 {
                            self.resets_asserted.push((o, bit));
                        }
                    }
                }
            }
            _ => return false,
        }
        true
    }

    fn next_event(&self) -> Option<Cycles> {
        match (self.settle.next(), self.sws_at) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        }
    }

    fn advance(&mut self, now: Cycles) {
        for s in self.settle.take_due(now) {
            let reg = self.reg_mut(s.reg);
            if s.value {
                *reg |= 1 << s.bit;
            } else {
                *reg &= !(1 << s.bit);
            }
        }
        if let Some(t) = self.sws_at.filter(|t| *t <= now) {
            self.sws_at = None;
            let sw = self.cfgr & 3;
            let ready = Rcc::ready_bit(sw).is_some_and(|b| self.cr & (1 << b) != 0);
            if ready {
                let before = self.hclk_hz();
                self.cfgr = (self.cfgr & !0xC) | (sw << 2);
                self.clock_changes.push(ClockChange {
                    at: t,
                    from_hz: before,
                    to_hz: self.hclk_hz(),
                    switch: true,
                    hpre_divides: hpre_div(self.cfgr) != 1,
                });
            } else if let Some(at) = Rcc::ready_bit(sw).and_then(|b| self.settle.ready_at(CR, b)) {
                // The source becomes ready later: the switch waits for it.
                self.sws_at = Some(at.max(t) + SWITCH);
            } else {
                self.reports.push(format!(
                    "RCC_CFGR.SW = {sw:#04b} selects a source that is off or never ready: \
                     the system clock does not switch (SWS stays)"
                ));
            }
        }
    }

    fn reset(&mut self) {
        self.reset_to(ResetKind::Software);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// RM0440 RCC_BDCR.RTCSEL: once selected, the RTC's clock changes only through a
    /// backup-domain reset; a later write of 00 (embassy's clock mux at every boot) leaves
    /// the RTC on its clock.
    #[test]
    fn rtcsel_holds_its_selection_until_bdrst() {
        let mut r = Rcc::new(ResetKind::PowerOn);
        r.set_backup_writable(true);
        let lse_rtc = bdcr::LSEON | (1 << bdcr::RTCSEL_SHIFT) | bdcr::RTCEN;
        r.write(Write::word(BDCR, lse_rtc), 0);
        assert_eq!(r.bdcr() & bdcr::RTCSEL, 1 << bdcr::RTCSEL_SHIFT);
        r.write(Write::word(BDCR, bdcr::LSEON | bdcr::RTCEN), 1);
        r.write(Write::word(BDCR, lse_rtc | (2 << bdcr::RTCSEL_SHIFT)), 2);
        assert_eq!(r.bdcr() & bdcr::RTCSEL, 1 << bdcr::RTCSEL_SHIFT, "kept");
        assert_eq!(r.bdcr() & bdcr::RTCEN, bdcr::RTCEN, "RTCEN takes writes");
        r.write(Write::word(BDCR, bdcr::LSEON), 3);
        assert_eq!(
            r.bdcr() & (bdcr::RTCSEL | bdcr::RTCEN),
            1 << bdcr::RTCSEL_SHIFT
        );
        // A system reset keeps it; BDRST clears it and a new selection takes.
        r.system_reset(ResetKind::Software);
        assert_eq!(r.bdcr() & bdcr::RTCSEL, 1 << bdcr::RTCSEL_SHIFT);
        r.set_backup_writable(true);
        r.write(Write::word(BDCR, bdcr::BDRST), 4);
        r.write(Write::word(BDCR, 0), 5);
        assert_eq!(r.bdcr(), 0);
        r.write(Write::word(BDCR, 2 << bdcr::RTCSEL_SHIFT), 6);
        assert_eq!(r.bdcr() & bdcr::RTCSEL, 2 << bdcr::RTCSEL_SHIFT);
    }

    /// embassy's 170 MHz: HSI16 / 4 x 85 / 2 (PLLSRC = HSI16, PLLM = 3, PLLN = 85, PLLREN).
    const PLL_170: u32 = 2 | (3 << 4) | (85 << 8) | (1 << 24);

    #[test]
    fn sysclk_follows_the_pll_only_once_it_is_locked() {
        let mut r = Rcc::new(ResetKind::PowerOn);
        assert_eq!(r.hclk_hz(), Some(16_000_000));
        r.write(Write::word(PLLCFGR, PLL_170), 0);
        r.write(Write::word(CR, (1 << 8) | (1 << 24)), 0);
        // SW = PLL at once, before the lock: SWS waits for PLLRDY.
        r.write(Write::word(CFGR, 3), 10);
        r.advance(10 + SWITCH);
        assert_eq!((r.read(CFGR, 0).unwrap_or(0) >> 2) & 3, 1, "still HSI16");
        r.advance(PLL_LOCK + SWITCH);
        assert_eq!((r.read(CFGR, 0).unwrap_or(0) >> 2) & 3, 3);
        assert_eq!(r.sysclk_hz(), Some(170_000_000));
        let ch = r.take_clock_changes();
        assert_eq!(ch.len(), 1);
        assert!(ch[0].switch && ch[0].to_hz == Some(170_000_000) && !ch[0].hpre_divides);
        assert!(r.take_reports().is_empty());
    }

    #[test]
    fn a_switch_to_a_pll_that_is_off_never_happens_and_is_reported() {
        let mut r = Rcc::new(ResetKind::PowerOn);
        r.write(Write::word(PLLCFGR, PLL_170), 0);
        r.write(Write::word(CFGR, 3), 0);
        r.advance(1_000_000);
        assert_eq!((r.read(CFGR, 0).unwrap_or(0) >> 2) & 3, 1);
        assert_eq!(r.take_reports().len(), 1);
        assert!(r.take_clock_changes().is_empty());
    }

    #[test]
    fn hpre_and_the_adc_kernel_clock() {
        let mut r = Rcc::new(ResetKind::PowerOn);
        // HPRE = 1000: /2.
        r.write(Write::word(CFGR, (0b1000 << 4) | 1), 0);
        assert_eq!(r.hclk_hz(), Some(8_000_000));
        let ch = r.take_clock_changes();
        assert_eq!(ch.len(), 1);
        assert!(!ch[0].switch && ch[0].hpre_divides);
        assert_eq!(ch[0].from_hz, Some(16_000_000));
        // ADC12SEL: reset 00 = no clock; 10 = SYSCLK; 01 = PLL P with PLLPEN.
        assert_eq!(r.adc12_kernel_hz(), None);
        r.write(Write::word(CCIPR, 0b10 << 28), 0);
        assert_eq!(r.adc12_kernel_hz(), Some(16_000_000));
        r.write(Write::word(CCIPR, 0b01 << 28), 0);
        r.write(Write::word(PLLCFGR, PLL_170 | (1 << 16)), 0);
        assert_eq!(r.adc12_kernel_hz(), None, "PLL not running");
        r.write(Write::word(CR, (1 << 8) | (1 << 24)), 0);
        r.advance(PLL_LOCK);
        // VCO 340 MHz / 7 (PLLP = 0, PLLPDIV = 0).
        assert_eq!(r.adc12_kernel_hz(), Some(340_000_000 / 7));
    }

    fn settle(r: &mut Rcc, now: Cycles) {
        r.advance(now);
    }

    #[test]
    fn usart_kernel_clocks_follow_ccipr_and_the_apb_prescalers() {
        let mut r = Rcc::new(ResetKind::PowerOn);
        // Reset: every U(S)ART on its PCLK, prescalers 1.
        for u in [UsartInstance::Usart1, UsartInstance::Lpuart1] {
            assert_eq!(r.usart_kernel_hz(u).0, Some(HCLK_HZ));
        }
        // PPRE1 = 100 (/2), PPRE2 = 101 (/4); SW = PLL kept.
        r.write(Write::word(CFGR, (0b101 << 11) | (0b100 << 8) | 3), 0);
        assert_eq!(
            r.usart_kernel_hz(UsartInstance::Lpuart1),
            (Some(85_000_000), "PCLK1")
        );
        assert_eq!(
            r.usart_kernel_hz(UsartInstance::Usart1),
            (Some(42_500_000), "PCLK2")
        );
        // LPUART1SEL (bits 11:10) = HSI16, USART1SEL = SYSCLK, USART2SEL = LSE.
        r.write(Write::word(CCIPR, (0b10 << 10) | (0b11 << 2) | 0b01), 0);
        assert_eq!(
            r.usart_kernel_hz(UsartInstance::Lpuart1),
            (Some(16_000_000), "HSI16")
        );
        assert_eq!(
            r.usart_kernel_hz(UsartInstance::Usart1),
            (Some(HCLK_HZ), "SYSCLK")
        );
        assert_eq!(r.usart_kernel_hz(UsartInstance::Usart2), (None, "LSE"));
    }

    #[test]
    fn pll_ready_follows_pllon_after_the_lock_time() {
        let mut r = Rcc::new(ResetKind::PowerOn);
        assert_eq!(r.read(CR, 0), Some(0x500), "HSI on and ready out of reset");
        r.write(Write::word(CR, 0x500 | (1 << 24)), 1000);
        settle(&mut r, 1000 + PLL_LOCK - 1);
        assert_eq!(r.read(CR, 0).unwrap_or(0) & (1 << 25), 0, "not locked yet");
        assert_eq!(r.next_event(), Some(1000 + PLL_LOCK));
        settle(&mut r, 1000 + PLL_LOCK);
        assert_ne!(r.read(CR, 0).unwrap_or(0) & (1 << 25), 0);
        // PLLRDY is read-only.
        r.write(Write::word(CR, 0x500 | (1 << 24) | (1 << 25)), 5);
    }

    #[test]
    fn sws_follows_sw() {
        let mut r = Rcc::new(ResetKind::PowerOn);
        // A locked PLL first: SWS follows SW only to a ready source.
        r.write(Write::word(CR, 0x500 | (1 << 24)), 0);
        settle(&mut r, PLL_LOCK);
        let t = PLL_LOCK;
        r.write(Write::word(CFGR, 0x3), t + 100);
        assert_eq!(r.read(CFGR, t + 100).unwrap_or(0) & 0xC, 0x4, "still HSI");
        settle(&mut r, t + 100 + SWITCH);
        assert_eq!(r.read(CFGR, 0).unwrap_or(0) & 0xC, 0xC);
        assert!(r.sysclk_is_pll());
    }

    #[test]
    fn lsi_ready_after_start_up_and_reset_flags() {
        let mut r = Rcc::new(ResetKind::PowerOn);
        let csr = r.read(CSR, 0).unwrap_or(0);
        assert_eq!(
            csr & (3 << 26),
            3 << 26,
            "BORRSTF and PINRSTF after power-on"
        );
        r.write(Write::word(CSR, csr | 1), 0);
        settle(&mut r, LSI_STARTUP - 1);
        assert!(!r.lsi_ready());
        settle(&mut r, LSI_STARTUP);
        assert!(r.lsi_ready());
        // RMVF clears the flags; a watchdog reset sets IWDGRSTF (and PINRSTF).
        r.write(Write::word(CSR, 1 << 23), 0);
        assert_eq!(r.read(CSR, 0).unwrap_or(0) & 0xFE00_0000, 0);
        r.system_reset(ResetKind::Watchdog);
        let csr = r.read(CSR, 0).unwrap_or(0);
        assert_ne!(csr & (1 << 29), 0);
        assert_eq!(csr & (1 << 27), 0);
        assert!(!r.lsi_ready(), "LSI stops at reset");
    }

    #[test]
    fn hsi48_ready_follows_its_enable() {
        let mut r = Rcc::new(ResetKind::PowerOn);
        r.write(Write::word(CRRCR, 1), 0);
        settle(&mut r, HSI48_STARTUP - 1);
        assert_eq!(r.read(CRRCR, 0).unwrap_or(0) & 2, 0);
        settle(&mut r, HSI48_STARTUP);
        assert_eq!(r.read(CRRCR, 0).unwrap_or(0) & 2, 2);
    }

    #[test]
    fn enable_bits_and_reset_requests() {
        let mut r = Rcc::new(ResetKind::PowerOn);
        assert!(!r.enabled(0x60, 11));
        r.write(Write::word(0x60, 1 << 11), 0);
        assert!(r.enabled(0x60, 11));
        r.write(Write::word(0x40, 1 << 11), 0);
        r.write(Write::word(0x40, 0), 0);
        assert_eq!(r.take_resets(), vec![(0x40, 11)]);
        assert!(r.take_resets().is_empty());
    }
}
