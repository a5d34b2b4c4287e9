//! General-purpose timers TIM2/TIM3/TIM4 (RM0440 §30 "General-purpose timers
//! (TIM2/TIM3/TIM4/TIM5)"; TIM2 is the 32-bit one), and the counter and output-compare core
//! they share with the advanced-control timers ([`super::tim_adv`]).
//!
//! TIM4 is embassy-stm32's time driver on both images (`time_driver/gp16.rs`): PSC = 169
//! (1 MHz), ARR = 0xFFFF, UG with URS set, CCR1 = 0x8000 as the half-period interrupt, CC2 as
//! the alarm, SR cleared by writing `!sr` (rc_w0), CNT read at any time.
//!
//! Timing is analytical: the counter never ticks. At an *anchor* (a cycle where the model last
//! had to change something) the model keeps the counter's position in its periodic trajectory
//! (the *phase*), the repetition counter and the cycle of the next prescaler overflow; the
//! counter value at any later cycle, the next update event and the next compare match are
//! computed from that in O(1). A compare flag that nobody can observe (its interrupt disabled)
//! costs one step of [`Peripheral::advance`]'s loop the first time it is set and nothing after.
//!
//! Conventions (documented in `docs/models.md`):
//! * the counter clock is CK_INT = the CPU clock (every timer kernel clock the images use is
//!   170 MHz); one counter step every PSC+1 cycles; the first step after CEN is set comes
//!   PSC+1-(prescaler count) cycles later (PSC+1 after UG, which clears the prescaler);
//! * centre-aligned: the counter counts 0..ARR-1 up (DIR reads 0) and ARR..1 down (DIR reads
//!   1); the overflow is the step onto ARR, the underflow the step onto 0 (RM0440 "Center-
//!   aligned mode (up/down counting)"); the repetition counter counts both;
//! * a compare match is the step onto CCRx; in centre-aligned mode n the flag is set on
//!   down-steps (n = 1), up-steps (2) or both (3).

use super::reports::Reports;
use std::collections::VecDeque;

use crate::names;
use crate::periph::{IrqLines, Peripheral, Write};
use crate::time::Cycles;

/// CR1 bits (RM0440 TIMx_CR1).
pub(crate) mod cr1 {
    pub const CEN: u32 = 1 << 0;
    pub const UDIS: u32 = 1 << 1;
    pub const URS: u32 = 1 << 2;
    pub const OPM: u32 = 1 << 3;
    pub const DIR: u32 = 1 << 4;
    pub const CMS_SHIFT: u32 = 5;
    pub const CMS: u32 = 3 << CMS_SHIFT;
    pub const ARPE: u32 = 1 << 7;
    pub const CKD_SHIFT: u32 = 8;
    pub const UIFREMAP: u32 = 1 << 11;
    pub const DITHEN: u32 = 1 << 12;
    /// Bits the register holds (bit 10 is reserved).
    pub const MASK: u32 = 0x1bff;
}

/// How the counter moves (CR1.CMS and, in edge-aligned mode, CR1.DIR).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CountMode {
    /// Edge-aligned, counting up: 0..=ARR, overflow onto 0.
    Up,
    /// Edge-aligned, counting down: ARR..=0, underflow onto ARR.
    Down,
    /// Centre-aligned mode 1, 2 or 3 (which direction sets the compare flags).
    Centre(u8),
}

/// Which direction of counting sets a compare flag.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum StepFilter {
    Any,
    UpOnly,
    DownOnly,
}

/// The counter before it joins its periodic trajectory (its value is above ARR: ARR was
/// lowered without preload, or CNT was written above it).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Excursion {
    cnt: u32,
    down: bool,
    /// Steps from the anchor to the join.
    join_steps: u64,
    join_phase: u64,
    /// The join is a wrap (the counter rolls over its maximum onto 0): it counts for the
    /// repetition counter and can be the update event.
    wraps: bool,
}

/// The registers both timer kinds only store (their effects are not modelled): ECR, TISEL,
/// OR1, DCR, with the bits RM0440 defines.
#[derive(Debug, Clone, Copy, Default)]
pub struct StoredRegs {
    ecr: u32,
    tisel: u32,
    or1: u32,
    dcr: u32,
}

impl StoredRegs {
    pub fn read(&self, offset: u32) -> Option<u32> {
        Some(match offset {
            0x58 => self.ecr,
            0x5c => self.tisel,
            0x68 => self.or1,
            0x3dc => self.dcr,
            _ => return None,
        })
    }

    /// `false`: not one of these registers.
    pub fn write(&mut self, offset: u32, v: u32) -> bool {
        match offset {
            0x58 => self.ecr = v & 0x07ff_00ff,
            0x5c => self.tisel = v & 0x0f0f_0f0f,
            0x68 => self.or1 = v,
            0x3dc => self.dcr = v & 0x1f1f,
            _ => return false,
        }
        true
    }
}

/// A timer that computes its next event analytically from its present state (both timer
/// kinds): [`advance_events`] runs it forward.
pub trait EventTimer {
    /// The earliest event after the last processed cycle; with `visible_only`, only those
    /// seen outside the timer.
    fn next_candidate(&self, visible_only: bool) -> Option<Cycles>;
    /// Everything that happens at `t`.
    fn process_at(&mut self, t: Cycles);
    /// The cycle the timer has been brought to.
    fn last_mut(&mut self) -> &mut Cycles;
}

/// [`Peripheral::advance`] of a timer: every event due up to `now`, in time order.
#[inline]
pub fn advance_events(tim: &mut impl EventTimer, now: Cycles) {
    while let Some(t) = tim.next_candidate(false) {
        if t > now {
            break;
        }
        tim.process_at(t);
        *tim.last_mut() = t;
    }
    let last = tim.last_mut();
    *last = (*last).max(now);
}

/// The time base (RM0440 "Time-base unit"): CR1, PSC, ARR, RCR with their preloads, the
/// counter, the prescaler and the repetition counter, with analytical timing.
#[derive(Debug, Clone)]
pub struct TimeBase {
    cr1: u32,
    /// Counter width mask (0xFFFF or 0xFFFF_FFFF).
    max: u32,
    psc: u16,
    psc_pre: u16,
    arr: u32,
    arr_pre: u32,
    rcr: u16,
    rcr_pre: u16,
    has_rcr: bool,
    frozen: bool,
    // Motion, exact at `t0`.
    t0: Cycles,
    p0: u64,
    rep0: u16,
    exc: Option<Excursion>,
    /// First counter step after `t0` (valid while running).
    next_step: Cycles,
    /// While stopped: cycles from a restart to the first step (PSC+1 minus the prescaler
    /// count).
    left: u64,
}

impl TimeBase {
    /// A time base in its reset state; `bits32` for TIM2/TIM5, `has_rcr` for timers with a
    /// repetition counter.
    pub fn new(bits32: bool, has_rcr: bool) -> Self {
        let max = if bits32 { u32::MAX } else { 0xffff };
        TimeBase {
            cr1: 0,
            max,
            psc: 0,
            psc_pre: 0,
            arr: max,
            arr_pre: max,
            rcr: 0,
            rcr_pre: 0,
            has_rcr,
            frozen: false,
            t0: 0,
            p0: 0,
            rep0: 0,
            exc: None,
            next_step: 0,
            left: 1,
        }
    }

    fn period(&self) -> u64 {
        u64::from(self.psc) + 1
    }

    /// The counter width mask.
    pub fn max(&self) -> u32 {
        self.max
    }

    /// The auto-reload value in effect (the shadow register, or the preload when ARPE = 0).
    pub fn arr(&self) -> u32 {
        if self.cr1 & cr1::ARPE != 0 {
            self.arr
        } else {
            self.arr_pre
        }
    }

    /// The prescaler in effect (PSC is always preloaded).
    pub fn psc(&self) -> u16 {
        self.psc
    }

    /// The repetition counter reload value in effect.
    pub fn rcr(&self) -> u16 {
        self.rcr
    }

    pub fn cr1_bits(&self) -> u32 {
        self.cr1
    }

    pub fn mode(&self) -> CountMode {
        match (self.cr1 & cr1::CMS) >> cr1::CMS_SHIFT {
            0 if self.cr1 & cr1::DIR != 0 => CountMode::Down,
            0 => CountMode::Up,
            n => CountMode::Centre(n as u8),
        }
    }

    /// CEN, not frozen by the debugger, and ARR not 0 ("the counter is blocked while the
    /// auto-reload value is null").
    pub fn running(&self) -> bool {
        self.cr1 & cr1::CEN != 0 && !self.frozen && self.arr() > 0
    }

    pub fn frozen(&self) -> bool {
        self.frozen
    }

    /// Steps in one period of the trajectory.
    fn len(&self) -> u64 {
        let a = u64::from(self.arr());
        match self.mode() {
            CountMode::Centre(_) => 2 * a,
            _ => a + 1,
        }
    }

    /// Steps between two wraps.
    fn wrap_every(&self) -> u64 {
        let a = u64::from(self.arr());
        match self.mode() {
            CountMode::Centre(_) => a,
            _ => a + 1,
        }
    }

    /// Counter steps in (t0, t].
    fn steps_by(&self, t: Cycles) -> u64 {
        if !self.running() || t < self.next_step {
            0
        } else {
            (t - self.next_step) / self.period() + 1
        }
    }

    /// The cycle of the `s`-th step after the anchor (s ≥ 1).
    fn time_of_step(&self, s: u64) -> Cycles {
        self.next_step
            .saturating_add(s.saturating_sub(1).saturating_mul(self.period()))
    }

    /// The first step strictly after `t` (running only).
    fn step_after(&self, t: Cycles) -> Cycles {
        if t < self.next_step {
            self.next_step
        } else {
            let k = (t - self.next_step) / self.period() + 1;
            self.next_step + k * self.period()
        }
    }

    /// (counter, counting down) at a phase of the periodic trajectory.
    fn phase_state(&self, p: u64) -> (u32, bool) {
        let a = u64::from(self.arr());
        match self.mode() {
            CountMode::Up => (p as u32, false),
            CountMode::Down => (a.saturating_sub(p) as u32, true),
            CountMode::Centre(_) => {
                if p < a {
                    (p as u32, false)
                } else {
                    ((2 * a).saturating_sub(p) as u32, true)
                }
            }
        }
    }

    /// The phase of a counter state, or the excursion that leads to the trajectory.
    fn state_phase(&self, cnt: u32, down: bool) -> Result<u64, Excursion> {
        let a = u64::from(self.arr());
        let c = u64::from(cnt);
        let top = u64::from(self.max) + 1;
        match self.mode() {
            CountMode::Up if c <= a => Ok(c),
            CountMode::Up => Err(Excursion {
                cnt,
                down: false,
                join_steps: top - c,
                join_phase: 0,
                wraps: true,
            }),
            CountMode::Down if c <= a => Ok(a - c),
            CountMode::Down => Err(Excursion {
                cnt,
                down: true,
                join_steps: c - a,
                join_phase: 0,
                wraps: false,
            }),
            CountMode::Centre(_) if c > a => {
                if down {
                    Err(Excursion {
                        cnt,
                        down: true,
                        join_steps: c - a,
                        join_phase: a,
                        wraps: false,
                    })
                } else {
                    Err(Excursion {
                        cnt,
                        down: false,
                        join_steps: top - c,
                        join_phase: 0,
                        wraps: true,
                    })
                }
            }
            CountMode::Centre(_) => Ok(if c == 0 {
                0
            } else if c == a {
                a
            } else if down {
                2 * a - c
            } else {
                c
            }),
        }
    }

    /// Steps from phase `p` to the next wrap.
    fn steps_to_wrap(&self, p: u64) -> u64 {
        let a = u64::from(self.arr());
        match self.mode() {
            CountMode::Centre(_) => {
                if p < a {
                    a - p
                } else {
                    2 * a - p
                }
            }
            _ => self.len() - p,
        }
    }

    /// Wraps among `s` steps taken from phase `p`.
    fn wraps_in(&self, p: u64, s: u64) -> u64 {
        let d = self.steps_to_wrap(p);
        if s < d {
            0
        } else {
            (s - d) / self.wrap_every().max(1) + 1
        }
    }

    /// (counter, counting down) at cycle `t` (t ≥ the last anchor).
    pub fn state_at(&self, t: Cycles) -> (u32, bool) {
        let s = self.steps_by(t);
        match self.exc {
            Some(e) => {
                let s = s.min(e.join_steps.saturating_sub(1));
                if e.down {
                    (e.cnt.wrapping_sub(s as u32), true)
                } else {
                    (e.cnt.wrapping_add(s as u32) & self.max, false)
                }
            }
            None if s == 0 => self.phase_state(self.p0),
            None => self.phase_state((self.p0 + s) % self.len().max(1)),
        }
    }

    /// The counter value at `t`.
    pub fn cnt_at(&self, t: Cycles) -> u32 {
        self.state_at(t).0
    }

    /// The phase at `t`, or `None` during an excursion.
    pub fn phase_at(&self, t: Cycles) -> Option<u64> {
        if self.exc.is_some() {
            return None;
        }
        let s = self.steps_by(t);
        Some(if s == 0 {
            self.p0
        } else {
            (self.p0 + s) % self.len().max(1)
        })
    }

    fn rep_at(&self, t: Cycles) -> u16 {
        if self.exc.is_some() {
            return self.rep0;
        }
        let w = self.wraps_in(self.p0, self.steps_by(t));
        self.rep0.saturating_sub(w.min(u64::from(u16::MAX)) as u16)
    }

    /// Re-anchors at `t` in (cnt, down), keeping the prescaler phase given by `next_step`.
    fn place(&mut self, t: Cycles, cnt: u32, down: bool, rep: u16) {
        self.t0 = t;
        self.rep0 = rep;
        match self.state_phase(cnt & self.max, down) {
            Ok(p) => {
                self.p0 = p;
                self.exc = None;
            }
            Err(e) => {
                self.p0 = 0;
                self.exc = Some(e);
            }
        }
    }

    /// Applies a configuration change at `t`: the counter keeps its value (and, in centre-
    /// aligned mode, its direction), the prescaler keeps counting.
    fn reconfigure(&mut self, t: Cycles, f: impl FnOnce(&mut Self)) {
        let (cnt, down) = self.state_at(t);
        let rep = self.rep_at(t);
        let was_running = self.running();
        let was_centre = matches!(self.mode(), CountMode::Centre(_));
        let resume = if was_running {
            self.step_after(t) - t
        } else {
            self.left
        };
        f(self);
        let is_centre = matches!(self.mode(), CountMode::Centre(_));
        let down = if is_centre && was_centre {
            down
        } else {
            self.cr1 & cr1::DIR != 0
        };
        if self.running() {
            self.next_step = t + resume;
        } else {
            self.left = resume;
        }
        self.place(t, cnt, down, rep);
    }

    /// CR1 as read at `t`: DIR shows the counting direction in centre-aligned mode.
    pub fn read_cr1(&self, t: Cycles) -> u32 {
        match self.mode() {
            CountMode::Centre(_) => {
                let down = self.state_at(t).1;
                (self.cr1 & !cr1::DIR) | if down { cr1::DIR } else { 0 }
            }
            _ => self.cr1,
        }
    }

    /// A CR1 write. Returns a complaint when the write asks for something the counter refuses
    /// (switching between edge- and centre-aligned while counting).
    pub fn write_cr1(&mut self, t: Cycles, value: u32) -> Option<&'static str> {
        let mut new = value & cr1::MASK;
        let mut complaint = None;
        let old = self.cr1;
        let edge_to_centre = (old & cr1::CMS == 0) != (new & cr1::CMS == 0);
        if old & cr1::CEN != 0 && edge_to_centre {
            new = (new & !cr1::CMS) | (old & cr1::CMS);
            complaint = Some("CMS switched between edge- and centre-aligned while CEN=1 (refused)");
        }
        if new & cr1::CMS != 0 && old & cr1::CMS != 0 {
            // DIR is read-only in centre-aligned mode.
            new = (new & !cr1::DIR) | (old & cr1::DIR);
        }
        self.reconfigure(t, |s| s.cr1 = new);
        complaint
    }

    /// Clears CEN (one-pulse mode at the update event).
    fn stop(&mut self, t: Cycles) {
        self.reconfigure(t, |s| s.cr1 &= !cr1::CEN);
    }

    pub fn write_psc(&mut self, value: u16) {
        self.psc_pre = value;
    }

    pub fn psc_preload(&self) -> u16 {
        self.psc_pre
    }

    pub fn write_arr(&mut self, t: Cycles, value: u32) {
        let v = value & self.max;
        if self.cr1 & cr1::ARPE != 0 {
            self.arr_pre = v;
        } else {
            self.reconfigure(t, |s| {
                s.arr_pre = v;
                s.arr = v;
            });
        }
    }

    pub fn arr_preload(&self) -> u32 {
        self.arr_pre
    }

    pub fn write_rcr(&mut self, value: u16) {
        if self.has_rcr {
            self.rcr_pre = value;
        }
    }

    pub fn rcr_preload(&self) -> u16 {
        self.rcr_pre
    }

    /// A CNT write: the counter takes the value, the direction and prescaler are kept.
    pub fn write_cnt(&mut self, t: Cycles, value: u32) {
        let down = self.state_at(t).1;
        let rep = self.rep_at(t);
        let resume = if self.running() {
            self.step_after(t)
        } else {
            t + self.left
        };
        if self.running() {
            self.next_step = resume;
        }
        self.place(t, value & self.max, down, rep);
    }

    /// Debug freeze (DBGMCU DBG_TIMx_STOP while the core is halted): the counter stops as if
    /// CEN were cleared.
    pub fn set_frozen(&mut self, t: Cycles, frozen: bool) {
        self.reconfigure(t, |s| s.frozen = frozen);
    }

    fn transfer_preloads(&mut self) {
        self.psc = self.psc_pre;
        self.arr = self.arr_pre;
        self.rcr = self.rcr_pre;
    }

    /// UG at `t`: the counter restarts (0, or ARR when counting down) with the prescaler
    /// cleared; unless UDIS the shadows are loaded. Returns whether an update event happened.
    pub fn generate_update(&mut self, t: Cycles) -> bool {
        let uev = self.cr1 & cr1::UDIS == 0;
        if uev {
            self.transfer_preloads();
        }
        let down = self.mode() == CountMode::Down;
        let cnt = if down { self.arr() } else { 0 };
        self.left = self.period();
        if self.running() {
            self.next_step = t + self.period();
        }
        self.place(t, cnt, down, self.rcr);
        uev
    }

    /// The next cycle at which the counter changes regime by itself: the wrap at which the
    /// repetition counter expires (the update event), or the end of an excursion.
    pub fn next_boundary(&self) -> Option<Cycles> {
        if !self.running() {
            return None;
        }
        if let Some(e) = self.exc {
            return Some(self.time_of_step(e.join_steps));
        }
        let steps = self.steps_to_wrap(self.p0) + u64::from(self.rep0) * self.wrap_every().max(1);
        Some(self.time_of_step(steps))
    }

    /// Processes the boundary due at `t`. `Some(uev)`: the repetition counter expired (a wrap
    /// with REP = 0); `uev` unless UDIS. `None`: an excursion joined the trajectory without a
    /// wrap (or the wrap only decremented the repetition counter).
    pub fn on_boundary(&mut self, t: Cycles) -> Option<bool> {
        let expired = match self.exc {
            Some(e) => {
                let (cnt, down) = self.phase_state(e.join_phase);
                self.next_step = t + self.period();
                if e.wraps && self.rep0 == 0 {
                    self.place(t, cnt, down, 0);
                    true
                } else {
                    let rep = if e.wraps {
                        self.rep0.saturating_sub(1)
                    } else {
                        self.rep0
                    };
                    self.place(t, cnt, down, rep);
                    false
                }
            }
            None => {
                let (cnt, down) = self.state_at(t);
                self.next_step = t + self.period();
                self.place(t, cnt, down, 0);
                true
            }
        };
        if !expired {
            return None;
        }
        let uev = self.cr1 & cr1::UDIS == 0;
        let (mut cnt, down) = self.state_at(t);
        if uev {
            self.transfer_preloads();
        }
        if self.mode() == CountMode::Down {
            // The underflow reloads the counter with the (new) auto-reload value.
            cnt = self.arr();
        }
        self.next_step = t + self.period();
        self.place(t, cnt, down, self.rcr);
        if uev && self.cr1 & cr1::OPM != 0 {
            self.stop(t);
        }
        Some(uev)
    }

    /// The first cycle after `after` at which the counter steps onto phase `q` (regular
    /// trajectory only).
    fn next_entry(&self, after: Cycles, q: u64) -> Option<Cycles> {
        if !self.running() || self.exc.is_some() {
            return None;
        }
        let len = self.len();
        if len == 0 || q >= len {
            return None;
        }
        let s = self.steps_by(after);
        let p = (self.p0 + s) % len;
        let d = match (q + len - p) % len {
            0 => len,
            d => d,
        };
        Some(self.time_of_step(s + d))
    }

    /// The phases at which the counter steps onto `v`, with whether that step counts up.
    fn match_phases(&self, v: u32) -> [Option<(u64, bool)>; 2] {
        let a = u64::from(self.arr());
        let v = u64::from(v);
        if v > a {
            return [None, None];
        }
        match self.mode() {
            CountMode::Up => [Some((v, true)), None],
            CountMode::Down => [Some((a - v, false)), None],
            CountMode::Centre(_) if v == 0 => [Some((0, false)), None],
            CountMode::Centre(_) if v == a => [Some((a, true)), None],
            CountMode::Centre(_) => [Some((v, true)), Some((2 * a - v, false))],
        }
    }

    /// Which steps set a compare flag in the current mode.
    pub(crate) fn flag_filter(&self) -> StepFilter {
        match self.mode() {
            CountMode::Centre(1) => StepFilter::DownOnly,
            CountMode::Centre(2) => StepFilter::UpOnly,
            _ => StepFilter::Any,
        }
    }

    /// The first step after `after` onto `v` that passes `filter`.
    pub(crate) fn next_match(&self, after: Cycles, v: u32, filter: StepFilter) -> Option<Cycles> {
        self.match_phases(v)
            .into_iter()
            .flatten()
            .filter(|(_, up)| match filter {
                StepFilter::Any => true,
                StepFilter::UpOnly => *up,
                StepFilter::DownOnly => !*up,
            })
            .filter_map(|(q, _)| self.next_entry(after, q))
            .min()
    }

    /// The PWM-mode reference level at phase `p` (RM0440 "PWM mode": mode 1 is active while
    /// CNT < CCR counting up and while CNT <= CCR counting down; mode 2 is its inverse).
    fn pwm_level_at_phase(&self, pwm2: bool, v: u32, p: u64) -> bool {
        let (cnt, down) = self.phase_state(p);
        let pwm1 = if down { cnt <= v } else { cnt < v };
        pwm1 != pwm2
    }

    /// The PWM reference level at `t`.
    pub(crate) fn pwm_level(&self, pwm2: bool, v: u32, t: Cycles) -> bool {
        let (cnt, down) = self.state_at(t);
        let pwm1 = if down { cnt <= v } else { cnt < v };
        pwm1 != pwm2
    }

    /// The next PWM reference edge after `after`: (cycle, new level).
    pub(crate) fn next_pwm_edge(
        &self,
        pwm2: bool,
        v: u32,
        after: Cycles,
    ) -> Option<(Cycles, bool)> {
        if !self.running() || self.exc.is_some() {
            return None;
        }
        let len = self.len();
        if len == 0 {
            return None;
        }
        let a = u64::from(self.arr());
        let mut candidates = [0u64; 6];
        let mut n = 0;
        for (q, _) in self.match_phases(v).into_iter().flatten() {
            candidates[n] = q;
            candidates[n + 1] = (q + 1) % len;
            n += 2;
        }
        candidates[n] = 0;
        candidates[n + 1] = a % len;
        n += 2;
        candidates
            .iter()
            .take(n)
            .filter(|&&q| {
                let before = (q + len - 1) % len;
                self.pwm_level_at_phase(pwm2, v, q) != self.pwm_level_at_phase(pwm2, v, before)
            })
            .filter_map(|&q| {
                self.next_entry(after, q)
                    .map(|t| (t, self.pwm_level_at_phase(pwm2, v, q)))
            })
            .min_by_key(|(t, _)| *t)
    }

    /// The cycle at which the counter (virtually) last stepped onto phase 0 at or before the
    /// anchor: with the prescaler (PSC+1 cycles per step) and the trajectory this gives the counter at any cycle
    /// until the next boundary. `None` during an excursion or before cycle 0.
    pub fn phase_origin(&self) -> Option<Cycles> {
        if self.exc.is_some() {
            return None;
        }
        let back = (self.p0 + 1).checked_mul(self.period())?;
        if self.running() {
            self.next_step.checked_sub(back)
        } else {
            None
        }
    }
}

/// Output-compare mode (OCxM, 4 bits).
pub(crate) mod ocm {
    pub const ACTIVE_ON_MATCH: u8 = 1;
    pub const INACTIVE_ON_MATCH: u8 = 2;
    pub const TOGGLE: u8 = 3;
    pub const FORCE_INACTIVE: u8 = 4;
    pub const FORCE_ACTIVE: u8 = 5;
    pub const PWM1: u8 = 6;
    pub const PWM2: u8 = 7;
}

/// The output-compare channels of a timer: CCMR (mode and preload enable per channel), CCR
/// with preload, and the reference signal OCxREF. Channel `i` is CCx with x = i + 1.
#[derive(Debug, Clone)]
pub(crate) struct Channels<const N: usize> {
    /// OCxM (4 bits) per channel.
    pub mode: [u8; N],
    /// OCxPE per channel.
    pub preload: [bool; N],
    /// CCxS != 0 (input capture: not modelled).
    pub input: [bool; N],
    pub ccr_pre: [u32; N],
    pub ccr: [u32; N],
    /// OCxREF for the modes that hold it (frozen, match-driven).
    pub held: [bool; N],
}

impl<const N: usize> Channels<N> {
    pub fn new() -> Self {
        Channels {
            mode: [0; N],
            preload: [false; N],
            input: [false; N],
            ccr_pre: [0; N],
            ccr: [0; N],
            held: [false; N],
        }
    }

    /// The compare value in effect.
    pub fn value(&self, i: usize) -> u32 {
        match (self.preload.get(i), self.ccr.get(i), self.ccr_pre.get(i)) {
            (Some(true), Some(v), _) => *v,
            (_, _, Some(v)) => *v,
            _ => 0,
        }
    }

    /// OCxREF at `t`.
    pub fn level(&self, tb: &TimeBase, i: usize, t: Cycles) -> bool {
        let held = self.held.get(i).copied().unwrap_or(false);
        match self.mode.get(i).copied().unwrap_or(0) {
            ocm::FORCE_INACTIVE => false,
            ocm::FORCE_ACTIVE => true,
            m @ (ocm::PWM1 | ocm::PWM2) => tb.pwm_level(m == ocm::PWM2, self.value(i), t),
            _ => held,
        }
    }

    /// The next OCxREF edge of channel `i` after `after`: (cycle, new level).
    pub fn next_edge(&self, tb: &TimeBase, i: usize, after: Cycles) -> Option<(Cycles, bool)> {
        if self.input.get(i).copied().unwrap_or(false) {
            return None;
        }
        let held = self.held.get(i).copied().unwrap_or(false);
        let v = self.value(i);
        match self.mode.get(i).copied().unwrap_or(0) {
            m @ (ocm::PWM1 | ocm::PWM2) => tb.next_pwm_edge(m == ocm::PWM2, v, after),
            m @ (ocm::ACTIVE_ON_MATCH | ocm::INACTIVE_ON_MATCH | ocm::TOGGLE) => {
                let new = match m {
                    ocm::ACTIVE_ON_MATCH => true,
                    ocm::INACTIVE_ON_MATCH => false,
                    _ => !held,
                };
                if new == held && m != ocm::TOGGLE {
                    return None;
                }
                tb.next_match(after, v, StepFilter::Any).map(|t| (t, new))
            }
            _ => None,
        }
    }

    /// Applies a match-driven reference change at a match of channel `i`.
    pub fn on_match(&mut self, i: usize) {
        let m = self.mode.get(i).copied().unwrap_or(0);
        if let Some(h) = self.held.get_mut(i) {
            match m {
                ocm::ACTIVE_ON_MATCH => *h = true,
                ocm::INACTIVE_ON_MATCH => *h = false,
                ocm::TOGGLE => *h = !*h,
                _ => {}
            }
        }
    }

    /// A mode change at `t`: a mode that holds the reference starts from its present level.
    pub fn set_mode(&mut self, tb: &TimeBase, i: usize, mode: u8, t: Cycles) {
        let level = self.level(tb, i, t);
        if let (Some(m), Some(h)) = (self.mode.get_mut(i), self.held.get_mut(i)) {
            if *m != mode {
                *h = level;
                *m = mode;
            }
        }
    }

    /// The update event: preloaded compare values take effect.
    pub fn transfer(&mut self) {
        self.ccr = self.ccr_pre;
    }

    /// Decodes one CCMR register (two channels) into `first` and `first + 1`.
    pub fn decode_ccmr(&mut self, tb: &TimeBase, first: usize, ccmr: u32, t: Cycles) {
        for k in 0..2 {
            let i = first + k;
            if i >= N {
                break;
            }
            let low = ccmr >> (8 * k);
            let ccs = low & 3;
            let mode = (((low >> 4) & 7) | ((ccmr >> (16 + 8 * k)) & 1) << 3) as u8;
            if let Some(x) = self.input.get_mut(i) {
                *x = ccs != 0;
            }
            if let Some(p) = self.preload.get_mut(i) {
                *p = low & (1 << 3) != 0;
            }
            self.set_mode(tb, i, if ccs != 0 { 0 } else { mode }, t);
        }
    }
}

/// A timer event the SoC may need for cross-wiring: TRGO edges (ADC and DAC triggers).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TrgoEdge {
    pub at: Cycles,
    /// The new level (a pulse is a rising edge followed by a falling edge at the same cycle).
    pub level: bool,
}

/// Most queued events a model keeps when the SoC does not drain them (oldest dropped).
pub(crate) const EVENT_QUEUE_LIMIT: usize = 8192;

/// A general-purpose timer: TIM2 (32-bit), TIM3, TIM4.
#[derive(Debug, Clone)]
pub struct TimGp {
    name: &'static str,
    irq: Option<u16>,
    tb: TimeBase,
    ch: Channels<4>,
    cr2: u32,
    smcr: u32,
    dier: u32,
    sr: u32,
    ccmr: [u32; 2],
    ccer: u32,
    af1: u32,
    af2: u32,
    /// Everything up to this cycle has been processed.
    stored: StoredRegs,
    last: Cycles,
    trgo: bool,
    trgo_events: VecDeque<TrgoEdge>,
    reports: Reports,
}

/// SR bits of the general-purpose timers.
mod sr {
    pub const UIF: u32 = 1 << 0;
    pub const CCIF1: u32 = 1 << 1;
    pub const MASK: u32 = 0x00f0_1e5f;
}

const DIER_MASK: u32 = 0x00f0_5f5f;
const DIER_DMA: u32 = 0x0000_5f00;

impl TimGp {
    /// The timer `name` ("TIM2", "TIM3" or "TIM4"); its interrupt line from the metadata.
    pub fn new(name: &'static str) -> Self {
        let bits32 = matches!(name, "TIM2" | "TIM5");
        TimGp {
            name,
            irq: names::irq(name),
            tb: TimeBase::new(bits32, false),
            ch: Channels::new(),
            cr2: 0,
            smcr: 0,
            dier: 0,
            sr: 0,
            ccmr: [0; 2],
            ccer: 0,
            af1: 0,
            af2: 0,
            stored: StoredRegs::default(),
            last: 0,
            trgo: false,
            trgo_events: VecDeque::new(),
            reports: Reports::new(name),
        }
    }

    /// The counter at `now` (after `advance(now)`).
    pub fn cnt(&self, now: Cycles) -> u32 {
        self.tb.cnt_at(now)
    }

    /// Debug freeze (the SoC calls this when the core halts with DBG_TIMx_STOP set, and again
    /// when it resumes).
    pub fn set_debug_halt(&mut self, frozen: bool, now: Cycles) {
        self.advance(now);
        let now = now.max(self.last);
        self.tb.set_frozen(now, frozen);
        self.refresh_trgo(now);
    }

    /// TRGO edges since the last call (MMS = enable, update, compare pulse or OCxREF).
    pub fn take_trgo(&mut self) -> impl Iterator<Item = TrgoEdge> + '_ {
        self.trgo_events.drain(..)
    }

    fn mms(&self) -> u32 {
        ((self.cr2 >> 4) & 7) | ((self.cr2 >> 25) & 1) << 3
    }

    fn push_trgo(&mut self, at: Cycles, level: bool) {
        if self.trgo_events.len() >= EVENT_QUEUE_LIMIT {
            self.trgo_events.pop_front();
        }
        self.trgo_events.push_back(TrgoEdge { at, level });
    }

    fn trgo_pulse(&mut self, at: Cycles) {
        self.push_trgo(at, true);
        self.push_trgo(at, false);
    }

    /// TRGO as a level (MMS = enable or OCxREF); `None` for the pulse sources.
    fn trgo_level(&self, t: Cycles) -> Option<bool> {
        match self.mms() {
            1 => Some(self.tb.cr1_bits() & cr1::CEN != 0),
            m @ 4..=7 => Some(self.ch.level(&self.tb, (m - 4) as usize, t)),
            _ => None,
        }
    }

    fn refresh_trgo(&mut self, t: Cycles) {
        if let Some(level) = self.trgo_level(t) {
            if level != self.trgo {
                self.trgo = level;
                self.push_trgo(t, level);
            }
        }
    }

    /// Channels whose OCxREF edges are observed (TRGO).
    fn observed(&self, i: usize) -> bool {
        self.mms() == 4 + i as u32
    }

    fn flag_candidate(&self, i: usize, after: Cycles) -> Option<Cycles> {
        if self.ch.input[i] || self.sr & (sr::CCIF1 << i) != 0 {
            return None;
        }
        self.tb
            .next_match(after, self.ch.value(i), self.tb.flag_filter())
    }

    /// The earliest event after `self.last`; with `visible_only`, only those seen outside
    /// (an interrupt line, TRGO) or changing the counter's regime (the update event). Events
    /// nobody can see (a compare flag with its interrupt disabled) do not change the visible
    /// ones, so both answers come from the present state.
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
        for i in 0..4 {
            let flag_visible = self.dier & (2 << i) != 0 || (i == 0 && self.mms() == 3);
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

    fn process_at(&mut self, t: Cycles) {
        let limit = self.tb.next_boundary();
        for i in 0..4 {
            if self.flag_candidate(i, self.last) == Some(t) {
                self.sr |= sr::CCIF1 << i;
                if i == 0 && self.mms() == 3 {
                    self.trgo_pulse(t);
                }
            }
            if matches!(self.ch.mode[i], 1..=3)
                && self.ch.next_edge(&self.tb, i, self.last).map(|e| e.0) == Some(t)
            {
                self.ch.on_match(i);
            }
        }
        self.refresh_trgo(t);
        if limit == Some(t) {
            if let Some(uev) = self.tb.on_boundary(t) {
                if uev {
                    self.ch.transfer();
                    self.sr |= sr::UIF;
                    if self.mms() == 2 {
                        self.trgo_pulse(t);
                    }
                }
            }
            self.refresh_trgo(t);
        }
    }

    fn write_ccmr(&mut self, k: usize, value: u32, now: Cycles) {
        let v = value & 0x0101_ffff;
        if let Some(r) = self.ccmr.get_mut(k) {
            *r = v;
        }
        self.ch.decode_ccmr(&self.tb, 2 * k, v, now);
        if self.ch.input.iter().any(|x| *x) {
            self.reports.once(now, "capture", || {
                "input capture (CCxS != 0) is not modelled".to_string()
            });
        }
        if self.ch.mode.iter().any(|m| *m >= 8) {
            self.reports.once(now, "ocm", || {
                "OCxM >= 8 (retriggerable OPM, combined/asymmetric PWM) is not modelled".into()
            });
        }
    }
}

impl EventTimer for TimGp {
    fn next_candidate(&self, visible_only: bool) -> Option<Cycles> {
        TimGp::next_candidate(self, visible_only)
    }
    fn process_at(&mut self, t: Cycles) {
        TimGp::process_at(self, t);
    }
    fn last_mut(&mut self) -> &mut Cycles {
        &mut self.last
    }
}

impl Peripheral for TimGp {
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
            0x20 => self.ccer,
            0x24 => {
                let uifcpy = if self.tb.cr1_bits() & cr1::UIFREMAP != 0 && self.sr & sr::UIF != 0 {
                    1 << 31
                } else {
                    0
                };
                let cnt = self.tb.cnt_at(now);
                if self.tb.max() == u32::MAX {
                    cnt
                } else {
                    cnt | uifcpy
                }
            }
            0x28 => u32::from(self.tb.psc_preload()),
            0x2c => self.tb.arr_preload(),
            0x34 => ccr(0),
            0x38 => ccr(1),
            0x3c => ccr(2),
            0x40 => ccr(3),
            0x60 => self.af1,
            0x64 => self.af2,
            o => return self.stored.read(o),
        })
    }

    fn write(&mut self, w: Write, now: Cycles) -> bool {
        let old = self.read(w.offset, now).unwrap_or(0);
        let v = w.merge(old);
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
            0x04 => self.cr2 = v & 0x0200_00f8,
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
            0x10 => self.sr = w.clear_w0(self.sr) & sr::MASK,
            0x14 => {
                if v & 1 != 0 {
                    let urs = self.tb.cr1_bits() & cr1::URS != 0;
                    if self.tb.generate_update(now) {
                        self.ch.transfer();
                        if !urs {
                            self.sr |= sr::UIF;
                        }
                        if self.mms() == 2 || self.mms() == 0 {
                            self.trgo_pulse(now);
                        }
                    }
                }
                for i in 0..4 {
                    if v & (2 << i) != 0 {
                        self.sr |= sr::CCIF1 << i;
                    }
                }
            }
            0x18 => self.write_ccmr(0, v, now),
            0x1c => self.write_ccmr(1, v, now),
            0x20 => self.ccer = v & 0x0000_bbbb,
            0x24 => self.tb.write_cnt(now, v),
            0x28 => self.tb.write_psc(v as u16),
            0x2c => self.tb.write_arr(now, v),
            0x34 | 0x38 | 0x3c | 0x40 => {
                let i = ((w.offset - 0x34) / 4) as usize;
                let val = v & self.tb.max();
                if let Some(p) = self.ch.ccr_pre.get_mut(i) {
                    *p = val;
                }
            }
            0x60 => self.af1 = v & 0x0003_c000,
            0x64 => self.af2 = v & 0x0007_0000,
            o => {
                if !self.stored.write(o, v) {
                    return false;
                }
            }
        }
        self.refresh_trgo(now);
        true
    }

    fn next_event(&self) -> Option<Cycles> {
        self.next_candidate(true)
    }

    fn advance(&mut self, now: Cycles) {
        advance_events(self, now);
    }

    fn irq_lines(&self, lines: &mut IrqLines) {
        if self.sr & self.dier & 0x5f != 0 {
            if let Some(irq) = self.irq {
                lines.set(irq);
            }
        }
    }

    fn reset(&mut self) {
        *self = TimGp::new(self.name);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const CR1: u32 = 0x00;
    const DIER: u32 = 0x0c;
    const SR: u32 = 0x10;
    const EGR: u32 = 0x14;
    const CNT: u32 = 0x24;
    const PSC: u32 = 0x28;
    const ARR: u32 = 0x2c;
    const CCR1: u32 = 0x34;
    const CCR2: u32 = 0x38;

    fn wr(t: &mut TimGp, off: u32, v: u32, now: Cycles) {
        t.advance(now);
        assert!(t.write(Write::word(off, v), now));
    }

    fn rd(t: &mut TimGp, off: u32, now: Cycles) -> u32 {
        t.advance(now);
        t.read(off, now).unwrap_or(0xdead_beef)
    }

    fn irq(t: &TimGp) -> bool {
        let mut l = IrqLines::default();
        t.irq_lines(&mut l);
        l.get(names::irq("TIM4").unwrap_or(0))
    }

    /// embassy-stm32 0.6 `time_driver/gp16.rs` `init_timer` + `init` at cycle `t`, one
    /// register access per cycle; returns the cycle CEN was set.
    fn embassy_init(tim: &mut TimGp, t: Cycles) -> Cycles {
        let seq = [
            (CR1, 0), // cr1.modify(cen = false)
            (CNT, 0),
            (PSC, 169), // 170 MHz / 1 MHz - 1
            (ARR, 0xffff),
            (CR1, cr1::URS),
            (EGR, 1),
            (CR1, 0),
            (CCR1, 0x8000),
            (DIER, 0b11), // UIE | CC1IE
            (CR1, cr1::CEN),
        ];
        for (k, (off, v)) in seq.into_iter().enumerate() {
            wr(tim, off, v, t + k as Cycles);
        }
        t + 9
    }

    #[test]
    fn reset_values() {
        let mut t = TimGp::new("TIM4");
        assert_eq!(rd(&mut t, ARR, 0), 0xffff);
        assert_eq!(rd(&mut t, CR1, 0), 0);
        assert_eq!(rd(&mut t, SR, 0), 0);
        assert_eq!(rd(&mut t, CNT, 0), 0);
        assert_eq!(t.read(0x3e0, 0), None, "DMAR is not modelled");
        assert_eq!(t.next_event(), None);
    }

    #[test]
    fn ug_with_urs_loads_the_prescaler_without_setting_uif() {
        let mut t = TimGp::new("TIM4");
        let cen = embassy_init(&mut t, 1000);
        assert_eq!(rd(&mut t, SR, cen + 1), 0, "URS=1 during UG: no UIF");
        // The prescaler (169) took effect at UG: one count per 170 cycles from CEN.
        assert_eq!(rd(&mut t, CNT, cen + 169), 0);
        assert_eq!(rd(&mut t, CNT, cen + 170), 1);
        assert_eq!(rd(&mut t, CNT, cen + 170 * 12_345 + 169), 12_345);
    }

    #[test]
    fn ug_without_urs_sets_uif() {
        let mut t = TimGp::new("TIM3");
        wr(&mut t, EGR, 1, 10);
        assert_eq!(rd(&mut t, SR, 11), 1);
    }

    #[test]
    fn sr_is_rc_w0() {
        let mut t = TimGp::new("TIM4");
        let cen = embassy_init(&mut t, 0);
        // Both CC1IF (0x8000 counts) and UIF (0x10000) are set by 0x10000 counts.
        let end = cen + 0x10000 * 170;
        assert_eq!(rd(&mut t, SR, end) & 0b11, 0b11);
        // Writing !UIF clears only UIF.
        wr(&mut t, SR, !1, end + 1);
        assert_eq!(rd(&mut t, SR, end + 2) & 0b11, 0b10);
        // Writing 1s never sets a flag.
        wr(&mut t, SR, 0xffff_ffff, end + 3);
        assert_eq!(rd(&mut t, SR, end + 4) & 0b11, 0b10);
        // A read-modify-write that read SR before a flag was set clears it when it writes back.
        let before = rd(&mut t, SR, end + 5); // CC1IF only
        let uif2 = cen + 2 * 0x10000 * 170;
        t.advance(uif2); // UIF set in between
        wr(&mut t, SR, before & !0b10, uif2 + 1); // "clear CC1IF" with the stale value
        assert_eq!(
            rd(&mut t, SR, uif2 + 2) & 1,
            0,
            "the RMW lost the UIF set in between"
        );
    }

    /// The embassy time driver: period counter, `now()`, half-period (CC1) and overflow
    /// interrupts, and an alarm on CC2, over several wraps; every interrupt at its exact cycle.
    #[test]
    fn embassy_time_driver_runs_exactly_over_several_wraps() {
        let mut tim = TimGp::new("TIM4");
        let cen = embassy_init(&mut tim, 5_000);
        let ticks_at = |t: Cycles| (t - cen) / 170; // the true 1 MHz tick count
        let mut period: u32 = 0;
        let calc_now = |period: u32, counter: u32| {
            (u64::from(period) << 15) + u64::from(counter ^ ((period & 1) << 15))
        };
        // Alarms to ring, in ticks.
        let mut alarms: Vec<u64> = vec![100, 40_000, 70_000, 131_000, 300_001, 500_000];
        let mut alarm_at: u64 = u64::MAX;
        let mut rung: Vec<(u64, Cycles)> = Vec::new();
        let mut irqs = 0;
        // set_alarm as the driver does it, at cycle `t`.
        let set_alarm = |tim: &mut TimGp, period: u32, ts: u64, t: Cycles| -> bool {
            let now = calc_now(period, rd(tim, CNT, t));
            if ts <= now {
                let d = rd(tim, DIER, t + 1);
                wr(tim, DIER, d & !(1 << 2), t + 2);
                return false;
            }
            wr(tim, CCR2, (ts as u16).into(), t + 1);
            let d = rd(tim, DIER, t + 2);
            let en = ts - now < 0xc000;
            wr(
                tim,
                DIER,
                (d & !(1 << 2)) | if en { 1 << 2 } else { 0 },
                t + 3,
            );
            true
        };
        let first = alarms.remove(0);
        assert!(set_alarm(&mut tim, period, first, cen + 10));
        alarm_at = alarm_at.min(first);
        let end = cen + 170 * 600_000;
        let mut t_now = cen + 20;
        while let Some(ev) = tim.next_event() {
            if ev > end {
                break;
            }
            assert!(ev >= t_now, "events never go back in time");
            tim.advance(ev);
            assert!(irq(&tim), "next_event() {ev} must be an interrupt here");
            irqs += 1;
            // ISR, one access per cycle from the event.
            let mut t = ev;
            let sr = rd(&mut tim, SR, t);
            let dier = rd(&mut tim, DIER, t + 1);
            wr(&mut tim, SR, !sr, t + 2);
            t += 3;
            if sr & 1 != 0 {
                period += 1;
                assert_eq!(ev, cen + u64::from(period / 2) * 0x10000 * 170, "overflow");
            }
            if sr & 2 != 0 {
                period += 1;
                assert_eq!(
                    ev,
                    cen + (u64::from(period / 2) * 0x10000 + 0x8000) * 170,
                    "half period"
                );
            }
            if sr & 3 != 0 {
                // next_period: enable CC2IE if the alarm is within 0xc000 of the period start.
                let tp = u64::from(period) << 15;
                if alarm_at < tp + 0xc000 {
                    let d = rd(&mut tim, DIER, t);
                    wr(&mut tim, DIER, d | (1 << 2), t + 1);
                    t += 2;
                }
            }
            if sr & 4 != 0 && dier & 4 != 0 {
                let now = calc_now(period, rd(&mut tim, CNT, t));
                assert_eq!(now, ticks_at(t), "now() is the true tick count");
                assert!(now >= alarm_at, "the alarm fires at or after its timestamp");
                rung.push((alarm_at, ev));
                alarm_at = u64::MAX;
                let d = rd(&mut tim, DIER, t + 1);
                wr(&mut tim, DIER, d & !(1 << 2), t + 2);
                t += 3;
                if !alarms.is_empty() {
                    let next = alarms.remove(0);
                    if set_alarm(&mut tim, period, next, t) {
                        alarm_at = next;
                    }
                    t += 4;
                }
            }
            assert!(!irq(&tim) || tim.next_event().is_some_and(|e| e <= t));
            // now() at an arbitrary cycle is the true tick count.
            let probe = t + 7;
            tim.advance(probe);
            let c = rd(&mut tim, CNT, probe);
            assert_eq!(calc_now(period, c), ticks_at(probe));
            t_now = probe + 1;
        }
        assert_eq!(
            period,
            (600_000 / 0x8000) as u32,
            "one period per 2^15 ticks"
        );
        assert_eq!(rung.len(), 6, "{rung:?}");
        for (ts, at) in rung {
            assert_eq!(at, cen + ts * 170, "alarm {ts} rings at its exact cycle");
        }
        assert_eq!(irqs, 18 + 6, "18 half periods and 6 alarms, nothing else");
    }

    #[test]
    fn down_counting_and_arr_without_preload() {
        let mut t = TimGp::new("TIM3");
        wr(&mut t, ARR, 99, 0);
        wr(&mut t, CR1, cr1::DIR, 1);
        wr(&mut t, EGR, 1, 2); // counter = ARR
        wr(&mut t, SR, 0, 3);
        wr(&mut t, DIER, 1, 4);
        wr(&mut t, CR1, cr1::DIR | cr1::CEN, 10);
        assert_eq!(rd(&mut t, CNT, 10), 99);
        assert_eq!(rd(&mut t, CNT, 11), 98);
        // Underflow: the step onto ARR after 0 (100 steps from 99 to 0, then one more).
        assert_eq!(t.next_event(), Some(10 + 100));
        assert_eq!(rd(&mut t, CNT, 109), 0);
        assert_eq!(rd(&mut t, CNT, 110), 99);
        assert_eq!(rd(&mut t, SR, 110) & 1, 1);
        // ARR lowered without preload below the counter: it keeps counting down to the new
        // ARR, then wraps as usual.
        wr(&mut t, SR, 0, 111); // counter 98
        wr(&mut t, ARR, 49, 112); // counter 97 > 49
        assert_eq!(rd(&mut t, CNT, 113), 96);
        // It joins its trajectory at 49 (a regime change the SoC is told about), then counts
        // 49..0 and underflows onto 49.
        assert_eq!(t.next_event(), Some(112 + 48));
        assert_eq!(rd(&mut t, CNT, 160), 49);
        assert_eq!(rd(&mut t, SR, 160) & 1, 0, "joining is not an update");
        assert_eq!(t.next_event(), Some(210));
        assert_eq!(rd(&mut t, CNT, 209), 0);
        assert_eq!(rd(&mut t, CNT, 210), 49);
        assert_eq!(rd(&mut t, SR, 210) & 1, 1);
    }

    #[test]
    fn arr_preload_takes_effect_at_the_update_event() {
        let mut t = TimGp::new("TIM3");
        wr(&mut t, ARR, 9, 0);
        wr(&mut t, CR1, cr1::ARPE, 1);
        wr(&mut t, EGR, 1, 2);
        wr(&mut t, CR1, cr1::ARPE | cr1::CEN, 10);
        wr(&mut t, ARR, 19, 12);
        // Still wraps after 10 steps (ARR 9), then every 20.
        assert_eq!(rd(&mut t, CNT, 19), 9);
        assert_eq!(rd(&mut t, CNT, 20), 0);
        assert_eq!(rd(&mut t, CNT, 39), 19);
        assert_eq!(rd(&mut t, CNT, 40), 0);
    }

    #[test]
    fn one_pulse_mode_stops_at_the_update() {
        let mut t = TimGp::new("TIM3");
        wr(&mut t, ARR, 4, 0);
        wr(&mut t, CR1, cr1::OPM | cr1::CEN, 1);
        assert_eq!(rd(&mut t, CNT, 5), 4);
        assert_eq!(rd(&mut t, CNT, 6), 0);
        assert_eq!(rd(&mut t, CR1, 7) & cr1::CEN, 0);
        assert_eq!(rd(&mut t, CNT, 100), 0);
    }

    #[test]
    fn debug_freeze_stops_the_counter() {
        let mut t = TimGp::new("TIM4");
        let cen = embassy_init(&mut t, 0);
        t.set_debug_halt(true, cen + 170 * 10 + 5);
        assert_eq!(rd(&mut t, CNT, cen + 170 * 1000), 10);
        t.set_debug_halt(false, cen + 170 * 1000);
        // The prescaler resumes where it stopped (165 cycles to the next count).
        assert_eq!(rd(&mut t, CNT, cen + 170 * 1000 + 164), 10);
        assert_eq!(rd(&mut t, CNT, cen + 170 * 1000 + 165), 11);
    }

    #[test]
    fn trgo_on_oc_reference() {
        let mut t = TimGp::new("TIM4");
        wr(&mut t, ARR, 9, 0);
        wr(&mut t, CCR1 + 12, 3, 1); // CCR4 = 3
        wr(&mut t, 0x1c, (6 << 12) | (1 << 11), 2); // CCMR2: OC4M = PWM1, OC4PE
        wr(&mut t, EGR, 1, 3);
        wr(&mut t, 0x04, 7 << 4, 4); // MMS = OC4REF
        wr(&mut t, CR1, cr1::CEN, 10);
        let edges: Vec<(Cycles, bool)> = t.take_trgo().map(|e| (e.at, e.level)).collect();
        // UG with MMS = reset is a TRGO pulse; then OC4REF (PWM1, counter 0 < 3) is high.
        assert_eq!(edges, vec![(3, true), (3, false), (4, true)]);
        assert_eq!(
            t.next_event(),
            Some(13),
            "OC4REF falls when the counter reaches 3"
        );
        t.advance(30);
        let edges: Vec<(Cycles, bool)> = t.take_trgo().map(|e| (e.at, e.level)).collect();
        assert_eq!(
            edges,
            vec![(13, false), (20, true), (23, false), (30, true)]
        );
    }
}
