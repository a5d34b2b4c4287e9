//! The power stage as the core drives it: one [`PeriodAction`] per PWM period, performed by
//! [`PeriodAction::apply`] over a small [`PowerPort`], so that the order of the register
//! writes is decided here, once, and host-tested; the board implements the port with
//! TIM1's registers, hil-sim with its plant. The break input's attribution, release and
//! re-arming are core decisions too ([`BreakMonitor`]), taking the comparator levels the
//! board reads.
//!
//! The rules `apply` keeps (tested with a recording port):
//! * outputs go off first whenever they are not to be on, before anything else is written;
//! * MOE is never set while a break is pending (the break flag not yet taken by the break
//!   interrupt, or the break input still active: RM0440 "MOE cannot be set while the break
//!   input is active"), and a break that arrives between that check and the write of MOE
//!   (a pulse shorter than the write, which the hardware then does not block) takes the
//!   outputs off again at once: the flag is checked once more after MOE is set;
//! * compares are never above ARR + 1 of the timing in effect;
//! * the blanking window (CCR5) is written right after the compares it belongs to (both
//!   preloaded: they take effect together at the update event);
//! * a timer change (PSC/ARR/dead time) is written with the outputs off, and they stay off
//!   for that period: they come back at the next period, once the new timing is in effect.

use crate::comparators::BoardProfile;
use crate::drive::PwmCommand;
use crate::protection::HwBreak;
use crate::timing::PwmTiming;

/// What the core needs of the power stage's registers.
pub trait PowerPort {
    /// MOE = 0: all six switches to their inactive level, at once.
    fn outputs_off(&mut self);
    /// A break is pending (the break flag set, or the break input active): MOE cannot be
    /// set.
    fn break_pending(&self) -> bool;
    /// PSC, ARR, the ADC trigger point and the dead time (all preloaded: from the next
    /// update event).
    fn set_timing(&mut self, t: &PwmTiming);
    /// CCR1-3 (preloaded).
    fn set_compares(&mut self, ccr: [u16; 3]);
    /// CCR5, the comparator blanking window (OC5 active while CNT < CCR5, preloaded: it
    /// takes effect with the compares of the same period; `crate::blanking`).
    fn set_blanking(&mut self, ccr5: u16);
    /// Per leg: its two switches follow their compare (CCxE = CCxNE = 1) or stay open.
    fn set_legs(&mut self, on: [bool; 3]);
    /// MOE = 1.
    fn outputs_on(&mut self);
    /// The brake chopper's switch.
    fn set_brake(&mut self, on: bool);
}

/// The power stage for one PWM period.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PeriodAction {
    /// Outputs on (MOE) this period.
    pub enable: bool,
    /// Legs that switch (all false when `enable` is false).
    pub legs: [bool; 3],
    /// CCR1-3, at most ARR + 1 of the timing in effect.
    pub ccr: [u16; 3],
    /// CCR5: the blanking window around the switching edges of these compares (0: none).
    pub blanking: u16,
    /// A new timing to program (the outputs stay off for this period).
    pub timing: Option<PwmTiming>,
    pub brake: bool,
}

impl PeriodAction {
    /// The action for the core's command `cmd`, given the timing TIM1 is programmed with
    /// (`programmed`) and the one the core wants (`wanted`).
    #[inline(always)]
    pub fn from_command(cmd: &PwmCommand, programmed: &PwmTiming, wanted: &PwmTiming) -> Self {
        let timing = (programmed != wanted).then_some(*wanted);
        let max = wanted.arr.saturating_add(1);
        let enable = cmd.enable && timing.is_none();
        let legs = if enable { cmd.leg_enable } else { [false; 3] };
        let [c0, c1, c2] = cmd.ccr();
        let ccr = [c0.min(max), c1.min(max), c2.min(max)];
        PeriodAction {
            enable,
            legs,
            ccr,
            blanking: crate::blanking::ccr5(ccr, legs, wanted),
            timing,
            brake: cmd.brake,
        }
    }

    /// Performs the action in the one order the module documents.
    pub fn apply(&self, port: &mut impl PowerPort) {
        if !self.enable {
            port.outputs_off();
        }
        if let Some(t) = &self.timing {
            port.set_timing(t);
        }
        port.set_compares(self.ccr);
        port.set_blanking(self.blanking);
        if self.enable {
            port.set_legs(self.legs);
            if port.break_pending() {
                port.outputs_off();
            } else {
                port.outputs_on();
                if port.break_pending() {
                    port.outputs_off();
                }
            }
        }
        port.set_brake(self.brake);
    }
}

/// The comparator outputs as the board reads them (COMPx value after polarity),
/// index = comparator number - 1 (COMP1..COMP7).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ComparatorLevels(pub [bool; 7]);

impl ComparatorLevels {
    /// Which causes the high comparators of `board` stand for.
    pub fn causes(&self, board: &BoardProfile) -> Causes {
        let mut out = Causes::NONE;
        for s in board.comparators {
            let high = self
                .0
                .get(usize::from(s.comp.saturating_sub(1)))
                .copied()
                .unwrap_or(false);
            if high {
                out.set(s.cause(), true);
            }
        }
        out
    }
}

/// One flag per hardware break cause, indexed by [`HwBreak`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Causes {
    pub overcurrent: bool,
    pub overvoltage: bool,
}

impl Causes {
    /// No cause.
    pub const NONE: Causes = Causes {
        overcurrent: false,
        overvoltage: false,
    };

    /// `cause` alone.
    pub const fn only(cause: HwBreak) -> Causes {
        let mut c = Causes::NONE;
        match cause {
            HwBreak::Overcurrent => c.overcurrent = true,
            HwBreak::Overvoltage => c.overvoltage = true,
        }
        c
    }

    pub const fn get(&self, cause: HwBreak) -> bool {
        match cause {
            HwBreak::Overcurrent => self.overcurrent,
            HwBreak::Overvoltage => self.overvoltage,
        }
    }

    pub fn set(&mut self, cause: HwBreak, on: bool) {
        match cause {
            HwBreak::Overcurrent => self.overcurrent = on,
            HwBreak::Overvoltage => self.overvoltage = on,
        }
    }

    pub const fn any(&self) -> bool {
        self.overcurrent || self.overvoltage
    }

    /// The causes set, in the order of [`HwBreak::ALL`].
    pub fn iter(self) -> impl Iterator<Item = HwBreak> {
        HwBreak::ALL.into_iter().filter(move |c| self.get(*c))
    }
}

/// What the break monitor tells the core and the board.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BreakReport {
    /// Causes to latch now (a break fired).
    pub fired: Causes,
    /// Causes whose comparators went low.
    pub released: Causes,
    /// No comparator is high any more and `STO_IN` is high: the break interrupt may be
    /// unmasked again (it was masked when a break fired, since a flag sets again at once
    /// while its input stays active). Only unmasked: a flag set while the interrupt was
    /// masked (a comparator break during an STO) is still set and is reported then,
    /// delayed, not lost.
    pub rearm: bool,
}

/// The break flags the break interrupt found, one per source of TIM1's break
/// (the board maps its status register to these).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BreakSources {
    /// `STO_IN` (break 1, BIF).
    pub sto: bool,
    /// A comparator (break 2, B2IF).
    pub comparator: bool,
    /// The system break (SBIF: PVD, SRAM parity, flash ECC, LOCKUP).
    pub system: bool,
}

impl BreakSources {
    pub const fn any(&self) -> bool {
        self.sto || self.comparator || self.system
    }
}

/// Attribution, release and re-arming of the hardware break: the comparators' break,
/// the `STO_IN` break and the system break (safety.md 6) share the one break interrupt,
/// masked after each report until every input it watches is inactive.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct BreakMonitor {
    active: Causes,
    masked: bool,
    /// `STO_IN` low as last read (the board reads it every millisecond).
    sto_low: bool,
}

impl BreakMonitor {
    /// The break interrupt fired with the comparators at `levels` (the hardware has already
    /// cleared MOE; the interrupt is masked). The causes whose comparators are high are
    /// latched; if none is high any more (a pulse shorter than the interrupt's latency),
    /// overcurrent is blamed, the faster and more dangerous cause.
    pub fn fired(&mut self, board: &BoardProfile, levels: ComparatorLevels) -> BreakReport {
        let mut causes = levels.causes(board);
        if !causes.any() {
            causes.overcurrent = true;
        }
        self.active.overcurrent |= causes.overcurrent;
        self.active.overvoltage |= causes.overvoltage;
        self.masked = true;
        BreakReport {
            fired: causes,
            released: Causes::NONE,
            rearm: false,
        }
    }

    /// The `STO_IN` break or the system break fired (the hardware has already cleared MOE;
    /// the interrupt is masked): masked until [`BreakMonitor::poll`] re-arms.
    pub fn other_fired(&mut self) {
        self.masked = true;
    }

    /// `STO_IN`'s level, every millisecond before [`BreakMonitor::poll`]: no re-arming
    /// while it is low (its flag would set again at once).
    pub fn set_sto_input(&mut self, low: bool) {
        self.sto_low = low;
    }

    /// Every millisecond with the comparators at `levels`: the latched causes whose
    /// comparators are low are released (the fault stays latched until ACK; only the
    /// "cause still present" check changes), and the interrupt is re-armed once none is
    /// high.
    pub fn poll(&mut self, board: &BoardProfile, levels: ComparatorLevels) -> BreakReport {
        let high = levels.causes(board);
        let mut released = Causes::NONE;
        for c in HwBreak::ALL {
            if self.active.get(c) && !high.get(c) {
                self.active.set(c, false);
                released.set(c, true);
            }
        }
        let rearm = self.masked && !high.any() && !self.sto_low;
        if rearm {
            self.masked = false;
        }
        BreakReport {
            fired: Causes::NONE,
            released,
            rearm,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::comparators::SOURCE_SENSORS;

    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    enum Op {
        Off,
        Timing(u16),
        Compares([u16; 3]),
        Blanking(u16),
        Legs([bool; 3]),
        On,
        Brake(bool),
    }

    /// A port that records the writes and models MOE and a pending break as TIM1 does.
    #[derive(Default)]
    struct Recorder {
        ops: Vec<Op>,
        moe: bool,
        break_pending: bool,
        /// A break pulse arrives during the write of MOE.
        break_during_moe_write: bool,
        arr: u16,
    }

    impl PowerPort for Recorder {
        fn outputs_off(&mut self) {
            self.moe = false;
            self.ops.push(Op::Off);
        }
        fn break_pending(&self) -> bool {
            self.break_pending
        }
        fn set_timing(&mut self, t: &PwmTiming) {
            assert!(!self.moe, "timer changed with the outputs on");
            self.arr = t.arr;
            self.ops.push(Op::Timing(t.arr));
        }
        fn set_compares(&mut self, ccr: [u16; 3]) {
            assert!(
                ccr.iter().all(|c| *c <= self.arr + 1),
                "compare above ARR + 1: {ccr:?} (ARR {})",
                self.arr
            );
            self.ops.push(Op::Compares(ccr));
        }
        fn set_blanking(&mut self, ccr5: u16) {
            assert!(ccr5 <= self.arr, "CCR5 {ccr5} above ARR {}", self.arr);
            self.ops.push(Op::Blanking(ccr5));
        }
        fn set_legs(&mut self, on: [bool; 3]) {
            self.ops.push(Op::Legs(on));
        }
        fn outputs_on(&mut self) {
            assert!(!self.break_pending, "MOE set while a break is pending");
            self.moe = true;
            self.ops.push(Op::On);
            if self.break_during_moe_write {
                self.break_pending = true;
            }
        }
        fn set_brake(&mut self, on: bool) {
            self.ops.push(Op::Brake(on));
        }
    }

    fn timing(arr: u16) -> PwmTiming {
        PwmTiming {
            arr,
            ..PwmTiming::compute(170_000_000, 16_000, 1, 1000, 500)
        }
    }

    fn cmd(enable: bool, duty: [u16; 3], period: u16) -> PwmCommand {
        PwmCommand {
            enable,
            leg_enable: [enable; 3],
            duty,
            period_counts: period,
            brake: false,
        }
    }

    #[test]
    fn running_period_writes_compares_legs_then_moe_then_brake() {
        let t = timing(1000);
        let mut p = Recorder {
            arr: 1000,
            ..Recorder::default()
        };
        PeriodAction::from_command(&cmd(true, [10, 500, 1000], 1000), &t, &t).apply(&mut p);
        // The leg at 1000 (100 %) does not switch: the window ends `blank_counts` after
        // the 500 leg's edge.
        assert_eq!(
            p.ops,
            vec![
                Op::Compares([10, 500, 1001]),
                Op::Blanking(500 + t.blank_counts),
                Op::Legs([true; 3]),
                Op::On,
                Op::Brake(false)
            ]
        );
    }

    #[test]
    fn off_goes_first() {
        let t = timing(1000);
        let mut p = Recorder {
            arr: 1000,
            moe: true,
            ..Recorder::default()
        };
        PeriodAction::from_command(&cmd(false, [0; 3], 1000), &t, &t).apply(&mut p);
        assert_eq!(p.ops.first(), Some(&Op::Off));
        assert!(!p.moe);
    }

    #[test]
    fn no_window_while_the_outputs_are_off() {
        let t = timing(1000);
        let mut p = Recorder {
            arr: 1000,
            ..Recorder::default()
        };
        PeriodAction::from_command(&cmd(false, [500; 3], 1000), &t, &t).apply(&mut p);
        assert!(p.ops.contains(&Op::Blanking(0)), "{:?}", p.ops);
    }

    #[test]
    fn no_moe_while_a_break_is_pending() {
        let t = timing(1000);
        let mut p = Recorder {
            arr: 1000,
            break_pending: true,
            ..Recorder::default()
        };
        PeriodAction::from_command(&cmd(true, [500; 3], 1000), &t, &t).apply(&mut p);
        assert!(!p.moe);
        assert!(!p.ops.contains(&Op::On));
    }

    #[test]
    fn a_break_during_the_moe_write_takes_the_outputs_off_again() {
        let t = timing(1000);
        let mut p = Recorder {
            arr: 1000,
            break_during_moe_write: true,
            ..Recorder::default()
        };
        PeriodAction::from_command(&cmd(true, [500; 3], 1000), &t, &t).apply(&mut p);
        assert!(!p.moe);
        let on = p.ops.iter().position(|o| *o == Op::On);
        let off = p.ops.iter().rposition(|o| *o == Op::Off);
        assert!(on < off, "{:?}", p.ops);
    }

    #[test]
    fn a_timer_change_is_written_with_the_outputs_off_and_they_stay_off_that_period() {
        let (old, new) = (timing(1000), timing(400));
        let mut p = Recorder {
            arr: 1000,
            moe: true,
            ..Recorder::default()
        };
        // The command still refers to the old period: the compares are clamped to the new.
        let a = PeriodAction::from_command(&cmd(true, [900, 100, 1000], 1000), &old, &new);
        a.apply(&mut p);
        assert_eq!(
            p.ops,
            vec![
                Op::Off,
                Op::Timing(400),
                Op::Compares([401, 100, 401]),
                Op::Blanking(0),
                Op::Brake(false)
            ]
        );
        assert!(!p.moe);
        // Next period, same timing: back on.
        let mut p2 = Recorder {
            arr: 400,
            ..Recorder::default()
        };
        PeriodAction::from_command(&cmd(true, [300; 3], 400), &new, &new).apply(&mut p2);
        assert!(p2.moe);
    }

    #[test]
    fn any_command_keeps_the_rules() {
        // Every combination of enable, break, a timing change and duties beyond ARR.
        for enable in [false, true] {
            for pending in [false, true] {
                for change in [false, true] {
                    for duty in [0u16, 1, 499, 500, 501, u16::MAX] {
                        let old = timing(500);
                        let new = if change { timing(300) } else { old };
                        let mut p = Recorder {
                            arr: 500,
                            moe: true,
                            break_pending: pending,
                            ..Recorder::default()
                        };
                        PeriodAction::from_command(&cmd(enable, [duty; 3], 500), &old, &new)
                            .apply(&mut p);
                        assert_eq!(p.moe, enable && !pending && !change);
                    }
                }
            }
        }
    }

    fn levels(high: &[u8]) -> ComparatorLevels {
        let mut l = ComparatorLevels::default();
        for c in high {
            l.0[usize::from(*c) - 1] = true;
        }
        l
    }

    #[test]
    fn break_attribution_release_and_rearm() {
        let b = &SOURCE_SENSORS;
        let mut m = BreakMonitor::default();
        // COMP3 is the DC link: overvoltage.
        let r = m.fired(b, levels(&[3]));
        assert_eq!(r.fired, Causes::only(HwBreak::Overvoltage));
        // Still high: nothing released, not re-armed.
        assert_eq!(m.poll(b, levels(&[3])), BreakReport::default());
        let r = m.poll(b, levels(&[]));
        assert_eq!(r.released, Causes::only(HwBreak::Overvoltage));
        assert!(r.rearm);
        // Re-armed once only.
        assert!(!m.poll(b, levels(&[])).rearm);
        // COMP4 (phase W) is overcurrent; a pulse already gone blames overcurrent.
        assert_eq!(
            m.fired(b, levels(&[4])).fired,
            Causes::only(HwBreak::Overcurrent)
        );
        assert_eq!(
            m.fired(b, levels(&[])).fired,
            Causes::only(HwBreak::Overcurrent)
        );
    }

    /// After an `STO_IN` break the interrupt stays masked while the input
    /// is low, even once the comparators are low (a comparator break meanwhile waits in
    /// its flag), and is re-armed once, when the input is high again.
    #[test]
    fn sto_break_rearms_only_with_the_input_high() {
        let b = &SOURCE_SENSORS;
        let mut m = BreakMonitor::default();
        m.other_fired();
        m.set_sto_input(true);
        assert!(!m.poll(b, levels(&[])).rearm, "STO_IN still low");
        m.set_sto_input(false);
        assert!(!m.poll(b, levels(&[3])).rearm, "a comparator still high");
        assert!(m.poll(b, levels(&[])).rearm);
        assert!(!m.poll(b, levels(&[])).rearm, "once");
        // Nothing masked: a low STO_IN alone asks for nothing.
        m.set_sto_input(true);
        assert_eq!(m.poll(b, levels(&[])), BreakReport::default());
    }
}
