//! Advanced-control timers TIM1/TIM8 (RM0440 §29 "Advanced-control timers (TIM1/TIM8/TIM20)").
//!
//! TIM1 is the drive's power stage (`drive-image/src/board/power_stage.rs`): centre-aligned
//! mode 1 with ARPE and RCR = 1 written before CEN (one update per period, at the valley),
//! CH1-3 in PWM mode 1 with preload and complementary outputs with dead time (DTG), CH4 in PWM
//! mode 2 at ARR-1 as TRGO2 (MMS2 = OC4REF) for the ADCs' injected sequences, break input 1
//! from COMP1-3 (AF1.BKCMPxE, BKINE cleared, BKP = 1), AOE off, MOE as the output switch, BIF
//! and UIF handling through the update and break interrupts.
//!
//! The counter and compare core is [`super::tim_gp::TimeBase`] (analytical timing, see there).
//! This module adds what the advanced timers have on top:
//! * six channels (CH5/CH6 internal; OC5 is the comparator blanking window and can be ANDed
//!   into OC1-3REF with CCR5.GC5Cx), complementary outputs, dead time (DTG/DTGF, DTAE, CKD)
//!   with its preload DTPE (RM0440 TIMx_DTR2), COM (CCPC) preload of CCxE/CCxNE/OCxM;
//! * the repetition counter (RCR);
//! * break and break 2 (RM0440 §29.3.18 "Using the break function"): the break signal is
//!   `(BKINE & (BKIN ^ BKINP)) | OR(BKCMPxE & (COMPx ^ BKCMPxP))` taken with polarity BKP,
//!   digitally filtered by BKF, ORed with the system break (`tim_sys_brk`: LOCKUP, PVD, SRAM
//!   parity, flash ECC as enabled in SYSCFG_CFGR2, which the SoC evaluates), and enabled by
//!   BKE. While it is active MOE is cleared at once and writing MOE = 1 is refused; BIF is
//!   set by the break input (BKIN, comparators) and SBIF by the system break, each only by
//!   its own source, and neither can be cleared while its source is active (RM0440 register
//!   "TIMx status register (TIMx_SR)" and §29.3.18; see `eval_breaks`); AOE sets MOE again
//!   at the next update event once the break is gone. Break 2 likewise with AF2/BK2E/BK2P/BK2F and B2IF. EGR.BG/B2G generate a
//!   break event from software;
//! * LOCK levels (BDTR.LOCK, write-once);
//! * the debug freeze (DBGMCU DBG_TIM1_STOP while the core is halted): the counter stops and
//!   the outputs are disabled "as if MOE was reset" until the core runs again;
//! * TRGO (MMS) and TRGO2 (MMS2) as timed edges, the OC5 blanking window as timed edges, and
//!   the effective gate state ([`GateState`]) for the SoC and the plant.

use std::collections::VecDeque;

use super::reports::Reports;
use super::tim_gp::{
    advance_events, cr1, ocm, Channels, CountMode, EventTimer, StoredRegs, TimeBase,
    EVENT_QUEUE_LIMIT,
};
use crate::names;
use crate::periph::{IrqLines, Peripheral, Signal, Write};
use crate::time::Cycles;

/// SR bits.
mod sr {
    pub const UIF: u32 = 1 << 0;
    pub const COMIF: u32 = 1 << 5;
    pub const TIF: u32 = 1 << 6;
    pub const BIF: u32 = 1 << 7;
    pub const B2IF: u32 = 1 << 8;
    pub const SBIF: u32 = 1 << 13;
    pub const CC5IF: u32 = 1 << 16;
    pub const CC6IF: u32 = 1 << 17;
    pub const MASK: u32 = 0x00f3_3fff;
}

/// BDTR bits.
mod bdtr {
    pub const DTG: u32 = 0xff;
    pub const LOCK_SHIFT: u32 = 8;
    pub const LOCK: u32 = 3 << LOCK_SHIFT;
    pub const OSSI: u32 = 1 << 10;
    pub const OSSR: u32 = 1 << 11;
    pub const BKE: u32 = 1 << 12;
    pub const BKP: u32 = 1 << 13;
    pub const AOE: u32 = 1 << 14;
    pub const MOE: u32 = 1 << 15;
    pub const BKF_SHIFT: u32 = 16;
    pub const BK2F_SHIFT: u32 = 20;
    pub const BK2E: u32 = 1 << 24;
    pub const BK2P: u32 = 1 << 25;
    pub const DSRM_BID: u32 = 0x3c00_0000;
    pub const MASK: u32 = 0x3fff_ffff;
    /// Bits frozen by LOCK level 1 (DTG, BKE/BKP/AOE, the filters, break 2, disarm/bid).
    pub const LOCK1: u32 = DTG | BKE | BKP | AOE | 0x3fff_0000;
    /// Added by LOCK level 2.
    pub const LOCK2: u32 = OSSI | OSSR;
}

const DIER_MASK: u32 = 0x00f0_7fff;
const DIER_UIE: u32 = 1 << 0;
const DIER_COMIE: u32 = 1 << 5;
const DIER_TIE: u32 = 1 << 6;
const DIER_BIE: u32 = 1 << 7;
const DIER_DMA: u32 = 0x0000_7f00;
const CR2_MASK: u32 = 0x02f5_fffd;
const CR2_CCPC: u32 = 1 << 0;
/// OISx/OISxN (frozen by LOCK level 1).
const CR2_OIS: u32 = 0x0005_ff00;
const CCER_MASK: u32 = 0x0033_ffff;
/// CCxP/CCxNP (frozen by LOCK level 2).
const CCER_POL: u32 = 0x0022_aaaa;
/// CCxE/CCxNE of channels 1-4 (preloaded with CCPC).
const CCER_EN14: u32 = 0x0000_5555;
const CCMR_MASK: u32 = 0x0101_ffff;
const CCMR3_MASK: u32 = 0x0101_fcfc;
/// OCxM/OCxPE bits of a CCMR (frozen by LOCK level 3).
const CCMR_OC: u32 = 0x0101_7878;
const AF1_MASK: u32 = 0x0003_ffff;
const AF2_MASK: u32 = 0x0007_3fff;
/// The break-related AF bits (frozen by LOCK level 1).
const AF_BRK: u32 = 0x0000_3fff;
const DTR2_MASK: u32 = 0x0003_00ff;
const DTR2_DTAE: u32 = 1 << 16;
const DTR2_DTPE: u32 = 1 << 17;

/// Why the outputs went off.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OffCause {
    /// MOE cleared by a BDTR write.
    Software,
    /// Break input 1 (BKIN pin or a comparator).
    Break,
    /// Break input 2.
    Break2,
    /// A system break (`tim_sys_brk`).
    SystemBreak,
    /// EGR.BG or EGR.B2G.
    SoftwareBreak,
    /// The core halted with DBG_TIM1_STOP set.
    DebugFreeze,
}

/// Which break flag a break event set.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BreakInput {
    Brk,
    Brk2,
    System,
}

/// How the timer drives one output pin (RM0440 "Output control bits for complementary OCx and
/// OCxN channels with break feature").
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PinDrive {
    /// Not driven by the timer (Hi-Z or the GPIO's own level).
    Released,
    /// Driven at a fixed level (inactive level, or the idle level OISx/OISxN).
    Forced(bool),
    /// Follows OCxREF (its inverse if `complement`, for OCxN), the rising edge of that signal
    /// delayed by `delay` cycles (dead time; 0 without complementary pair), then inverted if
    /// `inverted` (CCxP/CCxNP).
    Ref {
        complement: bool,
        delay: u32,
        inverted: bool,
    },
}

/// One output-compare reference (OCxREF) as configured.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct OcRef {
    /// OCxM (6 = PWM mode 1, 7 = PWM mode 2, 4/5 forced, 0-3 held/match-driven).
    pub mode: u8,
    /// The compare value in effect (after preload).
    pub ccr: u32,
    /// The held level for modes 0-3.
    pub held: bool,
}

/// One channel's outputs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ChannelGate {
    pub oc: OcRef,
    /// OCx (the high-side switch of a bridge leg).
    pub high: PinDrive,
    /// OCxN (the low-side switch).
    pub low: PinDrive,
    /// CCR5.GC5Cx: OCxREF is ANDed with OC5REF.
    pub with_oc5: bool,
}

/// The effective gate state: everything the plant needs to compute the six gate signals at any
/// cycle until the next [`TimEvent::Update`] or [`TimEvent::GateChanged`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct GateState {
    /// The cycle this state took effect.
    pub since: Cycles,
    /// BDTR.MOE.
    pub moe: bool,
    /// Debug freeze in effect.
    pub frozen: bool,
    /// MOE and not frozen: the outputs follow their references.
    pub outputs_enabled: bool,
    /// The counter is counting.
    pub counting: bool,
    pub mode: CountMode,
    /// ARR in effect.
    pub arr: u32,
    /// Cycles per counter step (PSC + 1, in effect).
    pub cycles_per_count: u64,
    /// The cycle the counter (virtually) stepped onto phase 0 (the valley in centre-aligned
    /// mode); `None` while stopped.
    pub phase_origin: Option<Cycles>,
    /// Dead time before a rising OCx, in cycles (DTG × tDTS).
    pub dead_time_rising: u32,
    /// Dead time before a rising OCxN (DTGF with DTAE, else the same as rising).
    pub dead_time_falling: u32,
    /// CH1-CH4.
    pub channels: [ChannelGate; 4],
    /// OC5REF (for GC5Cx).
    pub oc5: OcRef,
}

impl GateState {
    fn len(&self) -> u64 {
        let a = u64::from(self.arr);
        match self.mode {
            CountMode::Centre(_) => 2 * a,
            _ => a + 1,
        }
    }

    /// (counter, counting down) at phase `p`.
    fn phase_state(&self, p: u64) -> (u32, bool) {
        let a = u64::from(self.arr);
        match self.mode {
            CountMode::Up => (p as u32, false),
            CountMode::Down => (a.saturating_sub(p) as u32, true),
            CountMode::Centre(_) if p < a => (p as u32, false),
            CountMode::Centre(_) => ((2 * a).saturating_sub(p) as u32, true),
        }
    }

    /// The counter's phase at `t` (t ≥ `since`), `None` while stopped.
    pub fn phase_at(&self, t: Cycles) -> Option<u64> {
        let o = self.phase_origin?;
        let len = self.len();
        if len == 0 || !self.counting {
            return None;
        }
        Some(((t.checked_sub(o)?) / self.cycles_per_count.max(1)) % len)
    }

    /// The counter value at `t`.
    pub fn counter_at(&self, t: Cycles) -> Option<u32> {
        self.phase_at(t).map(|p| self.phase_state(p).0)
    }

    fn ref_at_phase(oc: &OcRef, state: (u32, bool)) -> bool {
        match oc.mode {
            ocm::FORCE_INACTIVE => false,
            ocm::FORCE_ACTIVE => true,
            ocm::PWM1 | ocm::PWM2 => {
                let (cnt, down) = state;
                let pwm1 = if down { cnt <= oc.ccr } else { cnt < oc.ccr };
                pwm1 != (oc.mode == ocm::PWM2)
            }
            _ => oc.held,
        }
    }

    /// OCxREF (after GC5Cx) of channel `ch` (0 = CH1) at phase `p`.
    fn refc_at_phase(&self, ch: usize, p: Option<u64>) -> bool {
        let Some(c) = self.channels.get(ch) else {
            return false;
        };
        let state = p.map(|p| self.phase_state(p));
        let level = |oc: &OcRef| match state {
            Some(s) => Self::ref_at_phase(oc, s),
            None => match oc.mode {
                ocm::FORCE_ACTIVE => true,
                ocm::FORCE_INACTIVE | ocm::PWM1 | ocm::PWM2 => false,
                _ => oc.held,
            },
        };
        level(&c.oc) && (!c.with_oc5 || level(&self.oc5))
    }

    /// OCxREF (ANDed with OC5REF when grouped) of channel `ch` (0 = CH1) at `t`. Exact for the
    /// PWM and forced modes; the match-driven modes give their level at `since`. While stopped
    /// the PWM reference is taken as inactive.
    pub fn ocref(&self, ch: usize, t: Cycles) -> bool {
        self.refc_at_phase(ch, self.phase_at(t))
    }

    /// How long (in cycles, capped at `cap`) OCxREF of `ch` has had its level at `t`.
    fn ref_stable_for(&self, ch: usize, t: Cycles, cap: u64) -> u64 {
        let (Some(o), true) = (self.phase_origin, self.counting) else {
            return cap;
        };
        let len = self.len();
        let Some(c) = self.channels.get(ch) else {
            return cap;
        };
        let Some(d) = t.checked_sub(o) else {
            return cap;
        };
        if len == 0 {
            return cap;
        }
        let per = self.cycles_per_count.max(1);
        let n = d / per;
        let p = n % len;
        // Cycles since the counter stepped onto the present phase.
        let into = d - n * per;
        // The reference can only change where the counter steps onto or off a compare value,
        // or turns around.
        let mut cand = [None; 12];
        let mut k = 0;
        for oc in [Some(&c.oc), c.with_oc5.then_some(&self.oc5)]
            .into_iter()
            .flatten()
        {
            if !matches!(oc.mode, ocm::PWM1 | ocm::PWM2) {
                continue;
            }
            for q in self.match_phases(oc.ccr).into_iter().flatten() {
                cand[k] = Some(q);
                cand[k + 1] = Some((q + 1) % len);
                k += 2;
            }
            cand[k] = Some(0);
            cand[k + 1] = Some(u64::from(self.arr) % len);
            k += 2;
        }
        let mut best = cap;
        for q in cand.into_iter().flatten() {
            let before = (q + len - 1) % len;
            if self.refc_at_phase(ch, Some(q)) != self.refc_at_phase(ch, Some(before)) {
                let back = (p + len - q) % len;
                best = best.min(into + back * per);
            }
        }
        best
    }

    /// The phases at which the counter steps onto `v`.
    fn match_phases(&self, v: u32) -> [Option<u64>; 2] {
        let a = u64::from(self.arr);
        let v = u64::from(v);
        if v > a {
            return [None, None];
        }
        match self.mode {
            CountMode::Up => [Some(v), None],
            CountMode::Down => [Some(a - v), None],
            CountMode::Centre(_) if v == 0 || v == a => [Some(v), None],
            CountMode::Centre(_) => [Some(v), Some(2 * a - v)],
        }
    }

    /// The level of output pin OCx (`high`) or OCxN of channel `ch` at `t`; `None` when the
    /// timer does not drive it.
    pub fn pin(&self, ch: usize, high: bool, t: Cycles) -> Option<bool> {
        let c = self.channels.get(ch)?;
        let drive = if high { c.high } else { c.low };
        match drive {
            PinDrive::Released => None,
            PinDrive::Forced(level) => Some(level),
            PinDrive::Ref {
                complement,
                delay,
                inverted,
            } => {
                let r = self.ocref(ch, t) != complement;
                let on = r && self.ref_stable_for(ch, t, u64::from(delay)) >= u64::from(delay);
                Some(on != inverted)
            }
        }
    }
}

/// A timed event for the SoC and the plant, drained with [`TimAdv::take_events`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TimEvent {
    /// An update event (the preloads took effect); the gate state from then on.
    Update { at: Cycles, gate: GateState },
    /// The gate state changed outside an update event (a register written without preload,
    /// MOE, the debug freeze, a break).
    GateChanged { at: Cycles, gate: GateState },
    /// The outputs went off (MOE cleared, or frozen).
    OutputsOff { at: Cycles, cause: OffCause },
    /// The outputs came on.
    OutputsOn { at: Cycles },
    /// TRGO changed level (a pulse is a rising and a falling edge at the same cycle).
    Trgo { at: Cycles, level: bool },
    /// TRGO2 changed level (TIM1_TRGO2 triggers the ADC injected sequences).
    Trgo2 { at: Cycles, level: bool },
    /// The OC5 output (CC5E, CC5P) changed: the comparator blanking window (COMP BLANKSEL =
    /// TIM1_OC5) opened (`true`) or closed.
    Blanking { at: Cycles, active: bool },
    /// A break set its flag.
    Break { at: Cycles, input: BreakInput },
}

/// The digital filter of a break input (BKF/BK2F).
#[derive(Debug, Clone, Copy, Default)]
struct Filter {
    raw: bool,
    out: bool,
    pending: Option<Cycles>,
}

impl Filter {
    fn set(&mut self, raw: bool, delay: u64, now: Cycles) {
        let changed = raw != self.raw;
        self.raw = raw;
        if delay == 0 {
            self.out = raw;
            self.pending = None;
        } else if raw == self.out {
            self.pending = None;
        } else if changed || self.pending.is_none() {
            self.pending = Some(now + delay);
        }
    }
}

/// Cycles a break filter needs to validate a transition: N samples at f_SAMPLING (RM0440 BDTR
/// BKF: fCK_INT for codes 1-3, fDTS/2..32 for 4-15). The sampling phase is not modelled: the
/// output follows the input exactly N sample periods after it last changed.
fn filter_delay(code: u32, tdts: u64) -> u64 {
    let (div, n, dts) = match code {
        0 => return 0,
        1 => (1, 2, false),
        2 => (1, 4, false),
        3 => (1, 8, false),
        4 => (2, 6, true),
        5 => (2, 8, true),
        6 => (4, 6, true),
        7 => (4, 8, true),
        8 => (8, 6, true),
        9 => (8, 8, true),
        10 => (16, 5, true),
        11 => (16, 6, true),
        12 => (16, 8, true),
        13 => (32, 5, true),
        14 => (32, 6, true),
        _ => (32, 8, true),
    };
    div * n * if dts { tdts } else { 1 }
}

/// Dead time in tDTS periods for a DTG code (RM0440 TIMx_BDTR.DTG).
pub fn decode_dtg(dtg: u8) -> u32 {
    let d = u32::from(dtg);
    match dtg >> 5 {
        0..=3 => d & 0x7f,
        4 | 5 => (64 + (d & 0x3f)) * 2,
        6 => (32 + (d & 0x1f)) * 8,
        _ => (32 + (d & 0x1f)) * 16,
    }
}

/// An advanced-control timer: TIM1 or TIM8.
#[derive(Debug, Clone)]
pub struct TimAdv {
    name: &'static str,
    irq_up: Option<u16>,
    irq_brk: Option<u16>,
    irq_cc: Option<u16>,
    irq_trg_com: Option<u16>,
    tb: TimeBase,
    ch: Channels<6>,
    cr2: u32,
    smcr: u32,
    dier: u32,
    sr: u32,
    ccmr: [u32; 3],
    /// CCER as written; `ccer` is in effect (they differ only with CCPC until COM).
    ccer_pre: u32,
    ccer: u32,
    bdtr: u32,
    /// Reads of BDTR by the bus since reset (a read-modify-write of BDTR can
    /// write a MOE back that a break cleared in between; the drive writes it whole).
    bdtr_reads: u64,
    dtr2: u32,
    /// DTG/DTGF as transferred at the last update (used with DTPE).
    dtg_shadow: u8,
    dtgf_shadow: u8,
    gc5: u32,
    af1: u32,
    af2: u32,
    lock_written: bool,
    // Inputs.
    bkin: bool,
    bkin2: bool,
    comp: [bool; 8],
    sys_brk: bool,
    brk: Filter,
    brk2: Filter,
    /// Break 1 (with system break) / break 2 active now.
    active1: bool,
    active2: bool,
    // Outputs as last reported.
    outputs_on: bool,
    trgo: bool,
    trgo2: bool,
    blank: bool,
    refs: [bool; 6],
    gate: GateState,
    stored: StoredRegs,
    last: Cycles,
    events: VecDeque<TimEvent>,
    reports: Reports,
}

impl TimAdv {
    /// The timer `name` ("TIM1" or "TIM8") in its reset state, with its interrupt lines from the
    /// metadata.
    pub fn new(name: &'static str) -> Self {
        let (up, brk, cc, trg) = match name {
            "TIM8" => ("TIM8_UP", "TIM8_BRK", "TIM8_CC", "TIM8_TRG_COM"),
            _ => (
                "TIM1_UP_TIM16",
                "TIM1_BRK_TIM15",
                "TIM1_CC",
                "TIM1_TRG_COM_TIM17",
            ),
        };
        let mut t = TimAdv {
            name,
            irq_up: names::irq(up),
            irq_brk: names::irq(brk),
            irq_cc: names::irq(cc),
            irq_trg_com: names::irq(trg),
            tb: TimeBase::new(false, true),
            ch: Channels::new(),
            cr2: 0,
            smcr: 0,
            dier: 0,
            sr: 0,
            ccmr: [0; 3],
            ccer_pre: 0,
            ccer: 0,
            bdtr: 0,
            bdtr_reads: 0,
            dtr2: 0,
            dtg_shadow: 0,
            dtgf_shadow: 0,
            gc5: 0,
            // BKINE / BK2INE reset to 1.
            af1: 1,
            af2: 1,
            lock_written: false,
            bkin: false,
            bkin2: false,
            comp: [false; 8],
            sys_brk: false,
            brk: Filter::default(),
            brk2: Filter::default(),
            active1: false,
            active2: false,
            outputs_on: false,
            trgo: false,
            trgo2: false,
            blank: false,
            refs: [false; 6],
            gate: GateState {
                since: 0,
                moe: false,
                frozen: false,
                outputs_enabled: false,
                counting: false,
                mode: CountMode::Up,
                arr: 0xffff,
                cycles_per_count: 1,
                phase_origin: None,
                dead_time_rising: 0,
                dead_time_falling: 0,
                channels: [ChannelGate {
                    oc: OcRef {
                        mode: 0,
                        ccr: 0,
                        held: false,
                    },
                    high: PinDrive::Released,
                    low: PinDrive::Released,
                    with_oc5: false,
                }; 4],
                oc5: OcRef {
                    mode: 0,
                    ccr: 0,
                    held: false,
                },
            },
            stored: StoredRegs::default(),
            last: 0,
            events: VecDeque::new(),
            reports: Reports::new(name),
        };
        t.update_break_inputs(0);
        t.gate = t.gate_state(0);
        t
    }

    // ---- Typed interface for the SoC ----

    /// Timed events since the last call, in time order.
    pub fn take_events(&mut self) -> impl Iterator<Item = TimEvent> + '_ {
        self.events.drain(..)
    }

    /// The comparator output COMPn (n = 1..=7, after its polarity and blanking) changed.
    pub fn set_comparator(&mut self, n: usize, level: bool, now: Cycles) {
        let now = self.catch_up(now);
        if let Some(c) = n.checked_sub(1).and_then(|i| self.comp.get_mut(i)) {
            *c = level;
        }
        self.update_break_inputs(now);
        self.settle(now);
    }

    /// The BKIN pin level changed.
    pub fn set_bkin(&mut self, level: bool, now: Cycles) {
        let now = self.catch_up(now);
        self.bkin = level;
        self.update_break_inputs(now);
        self.settle(now);
    }

    /// The BKIN2 pin level changed (the hardware STO input).
    pub fn set_bkin2(&mut self, level: bool, now: Cycles) {
        let now = self.catch_up(now);
        self.bkin2 = level;
        self.update_break_inputs(now);
        self.settle(now);
    }

    /// The system break input (`tim_sys_brk`: the OR of the sources SYSCFG_CFGR2 enables —
    /// LOCKUP (CLL), PVD (PVDL), SRAM parity (SPL), flash ECC (ECCL) — evaluated by the SoC).
    pub fn set_system_break(&mut self, active: bool, now: Cycles) {
        let now = self.catch_up(now);
        self.sys_brk = active;
        self.update_break_inputs(now);
        self.settle(now);
    }

    /// The debug freeze: the SoC calls this with `true` when the core halts while DBGMCU
    /// APB2FZR.DBG_TIM1_STOP is set, and with `false` when the core runs again. The counter
    /// stops and the outputs are disabled as if MOE was reset (MOE itself keeps its value).
    pub fn set_debug_halt(&mut self, frozen: bool, now: Cycles) {
        let now = self.catch_up(now);
        self.tb.set_frozen(now, frozen);
        self.settle_with(now, OffCause::DebugFreeze);
    }

    /// Break 1 (BKIN, the comparators routed to it, the system break) and break 2 active
    /// now, after their filters and enables (what holds MOE at 0).
    pub fn breaks_active(&self) -> [bool; 2] {
        [self.active1, self.active2]
    }

    /// The gate state at `now` (after `advance(now)`).
    pub fn gate(&self) -> GateState {
        self.gate
    }

    /// BDTR as it stands (not a bus read: not counted in [`TimAdv::bdtr_reads`]).
    pub fn bdtr(&self) -> u32 {
        self.bdtr
    }

    /// How often the bus read BDTR since reset.
    pub fn bdtr_reads(&self) -> u64 {
        self.bdtr_reads
    }

    /// OCxREF of channel `ch` (0 = CH1 .. 5 = CH6) at `now`.
    pub fn ocref(&self, ch: usize, now: Cycles) -> bool {
        self.ch.level(&self.tb, ch, now)
    }

    /// The OC5 output (the blanking window for COMP BLANKSEL = TIM1_OC5) at `now`.
    pub fn blanking(&self, now: Cycles) -> bool {
        self.blank_level(now)
    }

    /// TRGO2 at `now`.
    pub fn trgo2(&self) -> bool {
        self.trgo2
    }

    /// The counter at `now`.
    pub fn cnt(&self, now: Cycles) -> u32 {
        self.tb.cnt_at(now)
    }

    // ---- Internals ----

    /// Advances to `now`; an input timed before the last advance takes effect at the last
    /// advance (so the event queue stays in time order).
    fn catch_up(&mut self, now: Cycles) -> Cycles {
        self.advance(now);
        now.max(self.last)
    }

    fn push(&mut self, e: TimEvent) {
        if self.events.len() >= EVENT_QUEUE_LIMIT {
            self.events.pop_front();
        }
        self.events.push_back(e);
    }

    fn lock(&self) -> u32 {
        (self.bdtr & bdtr::LOCK) >> bdtr::LOCK_SHIFT
    }

    fn moe(&self) -> bool {
        self.bdtr & bdtr::MOE != 0
    }

    fn tdts(&self) -> u64 {
        match (self.tb.cr1_bits() >> cr1::CKD_SHIFT) & 3 {
            0 => 1,
            1 => 2,
            _ => 4,
        }
    }

    fn dtg(&self) -> u8 {
        if self.dtr2 & DTR2_DTPE != 0 {
            self.dtg_shadow
        } else {
            (self.bdtr & bdtr::DTG) as u8
        }
    }

    fn dtgf(&self) -> u8 {
        if self.dtr2 & DTR2_DTPE != 0 {
            self.dtgf_shadow
        } else {
            (self.dtr2 & 0xff) as u8
        }
    }

    fn mms(&self) -> u32 {
        ((self.cr2 >> 4) & 7) | ((self.cr2 >> 25) & 1) << 3
    }

    fn mms2(&self) -> u32 {
        (self.cr2 >> 20) & 0xf
    }

    /// The break-1 source after the per-input polarities and BKP: true = break requested.
    fn brk_raw(&self) -> bool {
        let af = self.af1;
        let mut src = false;
        if af & 1 != 0 {
            src |= self.bkin != (af & (1 << 9) != 0);
        }
        for (n, c) in self.comp.iter().enumerate() {
            if af & (1 << (1 + n)) != 0 {
                let inv = n < 4 && af & (1 << (10 + n)) != 0;
                src |= *c != inv;
            }
        }
        src == (self.bdtr & bdtr::BKP != 0)
    }

    fn brk2_raw(&self) -> bool {
        let af = self.af2;
        let mut src = false;
        if af & 1 != 0 {
            src |= self.bkin2 != (af & (1 << 9) != 0);
        }
        for (n, c) in self.comp.iter().enumerate() {
            if af & (1 << (1 + n)) != 0 {
                let inv = n < 4 && af & (1 << (10 + n)) != 0;
                src |= *c != inv;
            }
        }
        src == (self.bdtr & bdtr::BK2P != 0)
    }

    /// Re-evaluates both break paths after an input or configuration change at `now`.
    fn update_break_inputs(&mut self, now: Cycles) {
        let tdts = self.tdts();
        let d1 = filter_delay((self.bdtr >> bdtr::BKF_SHIFT) & 0xf, tdts);
        let d2 = filter_delay((self.bdtr >> bdtr::BK2F_SHIFT) & 0xf, tdts);
        let r1 = self.brk_raw();
        let r2 = self.brk2_raw();
        self.brk.set(r1, d1, now);
        self.brk2.set(r2, d2, now);
        self.eval_breaks(now);
    }

    /// Applies the break levels: while a break is active MOE is held at 0 and its flags set.
    fn eval_breaks(&mut self, now: Cycles) {
        let bke = self.bdtr & bdtr::BKE != 0;
        let bk2e = self.bdtr & bdtr::BK2E != 0;
        self.active1 = bke && (self.brk.out || self.sys_brk);
        self.active2 = bk2e && self.brk2.out;
        if self.active1 {
            // BIF follows the break input (BKIN and the comparators, after the filter) and
            // SBIF the system break input, each on its own (RM0440 TIMx_SR: BIF "set by
            // hardware as soon as the break input goes active", SBIF "as soon as the system
            // break input goes active"; "the break status flag (SBIF, BIF and B2IF bits in
            // the TIMx_SR register) is set", §29.3.18). A system break alone leaves BIF at 0:
            // the reading that does not hide an interrupt handler blind to SBIF (
            // E3), see docs/models.md "TIM1/TIM8".
            if self.brk.out {
                if self.sr & sr::BIF == 0 {
                    self.push(TimEvent::Break {
                        at: now,
                        input: BreakInput::Brk,
                    });
                }
                self.sr |= sr::BIF;
            }
            if self.sys_brk {
                if self.sr & sr::SBIF == 0 {
                    self.push(TimEvent::Break {
                        at: now,
                        input: BreakInput::System,
                    });
                }
                self.sr |= sr::SBIF;
            }
            if self.moe() {
                self.bdtr &= !bdtr::MOE;
                let cause = if self.brk.out {
                    OffCause::Break
                } else {
                    OffCause::SystemBreak
                };
                self.sync_outputs(now, cause);
            }
        }
        if self.active2 {
            if self.sr & sr::B2IF == 0 {
                self.push(TimEvent::Break {
                    at: now,
                    input: BreakInput::Brk2,
                });
            }
            self.sr |= sr::B2IF;
            if self.moe() {
                self.bdtr &= !bdtr::MOE;
                self.sync_outputs(now, OffCause::Break2);
            }
        }
    }

    fn sync_outputs(&mut self, now: Cycles, cause: OffCause) {
        let on = self.moe() && !self.tb.frozen();
        if on != self.outputs_on {
            self.outputs_on = on;
            self.push(if on {
                TimEvent::OutputsOn { at: now }
            } else {
                TimEvent::OutputsOff { at: now, cause }
            });
        }
    }

    fn blank_level(&self, t: Cycles) -> bool {
        self.ccer & (1 << 16) != 0
            && (self.ch.level(&self.tb, 4, t) != (self.ccer & (1 << 17) != 0))
    }

    /// Channels whose reference edges are seen outside (TRGO, TRGO2, the blanking window).
    fn observed(&self, i: usize) -> bool {
        let mms = self.mms();
        let mms2 = self.mms2();
        (4..=7).contains(&mms) && i == (mms - 4) as usize
            || (4..=9).contains(&mms2) && i == (mms2 - 4) as usize
            || match mms2 {
                10 => i == 3,
                11 => i == 5,
                12 | 13 => i == 3 || i == 5,
                14 | 15 => i == 4 || i == 5,
                _ => false,
            }
            || (i == 4 && self.ccer & (1 << 16) != 0)
    }

    fn flag_bit(i: usize) -> u32 {
        match i {
            0..=3 => 2 << i,
            4 => sr::CC5IF,
            _ => sr::CC6IF,
        }
    }

    fn flag_candidate(&self, i: usize, after: Cycles) -> Option<Cycles> {
        if self.ch.input[i] || self.sr & Self::flag_bit(i) != 0 {
            return None;
        }
        self.tb
            .next_match(after, self.ch.value(i), self.tb.flag_filter())
    }

    /// The earliest event after `self.last` (see [`super::tim_gp`]: invisible events do not
    /// change the visible ones).
    fn next_candidate(&self, visible_only: bool) -> Option<Cycles> {
        let after = self.last;
        let limit = self.tb.next_boundary();
        let cap = |t: Option<Cycles>| t.filter(|t| limit.is_none_or(|l| *t <= l));
        let mut best = limit;
        let mut offer = |t: Option<Cycles>| {
            if let Some(t) = t {
                best = Some(best.map_or(t, |b| b.min(t)));
            }
        };
        offer(self.brk.pending);
        offer(self.brk2.pending);
        for i in 0..6 {
            let flag_visible = (i < 4 && self.dier & (2 << i) != 0)
                || (i == 0 && (self.mms() == 3 || self.mms2() == 3));
            if flag_visible || !visible_only {
                offer(cap(self.flag_candidate(i, after)));
            }
            let held = matches!(self.ch.mode[i], 1..=3);
            if self.observed(i) || (held && !visible_only) {
                offer(cap(self.ch.next_edge(&self.tb, i, after).map(|e| e.0)));
            }
        }
        best
    }

    fn trgo_pulse(&mut self, at: Cycles, second: bool) {
        if second {
            self.push(TimEvent::Trgo2 { at, level: true });
            self.push(TimEvent::Trgo2 { at, level: false });
            self.trgo2 = false;
        } else {
            self.push(TimEvent::Trgo { at, level: true });
            self.push(TimEvent::Trgo { at, level: false });
            self.trgo = false;
        }
    }

    /// Reference levels, TRGO/TRGO2 levels and edges, and the blanking window at `t`.
    fn refresh_signals(&mut self, t: Cycles) {
        let mut now_refs = [false; 6];
        for (i, r) in now_refs.iter_mut().enumerate() {
            *r = self.ch.level(&self.tb, i, t);
        }
        let prev = self.refs;
        self.refs = now_refs;
        let rise = |i: usize| now_refs[i] && !prev[i];
        let fall = |i: usize| !now_refs[i] && prev[i];
        // TRGO.
        let trgo = match self.mms() {
            1 => Some(self.tb.cr1_bits() & cr1::CEN != 0),
            m @ 4..=7 => Some(now_refs[(m - 4) as usize]),
            _ => None,
        };
        if let Some(level) = trgo {
            if level != self.trgo {
                self.trgo = level;
                self.push(TimEvent::Trgo { at: t, level });
            }
        }
        // TRGO2.
        let mms2 = self.mms2();
        let trgo2 = match mms2 {
            1 => Some(self.tb.cr1_bits() & cr1::CEN != 0),
            m @ 4..=9 => Some(now_refs[(m - 4) as usize]),
            _ => None,
        };
        if let Some(level) = trgo2 {
            if level != self.trgo2 {
                self.trgo2 = level;
                self.push(TimEvent::Trgo2 { at: t, level });
            }
        }
        let pulse = match mms2 {
            10 => rise(3) || fall(3),
            11 => rise(5) || fall(5),
            12 => rise(3) || rise(5),
            13 => rise(3) || fall(5),
            14 => rise(4) || rise(5),
            15 => rise(4) || fall(5),
            _ => false,
        };
        if pulse {
            self.trgo_pulse(t, true);
        }
        let blank = self.blank_level(t);
        if blank != self.blank {
            self.blank = blank;
            self.push(TimEvent::Blanking {
                at: t,
                active: blank,
            });
        }
    }

    /// Everything that follows a change at `now`: break levels, outputs, signals, gate.
    fn settle(&mut self, now: Cycles) {
        self.settle_with(now, OffCause::Software);
    }

    fn settle_with(&mut self, now: Cycles, cause: OffCause) {
        self.eval_breaks(now);
        self.sync_outputs(now, cause);
        self.refresh_signals(now);
        let g = self.gate_state(now);
        if !same_gate(&g, &self.gate) {
            self.gate = g;
            self.push(TimEvent::GateChanged { at: now, gate: g });
        }
    }

    /// The update event at `t` (counter or UG): preloads, flags, AOE, TRGO, the gate snapshot.
    fn on_update(&mut self, t: Cycles, set_uif: bool) {
        self.ch.transfer();
        self.dtg_shadow = (self.bdtr & bdtr::DTG) as u8;
        self.dtgf_shadow = (self.dtr2 & 0xff) as u8;
        if set_uif {
            self.sr |= sr::UIF;
        }
        if self.mms() == 2 {
            self.trgo_pulse(t, false);
        }
        if self.mms2() == 2 {
            self.trgo_pulse(t, true);
        }
        if self.bdtr & bdtr::AOE != 0 && !self.active1 && !self.active2 {
            self.bdtr |= bdtr::MOE;
        }
        self.eval_breaks(t);
        self.sync_outputs(t, OffCause::Software);
        self.refresh_signals(t);
        let g = self.gate_state(t);
        self.gate = g;
        self.push(TimEvent::Update { at: t, gate: g });
    }

    fn process_at(&mut self, t: Cycles) {
        let limit = self.tb.next_boundary();
        for i in 0..6 {
            if self.flag_candidate(i, self.last) == Some(t) {
                self.sr |= Self::flag_bit(i);
                if i == 0 && self.mms() == 3 {
                    self.trgo_pulse(t, false);
                }
                if i == 0 && self.mms2() == 3 {
                    self.trgo_pulse(t, true);
                }
            }
            if matches!(self.ch.mode[i], 1..=3)
                && self.ch.next_edge(&self.tb, i, self.last).map(|e| e.0) == Some(t)
            {
                self.ch.on_match(i);
            }
        }
        let mut filters = false;
        for f in [&mut self.brk, &mut self.brk2] {
            if f.pending == Some(t) {
                f.out = f.raw;
                f.pending = None;
                filters = true;
            }
        }
        if filters {
            self.eval_breaks(t);
            self.sync_outputs(t, OffCause::Break);
        }
        self.refresh_signals(t);
        if limit == Some(t) {
            if let Some(uev) = self.tb.on_boundary(t) {
                if uev {
                    self.on_update(t, true);
                }
            }
            self.settle(t);
        }
    }

    /// The effective gate state at `t`.
    fn gate_state(&self, t: Cycles) -> GateState {
        let tdts = self.tdts() as u32;
        let rising = decode_dtg(self.dtg()) * tdts;
        let falling = if self.dtr2 & DTR2_DTAE != 0 {
            decode_dtg(self.dtgf()) * tdts
        } else {
            rising
        };
        let moe = self.moe();
        let frozen = self.tb.frozen();
        let enabled = moe && !frozen;
        let ossi = self.bdtr & bdtr::OSSI != 0;
        let ossr = self.bdtr & bdtr::OSSR != 0;
        let oc = |i: usize| OcRef {
            mode: self.ch.mode[i],
            ccr: self.ch.value(i),
            held: self.ch.held[i],
        };
        let mut channels = [ChannelGate {
            oc: oc(0),
            high: PinDrive::Released,
            low: PinDrive::Released,
            with_oc5: false,
        }; 4];
        for (i, c) in channels.iter_mut().enumerate() {
            let e = self.ccer & (1 << (4 * i)) != 0;
            let p = self.ccer & (2 << (4 * i)) != 0;
            let ne = self.ccer & (4 << (4 * i)) != 0;
            let np = self.ccer & (8 << (4 * i)) != 0;
            let ois = self.cr2 & (1 << (8 + 2 * i)) != 0;
            let oisn = self.cr2 & (1 << (9 + 2 * i)) != 0;
            let (high, low) = if enabled {
                match (e, ne) {
                    (false, false) => (PinDrive::Released, PinDrive::Released),
                    (true, false) => (
                        PinDrive::Ref {
                            complement: false,
                            delay: 0,
                            inverted: p,
                        },
                        if ossr {
                            PinDrive::Forced(np)
                        } else {
                            PinDrive::Released
                        },
                    ),
                    (false, true) => (
                        if ossr {
                            PinDrive::Forced(p)
                        } else {
                            PinDrive::Released
                        },
                        PinDrive::Ref {
                            complement: false,
                            delay: 0,
                            inverted: np,
                        },
                    ),
                    (true, true) => (
                        PinDrive::Ref {
                            complement: false,
                            delay: rising,
                            inverted: p,
                        },
                        PinDrive::Ref {
                            complement: true,
                            delay: falling,
                            inverted: np,
                        },
                    ),
                }
            } else if ossi && (e || ne) {
                (PinDrive::Forced(ois), PinDrive::Forced(oisn))
            } else {
                (PinDrive::Released, PinDrive::Released)
            };
            *c = ChannelGate {
                oc: oc(i),
                high,
                low,
                with_oc5: i < 3 && self.gc5 & (1 << i) != 0,
            };
        }
        GateState {
            since: t,
            moe,
            frozen,
            outputs_enabled: enabled,
            counting: self.tb.running(),
            mode: self.tb.mode(),
            arr: self.tb.arr(),
            cycles_per_count: u64::from(self.tb.psc()) + 1,
            phase_origin: self.tb.phase_origin(),
            dead_time_rising: rising,
            dead_time_falling: falling,
            channels,
            oc5: oc(4),
        }
    }

    fn write_ccmr(&mut self, k: usize, value: u32, now: Cycles) {
        let mask = if k == 2 { CCMR3_MASK } else { CCMR_MASK };
        let old = self.ccmr[k];
        let mut v = value & mask;
        if self.lock() >= 3 {
            v = (v & !CCMR_OC) | (old & CCMR_OC);
        }
        self.ccmr[k] = v;
        // With CCPC the OCxM bits of CH1-4 are preloaded until COM.
        if k == 2 || self.cr2 & CR2_CCPC == 0 {
            self.ch.decode_ccmr(&self.tb, 2 * k, v, now);
        } else {
            // Preload enable still applies at once; the mode waits for COM.
            let cur_modes = [self.ch.mode[2 * k], self.ch.mode[2 * k + 1]];
            self.ch.decode_ccmr(&self.tb, 2 * k, v, now);
            self.ch.mode[2 * k] = cur_modes[0];
            self.ch.mode[2 * k + 1] = cur_modes[1];
        }
        if self.ch.input.iter().any(|x| *x) {
            self.reports.once(now, "capture", || {
                "input capture (CCxS != 0) is not modelled".into()
            });
        }
        if self.ch.mode.iter().any(|m| *m >= 8) {
            self.reports.once(now, "ocm", || {
                "OCxM >= 8 (retriggerable OPM, combined/asymmetric PWM) is not modelled".into()
            });
        }
    }

    fn com_event(&mut self, now: Cycles) {
        if self.cr2 & CR2_CCPC != 0 {
            self.ccer = (self.ccer & !CCER_EN14) | (self.ccer_pre & CCER_EN14);
            for k in 0..2 {
                let v = self.ccmr[k];
                self.ch.decode_ccmr(&self.tb, 2 * k, v, now);
            }
        }
        self.sr |= sr::COMIF;
    }

    fn write_bdtr(&mut self, v: u32, now: Cycles) {
        let old = self.bdtr;
        let mut v = v & bdtr::MASK;
        // LOCK is write-once after reset; the level in force protects its bits from then on.
        let level = (old & bdtr::LOCK) >> bdtr::LOCK_SHIFT;
        if self.lock_written {
            v = (v & !bdtr::LOCK) | (old & bdtr::LOCK);
        }
        self.lock_written = true;
        if level >= 1 {
            v = (v & !bdtr::LOCK1) | (old & bdtr::LOCK1);
        }
        if level >= 2 {
            v = (v & !bdtr::LOCK2) | (old & bdtr::LOCK2);
        }
        if self.dtr2 & DTR2_DTPE == 0 {
            // Not preloaded: the dead-time generator takes the value at once.
            self.dtg_shadow = (v & bdtr::DTG) as u8;
        }
        let wants_moe = v & bdtr::MOE != 0 && old & bdtr::MOE == 0;
        if v & bdtr::MOE != 0 && (self.active1 || self.active2) {
            // MOE cannot be set while a break input is active (RM0440 §29.3.18).
            v &= !bdtr::MOE;
        }
        self.bdtr = v;
        if v & bdtr::DSRM_BID != 0 {
            self.reports.once(now, "bkbid", || {
                "bidirectional break / break disarm (BKBID, BKDSRM) are not modelled".into()
            });
        }
        // A break that this write enables (BKE, BKP) clears MOE before it reaches the outputs.
        self.update_break_inputs(now);
        if wants_moe && !self.moe() {
            self.reports.once(now, "moe-refused", || {
                "MOE = 1 refused while a break input is active".into()
            });
        }
    }
}

/// Gate states equal apart from `since`.
fn same_gate(a: &GateState, b: &GateState) -> bool {
    GateState { since: 0, ..*a } == GateState { since: 0, ..*b }
}

impl EventTimer for TimAdv {
    fn next_candidate(&self, visible_only: bool) -> Option<Cycles> {
        TimAdv::next_candidate(self, visible_only)
    }
    fn process_at(&mut self, t: Cycles) {
        TimAdv::process_at(self, t);
    }
    fn last_mut(&mut self) -> &mut Cycles {
        &mut self.last
    }
}

impl Peripheral for TimAdv {
    fn take_signals(&mut self, out: &mut Vec<Signal>) {
        out.extend(self.events.drain(..).map(Signal::Timer));
    }

    /// Misuse and unsupported-feature reports since the last call.
    fn take_reports(&mut self) -> Vec<String> {
        self.reports.take()
    }

    fn read(&mut self, offset: u32, now: Cycles) -> Option<u32> {
        let ccr = |i: usize| self.ch.ccr_pre.get(i).copied().unwrap_or(0);
        Some(match offset {
            0x00 => self.tb.read_cr1(now),
            0x04 => self.cr2,
            0x08 => self.smcr,
            0x0c => self.dier,
            0x10 => self.sr,
            0x14 => 0,
            0x18 => self.ccmr[0],
            0x1c => self.ccmr[1],
            0x20 => self.ccer_pre,
            0x24 => {
                let uifcpy = self.tb.cr1_bits() & cr1::UIFREMAP != 0 && self.sr & sr::UIF != 0;
                self.tb.cnt_at(now) | if uifcpy { 1 << 31 } else { 0 }
            }
            0x28 => u32::from(self.tb.psc_preload()),
            0x2c => self.tb.arr_preload(),
            0x30 => u32::from(self.tb.rcr_preload()),
            0x34 => ccr(0),
            0x38 => ccr(1),
            0x3c => ccr(2),
            0x40 => ccr(3),
            0x44 => {
                self.bdtr_reads += 1;
                self.bdtr
            }
            0x48 => ccr(4) | self.gc5 << 29,
            0x4c => ccr(5),
            0x50 => self.ccmr[2],
            0x54 => self.dtr2,
            0x60 => self.af1,
            0x64 => self.af2,
            o => return self.stored.read(o),
        })
    }

    fn write(&mut self, w: Write, now: Cycles) -> bool {
        let old = match w.offset {
            0x10 | 0x14 => 0,
            // Not through `read`: that counts the bus's reads of BDTR (`bdtr_reads`).
            0x44 => self.bdtr,
            o => match self.read(o, now) {
                Some(v) => v,
                None => return false,
            },
        };
        let v = w.merge(old);
        let lock = self.lock();
        match w.offset {
            0x00 => {
                if let Some(c) = self.tb.write_cr1(now, v) {
                    self.reports.once(now, "cms", || c.to_string());
                }
                if v & cr1::DITHEN != 0 {
                    self.reports.once(now, "dither", || {
                        "dithering (DITHEN) is not modelled".into()
                    });
                }
            }
            0x04 => {
                let mut n = v & CR2_MASK;
                if lock >= 1 {
                    n = (n & !CR2_OIS) | (self.cr2 & CR2_OIS);
                }
                self.cr2 = n;
                if self.mms() >= 8 {
                    self.reports
                        .once(now, "mms", || "MMS = encoder clock is not modelled".into());
                }
            }
            0x08 => {
                self.smcr = v & 0x0331_ffff;
                if self.smcr & 0x0001_0007 != 0 || self.smcr & (1 << 14) != 0 {
                    self.reports.once(now, "slave", || {
                        "slave mode / external clock (SMCR) is not modelled".into()
                    });
                }
            }
            0x0c => {
                self.dier = v & DIER_MASK;
                if self.dier & DIER_DMA != 0 {
                    self.reports
                        .once(now, "dma", || "timer DMA requests are not modelled".into());
                }
            }
            0x10 => {
                let mut n = w.clear_w0(self.sr) & sr::MASK;
                // A break flag cannot be cleared while its break input is active.
                if self.active1 && self.brk.out {
                    n |= sr::BIF;
                }
                if self.active2 {
                    n |= sr::B2IF;
                }
                if self.sys_brk && self.bdtr & bdtr::BKE != 0 {
                    n |= sr::SBIF;
                }
                self.sr = n;
            }
            0x14 => {
                if v & 1 != 0 {
                    let urs = self.tb.cr1_bits() & cr1::URS != 0;
                    if self.mms() == 0 {
                        self.trgo_pulse(now, false);
                    }
                    if self.mms2() == 0 {
                        self.trgo_pulse(now, true);
                    }
                    if self.tb.generate_update(now) {
                        self.on_update(now, !urs);
                    }
                }
                for i in 0..4 {
                    if v & (2 << i) != 0 {
                        self.sr |= 2 << i;
                    }
                }
                if v & (1 << 5) != 0 {
                    self.com_event(now);
                }
                if v & (1 << 6) != 0 {
                    self.sr |= sr::TIF;
                }
                if v & (3 << 7) != 0 {
                    // Software break: MOE cleared, BIF/B2IF set.
                    if v & (1 << 7) != 0 {
                        self.sr |= sr::BIF;
                        self.push(TimEvent::Break {
                            at: now,
                            input: BreakInput::Brk,
                        });
                    }
                    if v & (1 << 8) != 0 {
                        self.sr |= sr::B2IF;
                        self.push(TimEvent::Break {
                            at: now,
                            input: BreakInput::Brk2,
                        });
                    }
                    self.bdtr &= !bdtr::MOE;
                    self.sync_outputs(now, OffCause::SoftwareBreak);
                }
            }
            0x18 => self.write_ccmr(0, v, now),
            0x1c => self.write_ccmr(1, v, now),
            0x20 => {
                let mut n = v & CCER_MASK;
                if lock >= 2 {
                    n = (n & !CCER_POL) | (self.ccer_pre & CCER_POL);
                }
                self.ccer_pre = n;
                self.ccer = if self.cr2 & CR2_CCPC != 0 {
                    (n & !CCER_EN14) | (self.ccer & CCER_EN14)
                } else {
                    n
                };
            }
            0x24 => self.tb.write_cnt(now, v),
            0x28 => self.tb.write_psc(v as u16),
            0x2c => self.tb.write_arr(now, v),
            0x30 => self.tb.write_rcr(v as u16),
            0x34 | 0x38 | 0x3c | 0x40 | 0x48 | 0x4c => {
                let i = match w.offset {
                    0x48 => 4,
                    0x4c => 5,
                    o => ((o - 0x34) / 4) as usize,
                };
                if i == 4 {
                    self.gc5 = v >> 29;
                }
                if let Some(p) = self.ch.ccr_pre.get_mut(i) {
                    *p = v & 0xffff;
                }
            }
            0x44 => self.write_bdtr(v, now),
            0x50 => self.write_ccmr(2, v, now),
            0x54 => {
                let mut n = v & DTR2_MASK;
                if lock >= 1 {
                    n = self.dtr2;
                }
                if self.dtr2 & DTR2_DTPE == 0 {
                    // DTGF written while not preloaded takes effect at once; turning DTPE
                    // on keeps the values in force until the next update.
                    self.dtgf_shadow = (n & 0xff) as u8;
                    self.dtg_shadow = (self.bdtr & bdtr::DTG) as u8;
                }
                self.dtr2 = n;
            }
            0x60 => {
                let mut n = v & AF1_MASK;
                if lock >= 1 {
                    n = (n & !AF_BRK) | (self.af1 & AF_BRK);
                }
                self.af1 = n;
                self.update_break_inputs(now);
            }
            0x64 => {
                let mut n = v & AF2_MASK;
                if lock >= 1 {
                    n = (n & !AF_BRK) | (self.af2 & AF_BRK);
                }
                self.af2 = n;
                self.update_break_inputs(now);
            }
            o => {
                if !self.stored.write(o, v) {
                    return false;
                }
            }
        }
        self.settle(now);
        true
    }

    fn next_event(&self) -> Option<Cycles> {
        self.next_candidate(true)
    }

    fn advance(&mut self, now: Cycles) {
        advance_events(self, now);
    }

    fn irq_lines(&self, lines: &mut IrqLines) {
        let mut set = |irq: Option<u16>| {
            if let Some(i) = irq {
                lines.set(i);
            }
        };
        if self.sr & sr::UIF != 0 && self.dier & DIER_UIE != 0 {
            set(self.irq_up);
        }
        if self.sr & (sr::BIF | sr::B2IF | sr::SBIF) != 0 && self.dier & DIER_BIE != 0 {
            set(self.irq_brk);
        }
        if self.sr & self.dier & 0x1e != 0 {
            set(self.irq_cc);
        }
        if (self.sr & sr::TIF != 0 && self.dier & DIER_TIE != 0)
            || (self.sr & sr::COMIF != 0 && self.dier & DIER_COMIE != 0)
        {
            set(self.irq_trg_com);
        }
    }

    fn reset(&mut self) {
        let (bkin, bkin2, comp, sys) = (self.bkin, self.bkin2, self.comp, self.sys_brk);
        let (at, driven) = (self.last, self.outputs_on);
        *self = TimAdv::new(self.name);
        // The inputs are the outside world's: they survive a reset.
        self.bkin = bkin;
        self.bkin2 = bkin2;
        self.comp = comp;
        self.sys_brk = sys;
        self.update_break_inputs(0);
        // A reset takes MOE and every CCxE to 0 (RM0440 TIMx_BDTR, TIMx_CCER reset values):
        // the power stage sees its gates released, as after any other gate change.
        if driven {
            self.last = at;
            self.events.push_back(TimEvent::GateChanged {
                at,
                gate: self.gate,
            });
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const CR1: u32 = 0x00;
    const CR2: u32 = 0x04;
    const DIER: u32 = 0x0c;
    const SR: u32 = 0x10;
    const EGR: u32 = 0x14;
    const CCMR1: u32 = 0x18;
    const CCMR2: u32 = 0x1c;
    const CCER: u32 = 0x20;
    const CNT: u32 = 0x24;
    const PSC: u32 = 0x28;
    const ARR: u32 = 0x2c;
    const RCR: u32 = 0x30;
    const CCR1: u32 = 0x34;
    const CCR4: u32 = 0x40;
    const BDTR: u32 = 0x44;
    const CCR5: u32 = 0x48;
    const CCMR3: u32 = 0x50;
    const DTR2: u32 = 0x54;
    const AF1: u32 = 0x60;
    const AF2: u32 = 0x64;

    /// The timer behind a bus: one register access per cycle, `advance` before each.
    struct Bus {
        tim: TimAdv,
        t: Cycles,
    }

    impl Bus {
        fn new() -> Self {
            Bus {
                tim: TimAdv::new("TIM1"),
                t: 100,
            }
        }

        fn at(&mut self, t: Cycles) {
            assert!(t >= self.t, "time goes forward ({t} < {})", self.t);
            self.t = t;
            self.tim.advance(t);
        }

        fn rd(&mut self, off: u32) -> u32 {
            self.tim.advance(self.t);
            let v = self.tim.read(off, self.t).expect("modelled register");
            self.t += 1;
            v
        }

        fn wr(&mut self, off: u32, v: u32) {
            self.tim.advance(self.t);
            assert!(self.tim.write(Write::word(off, v), self.t));
            self.t += 1;
        }

        fn modify(&mut self, off: u32, f: impl FnOnce(u32) -> u32) {
            let v = self.rd(off);
            self.wr(off, f(v));
        }

        fn events(&mut self) -> Vec<TimEvent> {
            self.tim.take_events().collect()
        }

        fn irq(&self, name: &str) -> bool {
            let mut l = IrqLines::default();
            self.tim.irq_lines(&mut l);
            l.get(names::irq(name).expect("irq name"))
        }
    }

    const MOE: u32 = bdtr::MOE;

    /// `ComplementaryPwm::new(.., 500 Hz, CenterAlignedDownInterrupts)` then the drive's
    /// `power_stage::init` with `apply_timing(psc, arr, dtg)`, register by register as
    /// embassy-stm32 0.6 and the board code do it. Returns the cycle CEN was written.
    fn drive_init(b: &mut Bus, psc: u32, arr: u32, dtg: u32) -> Cycles {
        // embassy: set_counting_mode, set_frequency (500 Hz centre-aligned: PSC 2, ARR
        // 56666), enable_outputs, PWM mode 1 + preload on CH1-4, ARPE, UG with URS, start.
        let _ = b.rd(CR1);
        b.modify(CR1, |v| v & !cr1::DIR);
        b.modify(CR1, |v| (v & !cr1::CMS) | (1 << cr1::CMS_SHIFT));
        b.wr(PSC, 2);
        b.wr(ARR, 56_666);
        b.modify(BDTR, |v| v | MOE);
        for ch in 0..4u32 {
            let reg = if ch < 2 { CCMR1 } else { CCMR2 };
            let sh = 8 * (ch % 2);
            b.modify(reg, |v| (v & !(0x0001_0070 << sh)) | (6 << (4 + sh)));
            b.modify(reg, |v| v | (1 << (3 + sh)));
        }
        b.modify(CR1, |v| v | cr1::ARPE);
        b.modify(CR1, |v| v | cr1::URS);
        b.wr(EGR, 1);
        b.modify(CR1, |v| v & !cr1::URS);
        b.modify(CR1, |v| v | cr1::CEN);
        // power_stage::init
        b.modify(BDTR, |v| v & !MOE); // outputs_off
        b.modify(CR1, |v| v & !cr1::CEN);
        b.modify(BDTR, |v| {
            (v | bdtr::OSSI | bdtr::OSSR) & !(bdtr::AOE | bdtr::BKE)
        });
        b.modify(CR2, |v| (v & !0xff00 & !(0xf << 20)) | (7 << 20)); // MMS2 = OC4REF
        for ch in 0..4u32 {
            let reg = if ch < 2 { CCMR1 } else { CCMR2 };
            let sh = 8 * (ch % 2);
            let mode = if ch < 3 { 6 } else { 7 };
            b.modify(reg, |v| {
                (v & !((0x7 << (4 + sh)) | (1 << (16 + sh)))) | (mode << (4 + sh)) | (1 << (3 + sh))
            });
        }
        b.modify(CCER, |v| (v & !0xffff) | 0x0555);
        b.modify(CR1, |v| (v & !cr1::CMS) | (1 << cr1::CMS_SHIFT) | cr1::ARPE);
        b.wr(RCR, 1);
        // apply_timing
        b.wr(PSC, psc);
        b.wr(ARR, arr);
        b.wr(CCR4, arr - 1);
        b.modify(BDTR, |v| (v & !0xff) | dtg);
        for ch in 0..3 {
            b.wr(CCR1 + 4 * ch, 0);
        }
        b.wr(EGR, 1);
        b.wr(SR, 0);
        b.modify(DIER, |v| v | DIER_UIE);
        let cen = b.t;
        b.modify(CR1, |v| v | cr1::CEN);
        cen + 1
    }

    /// `power_stage::arm_break(&[0, 1, 2])`.
    fn arm_break(b: &mut Bus) {
        b.modify(AF1, |v| (v & !1) | 0b1110);
        b.modify(BDTR, |v| (v | bdtr::BKP | bdtr::BKE) & !bdtr::AOE);
        b.modify(SR, |v| v & !sr::BIF);
        b.modify(DIER, |v| v | DIER_BIE);
    }

    fn updates(ev: &[TimEvent]) -> Vec<Cycles> {
        ev.iter()
            .filter_map(|e| match e {
                TimEvent::Update { at, .. } => Some(*at),
                _ => None,
            })
            .collect()
    }

    fn trgo2_edges(ev: &[TimEvent]) -> Vec<(Cycles, bool)> {
        ev.iter()
            .filter_map(|e| match e {
                TimEvent::Trgo2 { at, level } => Some((*at, *level)),
                _ => None,
            })
            .collect()
    }

    fn check_period(psc: u32, arr: u32) {
        let mut b = Bus::new();
        let cen = drive_init(&mut b, psc, arr, 0x95);
        let _ = b.events();
        let period = 2 * u64::from(arr) * (u64::from(psc) + 1);
        // The visible events are the updates and the TRGO2 edges, each at its exact cycle.
        let mut seen = Vec::new();
        while let Some(t) = b.tim.next_event() {
            if t > cen + 5 * period {
                break;
            }
            b.at(t);
            seen.push(t);
            if b.tim.sr & sr::UIF != 0 {
                // The update ISR: at the valley, counting up.
                assert_eq!(b.rd(CNT) & 0xffff, 0);
                assert_eq!(b.rd(CR1) & cr1::DIR, 0, "DIR reads 0 at the valley");
                b.wr(SR, !sr::UIF);
            }
        }
        let ev = b.events();
        let ups = updates(&ev);
        let want: Vec<Cycles> = (1..=5).map(|k| cen + k * period).collect();
        assert_eq!(ups, want, "one update per period, at the valley");
        // TRGO2 = OC4REF (PWM2 at ARR-1): high for the two counts around the peak.
        let step = u64::from(psc) + 1;
        let mut want_trgo = Vec::new();
        for k in 0..5 {
            let base = cen + k * period;
            want_trgo.push((base + u64::from(arr - 1) * step, true));
            want_trgo.push((base + u64::from(arr + 1) * step, false));
        }
        assert_eq!(trgo2_edges(&ev), want_trgo);
        let mut all: Vec<Cycles> = want
            .iter()
            .copied()
            .chain(want_trgo.iter().map(|e| e.0))
            .collect();
        all.sort_unstable();
        assert_eq!(
            seen, all,
            "next_event() stops exactly at them and nowhere else"
        );
    }

    #[test]
    fn drive_init_updates_once_per_period_at_the_valley_20khz() {
        check_period(0, 4250);
    }

    #[test]
    fn drive_init_updates_once_per_period_at_the_valley_16khz() {
        // PwmTiming::compute(170 MHz, 16 kHz): ARR 5313, PSC 0.
        check_period(0, 5313);
    }

    #[test]
    fn prescaled_period() {
        check_period(3, 1000);
    }

    #[test]
    fn ccr_preload_takes_effect_at_the_next_update_only() {
        let mut b = Bus::new();
        let cen = drive_init(&mut b, 0, 4250, 0x95);
        let period = 8500;
        b.at(cen + period + 100); // after the first update
        let _ = b.events();
        b.wr(CCR1, 1000);
        let g = b.tim.gate();
        assert_eq!(
            g.channels[0].oc.ccr, 0,
            "the shadow keeps the old compare value"
        );
        // CNT 4000 counting up: CCR 1000 would make OC1REF low either way; check near the
        // valley instead, where PWM1 with CCR1 = 1000 is high.
        let near_valley = cen + 2 * period - 10;
        b.at(near_valley);
        assert!(
            !b.tim.ocref(0, near_valley),
            "still CCR1 = 0 before the update"
        );
        b.at(cen + 2 * period + 10);
        assert!(b.tim.ocref(0, b.t), "CCR1 = 1000 after the update");
        let ev = b.events();
        let upd = ev
            .iter()
            .find_map(|e| match e {
                TimEvent::Update { at, gate } if *at == cen + 2 * period => Some(*gate),
                _ => None,
            })
            .expect("update at the second valley");
        assert_eq!(upd.channels[0].oc.ccr, 1000);
        // No GateChanged for a preloaded write.
        assert!(!ev.iter().any(|e| matches!(e, TimEvent::GateChanged { .. })));
    }

    #[test]
    fn sr_read_modify_write_loses_a_break_flag_set_in_between() {
        let mut b = Bus::new();
        let cen = drive_init(&mut b, 0, 4250, 0x95);
        arm_break(&mut b);
        b.at(cen + 8500 + 5);
        // take_update(): SR read ...
        let sr_read = b.rd(SR);
        assert_ne!(sr_read & sr::UIF, 0);
        // ... a comparator pulse sets BIF and ends before the write-back ...
        let t = b.t;
        b.tim.set_comparator(1, true, t);
        b.tim.set_comparator(1, false, t + 1);
        b.t = t + 2;
        assert_ne!(b.rd(SR) & sr::BIF, 0);
        // ... and `sr().modify(|w| w.set_uif(false))` writes the stale value back.
        b.wr(SR, sr_read & !sr::UIF);
        assert_eq!(b.rd(SR) & sr::BIF, 0, "the RMW cleared the break flag");
        // Writing !UIF instead clears only UIF.
        let t = b.t;
        b.tim.set_comparator(2, true, t);
        b.tim.set_comparator(2, false, t + 1);
        b.t = t + 2;
        b.wr(SR, !sr::UIF);
        assert_ne!(b.rd(SR) & sr::BIF, 0, "writing !UIF leaves BIF alone");
    }

    #[test]
    fn a_reset_with_the_outputs_on_releases_the_gates() {
        let mut b = Bus::new();
        let cen = drive_init(&mut b, 0, 4250, 0x95);
        b.at(cen + 10_000);
        b.modify(BDTR, |v| v | MOE);
        assert!(b.tim.gate().outputs_enabled);
        let _ = b.events();
        b.tim.reset();
        let ev = b.events();
        assert!(
            matches!(ev.as_slice(), [TimEvent::GateChanged { gate, .. }] if !gate.outputs_enabled && !gate.moe),
            "{ev:?}"
        );
        // A timer reset with its outputs off says nothing.
        b.tim.reset();
        assert!(b.events().is_empty());
    }

    #[test]
    fn comparator_break_clears_moe_and_refuses_it_while_active() {
        let mut b = Bus::new();
        let cen = drive_init(&mut b, 0, 4250, 0x95);
        arm_break(&mut b);
        b.at(cen + 10_000);
        b.modify(BDTR, |v| v | MOE);
        assert_ne!(b.rd(BDTR) & MOE, 0);
        assert!(b.tim.gate().outputs_enabled);
        let _ = b.events();
        let trip = b.t;
        b.tim.set_comparator(3, true, trip);
        assert_eq!(
            b.tim.read(BDTR, trip).unwrap_or(0) & MOE,
            0,
            "MOE cleared at once"
        );
        assert_ne!(b.tim.read(SR, trip).unwrap_or(0) & sr::BIF, 0);
        assert!(b.irq("TIM1_BRK_TIM15"));
        let ev = b.events();
        assert!(ev.contains(&TimEvent::OutputsOff {
            at: trip,
            cause: OffCause::Break
        }));
        assert!(ev.contains(&TimEvent::Break {
            at: trip,
            input: BreakInput::Brk
        }));
        // While the comparator is high: MOE writes and BIF clears are refused.
        b.t = trip + 1;
        b.modify(BDTR, |v| v | MOE);
        assert_eq!(b.rd(BDTR) & MOE, 0, "MOE refused while the break is active");
        b.wr(SR, !sr::BIF);
        assert_ne!(b.rd(SR) & sr::BIF, 0, "BIF cannot be cleared while active");
        assert_eq!(b.tim.gate().channels[0].high, PinDrive::Forced(false));
        // The comparator falls: BIF clears, MOE is accepted (no AOE: only by software).
        let t = b.t;
        b.tim.set_comparator(3, false, t);
        b.t = t + 1;
        b.at(cen + 5 * 8500);
        assert_eq!(b.rd(BDTR) & MOE, 0, "AOE off: MOE stays 0 across updates");
        b.wr(SR, !sr::BIF);
        assert_eq!(b.rd(SR) & sr::BIF, 0);
        b.modify(BDTR, |v| v | MOE);
        assert_ne!(b.rd(BDTR) & MOE, 0, "MOE accepted once the break is gone");
        assert!(b
            .events()
            .iter()
            .any(|e| matches!(e, TimEvent::OutputsOn { .. })));
    }

    #[test]
    fn aoe_sets_moe_at_the_next_update_once_the_break_is_gone() {
        let mut b = Bus::new();
        let cen = drive_init(&mut b, 0, 4250, 0x95);
        arm_break(&mut b);
        b.modify(BDTR, |v| v | bdtr::AOE | MOE);
        b.at(cen + 8500 + 100);
        let t = b.t;
        b.tim.set_comparator(1, true, t);
        assert_eq!(b.tim.read(BDTR, t).unwrap_or(0) & MOE, 0);
        // Still active at the next update: MOE stays 0.
        b.at(cen + 2 * 8500 + 1);
        assert_eq!(b.rd(BDTR) & MOE, 0);
        let t = b.t;
        b.tim.set_comparator(1, false, t);
        b.at(cen + 3 * 8500 - 1);
        assert_eq!(b.rd(BDTR) & MOE, 0, "not before the update");
        b.at(cen + 3 * 8500);
        assert_ne!(b.rd(BDTR) & MOE, 0, "AOE set MOE at the update");
        assert!(b
            .events()
            .contains(&TimEvent::OutputsOn { at: cen + 3 * 8500 }));
    }

    #[test]
    fn break_polarity_and_enables() {
        let mut b = Bus::new();
        let _ = drive_init(&mut b, 0, 4250, 0x95);
        // BKINE is 1 after reset and BKIN reads 0: with BKE and BKP = 0 (active low) that is
        // a break.
        b.modify(BDTR, |v| (v | bdtr::BKE) & !bdtr::BKP);
        assert_ne!(b.rd(SR) & sr::BIF, 0);
        // Active high, BKIN inactive: no break; a comparator not enabled in AF1 does nothing.
        b.modify(BDTR, |v| v | bdtr::BKP);
        b.wr(SR, 0);
        b.modify(BDTR, |v| v | MOE);
        let t = b.t;
        b.tim.set_comparator(4, true, t);
        b.t += 1;
        assert_ne!(b.rd(BDTR) & MOE, 0);
        // The BKIN pin, active high.
        let t = b.t;
        b.tim.set_bkin(true, t);
        b.t += 1;
        assert_eq!(b.rd(BDTR) & MOE, 0);
        // Comparator polarity BKCMP4P inverts COMP4 (enabled): now COMP4 low is a break.
        let t = b.t;
        b.tim.set_bkin(false, t);
        b.t += 1;
        b.wr(AF1, (1 << 4) | (1 << 13));
        let t = b.t;
        b.tim.set_comparator(4, false, t);
        b.t += 1;
        b.wr(SR, 0);
        assert_ne!(b.rd(SR) & sr::BIF, 0, "inverted COMP4 low holds the break");
    }

    #[test]
    fn break2_from_the_bkin2_pin() {
        let mut b = Bus::new();
        let cen = drive_init(&mut b, 0, 4250, 0x95);
        b.at(cen + 50);
        b.wr(AF2, 1); // BK2INE only
        b.modify(BDTR, |v| v | bdtr::BK2E | bdtr::BK2P | MOE);
        assert_ne!(b.rd(BDTR) & MOE, 0);
        let _ = b.events();
        let t = b.t;
        b.tim.set_bkin2(true, t);
        assert_eq!(b.tim.read(BDTR, t).unwrap_or(0) & MOE, 0);
        let srv = b.tim.read(SR, t).unwrap_or(0);
        assert_ne!(srv & sr::B2IF, 0);
        assert_eq!(srv & sr::BIF, 0);
        let ev = b.events();
        assert!(ev.contains(&TimEvent::OutputsOff {
            at: t,
            cause: OffCause::Break2
        }));
    }

    #[test]
    fn system_break_needs_bke_and_sets_sbif() {
        let mut b = Bus::new();
        let cen = drive_init(&mut b, 0, 4250, 0x95);
        b.at(cen + 50);
        b.modify(BDTR, |v| v | MOE);
        let t = b.t;
        b.tim.set_system_break(true, t);
        b.t += 1;
        assert_ne!(
            b.rd(BDTR) & MOE,
            0,
            "without BKE the system break does nothing"
        );
        let t = b.t;
        b.tim.set_system_break(false, t);
        b.t += 1;
        arm_break(&mut b);
        b.modify(BDTR, |v| v | MOE);
        let _ = b.events();
        let t = b.t;
        b.tim.set_system_break(true, t);
        let srv = b.tim.read(SR, t).unwrap_or(0);
        assert_eq!(
            srv & (sr::BIF | sr::SBIF),
            sr::SBIF,
            "a system break alone sets SBIF, not BIF"
        );
        assert!(b.events().contains(&TimEvent::OutputsOff {
            at: t,
            cause: OffCause::SystemBreak
        }));
    }

    /// SBIF alone raises the break interrupt (BIE), cannot be cleared while the system
    /// break is active, and clears once it is gone (RM0440 TIMx_SR.SBIF).
    #[test]
    fn sbif_alone_raises_the_break_interrupt_and_clears_only_after_the_source() {
        let mut b = Bus::new();
        let cen = drive_init(&mut b, 0, 4250, 0x95);
        b.at(cen + 50);
        arm_break(&mut b);
        b.modify(BDTR, |v| v | MOE);
        let t = b.t;
        b.tim.set_system_break(true, t);
        assert!(
            b.irq("TIM1_BRK_TIM15"),
            "SBIF with BIE raises the break interrupt"
        );
        b.t += 10;
        // Clearing BIF (what a handler blind to SBIF does) leaves the line high.
        b.wr(SR, !sr::BIF);
        b.wr(SR, !sr::SBIF);
        assert_ne!(
            b.rd(SR) & sr::SBIF,
            0,
            "SBIF holds while the source is active"
        );
        let t = b.t;
        b.tim.set_system_break(false, t);
        b.t += 1;
        b.wr(SR, !sr::SBIF);
        assert_eq!(b.rd(SR) & (sr::SBIF | sr::BIF), 0);
        assert!(!b.irq("TIM1_BRK_TIM15"));
    }

    #[test]
    fn break_filter_drops_short_pulses() {
        let mut b = Bus::new();
        let cen = drive_init(&mut b, 0, 4250, 0x95);
        arm_break(&mut b);
        // BKF = 0011: fCK_INT, N = 8: 8 cycles.
        b.modify(BDTR, |v| (v & !(0xf << 16)) | (3 << 16) | MOE);
        b.at(cen + 100);
        let t = b.t;
        b.tim.set_comparator(1, true, t);
        b.tim.set_comparator(1, false, t + 7);
        b.at(t + 50);
        assert_eq!(b.rd(SR) & sr::BIF, 0, "a 7-cycle pulse is filtered out");
        let t = b.t;
        b.tim.set_comparator(1, true, t);
        assert_eq!(b.tim.next_event(), Some(t + 8));
        b.at(t + 7);
        assert_ne!(b.tim.read(BDTR, t + 7).unwrap_or(0) & MOE, 0);
        b.at(t + 8);
        assert_eq!(
            b.tim.read(BDTR, t + 8).unwrap_or(0) & MOE,
            0,
            "tripped after 8 cycles"
        );
    }

    #[test]
    fn software_break_generation() {
        let mut b = Bus::new();
        let _ = drive_init(&mut b, 0, 4250, 0x95);
        b.modify(BDTR, |v| v | MOE);
        b.wr(EGR, 1 << 7);
        assert_eq!(b.rd(BDTR) & MOE, 0);
        assert_ne!(b.rd(SR) & sr::BIF, 0);
    }

    #[test]
    fn dead_time_preload_with_dtpe() {
        let mut b = Bus::new();
        let cen = drive_init(&mut b, 0, 4250, 0x95);
        assert_eq!(b.tim.gate().dead_time_rising, 170);
        // Without DTPE a DTG write takes effect at once.
        b.at(cen + 1000);
        b.modify(BDTR, |v| (v & !0xff) | 0x80); // 128 counts
        assert_eq!(b.tim.gate().dead_time_rising, 128);
        assert!(b.events().iter().any(|e| matches!(
            e,
            TimEvent::GateChanged { gate, .. } if gate.dead_time_rising == 128
        )));
        // With DTPE it waits for the update event.
        b.wr(DTR2, DTR2_DTPE);
        b.modify(BDTR, |v| (v & !0xff) | 0xc0); // 256 counts
        assert_eq!(b.tim.gate().dead_time_rising, 128);
        b.at(cen + 8500);
        assert_eq!(b.tim.gate().dead_time_rising, 256);
        let ev = b.events();
        let upd = ev.iter().find_map(|e| match e {
            TimEvent::Update { at, gate } if *at == cen + 8500 => Some(gate.dead_time_rising),
            _ => None,
        });
        assert_eq!(upd, Some(256));
        // Asymmetric dead time (DTAE) with DTGF, also preloaded.
        // DTAE itself is not preloaded: until the update the falling edge uses the DTGF in
        // force (0).
        b.wr(DTR2, DTR2_DTPE | DTR2_DTAE | 50);
        assert_eq!(b.tim.gate().dead_time_falling, 0);
        assert_eq!(b.tim.gate().dead_time_rising, 256);
        b.at(cen + 2 * 8500);
        assert_eq!(b.tim.gate().dead_time_falling, 50);
    }

    #[test]
    fn debug_freeze_disables_the_outputs_and_stops_the_counter() {
        let mut b = Bus::new();
        let cen = drive_init(&mut b, 0, 4250, 0x95);
        b.modify(BDTR, |v| v | MOE);
        b.at(cen + 1234);
        let _ = b.events();
        let t = b.t;
        let c = b.tim.cnt(t);
        b.tim.set_debug_halt(true, t);
        let ev = b.events();
        assert!(ev.contains(&TimEvent::OutputsOff {
            at: t,
            cause: OffCause::DebugFreeze
        }));
        let g = b.tim.gate();
        assert!(g.moe && g.frozen && !g.outputs_enabled);
        assert_eq!(
            g.channels[0].high,
            PinDrive::Forced(false),
            "OSSI: idle level"
        );
        assert_eq!(b.tim.next_event(), None, "no update while frozen");
        b.at(t + 100_000);
        assert_eq!(b.rd(CNT) & 0xffff, c);
        let t2 = b.t;
        b.tim.set_debug_halt(false, t2);
        assert!(b.events().contains(&TimEvent::OutputsOn { at: t2 }));
        assert!(b.tim.gate().outputs_enabled);
        b.at(t2 + 10);
        assert_eq!(b.rd(CNT) & 0xffff, c + 10);
    }

    #[test]
    fn oc5_blanking_window_and_grouping() {
        let mut b = Bus::new();
        let cen = drive_init(&mut b, 0, 4250, 0x95);
        // OC5: PWM mode 1, CCR5 = 100, preload, CC5E: active for the 100 counts either side
        // of the valley. GC5C1 ANDs it into OC1REF.
        b.wr(CCMR3, (6 << 4) | (1 << 3));
        b.wr(CCR5, 100 | (1 << 29));
        b.modify(CCER, |v| v | (1 << 16));
        b.wr(CCR1, 4000);
        b.at(cen + 8500 + 1); // the update loads CCR5/CCR1
        let _ = b.events();
        let base = cen + 8500;
        b.at(base + 8500);
        let blank: Vec<(Cycles, bool)> = b
            .events()
            .iter()
            .filter_map(|e| match e {
                TimEvent::Blanking { at, active } => Some((*at, *active)),
                _ => None,
            })
            .collect();
        assert_eq!(blank, vec![(base + 100, false), (base + 8500 - 100, true)]);
        assert!(b.tim.blanking(base + 8500));
        // OC1REF (PWM1, CCR1 4000) alone is high around the valley for ±4000 counts; grouped
        // with OC5 only ±100.
        let g = b.tim.gate();
        assert!(g.channels[0].with_oc5);
        assert!(g.ocref(0, base + 8500 + 50));
        assert!(!g.ocref(0, base + 8500 + 500));
        assert!(
            b.tim.ocref(0, base + 8500 + 500),
            "OC1REF itself is still high"
        );
    }

    #[test]
    fn gate_pins_with_dead_time() {
        let mut b = Bus::new();
        let cen = drive_init(&mut b, 0, 4250, 0x95);
        b.wr(CCR1, 1000);
        b.at(cen + 8500 + 1);
        b.modify(BDTR, |v| v | MOE);
        let g = b.tim.gate();
        let valley = cen + 2 * 8500;
        // OC1REF high for phase in [7500, 8500) and [0, 1000).
        let pin = |t: Cycles, high: bool| g.pin(0, high, t);
        assert_eq!(pin(valley - 1001, true), Some(false));
        assert_eq!(
            pin(valley - 1000 + 169, true),
            Some(false),
            "inside the dead time"
        );
        assert_eq!(pin(valley - 1000 + 170, true), Some(true));
        assert_eq!(pin(valley + 999, true), Some(true));
        assert_eq!(pin(valley + 1000, true), Some(false));
        assert_eq!(
            pin(valley + 1000 + 169, false),
            Some(false),
            "low side waits too"
        );
        assert_eq!(pin(valley + 1000 + 170, false), Some(true));
        assert_eq!(pin(valley - 1000, false), Some(false));
        // Never both on.
        for t in (valley - 8500..valley + 8500).step_by(7) {
            assert!(
                !(pin(t, true) == Some(true) && pin(t, false) == Some(true)),
                "{t}"
            );
        }
    }

    #[test]
    fn gate_state_reference_matches_the_model_over_a_period() {
        let mut b = Bus::new();
        let cen = drive_init(&mut b, 1, 2000, 0x95);
        b.wr(CCR1, 700);
        b.wr(CCR1 + 4, 1999);
        b.wr(CCR1 + 8, 2001);
        b.at(cen + 8000 + 3);
        let g = b.tim.gate();
        for t in (cen + 8000..cen + 16_000).step_by(3) {
            for ch in 0..3 {
                assert_eq!(g.ocref(ch, t), b.tim.ocref(ch, t), "ch {ch} at {t}");
            }
            assert_eq!(g.counter_at(t), Some(b.tim.cnt(t)), "counter at {t}");
        }
    }

    /// `apply_timing`'s `bdtr().modify(..)` reads MOE = 1, a break pulse
    /// clears MOE and ends, the write-back sets MOE again (accepted: the break is over) while
    /// BIF stays set for the break interrupt.
    #[test]
    fn bdtr_read_modify_write_across_a_break_pulse_re_sets_moe() {
        let mut b = Bus::new();
        let cen = drive_init(&mut b, 0, 4250, 0x95);
        arm_break(&mut b);
        b.modify(BDTR, |v| v | MOE);
        b.at(cen + 3000);
        let read = b.rd(BDTR);
        assert_ne!(read & MOE, 0);
        let t = b.t;
        b.tim.set_comparator(1, true, t);
        b.tim.set_comparator(1, false, t + 2);
        b.t = t + 3;
        assert_eq!(b.rd(BDTR) & MOE, 0, "the break cleared MOE");
        b.t -= 1;
        b.wr(BDTR, (read & !0xff) | 0x96); // the stale value with a new DTG
        assert_ne!(b.rd(BDTR) & MOE, 0, "the stale MOE = 1 was written back");
        assert_ne!(
            b.rd(SR) & sr::BIF,
            0,
            "BIF is still there for the interrupt"
        );
    }

    #[test]
    fn lock_level_1_freezes_the_dead_time() {
        let mut b = Bus::new();
        b.wr(BDTR, 0x95 | (1 << 8)); // DTG + LOCK 1, in one write
        b.wr(BDTR, 0x10 | (3 << 8));
        let v = b.rd(BDTR);
        assert_eq!(v & 0xff, 0x95, "DTG frozen");
        assert_eq!((v >> 8) & 3, 1, "LOCK is write-once");
    }

    #[test]
    fn cc_flags_follow_the_centre_aligned_mode() {
        let mut b = Bus::new();
        let cen = drive_init(&mut b, 0, 4250, 0x95);
        b.wr(CCR1, 1000);
        b.at(cen + 8500);
        b.wr(SR, 0);
        // Mode 1: flags on the down-count only: counter 1000 counting down is phase 7500.
        b.at(cen + 8500 + 7499);
        assert_eq!(
            b.rd(SR) & 2,
            0,
            "no flag at the up-count match (phase 1000)"
        );
        b.at(cen + 8500 + 7500);
        assert_ne!(b.rd(SR) & 2, 0);
        // CC1IE makes it an interrupt (TIM1_CC) and a visible event.
        b.wr(SR, 0);
        b.modify(DIER, |v| v | 2);
        let next = b.tim.next_event();
        assert!(next.is_some_and(|t| t <= cen + 3 * 8500));
        b.at(cen + 2 * 8500 + 7500);
        assert!(b.irq("TIM1_CC"));
    }

    #[test]
    fn update_interrupt_line() {
        let mut b = Bus::new();
        let cen = drive_init(&mut b, 0, 4250, 0x95);
        assert!(!b.irq("TIM1_UP_TIM16"));
        b.at(cen + 8500);
        assert!(b.irq("TIM1_UP_TIM16"));
        b.wr(SR, !sr::UIF);
        assert!(!b.irq("TIM1_UP_TIM16"));
    }
}
