//! Operational amplifiers OPAMP1-OPAMP3 (RM0440 §25 "Operational amplifiers (OPAMP)").
//!
//! One [`OpampBank`] covers OPAMP1-3_CSR (offsets 0x00, 0x04, 0x08 from 0x4001_0300) and
//! OPAMP1-3_TCMR (0x18, 0x1C, 0x20); OPAMP4-6 do not exist on the G431.
//!
//! The drive image puts OPAMP1-3 in PGA mode on the B-G431B-ESC1's shunt
//! amplifiers: its `board/analog.rs` takes the ADC channel tokens from embassy's driver, then
//! `board/opamps.rs` writes each CSR (VP_SEL 00, VM_SEL PGA, PGA_GAIN x16, OPAHSM, OPAINTOEN,
//! OPAEN) with one read-modify-write. embassy-stm32 0.6 `opamp.rs` writes one
//! CSR modify per configuration (VP_SEL, VM_SEL = PGA, PGA_GAIN, OPAINTOEN, OPAEN) and
//! calibrates with CALON/USERTRIM, a binary search on TRIMOFFSETP (CALSEL = 10 %) and
//! TRIMOFFSETN (CALSEL = 90 %) reading CALOUT 2 ms after each trim.
//!
//! Modelled: the registers with LOCK, the decoded configuration ([`OpampConfig`]: inputs,
//! mode and gain, where the output goes), the output for the real input volts
//! ([`OpampConfig::output_volts`]) and CALOUT: in calibration mode it reads 1 while the
//! selected trim is below the amplifier's optimum (default 16, settable), and takes a new value
//! 2 ms (the worst-case settling RM0440 quotes) after the trim, CALSEL or CALON changes.
//!
//! The output, from RM0440 §25.3 "PGA mode" figures and the PGA_GAIN table (VM_SEL = 10):
//! * PGA_GAIN 00xxx, non-inverting gain G = 2, 4, .. 64 (xxx = 0..5), the feedback network's
//!   foot on VSSA: `G (VINP + Vio)`; 10xxx is the same with VINM0 carrying a filter capacitor
//!   at the network's midpoint (the DC gain is G);
//! * PGA_GAIN 01xxx, "inverting gain -(G-1) / non-inverting gain G, VINM0 used as input or
//!   bias" (embassy `pga_biased_int`/`pga_biased_ext`): the network's foot on the VINM0 pin,
//!   `G (VINP + Vio) - (G-1) VINM0`; 11xxx is the same with a filter capacitor on VINM1;
//! * follower (VM_SEL = 11): `VINP + Vio`;
//! * standalone (VM_SEL = 00/01): set by the external loop (no output computed here).
//!
//! Vio is the part's input offset voltage ([`AnalogErrors::opamp_offset_v`], DS12589 typical
//! by default), the output is clamped to the rails 0..VDDA (3.3 V). The inputs are the pins'
//! real volts (the board's), so a wrong mode gives a wrong output. PGA_GAIN xx110/xx111 are
//! reserved (reported; taken as x64). Not modelled: start-up time, bandwidth and slew rate,
//! the output's saturation a few tens of mV inside the rails, the timer-controlled input
//! multiplexer (TCMR.TxCM_EN, reported).

use crate::periph::adc::AdcId;
use crate::periph::analog_errors::AnalogErrors;
use crate::periph::reports::Reports;
use crate::periph::{Peripheral, Write};
use crate::time::{cycles_for, Cycles};

/// CSR bits.
mod csr {
    pub const OPAEN: u32 = 1 << 0;
    pub const FORCE_VP: u32 = 1 << 1;
    pub const VP_SHIFT: u32 = 2;
    pub const USERTRIM: u32 = 1 << 4;
    pub const VM_SHIFT: u32 = 5;
    pub const OPAHSM: u32 = 1 << 7;
    pub const OPAINTOEN: u32 = 1 << 8;
    pub const CALON: u32 = 1 << 11;
    pub const CALSEL_SHIFT: u32 = 12;
    pub const GAIN_SHIFT: u32 = 14;
    pub const TRIMP_SHIFT: u32 = 19;
    pub const TRIMN_SHIFT: u32 = 24;
    pub const CALOUT: u32 = 1 << 30;
    pub const LOCK: u32 = 1 << 31;
    pub const MASK: u32 = 0x9fff_f9ff;
}

/// CALOUT settling after a trim change.
const CAL_SETTLE_US: u64 = 2000;

/// Non-inverting input.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OpampInput {
    Pin(&'static str),
    /// DAC3 channel (0 = CH1).
    Dac3(usize),
    /// VP_SEL = 11 on OPAMP2 (VINP3 = PD14, not bonded on the G431).
    NotConnected,
}

/// Amplifier configuration (VM_SEL and PGA_GAIN).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OpampMode {
    /// Standalone: the inverting input is a pin.
    Standalone { vinm: &'static str },
    /// Follower (unity gain).
    Follower,
    /// Programmable-gain amplifier, non-inverting gain `gain` (2..64) on VINP.
    Pga { gain: u8 },
    /// PGA with VINM0 on the feedback network: gain `gain` on VINP around the bias on VINM0,
    /// or inverting gain -(gain-1) for a signal on VINM0 (`filter_vinm1`: VINM1 carries a
    /// filtering capacitor).
    PgaVinm0 {
        gain: u8,
        vinm0: &'static str,
        filter_vinm1: Option<&'static str>,
    },
    /// PGA with a filtering capacitor on VINM0 (non-inverting gain).
    PgaFiltered { gain: u8, vinm0: &'static str },
}

/// An OPAMP's configuration, decoded for the host.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OpampConfig {
    /// OPAMPn (1..=3).
    pub opamp: usize,
    pub enabled: bool,
    pub vinp: OpampInput,
    pub mode: OpampMode,
    pub high_speed: bool,
    /// OPAINTOEN: the output goes to the ADC channel only, not to the pin.
    pub internal_only: bool,
    /// The output pin (PA2, PA6, PB1), driven when enabled and not `internal_only`.
    pub output_pin: &'static str,
    /// The ADC channel the output reaches internally (OPAMP1 = ADC1 IN13, OPAMP2 = ADC2 IN16,
    /// OPAMP3 = ADC2 IN18).
    pub adc_channel: (AdcId, u8),
    pub calibrating: bool,
    pub locked: bool,
    /// The part's input offset voltage (volts), added to VINP.
    pub offset_v: f64,
}

/// The rails of the OPAMP's output (VSSA, VDDA on both boards).
pub const VDDA_VOLTS: f64 = 3.3;

impl OpampConfig {
    /// The output for the given pin volts (VINP, VINM0) with the part's input offset,
    /// clamped to the rails; `None` when disabled, calibrating, or standalone (its output
    /// depends on the external loop).
    pub fn output_volts(&self, vinp: f64, vinm0: f64) -> Option<f64> {
        if !self.enabled || self.calibrating {
            return None;
        }
        let vp = vinp + self.offset_v;
        let v = match self.mode {
            OpampMode::Standalone { .. } => return None,
            OpampMode::Follower => vp,
            OpampMode::Pga { gain } | OpampMode::PgaFiltered { gain, .. } => f64::from(gain) * vp,
            OpampMode::PgaVinm0 { gain, .. } => {
                // The network's foot on VINM0: non-inverting gain G on VINP, inverting
                // -(G-1) on VINM0.
                let g = f64::from(gain);
                g * vp - (g - 1.0) * vinm0
            }
        };
        Some(v.clamp(0.0, VDDA_VOLTS))
    }

    /// The pin on VINM0 whose volts [`OpampConfig::output_volts`] needs (`None`: the
    /// network's foot is on VSSA or there is no network).
    pub fn vinm0_pin(&self) -> Option<&'static str> {
        match self.mode {
            OpampMode::PgaVinm0 { vinm0, .. } => Some(vinm0),
            _ => None,
        }
    }
}

const VINP: [[&str; 3]; 3] = [
    ["PA1", "PA3", "PA7"],
    ["PA7", "PB14", "PB0"],
    ["PB0", "PB13", "PA1"],
];
const VINM: [[&str; 2]; 3] = [["PA3", "PC5"], ["PA5", "PC5"], ["PB2", "PB10"]];
const VOUT: [&str; 3] = ["PA2", "PA6", "PB1"];
const ADC_CH: [(AdcId, u8); 3] = [(AdcId::Adc1, 13), (AdcId::Adc2, 16), (AdcId::Adc2, 18)];

#[derive(Debug, Clone, Copy)]
struct Opamp {
    csr: u32,
    tcmr: u32,
    /// Optimum (TRIMOFFSETP, TRIMOFFSETN) of this amplifier.
    optimum: (u8, u8),
    /// CALOUT as it reads now, and a pending new value.
    calout: bool,
    pending: Option<(Cycles, bool)>,
}

/// OPAMP1-OPAMP3.
#[derive(Debug, Clone)]
pub struct OpampBank {
    amps: [Opamp; 3],
    reports: Reports,
    /// Input offset voltage, volts (kept across resets: a property of the part).
    offset_v: f64,
}

impl Default for OpampBank {
    fn default() -> Self {
        Self::new()
    }
}

impl OpampBank {
    pub fn new() -> Self {
        OpampBank {
            amps: [Opamp {
                csr: 0,
                tcmr: 0,
                optimum: (16, 16),
                calout: false,
                pending: None,
            }; 3],
            reports: Reports::new("OPAMP"),
            offset_v: AnalogErrors::TYPICAL.opamp_offset_v,
        }
    }

    /// Sets the part's input offset voltage (the rest of `errors` is the comparators' and
    /// DACs').
    pub fn set_errors(&mut self, errors: &AnalogErrors) {
        self.offset_v = errors.opamp_offset_v;
    }

    /// The trim values at which OPAMPn's calibration comparator flips (what a real part's
    /// offset determines).
    pub fn set_offset_trim_optimum(&mut self, n: usize, p: u8, nmos: u8) {
        if let Some(a) = n.checked_sub(1).and_then(|i| self.amps.get_mut(i)) {
            a.optimum = (p & 0x1f, nmos & 0x1f);
        }
    }

    /// The configuration of OPAMPn (n = 1..=3).
    pub fn config(&self, n: usize) -> Option<OpampConfig> {
        let i = n.checked_sub(1)?;
        let a = self.amps.get(i)?;
        let csr = a.csr;
        let vp = ((csr >> csr::VP_SHIFT) & 3) as usize;
        let vinp = match (i, vp) {
            (_, 0..=2) => OpampInput::Pin(VINP[i][vp]),
            (0, _) => OpampInput::Dac3(0),
            (2, _) => OpampInput::Dac3(1),
            _ => OpampInput::NotConnected,
        };
        let gain_field = (csr >> csr::GAIN_SHIFT) & 0x1f;
        let gain = 2u8 << (gain_field & 7).min(5);
        let mode = match (csr >> csr::VM_SHIFT) & 3 {
            0 => OpampMode::Standalone { vinm: VINM[i][0] },
            1 => OpampMode::Standalone { vinm: VINM[i][1] },
            2 => match gain_field >> 3 {
                0 => OpampMode::Pga { gain },
                1 => OpampMode::PgaVinm0 {
                    gain,
                    vinm0: VINM[i][0],
                    filter_vinm1: None,
                },
                2 => OpampMode::PgaFiltered {
                    gain,
                    vinm0: VINM[i][0],
                },
                _ => OpampMode::PgaVinm0 {
                    gain,
                    vinm0: VINM[i][0],
                    filter_vinm1: Some(VINM[i][1]),
                },
            },
            _ => OpampMode::Follower,
        };
        Some(OpampConfig {
            opamp: n,
            enabled: csr & csr::OPAEN != 0,
            vinp,
            mode,
            high_speed: csr & csr::OPAHSM != 0,
            internal_only: csr & csr::OPAINTOEN != 0,
            output_pin: VOUT[i],
            adc_channel: ADC_CH[i],
            calibrating: csr & csr::CALON != 0,
            locked: csr & csr::LOCK != 0,
            offset_v: self.offset_v,
        })
    }

    /// What CALOUT will settle to with the present CSR.
    fn cal_target(a: &Opamp) -> bool {
        if a.csr & csr::CALON == 0 {
            return false;
        }
        let calsel = (a.csr >> csr::CALSEL_SHIFT) & 3;
        let (trim, optimum) = if calsel == 3 {
            ((a.csr >> csr::TRIMN_SHIFT) & 0x1f, a.optimum.1)
        } else {
            ((a.csr >> csr::TRIMP_SHIFT) & 0x1f, a.optimum.0)
        };
        trim < u32::from(optimum)
    }
}

impl Peripheral for OpampBank {
    /// Misuse and unsupported-feature reports since the last call.
    fn take_reports(&mut self) -> Vec<String> {
        self.reports.take()
    }

    fn read(&mut self, offset: u32, _now: Cycles) -> Option<u32> {
        match offset {
            0x00 | 0x04 | 0x08 => {
                let a = self.amps.get((offset / 4) as usize)?;
                Some(a.csr | if a.calout { csr::CALOUT } else { 0 })
            }
            0x18 | 0x1c | 0x20 => self
                .amps
                .get(((offset - 0x18) / 4) as usize)
                .map(|a| a.tcmr),
            _ => None,
        }
    }

    fn write(&mut self, w: Write, now: Cycles) -> bool {
        match w.offset {
            0x00 | 0x04 | 0x08 => {
                let i = (w.offset / 4) as usize;
                let Some(a) = self.amps.get_mut(i) else {
                    return false;
                };
                if a.csr & csr::LOCK != 0 {
                    self.reports.once(now, "lock", || {
                        format!("OPAMP{}_CSR is locked: write ignored", i + 1)
                    });
                    return true;
                }
                let before = Self::cal_target(a);
                let old = a.csr;
                a.csr = w.merge(a.csr) & csr::MASK;
                let after = Self::cal_target(a);
                let cal_bits = csr::CALON
                    | (3 << csr::CALSEL_SHIFT)
                    | (0x1f << csr::TRIMP_SHIFT)
                    | (0x1f << csr::TRIMN_SHIFT);
                if (old ^ a.csr) & cal_bits != 0 || before != after {
                    if a.csr & csr::CALON == 0 {
                        a.pending = None;
                        a.calout = false;
                    } else {
                        a.pending = Some((now + cycles_for(CAL_SETTLE_US, 1_000_000), after));
                    }
                }
                let pga = (a.csr >> csr::VM_SHIFT) & 3 == 2;
                if pga && (a.csr >> csr::GAIN_SHIFT) & 6 == 6 {
                    self.reports.once(now, "gain-reserved", || {
                        format!(
                            "OPAMP{} PGA_GAIN {:#07b} is reserved",
                            i + 1,
                            (a.csr >> csr::GAIN_SHIFT) & 0x1f
                        )
                    });
                }
                if a.csr & csr::FORCE_VP != 0 && a.csr & csr::CALON == 0 {
                    self.reports.once(now, "force-vp", || {
                        "OPAMP FORCE_VP outside calibration is not modelled".into()
                    });
                }
                if a.csr & csr::CALON != 0 && a.csr & csr::USERTRIM == 0 {
                    self.reports.once(now, "usertrim", || {
                        "OPAMP calibration with USERTRIM = 0 (the factory trim is used)".into()
                    });
                }
                true
            }
            0x18 | 0x1c | 0x20 => {
                let i = ((w.offset - 0x18) / 4) as usize;
                let Some(a) = self.amps.get_mut(i) else {
                    return false;
                };
                if a.tcmr & (1 << 31) != 0 {
                    return true;
                }
                a.tcmr = w.merge(a.tcmr) & 0x8000_003f;
                if a.tcmr & 0x38 != 0 {
                    self.reports.once(now, "tcm", || {
                        "timer-controlled input multiplexer (TCMR.TxCM_EN) is not modelled".into()
                    });
                }
                true
            }
            _ => false,
        }
    }

    fn next_event(&self) -> Option<Cycles> {
        self.amps
            .iter()
            .filter_map(|a| a.pending.map(|p| p.0))
            .min()
    }

    fn advance(&mut self, now: Cycles) {
        for a in &mut self.amps {
            if let Some((t, v)) = a.pending {
                if t <= now {
                    a.calout = v;
                    a.pending = None;
                }
            }
        }
    }

    fn reset(&mut self) {
        let optimum = self.amps.map(|a| a.optimum);
        let offset_v = self.offset_v;
        *self = OpampBank::new();
        self.offset_v = offset_v;
        for (a, o) in self.amps.iter_mut().zip(optimum) {
            a.optimum = o;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn wr(b: &mut OpampBank, off: u32, v: u32, t: Cycles) {
        b.advance(t);
        assert!(b.write(Write::word(off, v), t));
    }

    fn rd(b: &mut OpampBank, off: u32, t: Cycles) -> u32 {
        b.advance(t);
        b.read(off, t).expect("modelled")
    }

    /// embassy `OpAmp::new(.., HighSpeed)` + `pga_int(pin, Gain16)` on each OPAMP, as the ESC1
    /// front end needs (VINP0: PA1, PA7, PB0).
    #[test]
    fn pga_configuration_decodes() {
        let mut b = OpampBank::new();
        for n in 0..3u32 {
            let off = 4 * n;
            let v = rd(&mut b, off, 0);
            wr(&mut b, off, v | csr::OPAHSM, 1);
            let v = rd(&mut b, off, 2);
            // VP_SEL = 00 (VINP0), VM_SEL = 10 (PGA), PGA_GAIN = 00011 (16).
            let v = (v & !(3 << 2) & !(3 << 5) & !(0x1f << 14))
                | (2 << 5)
                | (3 << 14)
                | csr::OPAINTOEN
                | csr::OPAEN;
            wr(&mut b, off, v, 3);
        }
        let c: Vec<OpampConfig> = (1..=3).filter_map(|n| b.config(n)).collect();
        assert_eq!(
            c.iter().map(|c| c.vinp).collect::<Vec<_>>(),
            vec![
                OpampInput::Pin("PA1"),
                OpampInput::Pin("PA7"),
                OpampInput::Pin("PB0")
            ]
        );
        assert!(c.iter().all(|c| c.mode == OpampMode::Pga { gain: 16 }));
        assert!(c
            .iter()
            .all(|c| c.enabled && c.internal_only && c.high_speed));
        assert_eq!(
            c.iter().map(|c| c.adc_channel).collect::<Vec<_>>(),
            vec![(AdcId::Adc1, 13), (AdcId::Adc2, 16), (AdcId::Adc2, 18)]
        );
        assert_eq!(c[2].output_pin, "PB1");
        // 16 x (0.1 V + the typical offset).
        let typ = AnalogErrors::TYPICAL.opamp_offset_v;
        let v = c[0].output_volts(0.1, 0.0).expect("enabled");
        assert!((v - 16.0 * (0.1 + typ)).abs() < 1e-12, "{v}");
        assert_eq!(
            c[0].output_volts(0.5, 0.0),
            Some(3.3),
            "clamped to the rail"
        );
    }

    #[test]
    fn other_modes() {
        let mut b = OpampBank::new();
        b.set_errors(&AnalogErrors::IDEAL);
        wr(&mut b, 0, csr::OPAEN | (3 << 2) | (3 << 5), 0);
        let c = b.config(1).expect("OPAMP1");
        assert_eq!(c.vinp, OpampInput::Dac3(0));
        assert_eq!(c.mode, OpampMode::Follower);
        wr(
            &mut b,
            8,
            csr::OPAEN | (3 << 2) | (2 << 5) | (0b01_001 << 14),
            1,
        );
        let c = b.config(3).expect("OPAMP3");
        assert_eq!(c.vinp, OpampInput::Dac3(1));
        assert_eq!(
            c.mode,
            OpampMode::PgaVinm0 {
                gain: 4,
                vinm0: "PB2",
                filter_vinm1: None
            }
        );
        // Gain 4 around a 1 V bias: 1.1 V in -> 4*1.1 - 3*1 = 1.4 V.
        let v = c.output_volts(1.1, 1.0).expect("enabled");
        assert!((v - 1.4).abs() < 1e-12);
        wr(&mut b, 4, csr::OPAEN | (1 << 5), 2);
        assert_eq!(
            b.config(2).map(|c| c.mode),
            Some(OpampMode::Standalone { vinm: "PC5" })
        );
        assert_eq!(b.read(0x0c, 3), None, "OPAMP4 does not exist on the G431");
    }

    /// embassy's `calibrate()`: CALON + USERTRIM, binary search on TRIMOFFSETP with CALSEL =
    /// 10 % then TRIMOFFSETN with 90 %, 2 ms between a trim write and the CALOUT read.
    #[test]
    fn embassy_calibration_finds_the_optimum() {
        let mut b = OpampBank::new();
        b.set_offset_trim_optimum(2, 11, 23);
        let off = 4;
        let mut t = 0;
        let v = rd(&mut b, off, t);
        wr(
            &mut b,
            off,
            v | csr::OPAEN | csr::CALON | csr::USERTRIM,
            t + 1,
        );
        t += 2;
        let mut results = [0u32; 2];
        for (k, (calsel, shift)) in [(1u32, csr::TRIMP_SHIFT), (3, csr::TRIMN_SHIFT)]
            .into_iter()
            .enumerate()
        {
            let v = rd(&mut b, off, t);
            wr(&mut b, off, (v & !(3 << 12)) | (calsel << 12), t + 1);
            t += 2;
            let (mut low, mut high) = (0i32, 31i32);
            let mut last = 0;
            while low <= high {
                let mid = (low + high) / 2;
                let v = rd(&mut b, off, t);
                wr(
                    &mut b,
                    off,
                    (v & !(0x1f << shift)) | ((mid as u32) << shift),
                    t + 1,
                );
                t += 1 + 340_000; // block_for_us(2000) at 170 MHz
                let calout = rd(&mut b, off, t) & csr::CALOUT != 0;
                t += 1;
                last = mid;
                if !calout {
                    if mid == 0 {
                        break;
                    }
                    high = mid - 1;
                } else {
                    if mid == 31 {
                        break;
                    }
                    low = mid + 1;
                }
            }
            results[k] = last as u32;
        }
        // The search converges next to the optimum (the last probe is within one step).
        assert!(results[0].abs_diff(11) <= 1, "{results:?}");
        assert!(results[1].abs_diff(23) <= 1, "{results:?}");
    }

    #[test]
    fn calout_settles_after_2_ms() {
        let mut b = OpampBank::new();
        wr(
            &mut b,
            0,
            csr::OPAEN | csr::CALON | csr::USERTRIM | (1 << 12),
            0,
        );
        assert_eq!(b.next_event(), Some(340_000));
        assert_eq!(rd(&mut b, 0, 339_999) & csr::CALOUT, 0);
        assert_ne!(
            rd(&mut b, 0, 340_000) & csr::CALOUT,
            0,
            "trim 0 < optimum 16"
        );
    }

    #[test]
    fn lock() {
        let mut b = OpampBank::new();
        wr(&mut b, 0, csr::LOCK | csr::OPAEN, 0);
        wr(&mut b, 0, 0, 1);
        assert_eq!(rd(&mut b, 0, 2), csr::LOCK | csr::OPAEN);
    }
    /// Every PGA_GAIN code RM0440 defines, from the pins' volts: the grounded network
    /// (00xxx, 10xxx) ignores VINM0, the VINM0-biased one (01xxx, 11xxx) subtracts (G-1)
    /// VINM0, so the two modes give different outputs for the same pins.
    #[test]
    fn every_pga_mode_computes_its_output_from_the_pins() {
        let mut b = OpampBank::new();
        b.set_errors(&AnalogErrors::IDEAL);
        let (vinp, vinm0) = (0.12, 0.1);
        for code in 0..32u32 {
            if code & 6 == 6 {
                continue; // reserved
            }
            let g = f64::from(2u32 << (code & 7));
            wr(
                &mut b,
                0,
                csr::OPAEN | (2 << 5) | (code << 14),
                u64::from(code),
            );
            let c = b.config(1).expect("OPAMP1");
            let v = c.output_volts(vinp, vinm0).expect("PGA");
            let want = match code >> 3 {
                0 | 2 => g * vinp,
                _ => g * vinp - (g - 1.0) * vinm0,
            };
            let want = want.clamp(0.0, 3.3);
            assert!(
                (v - want).abs() < 1e-12,
                "PGA_GAIN {code:#07b}: {v} V, want {want} V"
            );
            assert_eq!(c.vinm0_pin().is_some(), code & 8 != 0, "{code:#07b}");
        }
        // The ESC1's case at gain 16: 0.1 V on VINP and on VINM0 (a shunt at 0 A, both
        // sides at the bias): 1.6 V grounded, 0.1 V biased.
        wr(&mut b, 0, csr::OPAEN | (2 << 5) | (0b00011 << 14), 100);
        let grounded = b.config(1).and_then(|c| c.output_volts(0.1, 0.1));
        wr(&mut b, 0, csr::OPAEN | (2 << 5) | (0b01011 << 14), 101);
        let biased = b.config(1).and_then(|c| c.output_volts(0.1, 0.1));
        assert!((grounded.unwrap_or(0.0) - 1.6).abs() < 1e-12);
        assert!((biased.unwrap_or(0.0) - 0.1).abs() < 1e-12);
        assert!(b.take_reports().is_empty());
        wr(&mut b, 0, csr::OPAEN | (2 << 5) | (0b00110 << 14), 102);
        assert!(!b.take_reports().is_empty(), "reserved gain reported");
    }

    /// The input offset is amplified by the noise gain G in every PGA mode, keeps its sign,
    /// and the output stays within the rails.
    #[test]
    fn the_input_offset_is_amplified_with_its_sign() {
        for offset in [0.002, -0.002] {
            let mut b = OpampBank::new();
            b.set_errors(&AnalogErrors {
                opamp_offset_v: offset,
                ..AnalogErrors::IDEAL
            });
            for (code, vinm0) in [(0b00011u32, 0.0), (0b01011, 1.0)] {
                wr(&mut b, 0, csr::OPAEN | (2 << 5) | (code << 14), 0);
                let c = b.config(1).expect("OPAMP1");
                let v = c.output_volts(1.0, vinm0).expect("PGA");
                let ideal = 16.0 * 1.0 - 15.0 * vinm0;
                let ideal = if code == 0b00011 {
                    ideal.min(3.3)
                } else {
                    ideal
                };
                if code == 0b01011 {
                    assert!((v - (ideal + 16.0 * offset)).abs() < 1e-12, "{offset}: {v}");
                } else {
                    assert_eq!(v, 3.3, "clamped to VDDA");
                }
            }
            // Follower: VINP + Vio; a negative result clamps at VSSA.
            wr(&mut b, 0, csr::OPAEN | (3 << 5), 1);
            let c = b.config(1).expect("OPAMP1");
            let v = c.output_volts(0.5, 0.0).expect("follower");
            assert!((v - (0.5 + offset)).abs() < 1e-12);
            assert!(c.output_volts(0.0, 0.0).expect("follower") >= 0.0);
            // Kept across a reset.
            b.reset();
            assert_eq!(b.config(1).map(|c| c.offset_v), Some(offset));
        }
    }
}
