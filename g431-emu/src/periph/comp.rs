//! Comparators COMP1-COMP4 (RM0440 §24 "Comparator (COMP)").
//!
//! One [`CompBank`] covers the four COMPx_CSR registers (offsets 0x0, 0x4, 0x8, 0xC from
//! COMP1's base 0x4001_0200, inside SYSCFG's page).
//!
//! The drive (`drive-image/src/board/hw_protection.rs`, embassy-stm32 0.6 `comp.rs`) writes
//! each CSR once with INPSEL = 0 (COMP1 PA1, COMP2 PA7, COMP3 PA0), INMSEL = DAC (100 for
//! COMP1/2 = DAC3 CH1/CH2, 101 for COMP3 = DAC1 CH1), HYST = 20 mV, the polarity of its board
//! profile (inverted on the bare ESC1), BLANKSEL = 0 and EN, then sets EN again; the board then
//! writes BLANKSEL = TIM1_OC5 on COMP1/2/4 with a read-modify-write; it reads
//! VALUE in the break interrupt. The comparators' outputs
//! are ORed into TIM1's break input (AF1.BKCMPxE).
//!
//! The comparison itself is the host's business (a continuous-time plant): the model decodes
//! the configuration into [`CompConfig`] (which signal is INP, what INM is — a DAC channel, a
//! VREFINT fraction, a pin —, the polarity, the hysteresis in mV, the blanking source), gives
//! the host the level INP must pass next ([`CompBank::threshold`]: INM, the input offset and
//! the hysteresis applied to the comparator's present state), takes the raw comparison from
//! [`CompBank::set_input`] and the blanking signal from [`CompBank::set_blanking`], and gives
//! the output after polarity and blanking (RM0440 "VALUE ... after the polarity selector and
//! blanking"): `EN & ((raw ^ POL) & !blank)`. That output is VALUE and what goes to TIM1's
//! break, the EXTI lines and the COMPx_OUT pins.
//!
//! Analog effects ([`AnalogErrors`], DS12589 "COMP characteristics"; `docs/models.md`):
//! * **Hysteresis** (RM0440 COMP "Comparator hysteresis" figure; the HAL's "hysteresis mode
//!   of the input minus"): it acts on the inverting input and only on the way down. The raw
//!   output rises when INP passes INM (+ offset) and falls only when INP drops below INM
//!   (+ offset) minus the hysteresis: the band lies below INM whatever the polarity (the
//!   polarity selector comes after the comparator). HYST = n gives n x 10 mV (RM0440
//!   COMPx_CSR, `COMP_HYSTERESIS_10MV` .. `_70MV`).
//! * **Input offset**: INP must pass INM + offset (signed, the same for every instance).
//! * **Propagation delay**: a change of the raw comparison reaches the output tD later
//!   ([`Peripheral::next_event`]); a change back within tD cancels it (the pulse is shorter
//!   than the comparator's response). Polarity and blanking are logic after the comparator:
//!   they act at once.
//!
//! Not modelled: the comparator start-up time, the VREFINT scaler start-up time and offset;
//! the raw state at enable is "low" (INP below INM) until the first comparison.

use crate::periph::analog_errors::AnalogErrors;
use crate::periph::dac::DacId;
use crate::periph::reports::Reports;
use crate::periph::{Peripheral, Signal, Write};
use crate::time::Cycles;

/// CSR bits.
mod csr {
    pub const EN: u32 = 1 << 0;
    pub const INMSEL_SHIFT: u32 = 4;
    pub const INPSEL: u32 = 1 << 8;
    pub const POL: u32 = 1 << 15;
    pub const HYST_SHIFT: u32 = 16;
    pub const BLANKSEL_SHIFT: u32 = 19;
    pub const BRGEN: u32 = 1 << 22;
    pub const SCALEN: u32 = 1 << 23;
    pub const VALUE: u32 = 1 << 30;
    pub const LOCK: u32 = 1 << 31;
    pub const MASK: u32 = 0x80ff_8171;
}

/// What the inverting input is connected to (RM0440 "COMP inverting input selection").
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum InvertingInput {
    /// A fraction of VREFINT (1/4, 1/2, 3/4 need BRGEN and SCALEN; 1 needs SCALEN).
    /// `enabled` is false when the scaler/bridge bits it needs are not set.
    Vrefint { fraction: f64, enabled: bool },
    /// A DAC channel (ch 0 = channel 1).
    Dac { dac: DacId, channel: usize },
    /// A pin.
    Pin(&'static str),
}

/// Timer signals a comparator can be blanked with (RM0440 "COMP blanking sources").
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BlankingSource {
    Tim1Oc5,
    Tim2Oc3,
    Tim2Oc4,
    Tim3Oc3,
    Tim3Oc4,
    Tim4Oc3,
    Tim8Oc5,
    Tim15Oc1,
    Tim20Oc5,
}

/// A comparator's configuration, decoded for the host.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CompConfig {
    /// COMPn (1..=4).
    pub comp: usize,
    pub enabled: bool,
    /// The non-inverting input's pin (INPSEL; an OPAMP output pin when that OPAMP drives it:
    /// PA2 = OPAMP1, PA6 = OPAMP2, PB1 = OPAMP3).
    pub inp: &'static str,
    pub inm: InvertingInput,
    /// POLARITY: the output is inverted.
    pub inverted: bool,
    /// Hysteresis in mV (HYST: 0, 10 .. 70).
    pub hysteresis_mv: u16,
    pub blanking: Option<BlankingSource>,
    pub locked: bool,
}

/// One comparator's registers and signals.
#[derive(Debug, Clone, Copy, Default)]
struct Comp {
    csr: u32,
    /// The raw comparison (INP above INM) as the output sees it now.
    raw: bool,
    /// A raw change on its way to the output: (when it arrives, the new level).
    pending: Option<(Cycles, bool)>,
    blank: bool,
}

impl Comp {
    /// The comparator's own state (what its hysteresis follows): the latest decision, even
    /// if it has not reached the output yet.
    fn state(&self) -> bool {
        self.pending.map_or(self.raw, |p| p.1)
    }
}

/// An output change for the SoC (to TIM1's break, EXTI, the COMPx_OUT pin).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CompEdge {
    /// COMPn (1..=4).
    pub comp: usize,
    pub at: Cycles,
    pub level: bool,
}

/// COMP1-COMP4.
#[derive(Debug, Clone)]
pub struct CompBank {
    comps: [Comp; 4],
    outputs: [bool; 4],
    edges: Vec<CompEdge>,
    reports: Reports,
    /// Input offset, volts (kept across resets: a property of the part).
    offset_v: f64,
    /// Propagation delay, cycles.
    delay: Cycles,
}

impl Default for CompBank {
    fn default() -> Self {
        Self::new()
    }
}

const INP: [[&str; 2]; 4] = [
    ["PA1", "PB1"],
    ["PA7", "PA3"],
    ["PA0", "PC1"],
    ["PB0", "PE7"],
];
const INM_IO: [[&str; 2]; 4] = [
    ["PA4", "PA0"],
    ["PA5", "PA2"],
    ["PF1", "PC0"],
    ["PE8", "PB2"],
];

/// (INMSEL 100, INMSEL 101) DAC channels per comparator.
const INM_DAC: [[(DacId, usize); 2]; 4] = [
    [(DacId::Dac3, 0), (DacId::Dac1, 0)],
    [(DacId::Dac3, 1), (DacId::Dac1, 1)],
    [(DacId::Dac3, 0), (DacId::Dac1, 0)],
    [(DacId::Dac3, 1), (DacId::Dac1, 0)],
];

fn blanking(comp: usize, code: u32) -> Option<BlankingSource> {
    use BlankingSource::*;
    let table: [Option<BlankingSource>; 8] = match comp {
        1 | 2 => [
            None,
            Some(Tim1Oc5),
            Some(Tim2Oc3),
            Some(Tim3Oc3),
            Some(Tim8Oc5),
            Some(Tim20Oc5),
            Some(Tim15Oc1),
            Some(Tim4Oc3),
        ],
        3 => [
            None,
            Some(Tim1Oc5),
            Some(Tim3Oc3),
            Some(Tim2Oc4),
            Some(Tim8Oc5),
            Some(Tim20Oc5),
            Some(Tim15Oc1),
            Some(Tim4Oc3),
        ],
        _ => [
            None,
            Some(Tim3Oc4),
            Some(Tim8Oc5),
            Some(Tim15Oc1),
            Some(Tim1Oc5),
            Some(Tim20Oc5),
            Some(Tim15Oc1),
            Some(Tim4Oc3),
        ],
    };
    table[(code & 7) as usize]
}

impl CompBank {
    pub fn new() -> Self {
        let e = AnalogErrors::TYPICAL;
        CompBank {
            comps: [Comp::default(); 4],
            outputs: [false; 4],
            edges: Vec::new(),
            reports: Reports::new("COMP"),
            offset_v: e.comp_offset_v,
            delay: e.comp_delay_cycles(),
        }
    }

    /// Sets the part's input offset and propagation delay (the rest of `errors` is the DACs'
    /// and OPAMPs').
    pub fn set_errors(&mut self, errors: &AnalogErrors) {
        self.offset_v = errors.comp_offset_v;
        self.delay = errors.comp_delay_cycles();
    }

    /// The propagation delay in cycles.
    pub fn delay_cycles(&self) -> Cycles {
        self.delay
    }

    /// The level INP must pass for COMPn's next change, given the volts on INM: INM plus the
    /// input offset while the comparator is low (INP must rise above it); that minus the
    /// hysteresis while it is high (INP must fall below it). `None` for no such comparator.
    pub fn threshold(&self, n: usize, inm_volts: f64) -> Option<f64> {
        let c = self.comps.get(n.checked_sub(1)?)?;
        let hyst_v = f64::from(10 * ((c.csr >> csr::HYST_SHIFT) & 7)) / 1000.0;
        let band = if c.state() { hyst_v } else { 0.0 };
        Some(inm_volts + self.offset_v - band)
    }

    /// The configuration of COMPn (n = 1..=4).
    pub fn config(&self, n: usize) -> Option<CompConfig> {
        let c = self.comps.get(n.checked_sub(1)?)?;
        let i = n - 1;
        let csr = c.csr;
        let inmsel = (csr >> csr::INMSEL_SHIFT) & 7;
        let scalen = csr & csr::SCALEN != 0;
        let brgen = csr & csr::BRGEN != 0;
        let inm = match inmsel {
            0..=2 => InvertingInput::Vrefint {
                fraction: f64::from(inmsel + 1) / 4.0,
                enabled: scalen && brgen,
            },
            3 => InvertingInput::Vrefint {
                fraction: 1.0,
                enabled: scalen,
            },
            4 | 5 => {
                let (dac, channel) = INM_DAC[i][(inmsel - 4) as usize];
                InvertingInput::Dac { dac, channel }
            }
            _ => InvertingInput::Pin(INM_IO[i][(inmsel - 6) as usize]),
        };
        Some(CompConfig {
            comp: n,
            enabled: csr & csr::EN != 0,
            inp: INP[i][usize::from(csr & csr::INPSEL != 0)],
            inm,
            inverted: csr & csr::POL != 0,
            hysteresis_mv: 10 * ((csr >> csr::HYST_SHIFT) & 7) as u16,
            blanking: blanking(n, (csr >> csr::BLANKSEL_SHIFT) & 7),
            locked: csr & csr::LOCK != 0,
        })
    }

    /// The output of COMPn after polarity and blanking.
    pub fn output(&self, n: usize) -> bool {
        n.checked_sub(1)
            .and_then(|i| self.outputs.get(i))
            .copied()
            .unwrap_or(false)
    }

    fn compute(c: &Comp) -> bool {
        c.csr & csr::EN != 0 && (c.raw != (c.csr & csr::POL != 0)) && !c.blank
    }

    /// Recomputes COMPn's output; `Some(level)` when it changed.
    fn refresh(&mut self, i: usize, now: Cycles) -> Option<bool> {
        let c = self.comps.get(i)?;
        let level = Self::compute(c);
        let out = self.outputs.get_mut(i)?;
        if *out == level {
            return None;
        }
        *out = level;
        if self.edges.len() < 4096 {
            self.edges.push(CompEdge {
                comp: i + 1,
                at: now,
                level,
            });
        }
        Some(level)
    }

    /// The host's comparison for COMPn at `now`: whether INP is above
    /// [`CompBank::threshold`]. A change reaches the output after the propagation delay
    /// (at once with no delay: then the new output is returned; forward it to TIM1's
    /// `set_comparator(n, ..)`; delayed changes come out of [`CompBank::take_edges`]).
    pub fn set_input(&mut self, n: usize, above: bool, now: Cycles) -> Option<bool> {
        let i = n.checked_sub(1)?;
        let delay = self.delay;
        let c = self.comps.get_mut(i)?;
        if above == c.state() {
            return None;
        }
        if above == c.raw {
            // Back before the change reached the output: too short for the comparator.
            c.pending = None;
            return None;
        }
        if delay == 0 {
            c.raw = above;
            c.pending = None;
            return self.refresh(i, now);
        }
        c.pending = Some((now + delay, above));
        None
    }

    /// The blanking signal COMPn's BLANKSEL selects changed (e.g. TIM1's OC5 window).
    pub fn set_blanking(&mut self, n: usize, active: bool, now: Cycles) -> Option<bool> {
        let i = n.checked_sub(1)?;
        self.comps.get_mut(i)?.blank = active;
        self.refresh(i, now)
    }

    /// Output changes since the last call (from inputs, blanking and CSR writes).
    pub fn take_edges(&mut self) -> Vec<CompEdge> {
        std::mem::take(&mut self.edges)
    }
}

impl Peripheral for CompBank {
    fn take_signals(&mut self, out: &mut Vec<Signal>) {
        out.extend(self.edges.drain(..).map(Signal::Comparator));
    }

    /// Misuse and unsupported-feature reports since the last call.
    fn take_reports(&mut self) -> Vec<String> {
        self.reports.take()
    }

    fn read(&mut self, offset: u32, _now: Cycles) -> Option<u32> {
        let i = match offset {
            0x0 | 0x4 | 0x8 | 0xc => (offset / 4) as usize,
            _ => return None,
        };
        let c = self.comps.get(i)?;
        let value = if self.outputs.get(i).copied().unwrap_or(false) {
            csr::VALUE
        } else {
            0
        };
        Some(c.csr | value)
    }

    fn write(&mut self, w: Write, now: Cycles) -> bool {
        let i = match w.offset {
            0x0 | 0x4 | 0x8 | 0xc => (w.offset / 4) as usize,
            _ => return false,
        };
        let Some(c) = self.comps.get_mut(i) else {
            return false;
        };
        if c.csr & csr::LOCK != 0 {
            self.reports.once(now, "lock", || {
                format!("COMP{}_CSR is locked (LOCK): write ignored", i + 1)
            });
            return true;
        }
        c.csr = w.merge(c.csr) & csr::MASK;
        let csr_v = c.csr;
        let inmsel = (csr_v >> csr::INMSEL_SHIFT) & 7;
        let needs = match inmsel {
            0..=2 => csr::SCALEN | csr::BRGEN,
            3 => csr::SCALEN,
            _ => 0,
        };
        if csr_v & csr::EN != 0 && csr_v & needs != needs {
            self.reports.once(now, "scaler", || {
                format!(
                    "COMP{}: INM is a VREFINT fraction without SCALEN/BRGEN: the input is not driven",
                    i + 1
                )
            });
        }
        self.refresh(i, now);
        true
    }

    fn next_event(&self) -> Option<Cycles> {
        self.comps
            .iter()
            .filter_map(|c| c.pending.map(|p| p.0))
            .min()
    }

    fn advance(&mut self, now: Cycles) {
        // In time order, so that the edges are.
        let mut due: Vec<(Cycles, usize, bool)> = self
            .comps
            .iter()
            .enumerate()
            .filter_map(|(i, c)| c.pending.filter(|p| p.0 <= now).map(|p| (p.0, i, p.1)))
            .collect();
        due.sort_unstable_by_key(|d| (d.0, d.1));
        for (at, i, level) in due {
            if let Some(c) = self.comps.get_mut(i) {
                c.raw = level;
                c.pending = None;
            }
            self.refresh(i, at);
        }
    }

    fn reset(&mut self) {
        let (offset_v, delay) = (self.offset_v, self.delay);
        *self = CompBank::new();
        self.offset_v = offset_v;
        self.delay = delay;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// embassy-stm32 0.6 `Comp::new` + `enable` as `hw_protection::init` calls it: one CSR
    /// modify with INPSEL, INMSEL, HYST, POLARITY, BLANKSEL, SCALEN/BRGEN, EN, then EN again.
    fn embassy_comp(b: &mut CompBank, n: usize, inmsel: u32, t: Cycles) {
        let off = 4 * (n as u32 - 1);
        let v = b.read(off, t).unwrap_or(0);
        let v = (v & !(csr::INPSEL | (7 << 4) | (7 << 16) | csr::POL | (7 << 19)))
            | (inmsel << 4)
            | (2 << 16) // Hyst20M
            | csr::EN;
        assert!(b.write(Write::word(off, v), t));
        let v = b.read(off, t + 1).unwrap_or(0);
        assert!(b.write(Write::word(off, v | csr::EN), t + 2));
    }

    #[test]
    fn drive_configuration_decodes() {
        let mut b = CompBank::new();
        embassy_comp(&mut b, 1, 0b100, 10); // InvertingInput::Dac1 -> DACA
        embassy_comp(&mut b, 2, 0b100, 20);
        embassy_comp(&mut b, 3, 0b101, 30); // Dac2 -> DACB
        let c1 = b.config(1).expect("COMP1");
        assert_eq!(c1.inp, "PA1");
        assert_eq!(
            c1.inm,
            InvertingInput::Dac {
                dac: DacId::Dac3,
                channel: 0
            }
        );
        assert_eq!(c1.hysteresis_mv, 20);
        assert!(c1.enabled && !c1.inverted && c1.blanking.is_none());
        let c2 = b.config(2).expect("COMP2");
        assert_eq!(c2.inp, "PA7");
        assert_eq!(
            c2.inm,
            InvertingInput::Dac {
                dac: DacId::Dac3,
                channel: 1
            }
        );
        let c3 = b.config(3).expect("COMP3");
        assert_eq!(c3.inp, "PA0");
        assert_eq!(
            c3.inm,
            InvertingInput::Dac {
                dac: DacId::Dac1,
                channel: 0
            }
        );
        assert!(b.take_reports().is_empty());
    }

    #[test]
    fn value_follows_the_input_polarity_and_blanking() {
        let mut b = CompBank::new();
        b.set_errors(&AnalogErrors::IDEAL);
        embassy_comp(&mut b, 1, 0b100, 0);
        assert_eq!(b.read(0, 3).unwrap_or(0) & csr::VALUE, 0);
        assert_eq!(b.set_input(1, true, 5), Some(true));
        assert_ne!(b.read(0, 5).unwrap_or(0) & csr::VALUE, 0);
        assert_eq!(b.set_input(1, true, 6), None, "no change, no edge");
        // Blanking masks the output.
        let v = b.read(0, 7).unwrap_or(0);
        assert!(b.write(Write::word(0, v | (1 << 19)), 7));
        assert_eq!(
            b.config(1).and_then(|c| c.blanking),
            Some(BlankingSource::Tim1Oc5)
        );
        assert_eq!(b.set_blanking(1, true, 8), Some(false));
        assert_eq!(b.read(0, 8).unwrap_or(0) & csr::VALUE, 0);
        assert_eq!(b.set_blanking(1, false, 9), Some(true));
        // Polarity inverts.
        let v = b.read(0, 10).unwrap_or(0);
        assert!(b.write(Write::word(0, v | csr::POL), 10));
        assert_eq!(b.read(0, 10).unwrap_or(0) & csr::VALUE, 0);
        // VALUE is read-only.
        assert!(b.write(Write::word(0, csr::VALUE | csr::EN), 11));
        let edges = b.take_edges();
        assert_eq!(
            edges.iter().map(|e| (e.at, e.level)).collect::<Vec<_>>(),
            vec![(5, true), (8, false), (9, true), (10, false), (11, true)]
        );
        // Disabled: output low.
        assert!(b.write(Write::word(0, 0), 12));
        assert!(!b.output(1));
    }

    #[test]
    fn lock_makes_the_csr_read_only() {
        let mut b = CompBank::new();
        assert!(b.write(Write::word(4, csr::LOCK | csr::EN), 0));
        assert!(b.write(Write::word(4, 0), 1));
        assert_eq!(b.read(4, 2), Some(csr::LOCK | csr::EN));
    }

    #[test]
    fn inputs_of_every_instance() {
        let mut b = CompBank::new();
        for n in 1..=4usize {
            let off = 4 * (n as u32 - 1);
            assert!(b.write(Write::word(off, csr::INPSEL | (0b111 << 4) | (4 << 19)), 0));
        }
        let inp: Vec<&str> = (1..=4).filter_map(|n| b.config(n)).map(|c| c.inp).collect();
        assert_eq!(inp, vec!["PB1", "PA3", "PC1", "PE7"]);
        let inm: Vec<InvertingInput> = (1..=4).filter_map(|n| b.config(n)).map(|c| c.inm).collect();
        assert_eq!(
            inm,
            vec![
                InvertingInput::Pin("PA0"),
                InvertingInput::Pin("PA2"),
                InvertingInput::Pin("PC0"),
                InvertingInput::Pin("PB2")
            ]
        );
        assert_eq!(
            b.config(4).and_then(|c| c.blanking),
            Some(BlankingSource::Tim1Oc5)
        );
        assert_eq!(
            b.config(3).and_then(|c| c.blanking),
            Some(BlankingSource::Tim8Oc5)
        );
        assert_eq!(b.config(5), None);
        // A VREFINT fraction without the scaler is reported.
        assert!(b.write(Write::word(0, csr::EN | (1 << 4)), 1));
        assert!(!b.take_reports().is_empty());
        assert!(b.write(
            Write::word(0, csr::EN | (1 << 4) | csr::SCALEN | csr::BRGEN),
            2
        ));
        assert_eq!(
            b.config(1).map(|c| c.inm),
            Some(InvertingInput::Vrefint {
                fraction: 0.5,
                enabled: true
            })
        );
    }

    /// TIM1 OC5 as the blanking window of COMP1 (BLANKSEL = 001), COMP1 into
    /// TIM1's break; a spike inside the window does not trip, one outside does.
    #[test]
    fn tim1_oc5_blanks_the_comparator_break() {
        use crate::periph::tim_adv::{OffCause, TimAdv, TimEvent};
        let mut tim = TimAdv::new("TIM1");
        let mut comps = CompBank::new();
        comps.set_errors(&AnalogErrors::IDEAL);
        let mut t: Cycles = 10;
        let w = |tim: &mut TimAdv, off: u32, v: u32, t: &mut Cycles| {
            tim.advance(*t);
            assert!(tim.write(Write::word(off, v), *t));
            *t += 1;
        };
        w(&mut tim, 0x2c, 1000, &mut t); // ARR
        w(&mut tim, 0x50, 6 << 4, &mut t); // CCMR3: OC5 PWM mode 1
        w(&mut tim, 0x48, 50, &mut t); // CCR5: window of +-50 counts around the valley
        w(&mut tim, 0x20, 1 << 16, &mut t); // CC5E
        w(&mut tim, 0x60, 1 << 1, &mut t); // AF1: BKCMP1E only
        w(&mut tim, 0x44, (1 << 12) | (1 << 13) | (1 << 15), &mut t); // BKE, BKP, MOE
        w(&mut tim, 0x00, (1 << 5) | 1, &mut t); // centre-aligned 1, CEN
        let cen = t - 1;
        let _ = tim.take_events().count();
        assert!(comps.write(Write::word(0, csr::EN | (0b100 << 4) | (1 << 19)), t));
        // The SoC's wiring: TIM1 blanking edges to COMP1, COMP1 output edges to the break.
        let forward = |tim: &mut TimAdv, comps: &mut CompBank, now: Cycles| {
            tim.advance(now);
            let ev: Vec<TimEvent> = tim.take_events().collect();
            for e in ev {
                if let TimEvent::Blanking { at, active } = e {
                    if let Some(level) = comps.set_blanking(1, active, at) {
                        tim.set_comparator(1, level, at);
                    }
                }
            }
        };
        forward(&mut tim, &mut comps, t);
        // The window is open for phases [1950, 2000) and [0, 50): after cen + 1950.
        let valley = cen + 2000;
        let mut now = t;
        while let Some(next) = tim.next_event() {
            if next > valley {
                break;
            }
            now = next;
            forward(&mut tim, &mut comps, now);
        }
        assert!(comps
            .config(1)
            .is_some_and(|c| c.blanking == Some(BlankingSource::Tim1Oc5)));
        assert!(tim.blanking(valley - 10));
        // A current spike inside the window (20 cycles from the valley on): no break.
        if let Some(l) = comps.set_input(1, true, valley) {
            tim.set_comparator(1, l, valley);
        }
        if let Some(l) = comps.set_input(1, false, valley + 20) {
            tim.set_comparator(1, l, valley + 20);
        }
        assert!(tim.gate().moe, "blanked: MOE stays set");
        // Run past the window's end (valley + 50) and spike again: the break trips.
        while let Some(next) = tim.next_event() {
            if next > valley + 100 {
                break;
            }
            now = next;
            forward(&mut tim, &mut comps, now);
        }
        assert!(now >= valley + 50 && !tim.blanking(valley + 100));
        forward(&mut tim, &mut comps, valley + 100);
        let at = valley + 100;
        if let Some(l) = comps.set_input(1, true, at) {
            tim.set_comparator(1, l, at);
        }
        assert!(!tim.gate().moe);
        assert!(tim.take_events().any(|e| e
            == TimEvent::OutputsOff {
                at,
                cause: OffCause::Break
            }));
    }
    /// The host's side of the comparison (what the SoC does at each sample).
    fn sample(b: &mut CompBank, n: usize, inp: f64, inm: f64, t: Cycles) {
        let thr = b.threshold(n, inm).expect("COMPn");
        b.set_input(n, inp > thr, t);
        b.advance(t);
    }

    /// CSR with EN, INMSEL = DAC3, HYST = `hyst`, polarity `inverted`.
    fn csr_word(hyst: u32, inverted: bool) -> u32 {
        csr::EN | (0b100 << 4) | (hyst << 16) | if inverted { csr::POL } else { 0 }
    }

    /// RM0440's hysteresis figure: the output rises when INP passes INM and falls only when
    /// INP drops below INM - Vhyst; the band is below INM in both directions of travel.
    #[test]
    fn hysteresis_lies_below_inm_and_acts_on_the_way_down() {
        let mut b = CompBank::new();
        b.set_errors(&AnalogErrors::IDEAL);
        assert!(b.write(Write::word(0, csr_word(2, false)), 0));
        let inm = 1.0;
        // Rising: high as soon as INP passes INM.
        sample(&mut b, 1, 0.999, inm, 1);
        assert!(!b.output(1));
        sample(&mut b, 1, 1.001, inm, 2);
        assert!(b.output(1));
        // Falling: stays high down to INM - 20 mV.
        sample(&mut b, 1, 0.985, inm, 3);
        assert!(b.output(1), "inside the band: no change");
        sample(&mut b, 1, 0.979, inm, 4);
        assert!(!b.output(1), "below INM - 20 mV");
        // Rising again: inside the band it stays low; the threshold is INM again.
        sample(&mut b, 1, 0.995, inm, 5);
        assert!(!b.output(1));
        assert_eq!(b.threshold(1, inm), Some(1.0));
        // Inverted polarity: the same comparator, the output inverted after it. A signal
        // that must trip when it falls below INM (the ESC1's positive current) trips only
        // 20 mV further down; it releases when it rises back above INM.
        let mut b = CompBank::new();
        b.set_errors(&AnalogErrors::IDEAL);
        assert!(b.write(Write::word(0, csr_word(2, true)), 0));
        sample(&mut b, 1, 1.05, inm, 1);
        assert!(!b.output(1), "INP above INM: inverted output low");
        sample(&mut b, 1, 0.99, inm, 2);
        assert!(!b.output(1), "10 mV below INM: no trip yet");
        sample(&mut b, 1, 0.975, inm, 3);
        assert!(b.output(1), "25 mV below INM: trip");
        sample(&mut b, 1, 0.99, inm, 4);
        assert!(b.output(1), "inside the band: still tripped");
        sample(&mut b, 1, 1.001, inm, 5);
        assert!(!b.output(1), "released above INM");
    }

    #[test]
    fn hysteresis_levels_of_every_code() {
        let mut b = CompBank::new();
        b.set_errors(&AnalogErrors::IDEAL);
        for hyst in 0..8u32 {
            assert!(b.write(Write::word(0, csr_word(hyst, false)), 0));
            sample(&mut b, 1, 2.0, 1.0, 1);
            assert!(b.output(1));
            let thr = b.threshold(1, 1.0).expect("COMP1");
            assert!(
                (thr - (1.0 - 0.01 * f64::from(hyst))).abs() < 1e-12,
                "HYST {hyst}: {thr}"
            );
            sample(&mut b, 1, 0.0, 1.0, 2);
            assert!(!b.output(1));
        }
    }

    #[test]
    fn the_input_offset_moves_both_levels_by_its_signed_value() {
        for offset in [0.005, -0.005] {
            let mut b = CompBank::new();
            b.set_errors(&AnalogErrors {
                comp_offset_v: offset,
                ..AnalogErrors::IDEAL
            });
            assert!(b.write(Write::word(0, csr_word(1, false)), 0));
            let rise = b.threshold(1, 1.0).expect("COMP1");
            assert!((rise - (1.0 + offset)).abs() < 1e-12);
            // Just below and just above the offset level.
            sample(&mut b, 1, 1.0 + offset - 0.0005, 1.0, 1);
            assert!(!b.output(1), "offset {offset}");
            sample(&mut b, 1, 1.0 + offset + 0.0005, 1.0, 2);
            assert!(b.output(1), "offset {offset}");
            let fall = b.threshold(1, 1.0).expect("COMP1");
            assert!((fall - (1.0 + offset - 0.010)).abs() < 1e-12);
        }
        // The typical part: INP must pass INM + 2 mV.
        let b = CompBank::new();
        assert_eq!(
            b.threshold(1, 1.0),
            Some(1.0 + AnalogErrors::TYPICAL.comp_offset_v)
        );
    }

    #[test]
    fn the_output_follows_a_crossing_after_the_propagation_delay() {
        let mut b = CompBank::new();
        assert_eq!(b.delay_cycles(), 3, "DS12589 tD 16.7 ns at 170 MHz");
        assert!(b.write(Write::word(0, csr_word(0, false)), 0));
        let _ = b.take_edges();
        assert_eq!(b.set_input(1, true, 100), None, "not yet at the output");
        assert_eq!(b.next_event(), Some(103));
        b.advance(102);
        assert!(!b.output(1));
        b.advance(103);
        assert!(b.output(1));
        assert_eq!(b.next_event(), None);
        // VALUE reads the delayed output too.
        assert_ne!(b.read(0, 103).unwrap_or(0) & csr::VALUE, 0);
        // A dip shorter than the delay never reaches the output.
        assert_eq!(b.set_input(1, false, 200), None);
        assert_eq!(b.set_input(1, true, 201), None);
        assert_eq!(b.next_event(), None);
        b.advance(210);
        assert!(b.output(1));
        assert_eq!(
            b.take_edges(),
            vec![CompEdge {
                comp: 1,
                at: 103,
                level: true
            }]
        );
        // Blanking is logic after the comparator: it acts at once.
        let v = b.read(0, 211).unwrap_or(0);
        assert!(b.write(Write::word(0, v | (1 << 19)), 211));
        assert_eq!(b.set_blanking(1, true, 212), Some(false));
        // The errors survive a reset (they are the part's).
        b.reset();
        assert_eq!(b.delay_cycles(), 3);
    }
}
