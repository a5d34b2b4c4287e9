//! ADC1 and ADC2 with their common registers (ADC12_COMMON), RM0440 §21 "Analog-to-digital
//! converters (ADC)".
//!
//! One [`Adc12`] model covers the whole ADC12 page: ADC1 at offset 0x000, ADC2 at 0x100, the
//! common registers at 0x300 (the SoC maps it at ADC1's base, 0x5000_0000, 0x400 bytes).
//!
//! What the images do (embassy-stm32 0.6 `adc/g4.rs`, `adc/mod.rs`): `Adc::new` clears
//! DEEPPWD and sets ADVREGEN, waits 20 µs, calibrates single-ended then differential (ADCAL,
//! polling it), waits 20 µs, enables (ADRDY cleared by writing it, ADEN, polling ADRDY). The
//! PLC then does regular `blocking_read`s at 10 bits (SMPR/SQR1 with ADSTART, polling EOS,
//! reading DR); the drive arms injected sequences (JSQR with JEXTSEL = TIM1_TRGO2, JEXTEN =
//! rising, JADSTART) and reads JDR1..4 in the PWM interrupt.
//!
//! Timing, all from the ADC clock (CKMODE = 00: the kernel clock, PLL P = 42.5 MHz, divided by
//! PRESC; CKMODE = 01/10/11: HCLK/1, /2, /4):
//! * the voltage regulator needs tADCVREG_STUP = 20 µs after ADVREGEN; ADEN before that is
//!   refused (ADRDY never comes) and ADCAL before that yields an invalid calibration; both are
//!   reported;
//! * calibration takes tCAL = 112 ADC clocks (the HAL's "maximum delay is 112/fADC"), and ADEN
//!   is refused for 4 ADC clocks after it (LL_ADC_DELAY_CALIB_ENABLE_ADC_CYCLES);
//! * ADRDY comes 15 ADC clocks after ADEN (tSTAB, "1 conversion cycle");
//! * a conversion takes the channel's sampling time (SMPRx, 2.5..640.5 clocks, SMPPLUS) plus
//!   12.5/10.5/8.5/6.5 clocks for 12/10/8/6 bits; the input is sampled at the end of the
//!   sampling phase; ranks follow each other without gap; a software start begins at the next
//!   ADC clock edge, a hardware trigger 2 ADC clocks later (trigger resynchronisation; RM0440's
//!   latency figures were not at hand, see `docs/models.md`).
//!
//! Analog values come from the SoC through [`AnalogSource`]: the volts on (ADC, channel) at the
//! end of the sampling phase, converted with VREF+ = 3.3 V as `round(v / 3.3 * 4095)` clamped
//! to 0..4095, then shifted right to the resolution.

use crate::names;
use crate::periph::reports::Reports;
use crate::periph::{DmaRequests, IrqLines, Peripheral, Write};
use crate::time::{cycles_for, Cycles, HCLK_HZ};

/// VREF+ of both boards.
pub const VREF_VOLTS: f64 = 3.3;

/// JEXTSEL code of TIM1_TRGO2 for ADC1 and ADC2 (embassy's generated `triggers` table,
/// RM0440 "ADC1/2 - External triggers for injected channels").
pub const JEXTSEL_TIM1_TRGO2: u8 = 8;
/// EXTSEL code of TIM1_TRGO2 for ADC1/ADC2 regular conversions.
pub const EXTSEL_TIM1_TRGO2: u8 = 10;

/// Which converter.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum AdcId {
    Adc1,
    Adc2,
}

/// The analog world as the ADC sees it.
pub trait AnalogSource {
    /// Volts on `channel` (the ADC's INx number, 0..=18; the internal channels included:
    /// ADC1 IN13 = OPAMP1, IN16 = temperature, IN17 = VBAT/3, IN18 = VREFINT; ADC2 IN16 =
    /// OPAMP2, IN18 = OPAMP3) of `adc`, at cycle `at` (the end of the sampling phase).
    fn volts(&mut self, adc: AdcId, channel: u8, at: Cycles) -> f64;
}

/// A source that reads 0 V everywhere (used when the SoC gives none; reported).
struct Ground;

impl AnalogSource for Ground {
    fn volts(&mut self, _adc: AdcId, _channel: u8, _at: Cycles) -> f64 {
        0.0
    }
}

/// Timer signals that can trigger ADC1/ADC2 conversions, for [`Adc12::trigger_signal`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TriggerSignal {
    Tim1Trgo,
    Tim1Trgo2,
    Tim1Cc1,
    Tim1Cc2,
    Tim1Cc3,
    Tim1Cc4,
    Tim3Trgo,
    Tim4Trgo,
    Tim4Cc4,
}

impl TriggerSignal {
    /// (EXTSEL, JEXTSEL) codes of the signal on ADC1/ADC2 (the same for both; embassy's
    /// generated trigger table, from the STM32 metadata).
    pub fn codes(self) -> (Option<u8>, Option<u8>) {
        match self {
            TriggerSignal::Tim1Cc1 => (Some(0), None),
            TriggerSignal::Tim1Cc2 => (Some(1), None),
            TriggerSignal::Tim1Cc3 => (Some(2), None),
            TriggerSignal::Tim1Cc4 => (None, Some(1)),
            TriggerSignal::Tim3Trgo => (Some(4), Some(12)),
            TriggerSignal::Tim4Cc4 => (Some(5), None),
            TriggerSignal::Tim1Trgo => (Some(9), Some(0)),
            TriggerSignal::Tim1Trgo2 => (Some(EXTSEL_TIM1_TRGO2), Some(JEXTSEL_TIM1_TRGO2)),
            TriggerSignal::Tim4Trgo => (Some(12), Some(5)),
        }
    }
}

/// CR bits.
mod cr {
    pub const ADEN: u32 = 1 << 0;
    pub const ADDIS: u32 = 1 << 1;
    pub const ADSTART: u32 = 1 << 2;
    pub const JADSTART: u32 = 1 << 3;
    pub const ADSTP: u32 = 1 << 4;
    pub const JADSTP: u32 = 1 << 5;
    pub const ADVREGEN: u32 = 1 << 28;
    pub const DEEPPWD: u32 = 1 << 29;
    pub const ADCALDIF: u32 = 1 << 30;
    pub const ADCAL: u32 = 1 << 31;
    /// The bits software sets and hardware clears.
    pub const CMD: u32 = ADEN | ADDIS | ADSTART | JADSTART | ADSTP | JADSTP | ADCAL;
}

/// ISR bits.
mod isr {
    pub const ADRDY: u32 = 1 << 0;
    pub const EOSMP: u32 = 1 << 1;
    pub const EOC: u32 = 1 << 2;
    pub const EOS: u32 = 1 << 3;
    pub const OVR: u32 = 1 << 4;
    pub const JEOC: u32 = 1 << 5;
    pub const JEOS: u32 = 1 << 6;
    pub const MASK: u32 = 0x7ff;
}

/// CFGR bits.
mod cfgr {
    pub const DMAEN: u32 = 1 << 0;
    pub const RES_SHIFT: u32 = 3;
    pub const EXTSEL_SHIFT: u32 = 5;
    pub const EXTEN_SHIFT: u32 = 10;
    pub const OVRMOD: u32 = 1 << 12;
    pub const CONT: u32 = 1 << 13;
    pub const ALIGN: u32 = 1 << 15;
    pub const DISCEN: u32 = 1 << 16;
    pub const JDISCEN: u32 = 1 << 20;
    pub const JAUTO: u32 = 1 << 25;
    pub const JQDIS: u32 = 1 << 31;
    /// Bits that may change only while JADSTART = 0 (the others need ADSTART = 0).
    pub const INJECTED: u32 = JDISCEN | (1 << 21) | (1 << 24) | JAUTO | JQDIS;
    pub const AWD: u32 = (1 << 23) | (1 << 24);
    pub const MASK: u32 = 0xffff_fffb;
}

/// Sampling time per SMP code, in half ADC clocks.
const SMP_HALF: [u64; 8] = [5, 13, 25, 49, 95, 185, 495, 1281];
/// Successive-approximation time per RES code (12, 10, 8, 6 bits), in half ADC clocks.
const SAR_HALF: [u64; 4] = [25, 21, 17, 13];
/// tCAL in ADC clocks.
const CAL_CLOCKS: u64 = 112;
/// ADEN refused for this many ADC clocks after a calibration ends.
const CAL_TO_EN_CLOCKS: u64 = 4;
/// ADEN to ADRDY (tSTAB) in ADC clocks.
const STAB_CLOCKS: u64 = 15;
/// ADDIS, ADSTP, JADSTP take effect after this many ADC clocks.
const STOP_CLOCKS: u64 = 4;
/// Hardware trigger to start of sampling, in ADC clocks (before alignment to a clock edge).
const TRIGGER_LATENCY_CLOCKS: u64 = 2;
/// Calibration factor the model reports after a calibration (any plausible value).
const CALFACT: u32 = 0x40;

/// One conversion in progress.
#[derive(Debug, Clone, Copy)]
struct Conv {
    injected: bool,
    rank: usize,
    channel: u8,
    sample_end: Cycles,
    end: Cycles,
    value: Option<u16>,
}

/// One converter's registers and state.
#[derive(Debug, Clone)]
struct Unit {
    id: AdcId,
    isr: u32,
    ier: u32,
    cr: u32,
    cfgr: u32,
    cfgr2: u32,
    smpr1: u32,
    smpr2: u32,
    tr: [u32; 3],
    sqr: [u32; 4],
    dr: u32,
    jsqr: u32,
    ofr: [u32; 4],
    jdr: [u32; 4],
    awd2cr: u32,
    awd3cr: u32,
    difsel: u32,
    calfact: u32,
    gcomp: u32,
    regulator_ready: Option<Cycles>,
    cal_end: Option<Cycles>,
    cal_invalid: bool,
    cal_single_ok: bool,
    cal_done_at: Option<Cycles>,
    ready_at: Option<Cycles>,
    ready: bool,
    disable_at: Option<Cycles>,
    reg_stop_at: Option<Cycles>,
    inj_stop_at: Option<Cycles>,
    reg: Option<Conv>,
    inj: Option<Conv>,
    /// A regular conversion interrupted by an injected sequence, to restart afterwards.
    reg_resume: Option<usize>,
    /// The injected sequence in force (JSQR latched when the sequence started).
    inj_seq: u32,
}

impl Unit {
    fn new(id: AdcId) -> Self {
        Unit {
            id,
            isr: 0,
            ier: 0,
            cr: cr::DEEPPWD,
            cfgr: cfgr::JQDIS,
            cfgr2: 0,
            smpr1: 0,
            smpr2: 0,
            tr: [0x0fff_0000, 0x00ff_0000, 0x00ff_0000],
            sqr: [0; 4],
            dr: 0,
            jsqr: 0,
            ofr: [0; 4],
            jdr: [0; 4],
            awd2cr: 0,
            awd3cr: 0,
            difsel: 0,
            calfact: 0,
            gcomp: 0,
            regulator_ready: None,
            cal_end: None,
            cal_invalid: false,
            cal_single_ok: false,
            cal_done_at: None,
            ready_at: None,
            ready: false,
            disable_at: None,
            reg_stop_at: None,
            inj_stop_at: None,
            reg: None,
            inj: None,
            reg_resume: None,
            inj_seq: 0,
        }
    }

    fn name(&self) -> &'static str {
        match self.id {
            AdcId::Adc1 => "ADC1",
            AdcId::Adc2 => "ADC2",
        }
    }

    fn enabled(&self) -> bool {
        self.cr & cr::ADEN != 0
    }

    fn res(&self) -> usize {
        ((self.cfgr >> cfgr::RES_SHIFT) & 3) as usize
    }

    /// The sampling time of `channel` in half ADC clocks.
    fn smp_half(&self, channel: u8) -> u64 {
        let code = if channel < 10 {
            (self.smpr1 >> (3 * u32::from(channel))) & 7
        } else {
            (self.smpr2 >> (3 * u32::from(channel.saturating_sub(10)).min(9))) & 7
        };
        if code == 0 && self.smpr1 & (1 << 31) != 0 {
            7 // SMPPLUS: 2.5 -> 3.5 clocks
        } else {
            SMP_HALF[code as usize & 7]
        }
    }

    fn regular_len(&self) -> usize {
        (self.sqr[0] & 0xf) as usize + 1
    }

    fn regular_channel(&self, rank: usize) -> u8 {
        let (reg, pos) = match rank {
            0..=3 => (0, 6 + 6 * rank),
            4..=8 => (1, 6 * (rank - 4)),
            9..=13 => (2, 6 * (rank - 9)),
            _ => (3, 6 * (rank.saturating_sub(14)).min(1)),
        };
        ((self.sqr[reg] >> pos) & 0x1f) as u8
    }

    fn injected_len(&self) -> usize {
        (self.inj_seq & 3) as usize + 1
    }

    fn injected_channel(&self, rank: usize) -> u8 {
        let pos = [9, 15, 21, 27][rank & 3];
        ((self.inj_seq >> pos) & 0x1f) as u8
    }

    /// Conversion result of `volts` at the present resolution and alignment.
    fn code(&self, volts: f64) -> u16 {
        let v = if volts.is_finite() { volts } else { 0.0 };
        let c12 = (v / VREF_VOLTS * 4095.0).round().clamp(0.0, 4095.0) as u16;
        let res = self.res();
        let c = c12 >> (2 * res);
        if self.cfgr & cfgr::ALIGN != 0 {
            if res == 3 {
                c << 2
            } else {
                c << (4 + 2 * res)
            }
        } else {
            c
        }
    }
}

/// ADC1, ADC2 and their common registers.
pub struct Adc12 {
    units: [Unit; 2],
    ccr: u32,
    /// The asynchronous kernel clock (RCC ADC12SEL), Hz.
    kernel_hz: u64,
    irq: Option<u16>,
    dma: [Option<u8>; 2],
    last: Cycles,
    source: Option<Box<dyn AnalogSource>>,
    reports: Reports,
}

impl std::fmt::Debug for Adc12 {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Adc12")
            .field("units", &self.units)
            .field("ccr", &self.ccr)
            .field("kernel_hz", &self.kernel_hz)
            .field("last", &self.last)
            .finish_non_exhaustive()
    }
}

impl Default for Adc12 {
    fn default() -> Self {
        Self::new()
    }
}

impl Adc12 {
    /// Both converters in their reset state, the kernel clock at the images' PLL P (42.5 MHz).
    pub fn new() -> Self {
        Adc12 {
            units: [Unit::new(AdcId::Adc1), Unit::new(AdcId::Adc2)],
            ccr: 0,
            kernel_hz: 42_500_000,
            irq: names::irq("ADC1_2"),
            dma: [
                names::dma_request("ADC1", "ADC1"),
                names::dma_request("ADC2", "ADC2"),
            ],
            last: 0,
            source: None,
            reports: Reports::new("ADC12"),
        }
    }

    /// The asynchronous kernel clock (RCC_CCIPR ADC12SEL), when the SoC's RCC says otherwise.
    pub fn set_kernel_clock_hz(&mut self, hz: u64) {
        self.kernel_hz = hz.max(1);
    }

    /// The source [`Peripheral::advance`] samples from (without one it reads 0 V and
    /// reports it). [`Adc12::advance_with`] takes one per call instead.
    pub fn set_source(&mut self, source: Box<dyn AnalogSource>) {
        self.source = Some(source);
    }

    /// CCR.VREFEN, VSENSEEN, VBATEN: whether the internal channels are connected.
    pub fn internal_paths(&self) -> (bool, bool, bool) {
        (
            self.ccr & (1 << 22) != 0,
            self.ccr & (1 << 23) != 0,
            self.ccr & (1 << 24) != 0,
        )
    }

    fn unit(&self, id: AdcId) -> &Unit {
        match id {
            AdcId::Adc1 => &self.units[0],
            AdcId::Adc2 => &self.units[1],
        }
    }

    /// JDRx (x = 1..=4) of `adc`, for tests and tracing.
    pub fn jdr(&self, adc: AdcId, x: usize) -> u16 {
        self.unit(adc)
            .jdr
            .get(x.wrapping_sub(1))
            .map_or(0, |v| *v as u16)
    }

    /// Clock period as a rational number of CPU cycles: (num, den).
    fn clock(&self) -> (u128, u128) {
        match (self.ccr >> 16) & 3 {
            0 => {
                let presc: u128 = match (self.ccr >> 18) & 0xf {
                    0 => 1,
                    1 => 2,
                    2 => 4,
                    3 => 6,
                    4 => 8,
                    5 => 10,
                    6 => 12,
                    7 => 16,
                    8 => 32,
                    9 => 64,
                    10 => 128,
                    _ => 256,
                };
                (u128::from(HCLK_HZ) * presc, u128::from(self.kernel_hz))
            }
            1 => (1, 1),
            2 => (2, 1),
            _ => (4, 1),
        }
    }

    /// `t` plus `half` half ADC clocks, rounded up to a cycle.
    fn after_half(&self, t: Cycles, half: u64) -> Cycles {
        let (num, den) = self.clock();
        let d = (u128::from(half) * num).div_ceil(2 * den);
        t.saturating_add(d.min(u128::from(u64::MAX)) as u64)
    }

    fn after_clocks(&self, t: Cycles, clocks: u64) -> Cycles {
        self.after_half(t, 2 * clocks)
    }

    /// The first ADC clock edge at or after `t`.
    fn edge_at_or_after(&self, t: Cycles) -> Cycles {
        let (num, den) = self.clock();
        let k = (u128::from(t) * den).div_ceil(num);
        ((k * num).div_ceil(den)).min(u128::from(u64::MAX)) as u64
    }

    /// The trigger `signal` changed to `level` at `at` (≥ the last advance): starts the
    /// regular or injected sequence of each converter armed on it with a matching edge.
    pub fn trigger_signal(&mut self, signal: TriggerSignal, level: bool, at: Cycles) {
        let (ext, jext) = signal.codes();
        for k in 0..2 {
            let u = &self.units[k];
            let edge_ok = |exten: u32| match exten {
                1 => level,
                2 => !level,
                3 => true,
                _ => false,
            };
            let jexten = (u.jsqr >> 7) & 3;
            let jextsel = ((u.jsqr >> 2) & 0x1f) as u8;
            let inj = u.cr & cr::JADSTART != 0 && Some(jextsel) == jext && edge_ok(jexten);
            let exten = (u.cfgr >> cfgr::EXTEN_SHIFT) & 3;
            let extsel = ((u.cfgr >> cfgr::EXTSEL_SHIFT) & 0x1f) as u8;
            let reg = u.cr & cr::ADSTART != 0 && Some(extsel) == ext && edge_ok(exten);
            if inj {
                self.start_injected(k, at, true);
            }
            if reg {
                self.start_regular(k, at, true);
            }
        }
    }

    /// An injected-trigger edge for `adc` at `at`, already matched against JEXTSEL/JEXTEN by
    /// the SoC (what [`Self::trigger_signal`] does for the signals it knows).
    pub fn trigger_injected(&mut self, adc: AdcId, at: Cycles) {
        let k = match adc {
            AdcId::Adc1 => 0,
            AdcId::Adc2 => 1,
        };
        if self.units[k].cr & cr::JADSTART != 0 {
            self.start_injected(k, at, true);
        }
    }

    fn first_sample(&self, k: usize, start: Cycles, injected: bool, rank: usize) -> Conv {
        let u = &self.units[k];
        let channel = if injected {
            u.injected_channel(rank)
        } else {
            u.regular_channel(rank)
        };
        let sample_end = self.after_half(start, u.smp_half(channel));
        let end = self.after_half(sample_end, SAR_HALF[u.res()]);
        Conv {
            injected,
            rank,
            channel,
            sample_end,
            end,
            value: None,
        }
    }

    fn start_injected(&mut self, k: usize, at: Cycles, hardware: bool) {
        let now = at.max(self.last);
        if self.units[k].inj.is_some() {
            let name = self.units[k].name();
            self.reports.once(now, "inj-overlap", || {
                format!("{name}: injected trigger during an injected sequence (ignored)")
            });
            return;
        }
        if !self.units[k].ready {
            return;
        }
        let start = if hardware {
            self.edge_at_or_after(self.after_clocks(now, TRIGGER_LATENCY_CLOCKS))
        } else {
            self.edge_at_or_after(now)
        };
        // An injected sequence interrupts a regular conversion (restarted afterwards).
        if let Some(r) = self.units[k].reg.take() {
            self.units[k].reg_resume = Some(r.rank);
        }
        self.units[k].inj_seq = self.units[k].jsqr;
        let c = self.first_sample(k, start, true, 0);
        self.units[k].inj = Some(c);
    }

    fn start_regular(&mut self, k: usize, at: Cycles, hardware: bool) {
        let now = at.max(self.last);
        if self.units[k].reg.is_some() || self.units[k].reg_resume.is_some() {
            return;
        }
        if !self.units[k].ready {
            return;
        }
        let start = if hardware {
            self.edge_at_or_after(self.after_clocks(now, TRIGGER_LATENCY_CLOCKS))
        } else {
            self.edge_at_or_after(now)
        };
        if self.units[k].inj.is_some() {
            self.units[k].reg_resume = Some(0);
            return;
        }
        let c = self.first_sample(k, start, false, 0);
        self.units[k].reg = Some(c);
    }

    fn unit_next(u: &Unit) -> Option<Cycles> {
        let conv = |c: &Option<Conv>| {
            c.map(|c| {
                if c.value.is_none() {
                    c.sample_end
                } else {
                    c.end
                }
            })
        };
        [
            u.cal_end,
            u.ready_at,
            u.disable_at,
            u.reg_stop_at,
            u.inj_stop_at,
            conv(&u.reg),
            conv(&u.inj),
        ]
        .into_iter()
        .flatten()
        .min()
    }

    /// Brings both converters to `now`, sampling from `src`.
    pub fn advance_with(&mut self, now: Cycles, src: &mut dyn AnalogSource) {
        loop {
            let next = [
                Self::unit_next(&self.units[0]),
                Self::unit_next(&self.units[1]),
            ];
            let Some((k, t)) = next
                .iter()
                .enumerate()
                .filter_map(|(k, t)| t.map(|t| (k, t)))
                .min_by_key(|(_, t)| *t)
            else {
                break;
            };
            if t > now {
                break;
            }
            self.last = self.last.max(t);
            self.step_unit(k, t, src);
        }
        self.last = self.last.max(now);
    }

    fn step_unit(&mut self, k: usize, t: Cycles, src: &mut dyn AnalogSource) {
        let u = &mut self.units[k];
        if u.cal_end == Some(t) {
            u.cal_end = None;
            u.cr &= !cr::ADCAL;
            u.cal_done_at = Some(t);
            let diff = u.cr & cr::ADCALDIF != 0;
            if diff {
                u.calfact = (u.calfact & 0x7f) | (CALFACT << 16);
            } else {
                u.calfact = (u.calfact & (0x7f << 16)) | CALFACT;
                u.cal_single_ok = !u.cal_invalid;
            }
            return;
        }
        if u.ready_at == Some(t) {
            u.ready_at = None;
            u.ready = true;
            u.isr |= isr::ADRDY;
            return;
        }
        if u.disable_at == Some(t) {
            u.disable_at = None;
            u.cr &= !(cr::ADEN | cr::ADDIS);
            u.ready = false;
            return;
        }
        if u.reg_stop_at == Some(t) {
            u.reg_stop_at = None;
            u.reg = None;
            u.reg_resume = None;
            u.cr &= !(cr::ADSTART | cr::ADSTP);
            return;
        }
        if u.inj_stop_at == Some(t) {
            u.inj_stop_at = None;
            u.inj = None;
            u.cr &= !(cr::JADSTART | cr::JADSTP);
            self.resume_regular(k, t);
            return;
        }
        for injected in [true, false] {
            let slot = if injected { u.inj } else { u.reg };
            let Some(mut c) = slot else { continue };
            if c.value.is_none() && c.sample_end == t {
                let v = src.volts(u.id, c.channel, t);
                c.value = Some(u.code(v));
                if !injected {
                    u.isr |= isr::EOSMP;
                }
                if injected {
                    u.inj = Some(c);
                } else {
                    u.reg = Some(c);
                }
                return;
            }
            if c.value.is_some() && c.end == t {
                self.finish(k, c, t);
                return;
            }
        }
    }

    fn finish(&mut self, k: usize, c: Conv, t: Cycles) {
        let value = u32::from(c.value.unwrap_or(0));
        if !self.units[k].cal_single_ok {
            let name = self.units[k].name();
            self.reports.once(t, "uncalibrated", || {
                format!("{name}: conversion without a valid single-ended calibration")
            });
        }
        let u = &mut self.units[k];
        if c.injected {
            if let Some(j) = u.jdr.get_mut(c.rank) {
                *j = value;
            }
            u.isr |= isr::JEOC;
            let last = c.rank + 1 >= u.injected_len();
            if last {
                u.inj = None;
                u.isr |= isr::JEOS;
                if (u.jsqr >> 7) & 3 == 0 {
                    u.cr &= !cr::JADSTART;
                }
                self.resume_regular(k, t);
            } else {
                let next = self.first_sample(k, t, true, c.rank + 1);
                self.units[k].inj = Some(next);
            }
            return;
        }
        if u.isr & isr::EOC != 0 {
            u.isr |= isr::OVR;
            if u.cfgr & cfgr::OVRMOD != 0 {
                u.dr = value;
            }
        } else {
            u.dr = value;
        }
        u.isr |= isr::EOC;
        let last = c.rank + 1 >= u.regular_len();
        if !last {
            let next = self.first_sample(k, t, false, c.rank + 1);
            self.units[k].reg = Some(next);
            return;
        }
        u.isr |= isr::EOS;
        u.reg = None;
        let software = (u.cfgr >> cfgr::EXTEN_SHIFT) & 3 == 0;
        if u.cfgr & cfgr::CONT != 0 {
            let next = self.first_sample(k, t, false, 0);
            self.units[k].reg = Some(next);
        } else if software {
            u.cr &= !cr::ADSTART;
        }
    }

    fn resume_regular(&mut self, k: usize, t: Cycles) {
        if let Some(rank) = self.units[k].reg_resume.take() {
            if self.units[k].cr & cr::ADSTART != 0 {
                let c = self.first_sample(k, t, false, rank);
                self.units[k].reg = Some(c);
            }
        }
    }

    fn write_cr(&mut self, k: usize, w: Write, now: Cycles) {
        let old = self.units[k].cr;
        let v = w.merge(old);
        let name = self.units[k].name();
        // Plain bits: DEEPPWD, ADVREGEN, ADCALDIF.
        let mut cfg = old & !(cr::DEEPPWD | cr::ADVREGEN | cr::ADCALDIF);
        cfg |= v & (cr::DEEPPWD | cr::ADCALDIF);
        let deeppwd = v & cr::DEEPPWD != 0;
        if v & cr::ADVREGEN != 0 && !deeppwd {
            cfg |= cr::ADVREGEN;
        } else if v & cr::ADVREGEN != 0 {
            self.reports.once(now, "advregen-deeppwd", || {
                format!("{name}: ADVREGEN set while DEEPPWD = 1 (ignored)")
            });
        }
        {
            let u = &mut self.units[k];
            if cfg & cr::ADVREGEN != 0 && old & cr::ADVREGEN == 0 {
                u.regulator_ready = Some(now + cycles_for(20, 1_000_000));
            }
            if cfg & cr::ADVREGEN == 0 {
                u.regulator_ready = None;
            }
            if deeppwd && old & cr::DEEPPWD == 0 {
                // Deep power-down loses the calibration.
                u.cal_single_ok = false;
                u.calfact = 0;
            }
            u.cr = (old & cr::CMD) | cfg;
        }
        let set = |bit: u32| v & bit != 0 && old & bit == 0;
        let regulator_ok = {
            let u = &self.units[k];
            u.regulator_ready.is_some_and(|r| now >= r)
        };
        if set(cr::ADCAL) {
            let u = &self.units[k];
            if u.enabled() || u.cr & cr::ADVREGEN == 0 {
                self.reports.once(now, "adcal", || {
                    format!("{name}: ADCAL set with ADEN = 1 or the regulator off (ignored)")
                });
            } else {
                if !regulator_ok {
                    self.reports.once(now, "adcal-early", || {
                        format!(
                            "{name}: ADCAL set before the regulator start-up time \
                             (tADCVREG_STUP = 20 us): the calibration is invalid"
                        )
                    });
                }
                let end = self.after_clocks(now, CAL_CLOCKS);
                let u = &mut self.units[k];
                u.cal_invalid = !regulator_ok;
                u.cr |= cr::ADCAL;
                u.cal_end = Some(end);
            }
        }
        if set(cr::ADEN) {
            let cal_guard = self.units[k]
                .cal_done_at
                .map(|t| self.after_clocks(t, CAL_TO_EN_CLOCKS));
            let u = &self.units[k];
            let busy = u.cr & (cr::CMD & !cr::ADEN) != 0;
            if busy || !regulator_ok || cal_guard.is_some_and(|g| now < g) {
                self.reports.once(now, "aden", || {
                    format!(
                        "{name}: ADEN refused (ADCAL/ADSTART/JADSTART/ADSTP/ADDIS busy, the \
                         regulator not started, or within 4 ADC clocks of the calibration's end)"
                    )
                });
            } else {
                let at = self.after_clocks(now, STAB_CLOCKS);
                let u = &mut self.units[k];
                u.cr |= cr::ADEN;
                u.ready_at = Some(at);
            }
        }
        if set(cr::ADDIS) {
            let u = &self.units[k];
            if !u.enabled() || u.cr & (cr::ADSTART | cr::JADSTART) != 0 {
                self.reports.once(now, "addis", || {
                    format!("{name}: ADDIS refused (ADC not enabled or conversions running)")
                });
            } else {
                let at = self.after_clocks(now, STOP_CLOCKS);
                let u = &mut self.units[k];
                u.cr |= cr::ADDIS;
                u.ready_at = None;
                u.disable_at = Some(at);
            }
        }
        if set(cr::ADSTART) || set(cr::JADSTART) {
            let u = &self.units[k];
            if !u.enabled() || u.cr & cr::ADDIS != 0 || !u.ready {
                self.reports.once(now, "start", || {
                    format!("{name}: ADSTART/JADSTART refused (ADC not enabled and ready)")
                });
            } else {
                if set(cr::JADSTART) {
                    let software = (self.units[k].jsqr >> 7) & 3 == 0;
                    self.units[k].cr |= cr::JADSTART;
                    if software {
                        self.start_injected(k, now, false);
                    }
                }
                if set(cr::ADSTART) {
                    let software = (self.units[k].cfgr >> cfgr::EXTEN_SHIFT) & 3 == 0;
                    self.units[k].cr |= cr::ADSTART;
                    if software {
                        self.start_regular(k, now, false);
                    }
                }
            }
        }
        if set(cr::ADSTP) && self.units[k].cr & cr::ADSTART != 0 {
            let at = self.after_clocks(now, STOP_CLOCKS);
            let u = &mut self.units[k];
            u.cr |= cr::ADSTP;
            u.reg_stop_at = Some(at);
        }
        if set(cr::JADSTP) && self.units[k].cr & cr::JADSTART != 0 {
            let at = self.after_clocks(now, STOP_CLOCKS);
            let u = &mut self.units[k];
            u.cr |= cr::JADSTP;
            u.inj_stop_at = Some(at);
        }
    }

    fn write_unit(&mut self, k: usize, w: Write, now: Cycles) -> bool {
        let name = self.units[k].name();
        let off = w.offset;
        if off == 0x08 {
            self.write_cr(k, w, now);
            return true;
        }
        let old = match self.read_unit(k, off, false) {
            Some(v) => v,
            None => return false,
        };
        let v = w.merge(old);
        let u = &self.units[k];
        let adstart = u.cr & cr::ADSTART != 0;
        let jadstart = u.cr & cr::JADSTART != 0;
        let mut refuse = |what: &'static str, kind: &'static str| {
            self.reports.once(now, kind, || {
                format!("{name}: {what} written while conversions run (ignored)")
            });
        };
        match off {
            0x00 => {
                let u = &mut self.units[k];
                u.isr = w.clear_w1(u.isr) & isr::MASK;
            }
            0x04 => self.units[k].ier = v & 0x7ff,
            0x0c => {
                let v = v & cfgr::MASK;
                let changed = v ^ old;
                if (changed & !cfgr::INJECTED != 0 && adstart)
                    || (changed & cfgr::INJECTED != 0 && jadstart)
                    || (changed & (3 << cfgr::RES_SHIFT) != 0 && (adstart || jadstart))
                {
                    refuse("CFGR", "cfgr-busy");
                } else {
                    self.units[k].cfgr = v;
                    if v & (cfgr::DISCEN | cfgr::JDISCEN | cfgr::JAUTO) != 0 {
                        self.reports.once(now, "disc", || {
                            format!("{name}: discontinuous / auto-injected modes are not modelled")
                        });
                    }
                    if v & (cfgr::AWD | (1 << 22)) != 0 {
                        self.reports.once(now, "awd", || {
                            format!("{name}: analog watchdogs are not modelled")
                        });
                    }
                    if v & cfgr::JQDIS == 0 {
                        self.reports.once(now, "jqdis", || {
                            format!("{name}: the injected context queue (JQDIS = 0) is not modelled: JSQR acts at once")
                        });
                    }
                }
            }
            0x10 => {
                self.units[k].cfgr2 = v & 0x0e01_07ff;
                if v & 0x0e01_0003 != 0 {
                    self.reports.once(now, "cfgr2", || {
                        format!("{name}: oversampling, gain compensation and bulb/trigger sampling are not modelled")
                    });
                }
            }
            0x14 | 0x18 => {
                if adstart || jadstart {
                    refuse("SMPRx", "smpr-busy");
                } else if off == 0x14 {
                    self.units[k].smpr1 = v & 0xbfff_ffff;
                } else {
                    self.units[k].smpr2 = v & 0x07ff_ffff;
                }
            }
            0x20 => self.units[k].tr[0] = v & 0x0fff_7fff,
            0x24 => self.units[k].tr[1] = v & 0x00ff_00ff,
            0x28 => self.units[k].tr[2] = v & 0x00ff_00ff,
            0x30..=0x3c => {
                if adstart {
                    refuse("SQRx", "sqr-busy");
                } else {
                    let i = ((off - 0x30) / 4) as usize;
                    let mask = [0x1f7d_f7cf, 0x1f7d_f7df, 0x1f7d_f7df, 0x0000_07df][i & 3];
                    self.units[k].sqr[i & 3] = v & mask;
                }
            }
            0x40 => {}
            0x4c => {
                if jadstart {
                    refuse("JSQR", "jsqr-busy");
                } else {
                    self.units[k].jsqr = v;
                }
            }
            0x60..=0x6c => {
                let i = ((off - 0x60) / 4) as usize;
                self.units[k].ofr[i & 3] = v & 0xff00_0fff;
                if v & (1 << 31) != 0 {
                    self.reports.once(now, "offset", || {
                        format!("{name}: data offsets (OFRy) are not modelled")
                    });
                }
            }
            0x80..=0x8c => {}
            0xa0 => self.units[k].awd2cr = v & 0x7_ffff,
            0xa4 => self.units[k].awd3cr = v & 0x7_ffff,
            0xb0 => {
                let u = &self.units[k];
                let n = v & 0x7_ffff;
                if u.enabled() {
                    if n != u.difsel {
                        self.reports.once(now, "difsel", || {
                            format!("{name}: DIFSEL written with ADEN = 1 (ignored)")
                        });
                    }
                } else {
                    self.units[k].difsel = n;
                    if n != 0 {
                        self.reports.once(now, "diff", || {
                            format!("{name}: differential inputs are not modelled (the source gives single-ended volts)")
                        });
                    }
                }
            }
            0xb4 => {
                if self.units[k].enabled() {
                    self.units[k].calfact = v & 0x007f_007f;
                }
            }
            0xc0 => self.units[k].gcomp = v & 0x3fff,
            _ => return false,
        }
        true
    }

    /// A register of unit `k`; `side_effects`: a DR read clears EOC.
    fn read_unit(&mut self, k: usize, off: u32, side_effects: bool) -> Option<u32> {
        let u = &mut self.units[k];
        Some(match off {
            0x00 => u.isr,
            0x04 => u.ier,
            0x08 => u.cr,
            0x0c => u.cfgr,
            0x10 => u.cfgr2,
            0x14 => u.smpr1,
            0x18 => u.smpr2,
            0x20 => u.tr[0],
            0x24 => u.tr[1],
            0x28 => u.tr[2],
            0x30..=0x3c => u.sqr[((off - 0x30) / 4) as usize & 3],
            0x40 => {
                if side_effects {
                    u.isr &= !isr::EOC;
                }
                u.dr
            }
            0x4c => u.jsqr,
            0x60..=0x6c => u.ofr[((off - 0x60) / 4) as usize & 3],
            0x80..=0x8c => u.jdr[((off - 0x80) / 4) as usize & 3],
            0xa0 => u.awd2cr,
            0xa4 => u.awd3cr,
            0xb0 => u.difsel,
            0xb4 => u.calfact,
            0xc0 => u.gcomp,
            _ => return None,
        })
    }
}

impl Peripheral for Adc12 {
    /// Misuse and unsupported-feature reports since the last call.
    fn take_reports(&mut self) -> Vec<String> {
        self.reports.take()
    }

    fn read(&mut self, offset: u32, _now: Cycles) -> Option<u32> {
        match offset {
            0x000..=0x0ff => self.read_unit(0, offset, true),
            0x100..=0x1ff => self.read_unit(1, offset - 0x100, true),
            0x300 => {
                Some((self.units[0].isr & isr::MASK) | ((self.units[1].isr & isr::MASK) << 16))
            }
            0x308 => Some(self.ccr),
            0x30c => Some((self.units[0].dr & 0xffff) | (self.units[1].dr & 0xffff) << 16),
            _ => None,
        }
    }

    fn write(&mut self, w: Write, now: Cycles) -> bool {
        match w.offset {
            0x000..=0x0ff => self.write_unit(0, w, now),
            0x100..=0x1ff => self.write_unit(
                1,
                Write {
                    offset: w.offset - 0x100,
                    ..w
                },
                now,
            ),
            0x300 | 0x30c => true, // read-only
            0x308 => {
                let v = w.merge(self.ccr) & 0x01ff_ef1f;
                let clock_bits = 0x003f_0000;
                let any_enabled = self.units.iter().any(|u| u.enabled());
                if any_enabled && (v ^ self.ccr) & clock_bits != 0 {
                    self.reports.once(now, "ccr-clock", || {
                        "ADC12 CCR: CKMODE/PRESC changed with an ADC enabled (ignored)".into()
                    });
                    self.ccr = (v & !clock_bits) | (self.ccr & clock_bits);
                } else {
                    self.ccr = v;
                }
                if self.ccr & 0x1f != 0 {
                    self.reports.once(now, "dual", || {
                        "ADC dual mode (DUAL != 0) is not modelled".into()
                    });
                }
                true
            }
            _ => false,
        }
    }

    fn next_event(&self) -> Option<Cycles> {
        [
            Self::unit_next(&self.units[0]),
            Self::unit_next(&self.units[1]),
        ]
        .into_iter()
        .flatten()
        .min()
    }

    fn advance(&mut self, now: Cycles) {
        let mut src = self.source.take();
        if src.is_none() && self.next_event().is_some_and(|t| t <= now) {
            let busy = self
                .units
                .iter()
                .any(|u| u.reg.is_some() || u.inj.is_some());
            if busy {
                self.reports.once(now, "no-source", || {
                    "no AnalogSource given: conversions read 0 V".into()
                });
            }
        }
        match src.as_deref_mut() {
            Some(s) => self.advance_with(now, s),
            None => self.advance_with(now, &mut Ground),
        }
        self.source = src;
    }

    fn irq_lines(&self, lines: &mut IrqLines) {
        if self.units.iter().any(|u| u.isr & u.ier & 0x7ff != 0) {
            if let Some(irq) = self.irq {
                lines.set(irq);
            }
        }
    }

    fn dma_requests(&self, requests: &mut DmaRequests) {
        for (u, id) in self.units.iter().zip(self.dma) {
            if u.cfgr & cfgr::DMAEN != 0 && u.isr & isr::EOC != 0 {
                if let Some(id) = id {
                    requests.set(id);
                }
            }
        }
    }

    fn reset(&mut self) {
        let kernel = self.kernel_hz;
        let source = self.source.take();
        *self = Adc12::new();
        self.kernel_hz = kernel;
        self.source = source;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::periph::tim_adv::{TimAdv, TimEvent};

    const ISR: u32 = 0x00;
    const IER: u32 = 0x04;
    const CR: u32 = 0x08;
    const CFGR: u32 = 0x0c;
    const SMPR1: u32 = 0x14;
    const SMPR2: u32 = 0x18;
    const SQR1: u32 = 0x30;
    const DR: u32 = 0x40;
    const JSQR: u32 = 0x4c;
    const JDR1: u32 = 0x80;
    const DIFSEL: u32 = 0xb0;
    const CCR: u32 = 0x308;

    /// Volts per (adc, channel); records every sample.
    #[derive(Default)]
    struct Probe {
        volts: Vec<((AdcId, u8), f64)>,
        samples: Vec<(AdcId, u8, Cycles)>,
    }

    impl AnalogSource for Probe {
        fn volts(&mut self, adc: AdcId, channel: u8, at: Cycles) -> f64 {
            self.samples.push((adc, channel, at));
            self.volts
                .iter()
                .find(|(k, _)| *k == (adc, channel))
                .map_or(0.0, |(_, v)| *v)
        }
    }

    /// One register access per cycle, `advance_with` before each.
    struct Bus {
        adc: Adc12,
        src: Probe,
        t: Cycles,
    }

    impl Bus {
        fn new() -> Self {
            Bus {
                adc: Adc12::new(),
                src: Probe::default(),
                t: 1000,
            }
        }

        fn sync(&mut self) {
            let t = self.t;
            self.adc.advance_with(t, &mut self.src);
        }

        fn rd(&mut self, off: u32) -> u32 {
            self.sync();
            let v = self.adc.read(off, self.t).expect("modelled register");
            self.t += 1;
            v
        }

        fn wr(&mut self, off: u32, v: u32) {
            self.sync();
            assert!(self.adc.write(Write::word(off, v), self.t));
            self.t += 1;
        }

        fn modify(&mut self, off: u32, f: impl FnOnce(u32) -> u32) {
            let v = self.rd(off);
            self.wr(off, f(v));
        }

        fn delay_us(&mut self, us: u64) {
            // embassy's block_for_us: cortex_m::asm::delay(170 * us) is 2 instructions per
            // loop iteration, 1 cycle each in the emulator.
            self.t += 2 * (170 * us + 1);
        }

        /// Polls `off` until `done(value)`; returns the cycle of the read that saw it.
        fn poll(&mut self, off: u32, done: impl Fn(u32) -> bool) -> Cycles {
            for _ in 0..1_000_000 {
                let at = self.t;
                if done(self.rd(off)) {
                    return at;
                }
            }
            panic!("stuck polling {off:#x}");
        }
    }

    const A2: u32 = 0x100;

    /// embassy-stm32 0.6 `Adc::new(ADCx, config)` for unit base `b` (0 or 0x100). Returns the
    /// cycles at which ADCAL was first set and ADEN was set.
    fn adc_new(bus: &mut Bus, b: u32, res: Option<u32>) -> (Cycles, Cycles) {
        bus.modify(CCR, |v| v & !(0xf << 18)); // PRESC = /1 (42.5 MHz)
        bus.modify(b + CR, |v| (v & !cr::DEEPPWD) | cr::ADVREGEN);
        bus.delay_us(20);
        bus.modify(b + DIFSEL, |v| v & !0x3_ffff);
        bus.modify(b + CR, |v| v & !cr::ADCALDIF);
        let cal = bus.t + 1;
        bus.modify(b + CR, |v| v | cr::ADCAL);
        bus.poll(b + CR, |v| v & cr::ADCAL == 0);
        bus.delay_us(20);
        bus.modify(b + CR, |v| v | cr::ADCALDIF);
        bus.modify(b + CR, |v| v | cr::ADCAL);
        bus.poll(b + CR, |v| v & cr::ADCAL == 0);
        bus.delay_us(20);
        // enable()
        let _ = bus.rd(b + CR);
        let _ = bus.rd(b + CR);
        bus.modify(b + ISR, |v| v | isr::ADRDY);
        let en = bus.t + 1;
        bus.modify(b + CR, |v| v | cr::ADEN);
        bus.poll(b + ISR, |v| v & isr::ADRDY != 0);
        bus.modify(b + CFGR, |v| v & !(cfgr::CONT | (3 << cfgr::EXTEN_SHIFT)));
        if let Some(r) = res {
            bus.modify(b + CFGR, |v| {
                (v & !(3 << cfgr::RES_SHIFT)) | (r << cfgr::RES_SHIFT)
            });
        }
        (cal, en)
    }

    #[test]
    fn reset_values() {
        let mut b = Bus::new();
        assert_eq!(b.rd(CR), cr::DEEPPWD);
        assert_eq!(b.rd(CFGR), cfgr::JQDIS);
        assert_eq!(b.rd(0x20), 0x0fff_0000);
        assert_eq!(b.rd(A2 + CR), cr::DEEPPWD);
        assert_eq!(b.adc.read(0x200, 0), None);
        assert_eq!(b.adc.next_event(), None);
    }

    #[test]
    fn calibration_and_enable_timing() {
        let mut b = Bus::new();
        let cal0 = b.t;
        b.modify(CR, |v| (v & !cr::DEEPPWD) | cr::ADVREGEN);
        b.delay_us(20);
        let cal = b.t + 1;
        b.modify(CR, |v| v | cr::ADCAL);
        assert!(cal >= cal0 + 3400);
        // tCAL = 112 ADC clocks of 4 cycles.
        let seen = b.poll(CR, |v| v & cr::ADCAL == 0);
        assert_eq!(
            seen,
            cal + 448,
            "ADCAL clears 112 ADC clocks after it was set"
        );
        assert_eq!(b.rd(0xb4) & 0x7f, CALFACT);
        b.delay_us(20);
        let en = b.t + 1;
        b.modify(CR, |v| v | cr::ADEN);
        assert_ne!(b.rd(CR) & cr::ADEN, 0);
        let ready = b.poll(ISR, |v| v & isr::ADRDY != 0);
        assert_eq!(ready, en + 60, "ADRDY 15 ADC clocks after ADEN");
        assert!(b.adc.take_reports().is_empty());
        // ADRDY is rc_w1.
        b.wr(ISR, 0);
        assert_ne!(b.rd(ISR) & isr::ADRDY, 0);
        b.wr(ISR, isr::ADRDY);
        assert_eq!(b.rd(ISR) & isr::ADRDY, 0);
        // ADDIS: ADEN clears a few clocks later.
        let dis = b.t;
        b.wr(CR, cr::ADVREGEN | cr::ADDIS);
        assert_ne!(b.rd(CR) & cr::ADDIS, 0);
        let off = b.poll(CR, |v| v & cr::ADEN == 0);
        assert_eq!(off, dis + 16);
        assert_eq!(b.rd(CR) & cr::ADDIS, 0);
    }

    #[test]
    fn embassy_adc_new_is_clean() {
        let mut b = Bus::new();
        let (_, en) = adc_new(&mut b, 0, None);
        assert!(en > 0);
        assert!(
            b.adc.take_reports().is_empty(),
            "embassy's sequence is by the book"
        );
    }

    #[test]
    fn adcal_before_the_regulator_is_up_is_reported_and_invalid() {
        let mut b = Bus::new();
        b.modify(CR, |v| (v & !cr::DEEPPWD) | cr::ADVREGEN);
        b.modify(CR, |v| v | cr::ADCAL); // no 20 us wait
        b.poll(CR, |v| v & cr::ADCAL == 0);
        let r = b.adc.take_reports();
        assert!(r.iter().any(|m| m.contains("tADCVREG_STUP")), "{r:?}");
        b.delay_us(20);
        b.modify(CR, |v| v | cr::ADEN);
        b.poll(ISR, |v| v & isr::ADRDY != 0);
        b.wr(SQR1, 1 << 6);
        b.modify(CR, |v| v | cr::ADSTART);
        b.poll(ISR, |v| v & isr::EOS != 0);
        let r = b.adc.take_reports();
        assert!(r.iter().any(|m| m.contains("calibration")), "{r:?}");
    }

    #[test]
    fn aden_before_the_regulator_is_refused() {
        let mut b = Bus::new();
        b.modify(CR, |v| (v & !cr::DEEPPWD) | cr::ADVREGEN);
        b.modify(CR, |v| v | cr::ADEN);
        assert_eq!(b.rd(CR) & cr::ADEN, 0);
        b.t += 100_000;
        assert_eq!(b.rd(ISR) & isr::ADRDY, 0, "ADRDY never comes");
        assert!(!b.adc.take_reports().is_empty());
    }

    /// The PLC's `blocking_read` at 10 bits, 47.5-clock sampling.
    #[test]
    fn regular_blocking_read_at_10_bits() {
        let mut b = Bus::new();
        adc_new(&mut b, 0, Some(1));
        b.src.volts.push(((AdcId::Adc1, 2), 1.234));
        for _ in 0..2 {
            // stop()
            let _ = b.rd(CR);
            b.modify(CFGR, |v| v & !(cfgr::CONT | cfgr::DMAEN));
            // configure_sequence
            b.modify(CR, |v| v & !cr::ADEN);
            b.wr(SMPR1, 4 << 6); // SMP2 = 47.5 clocks
            b.wr(SMPR2, 0);
            b.wr(SQR1, 2 << 6);
            b.wr(SQR1 + 4, 0);
            b.wr(SQR1 + 8, 0);
            b.wr(SQR1 + 12, 0);
            b.wr(DIFSEL, 0);
            // enable()
            let _ = b.rd(CR);
            assert_ne!(b.rd(CR) & cr::ADEN, 0, "writing ADEN = 0 does not disable");
            // convert()
            b.modify(ISR, |v| v | isr::EOS | isr::EOC);
            let start = b.t + 1;
            b.modify(CR, |v| v | cr::ADSTART);
            let eos = b.poll(ISR, |v| v & isr::EOS != 0);
            // Start at the next ADC clock edge (multiples of 4 cycles); 47.5 + 10.5 clocks.
            let edge = start.div_ceil(4) * 4;
            assert_eq!(eos, edge + 58 * 4);
            assert_eq!(b.rd(CR) & cr::ADSTART, 0, "ADSTART clears at EOS");
            let dr = b.rd(DR);
            assert_eq!(dr, ((1.234f64 / 3.3 * 4095.0).round() as u32) >> 2);
            assert_eq!(b.rd(ISR) & isr::EOC, 0, "reading DR clears EOC");
            let &(adc, ch, at) = b.src.samples.last().expect("sampled");
            assert_eq!(
                (adc, ch, at),
                (AdcId::Adc1, 2, edge + 190),
                "end of sampling"
            );
        }
        assert!(b.adc.take_reports().is_empty());
    }

    #[test]
    fn overrun_when_dr_is_not_read() {
        let mut b = Bus::new();
        adc_new(&mut b, 0, None);
        b.src.volts.push(((AdcId::Adc1, 1), 3.3));
        b.src.volts.push(((AdcId::Adc1, 3), 1.0));
        b.wr(SQR1, 1 | (1 << 6) | (3 << 12)); // L = 2 conversions: IN1, IN3
        b.modify(CR, |v| v | cr::ADSTART);
        b.poll(ISR, |v| v & isr::EOS != 0);
        let isr_v = b.rd(ISR);
        assert_ne!(isr_v & isr::OVR, 0);
        assert_eq!(b.rd(DR), 4095, "OVRMOD = 0 keeps the unread data");
    }

    /// The drive's `setup_injected_conversions` for ADC1 (3 ranks) on TIM1_TRGO2.
    fn setup_injected(b: &mut Bus, base: u32, chans: &[u32]) {
        // enable() (already enabled)
        let _ = b.rd(base + CR);
        let _ = b.rd(base + CR);
        b.modify(base + JSQR, |v| (v & !3) | (chans.len() as u32 - 1));
        for (n, ch) in chans.iter().enumerate() {
            let (reg, sh) = if *ch <= 9 {
                (SMPR1, 3 * ch)
            } else {
                (SMPR2, 3 * (ch - 10))
            };
            b.modify(base + reg, |v| (v & !(7 << sh)) | (2 << sh)); // 12.5 clocks
            let pos = [9, 15, 21, 27][n];
            b.modify(base + JSQR, |v| (v & !(0x1f << pos)) | (ch << pos));
        }
        b.modify(base + CFGR, |v| v & !cfgr::JDISCEN);
        b.modify(base + JSQR, |v| {
            (v & !(0x7f << 2)) | (u32::from(JEXTSEL_TIM1_TRGO2) << 2) | (1 << 7)
        });
        b.modify(base + IER, |v| v & !(1 << 6));
        b.modify(base + CR, |v| v | cr::JADSTART);
    }

    #[test]
    fn injected_sequence_on_trgo2() {
        let mut b = Bus::new();
        adc_new(&mut b, 0, None);
        adc_new(&mut b, A2, None);
        setup_injected(&mut b, 0, &[2, 1, 11]);
        setup_injected(&mut b, A2, &[4]);
        b.src.volts = vec![
            ((AdcId::Adc1, 2), 1.65),
            ((AdcId::Adc1, 1), 0.5),
            ((AdcId::Adc1, 11), 3.0),
            ((AdcId::Adc2, 4), 2.0),
        ];
        assert_ne!(b.rd(CR) & cr::JADSTART, 0);
        b.sync();
        let trig = b.t + 3;
        b.t = trig;
        b.sync();
        // A falling edge does nothing (JEXTEN = rising); a rising one starts both ADCs.
        b.adc.trigger_signal(TriggerSignal::Tim1Trgo2, false, trig);
        assert_eq!(b.adc.next_event(), None);
        b.adc.trigger_signal(TriggerSignal::Tim1Trgo2, true, trig);
        // Start: 2 ADC clocks after the trigger, at an ADC clock edge; each rank 25 clocks.
        let start = (trig + 8).div_ceil(4) * 4;
        let jeos = b.poll(ISR, |v| v & isr::JEOS != 0);
        assert_eq!(
            jeos,
            start + 3 * 100,
            "JEOS after three 25-clock conversions"
        );
        let want = |v: f64| (v / 3.3 * 4095.0).round() as u32;
        assert_eq!(b.rd(JDR1), want(1.65));
        assert_eq!(b.rd(JDR1 + 4), want(0.5));
        assert_eq!(b.rd(JDR1 + 8), want(3.0));
        assert_eq!(b.rd(A2 + JDR1), want(2.0));
        assert_ne!(
            b.rd(CR) & cr::JADSTART,
            0,
            "JADSTART stays set with a hardware trigger"
        );
        let at: Vec<Cycles> = b.src.samples.iter().map(|s| s.2).collect();
        assert!(at.contains(&(start + 50)) && at.contains(&(start + 150)));
        assert!(at.contains(&(start + 250)));
        // JEOS is rc_w1 (the driver's `isr().modify(set_jeos(true))`).
        b.modify(ISR, |v| v | isr::JEOS);
        assert_eq!(b.rd(ISR) & isr::JEOS, 0);
        assert!(b.adc.take_reports().is_empty());
    }

    /// TIM1 as the drive programs it, its TRGO2 edges forwarded to the ADCs as a SoC would:
    /// every PWM period the injected sequences run after the peak and the JDRs are fresh at
    /// the next valley.
    #[test]
    fn tim1_trgo2_drives_the_injected_sequences() {
        let mut b = Bus::new();
        adc_new(&mut b, 0, None);
        adc_new(&mut b, A2, None);
        setup_injected(&mut b, 0, &[2, 1, 11]);
        setup_injected(&mut b, A2, &[4]);
        let mut tim = TimAdv::new("TIM1");
        let mut t = b.t;
        let w = |tim: &mut TimAdv, off: u32, v: u32, t: &mut Cycles| {
            tim.advance(*t);
            assert!(tim.write(Write::word(off, v), *t));
            *t += 1;
        };
        // The essentials of power_stage::init (centre-aligned 1, ARPE, RCR 1, CH4 PWM2 at
        // ARR-1, MMS2 = OC4REF).
        w(&mut tim, 0x2c, 4250, &mut t);
        w(&mut tim, 0x40, 4249, &mut t);
        w(&mut tim, 0x1c, (7 << 12) | (1 << 11), &mut t);
        w(&mut tim, 0x04, 7 << 20, &mut t);
        w(&mut tim, 0x00, (1 << 5) | (1 << 7), &mut t);
        w(&mut tim, 0x30, 1, &mut t);
        w(&mut tim, 0x14, 1, &mut t);
        let cen = t;
        w(&mut tim, 0x00, (1 << 5) | (1 << 7) | 1, &mut t);
        let _ = tim.take_events().count();
        let mut level = 0.0;
        let mut valleys = 0;
        loop {
            let next = [tim.next_event(), b.adc.next_event()]
                .into_iter()
                .flatten()
                .min()
                .expect("something pending");
            if next > cen + 10 * 8500 {
                break;
            }
            tim.advance(next);
            b.t = next;
            b.sync();
            for e in tim.take_events().collect::<Vec<_>>() {
                match e {
                    TimEvent::Trgo2 { at, level: l } => {
                        b.adc.trigger_signal(TriggerSignal::Tim1Trgo2, l, at);
                    }
                    TimEvent::Update { at, .. } => {
                        valleys += 1;
                        // The PWM interrupt reads the JDRs at the valley: the sequence
                        // started at the previous peak has finished.
                        b.t = at;
                        if valleys > 1 {
                            let want = (level / 3.3 * 4095.0_f64).round() as u32;
                            assert_eq!(b.rd(JDR1), want, "valley {valleys}");
                            assert_ne!(b.rd(ISR) & isr::JEOS, 0);
                            b.wr(ISR, isr::JEOS);
                        }
                        // A new level for the next peak.
                        level = 0.1 * f64::from(valleys);
                        b.src.volts = vec![((AdcId::Adc1, 2), level)];
                    }
                    _ => {}
                }
            }
        }
        assert_eq!(valleys, 10);
        // Every sample of ADC1 rank 1 was taken 2+12.5 clocks (plus alignment) after a peak
        // TRGO2 rising edge at cen + 4249 + k * 8500.
        let firsts: Vec<Cycles> = b
            .src
            .samples
            .iter()
            .filter(|s| s.0 == AdcId::Adc1 && s.1 == 2)
            .map(|s| s.2)
            .collect();
        assert_eq!(firsts.len(), 10);
        for (k, at) in firsts.iter().enumerate() {
            let trig = cen + 4249 + k as u64 * 8500;
            let start = (trig + 8).div_ceil(4) * 4;
            assert_eq!(*at, start + 50);
        }
    }

    #[test]
    fn adc_clock_modes() {
        let mut b = Bus::new();
        // CKMODE = HCLK/4 and the async clock with PRESC = /4 (10.625 MHz, 16 cycles).
        b.wr(CCR, 3 << 16);
        b.modify(CR, |v| (v & !cr::DEEPPWD) | cr::ADVREGEN);
        b.delay_us(20);
        let cal = b.t + 1;
        b.modify(CR, |v| v | cr::ADCAL);
        assert_eq!(b.poll(CR, |v| v & cr::ADCAL == 0), cal + 112 * 4);
        b.wr(CCR, 2 << 18);
        let cal = b.t + 1;
        b.modify(CR, |v| v | cr::ADCAL);
        assert_eq!(b.poll(CR, |v| v & cr::ADCAL == 0), cal + 112 * 16);
    }

    #[test]
    fn interrupt_line() {
        let mut b = Bus::new();
        adc_new(&mut b, 0, None);
        let mut l = IrqLines::default();
        b.adc.irq_lines(&mut l);
        assert!(l.is_empty());
        b.wr(IER, 1); // ADRDYIE, ADRDY still set
        let mut l = IrqLines::default();
        b.adc.irq_lines(&mut l);
        assert!(l.get(names::irq("ADC1_2").unwrap_or(0)));
    }
}
