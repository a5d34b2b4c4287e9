//! DAC1 and DAC3 (RM0440 §22 "Digital-to-analog converter (DAC)"; DAC3 is internal-only and
//! feeds the comparators and OPAMP inputs).
//!
//! The drive (`drive-image/src/board/hw_protection.rs`) uses them as comparator thresholds:
//! `Dac::new_internal` (embassy-stm32 0.6 `dac/mod.rs`) sets MCR.HFSEL = 10 (AHB above
//! 160 MHz), clears EN and writes MODE = 011 (normal, internal, unbuffered) for each channel,
//! then sets EN; the board writes DHR12Rx. Nothing waits on DACxRDY.
//!
//! Modelled: CR (EN, TEN, TSEL, WAVE, MAMP, DMAEN, DMAUDRIE, CEN), MCR (MODE writable only while
//! EN = 0, DMADOUBLE, SINFORMAT, HFSEL), every DHR alignment including the dual registers,
//! DOR, SWTRGR, SR (DACxRDY, CAL_FLAG, DMAUDR), CCR (OTRIM), the sample-and-hold and sawtooth
//! registers as storage. Timing: DHR → DOR one dac_hclk (one cycle) after the write when TEN = 0,
//! three after a trigger when TEN = 1 (RM0440 "DAC conversion"); DACxRDY sets tWAKEUP = 8 µs
//! after EN (the HAL's LL_DAC_DELAY_STARTUP_VOLTAGE_SETTLING_US, the datasheet maximum). The
//! output settling (tSETTLING) is not modelled: the output steps when DOR changes.
//! Output: VREF+ x DOR / 4096 (RM0440 "DAC output voltage") plus the part's offset error
//! ([`AnalogErrors::dac_offset_v`], DS12589 typical by default, `docs/models.md`), clamped to
//! 0..VREF+; that is what the comparators' inverting inputs and the OPAMPs' DAC inputs get.
//! Not modelled (reported): noise/triangle/sawtooth generation, sample-and-hold modes, DMA
//! underrun.

use crate::names;
use crate::periph::analog_errors::AnalogErrors;
use crate::periph::reports::Reports;
use crate::periph::{DmaRequests, Peripheral, Write};
use crate::time::{cycles_for, Cycles};

/// VREF+ of both boards.
pub const VREF_VOLTS: f64 = 3.3;

/// tWAKEUP (EN to DACxRDY) in µs.
const WAKEUP_US: u64 = 8;
/// Optimum OTRIM of the calibration model (CAL_FLAG = OTRIM < this).
const OTRIM_OPTIMUM: u32 = 16;

/// Which DAC.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum DacId {
    Dac1,
    Dac3,
}

/// Where a channel's output goes (MCR.MODE).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DacMode {
    /// Connected to the pin (DAC1: OUT1 = PA4, OUT2 = PA5).
    pub external: bool,
    /// Connected to the on-chip peripherals (comparators, OPAMPs).
    pub internal: bool,
    /// Output buffer on.
    pub buffered: bool,
    /// Sample-and-hold mode (not modelled).
    pub sample_hold: bool,
}

impl DacMode {
    fn decode(mode: u32) -> Self {
        let sh = mode & 4 != 0;
        match mode & 3 {
            0 => DacMode {
                external: true,
                internal: false,
                buffered: true,
                sample_hold: sh,
            },
            1 => DacMode {
                external: true,
                internal: true,
                buffered: true,
                sample_hold: sh,
            },
            2 => DacMode {
                external: true,
                internal: sh, // S&H mode 110: external and internal, unbuffered
                buffered: false,
                sample_hold: sh,
            },
            _ => DacMode {
                external: false,
                internal: true,
                buffered: false,
                sample_hold: sh,
            },
        }
    }
}

/// One DAC (two channels).
#[derive(Debug, Clone)]
pub struct Dac {
    id: DacId,
    cr: u32,
    mcr: u32,
    /// DHRx (12-bit right-aligned view) and the B halves of the double-data mode.
    dhr: [u32; 2],
    dhrb: [u32; 2],
    dor: [u32; 2],
    /// A pending DHR → DOR transfer: (cycle, value).
    pending: [Option<(Cycles, u32)>; 2],
    ready_at: [Option<Cycles>; 2],
    ready: [bool; 2],
    sr: u32,
    ccr: u32,
    shsr: [u32; 2],
    shhr: u32,
    shrr: u32,
    str_: [u32; 2],
    stmodr: u32,
    dma: [Option<u8>; 2],
    dma_pending: [bool; 2],
    reports: Reports,
    /// Offset error of the output, volts (kept across resets: a property of the part).
    offset_v: f64,
}

const CR_EN: u32 = 1;
const CR_TEN: u32 = 1 << 1;
const CR_DMAEN: u32 = 1 << 12;
const CR_CEN: u32 = 1 << 14;
const SR_RDY: u32 = 1 << 11;
const SR_DMAUDR: u32 = 1 << 13;
const SR_CAL: u32 = 1 << 14;

impl Dac {
    pub fn new(id: DacId) -> Self {
        let name = match id {
            DacId::Dac1 => "DAC1",
            DacId::Dac3 => "DAC3",
        };
        Dac {
            id,
            cr: 0,
            mcr: 0,
            dhr: [0; 2],
            dhrb: [0; 2],
            dor: [0; 2],
            pending: [None; 2],
            ready_at: [None; 2],
            ready: [false; 2],
            sr: 0,
            ccr: 0,
            shsr: [0; 2],
            shhr: 0x0001_0001,
            shrr: 0x0001_0001,
            str_: [0; 2],
            stmodr: 0,
            dma: [
                names::dma_request(name, "CH1"),
                names::dma_request(name, "CH2"),
            ],
            dma_pending: [false; 2],
            reports: Reports::new(name),
            offset_v: AnalogErrors::TYPICAL.dac_offset_v,
        }
    }

    /// Sets the part's offset error (the rest of `errors` is the comparators' and OPAMPs').
    pub fn set_errors(&mut self, errors: &AnalogErrors) {
        self.offset_v = errors.dac_offset_v;
    }

    pub fn id(&self) -> DacId {
        self.id
    }

    /// Bit offset of channel `ch` (0 = channel 1, 1 = channel 2) in the shared registers;
    /// the public methods reject other indices before they get here.
    fn shift(ch: usize) -> u32 {
        16 * (ch as u32 & 1)
    }

    fn ch_cr(&self, ch: usize) -> u32 {
        (self.cr >> Self::shift(ch)) & 0xffff
    }

    /// The channel's mode (MCR.MODEx).
    pub fn mode(&self, ch: usize) -> DacMode {
        let ch = ch.min(1);
        DacMode::decode((self.mcr >> Self::shift(ch)) & 7)
    }

    /// DORx (ch = 0 for channel 1).
    pub fn dor(&self, ch: usize) -> u16 {
        self.dor.get(ch).map_or(0, |v| *v as u16)
    }

    /// The channel's output in volts, `None` while it is disabled or not yet ready (tWAKEUP):
    /// VREF+ x DOR / 4096 plus the offset error, within the rails.
    pub fn output_volts(&self, ch: usize) -> Option<f64> {
        if ch > 1 || self.ch_cr(ch) & CR_EN == 0 || !self.ready.get(ch).copied().unwrap_or(false) {
            return None;
        }
        let mut code = self.dor.get(ch).copied().unwrap_or(0) & 0xfff;
        if self.mcr & (1 << (9 + Self::shift(ch))) != 0 {
            // SINFORMAT: two's complement input, MSB inverted.
            code ^= 0x800;
        }
        Some((f64::from(code) / 4096.0 * VREF_VOLTS + self.offset_v).clamp(0.0, VREF_VOLTS))
    }

    /// A hardware trigger (the signal TSELx = `tsel` selects) at `now`.
    pub fn trigger(&mut self, ch: usize, tsel: u8, now: Cycles) {
        self.advance(now);
        if ch > 1 {
            return;
        }
        let c = self.ch_cr(ch);
        if c & CR_EN != 0 && c & CR_TEN != 0 && (c >> 2) & 0xf == u32::from(tsel) {
            self.triggered(ch, now);
        }
    }

    fn triggered(&mut self, ch: usize, now: Cycles) {
        let v = self.dhr[ch & 1];
        self.pending[ch & 1] = Some((now + 3, v));
        if self.ch_cr(ch) & CR_DMAEN != 0 {
            self.dma_pending[ch & 1] = true;
        }
    }

    /// A DHR write for channel `ch` at `now`.
    fn load(&mut self, ch: usize, value: u32, now: Cycles) {
        let ch = ch & 1;
        self.dhr[ch] = value & 0xfff;
        self.dma_pending[ch] = false;
        if self.ch_cr(ch) & CR_TEN == 0 {
            self.pending[ch] = Some((now + 1, value & 0xfff));
        }
    }

    fn write_cr(&mut self, v: u32, now: Cycles) {
        let old = self.cr;
        self.cr = v & 0x7fff_7fff & !(0x8000_8000);
        for ch in 0..2 {
            let sh = Self::shift(ch);
            let was = old & (CR_EN << sh) != 0;
            let is = self.cr & (CR_EN << sh) != 0;
            if is && !was {
                self.ready_at[ch] = Some(now + cycles_for(WAKEUP_US, 1_000_000));
            }
            if !is {
                self.ready_at[ch] = None;
                self.ready[ch] = false;
            }
            if is && (self.cr >> sh) & 0xc0 != 0 {
                self.reports.once(now, "wave", || {
                    "noise/triangle/sawtooth generation (WAVEx) is not modelled".into()
                });
            }
            if is && self.mode(ch).sample_hold {
                self.reports.once(now, "sh", || {
                    "sample-and-hold modes are not modelled".into()
                });
            }
            if is && self.id == DacId::Dac3 && self.mode(ch).external {
                self.reports.once(now, "dac3-ext", || {
                    "DAC3 is internal-only: MODE must be 011 (internal, unbuffered)".into()
                });
            }
            if self.cr & (CR_CEN << sh) != 0 {
                self.update_cal(ch);
            }
        }
    }

    fn update_cal(&mut self, ch: usize) {
        let otrim = (self.ccr >> Self::shift(ch)) & 0x1f;
        let bit = SR_CAL << Self::shift(ch);
        if otrim < OTRIM_OPTIMUM {
            self.sr |= bit;
        } else {
            self.sr &= !bit;
        }
    }
}

impl Peripheral for Dac {
    /// Misuse and unsupported-feature reports since the last call.
    fn take_reports(&mut self) -> Vec<String> {
        self.reports.take()
    }

    fn read(&mut self, offset: u32, _now: Cycles) -> Option<u32> {
        Some(match offset {
            0x00 => self.cr,
            0x04 => 0,
            0x08 => self.dhr[0] | self.dhrb[0] << 16,
            0x0c => self.dhr[0] << 4 | self.dhrb[0] << 20,
            0x10 => self.dhr[0] >> 4 | (self.dhrb[0] >> 4) << 8,
            0x14 => self.dhr[1] | self.dhrb[1] << 16,
            0x18 => self.dhr[1] << 4 | self.dhrb[1] << 20,
            0x1c => self.dhr[1] >> 4 | (self.dhrb[1] >> 4) << 8,
            0x20 => self.dhr[0] | self.dhr[1] << 16,
            0x24 => self.dhr[0] << 4 | self.dhr[1] << 20,
            0x28 => self.dhr[0] >> 4 | (self.dhr[1] >> 4) << 8,
            0x2c => self.dor[0],
            0x30 => self.dor[1],
            0x34 => self.sr,
            0x38 => self.ccr,
            0x3c => self.mcr,
            0x40 => self.shsr[0],
            0x44 => self.shsr[1],
            0x48 => self.shhr,
            0x4c => self.shrr,
            0x58 => self.str_[0],
            0x5c => self.str_[1],
            0x60 => self.stmodr,
            _ => return None,
        })
    }

    fn write(&mut self, w: Write, now: Cycles) -> bool {
        let old = match w.offset {
            0x04 => 0,
            o => match self.read(o, now) {
                Some(v) => v,
                None => return false,
            },
        };
        let v = w.merge(old);
        match w.offset {
            0x00 => self.write_cr(v, now),
            0x04 => {
                for ch in 0..2 {
                    let c = self.ch_cr(ch);
                    if v & (1 << ch) != 0
                        && c & CR_EN != 0
                        && c & CR_TEN != 0
                        && (c >> 2) & 0xf == 0
                    {
                        self.triggered(ch, now);
                    }
                }
                if v & 0x3_0000 != 0 {
                    self.reports.once(now, "swtrigb", || {
                        "SWTRIGB (sawtooth step) is not modelled".into()
                    });
                }
            }
            0x08 => {
                self.dhrb[0] = (v >> 16) & 0xfff;
                self.load(0, v & 0xfff, now);
            }
            0x0c => {
                self.dhrb[0] = (v >> 20) & 0xfff;
                self.load(0, (v >> 4) & 0xfff, now);
            }
            0x10 => {
                self.dhrb[0] = ((v >> 8) & 0xff) << 4;
                self.load(0, (v & 0xff) << 4, now);
            }
            0x14 => {
                self.dhrb[1] = (v >> 16) & 0xfff;
                self.load(1, v & 0xfff, now);
            }
            0x18 => {
                self.dhrb[1] = (v >> 20) & 0xfff;
                self.load(1, (v >> 4) & 0xfff, now);
            }
            0x1c => {
                self.dhrb[1] = ((v >> 8) & 0xff) << 4;
                self.load(1, (v & 0xff) << 4, now);
            }
            0x20 => {
                self.load(0, v & 0xfff, now);
                self.load(1, (v >> 16) & 0xfff, now);
            }
            0x24 => {
                self.load(0, (v >> 4) & 0xfff, now);
                self.load(1, (v >> 20) & 0xfff, now);
            }
            0x28 => {
                self.load(0, (v & 0xff) << 4, now);
                self.load(1, ((v >> 8) & 0xff) << 4, now);
            }
            0x2c | 0x30 => {}
            0x34 => self.sr = w.clear_w1(self.sr) | (self.sr & !((SR_DMAUDR) | (SR_DMAUDR << 16))),
            0x38 => {
                self.ccr = v & 0x001f_001f;
                for ch in 0..2 {
                    if self.ch_cr(ch) & CR_CEN != 0 {
                        self.update_cal(ch);
                    }
                }
            }
            0x3c => {
                let mut n = v & 0x0000_c707 | (v & 0x0307_0000);
                for ch in 0..2 {
                    let field = 7 << Self::shift(ch);
                    if self.ch_cr(ch) & (CR_EN | CR_CEN) != 0 && (n ^ self.mcr) & field != 0 {
                        n = (n & !field) | (self.mcr & field);
                        self.reports.once(now, "mode-en", || {
                            "MCR.MODEx written while the channel is enabled (ignored)".into()
                        });
                    }
                }
                self.mcr = n;
            }
            0x40 => self.shsr[0] = v & 0x3ff,
            0x44 => self.shsr[1] = v & 0x3ff,
            0x48 => self.shhr = v & 0x03ff_03ff,
            0x4c => self.shrr = v & 0x00ff_00ff,
            0x58 => self.str_[0] = v,
            0x5c => self.str_[1] = v,
            0x60 => self.stmodr = v & 0x0f0f_0f0f,
            _ => return false,
        }
        true
    }

    fn next_event(&self) -> Option<Cycles> {
        self.pending
            .iter()
            .flatten()
            .map(|p| p.0)
            .chain(self.ready_at.iter().flatten().copied())
            .min()
    }

    fn advance(&mut self, now: Cycles) {
        for ch in 0..2 {
            if let Some((t, v)) = self.pending[ch] {
                if t <= now {
                    self.dor[ch] = v;
                    self.pending[ch] = None;
                }
            }
            if let Some(t) = self.ready_at[ch] {
                if t <= now {
                    self.ready_at[ch] = None;
                    self.ready[ch] = true;
                    self.sr |= SR_RDY << Self::shift(ch);
                }
            }
            if !self.ready[ch] {
                self.sr &= !(SR_RDY << Self::shift(ch));
            }
        }
    }

    fn dma_requests(&self, requests: &mut DmaRequests) {
        for ch in 0..2 {
            if self.dma_pending[ch] {
                if let Some(id) = self.dma[ch] {
                    requests.set(id);
                }
            }
        }
    }

    fn reset(&mut self) {
        let offset_v = self.offset_v;
        *self = Dac::new(self.id);
        self.offset_v = offset_v;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const CR: u32 = 0x00;
    const SWTRGR: u32 = 0x04;
    const DHR12R1: u32 = 0x08;
    const DHR12L1: u32 = 0x0c;
    const DHR8R1: u32 = 0x10;
    const DHR12R2: u32 = 0x14;
    const DHR12RD: u32 = 0x20;
    const DOR1: u32 = 0x2c;
    const DOR2: u32 = 0x30;
    const SR: u32 = 0x34;
    const MCR: u32 = 0x3c;

    fn wr(d: &mut Dac, off: u32, v: u32, t: Cycles) {
        d.advance(t);
        assert!(d.write(Write::word(off, v), t));
    }

    fn rd(d: &mut Dac, off: u32, t: Cycles) -> u32 {
        d.advance(t);
        d.read(off, t).expect("modelled")
    }

    /// embassy `Dac::new_internal` (both channels) as the drive uses it for DAC3, then
    /// `set(Bit12Right(v))` per channel.
    #[test]
    fn embassy_new_internal_and_thresholds() {
        let mut d = Dac::new(DacId::Dac3);
        let mut t = 100;
        for ch in 0..2u32 {
            let sh = 16 * ch;
            // set_hfsel (MCR modify), set_mode (CR modify EN=0, MCR modify MODE=011), enable
            let m = rd(&mut d, MCR, t);
            wr(&mut d, MCR, (m & !0xc000) | (0b10 << 14), t + 1);
            let c = rd(&mut d, CR, t + 2);
            wr(&mut d, CR, c & !(1 << sh), t + 3);
            let m = rd(&mut d, MCR, t + 4);
            wr(&mut d, MCR, (m & !(7 << sh)) | (0b011 << sh), t + 5);
            let c = rd(&mut d, CR, t + 6);
            wr(&mut d, CR, c | (1 << sh), t + 7);
            t += 8;
        }
        assert!(d.mode(0).internal && !d.mode(0).external && !d.mode(0).buffered);
        assert!(d.take_reports().is_empty());
        // The board writes the thresholds right after.
        wr(&mut d, DHR12R1, 2662, t);
        assert_eq!(rd(&mut d, DOR1, t), 0, "DOR not yet");
        assert_eq!(d.next_event(), Some(t + 1));
        assert_eq!(
            rd(&mut d, DOR1, t + 1),
            2662,
            "DOR one dac_hclk after the write"
        );
        wr(&mut d, DHR12R2, 2662, t + 2);
        assert_eq!(rd(&mut d, DOR2, t + 3), 2662);
        // DACxRDY tWAKEUP = 8 us after EN (channel 1 enabled at cycle 107).
        assert_eq!(rd(&mut d, SR, 107 + 1359) & SR_RDY, 0);
        assert_eq!(d.output_volts(0), None, "not ready: no defined output");
        assert_ne!(rd(&mut d, SR, 107 + 1360) & SR_RDY, 0);
        let v = d.output_volts(0).expect("ready");
        let typ = AnalogErrors::TYPICAL.dac_offset_v;
        assert!((v - (2662.0 / 4096.0 * 3.3 + typ)).abs() < 1e-12);
    }

    /// The offset error adds to the output, with its sign, and the output stays within the
    /// rails; it survives a reset.
    #[test]
    fn offset_error_moves_the_output_within_the_rails() {
        for offset in [0.01, -0.01] {
            let mut d = Dac::new(DacId::Dac3);
            d.set_errors(&AnalogErrors {
                dac_offset_v: offset,
                ..AnalogErrors::IDEAL
            });
            wr(&mut d, CR, CR_EN, 0);
            wr(&mut d, DHR12R1, 2048, 1);
            d.advance(1 + 1360);
            let v = d.output_volts(0).expect("ready");
            assert!((v - (1.65 + offset)).abs() < 1e-12, "{offset}: {v}");
            wr(&mut d, DHR12R1, if offset < 0.0 { 0 } else { 4095 }, 1400);
            d.advance(1401);
            let rail = d.output_volts(0).expect("ready");
            assert!((0.0..=3.3).contains(&rail), "{rail}");
            d.reset();
            wr(&mut d, CR, CR_EN, 1500);
            wr(&mut d, DHR12R1, 2048, 1501);
            d.advance(1501 + 1360);
            let v = d.output_volts(0).expect("ready");
            assert!((v - (1.65 + offset)).abs() < 1e-12, "after reset: {v}");
        }
    }

    #[test]
    fn mode_is_writable_only_while_disabled() {
        let mut d = Dac::new(DacId::Dac1);
        wr(&mut d, CR, CR_EN, 0);
        wr(&mut d, MCR, 0b011, 1);
        assert_eq!(rd(&mut d, MCR, 2) & 7, 0);
        assert!(!d.take_reports().is_empty());
    }

    #[test]
    fn alignments_and_dual_registers() {
        let mut d = Dac::new(DacId::Dac1);
        wr(&mut d, DHR12L1, 0xabc0, 0);
        assert_eq!(rd(&mut d, DOR1, 1), 0xabc);
        wr(&mut d, DHR8R1, 0x12, 2);
        assert_eq!(rd(&mut d, DOR1, 3), 0x120);
        wr(&mut d, DHR12RD, 0x0456_0123, 4);
        assert_eq!(rd(&mut d, DOR1, 5), 0x123);
        assert_eq!(rd(&mut d, DOR2, 5), 0x456);
    }

    #[test]
    fn software_trigger_with_ten() {
        let mut d = Dac::new(DacId::Dac1);
        wr(&mut d, CR, CR_EN | CR_TEN, 0); // TSEL = 0: SWTRIG
        wr(&mut d, DHR12R1, 1000, 10);
        assert_eq!(rd(&mut d, DOR1, 100), 0, "waits for the trigger");
        wr(&mut d, SWTRGR, 1, 100);
        assert_eq!(rd(&mut d, DOR1, 102), 0);
        assert_eq!(
            rd(&mut d, DOR1, 103),
            1000,
            "three dac_hclk after the trigger"
        );
        assert_eq!(rd(&mut d, SWTRGR, 104), 0);
        // A hardware trigger on the selected TSEL.
        wr(&mut d, CR, CR_EN | CR_TEN | (5 << 2), 110);
        wr(&mut d, DHR12R1, 2000, 111);
        d.trigger(0, 4, 120);
        assert_eq!(rd(&mut d, DOR1, 130), 1000, "another TSEL does nothing");
        d.trigger(0, 5, 140);
        assert_eq!(rd(&mut d, DOR1, 143), 2000);
    }

    #[test]
    fn signed_format() {
        let mut d = Dac::new(DacId::Dac1);
        wr(&mut d, MCR, 1 << 9, 0);
        wr(&mut d, CR, CR_EN, 1);
        wr(&mut d, DHR12R1, 0, 2);
        d.advance(2 + 1360);
        let v = d.output_volts(0).expect("ready");
        assert!(
            (v - (1.65 + AnalogErrors::TYPICAL.dac_offset_v)).abs() < 1e-12,
            "0 signed is mid-scale"
        );
    }
}
