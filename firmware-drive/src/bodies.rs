//! The drive's interrupt and task bodies, each one function over a port: the board
//! implements the ports with TIM1's, the ADC's, the comparators' and the DACs' registers
//! (`src/board/`), hil-sim with its timer model and plant, and both call these functions at
//! the same cadence, so the two run one sequence (`docs/board.md`, "Task and interrupt
//! bodies").
//!
//! | body | port | cadence |
//! | --- | --- | --- |
//! | [`DriveApp::pwm_interrupt`] | [`PwmPort`] | TIM1 update, once per PWM period |
//! | [`DriveApp::break_interrupt`] | [`BreakPort`] | TIM1 break (unmasked by the control tick) |
//! | [`DriveApp::control_tick`] | [`ControlPort`] | every 1 ms |
//!
//! A port method is one register access (or a few, for one register's fields); the order
//! of the accesses and every decision are here.

use shared_protocol::link::pump::is_due;
use shared_protocol::units::Micros;

use crate::app::{AppEvent, DriveApp, TickStep};
use crate::comparators::DacValues;
use crate::measure::AdcSample;
use crate::power_port::{BreakSources, ComparatorLevels, PowerPort};

/// Events one control tick hands to the board for its log (the application keeps the
/// newest 32; the link task leaves its events for this task).
pub const EVENTS_PER_TICK: usize = 32;

/// The events of one control tick, oldest first.
pub type TickEvents = heapless::Vec<AppEvent, EVENTS_PER_TICK>;

/// The TIM1 update interrupt's registers: the power stage plus the update flag and this
/// period's ADC sample.
pub trait PwmPort: PowerPort {
    /// Whether the update flag is set; clears it (and only it).
    fn take_update(&mut self) -> bool;
    /// The injected conversions of this period.
    fn sample(&mut self) -> AdcSample;
}

/// The TIM1 break interrupt's registers.
pub trait BreakPort {
    /// The break flags set now (they stay set until [`BreakPort::clear_break_flags`]).
    fn break_flags(&mut self) -> BreakSources;
    /// Masks the break interrupt (BIE = 0): a flag sets again at once while its input
    /// stays active.
    fn mask_break_irq(&mut self);
    /// MOE = 0.
    fn outputs_off(&mut self);
    /// The comparator outputs now.
    fn comparator_levels(&mut self) -> ComparatorLevels;
    /// Clears the flags of `seen` and no other (a flag set since stays for the next entry).
    fn clear_break_flags(&mut self, seen: BreakSources);
}

/// The 1 ms task's inputs and outputs, and its access to the application: the board runs
/// each [`ControlPort::with_app`] in a critical section of its own, so that the PWM
/// interrupt waits for one step of the tick at most.
pub trait ControlPort {
    /// `f` on the application (the board: inside one critical section); `None` before
    /// the application exists.
    fn with_app<R>(&mut self, f: impl FnOnce(&mut DriveApp) -> R) -> Option<R>;
    /// The application's clock.
    fn now(&mut self) -> Micros;
    /// `STO_IN` is low (STO requested).
    fn sto_input_low(&mut self) -> bool;
    /// The comparator outputs now.
    fn comparator_levels(&mut self) -> ComparatorLevels;
    /// Unmasks the break interrupt (BIE = 1) without clearing any flag.
    fn rearm_break_irq(&mut self);
    /// Writes the threshold DACs the values name.
    fn write_dacs(&mut self, v: DacValues);
    /// Wakes the link task now.
    fn kick_link(&mut self);
}

impl DriveApp {
    /// The TIM1 update interrupt: the update flag taken, this period's sample in, the
    /// [`PeriodAction`](crate::power_port::PeriodAction) performed on the port.
    #[inline(always)]
    pub fn pwm_interrupt(&mut self, port: &mut impl PwmPort) {
        if !port.take_update() {
            return;
        }
        let sample = port.sample();
        let action = self.pwm_period(&sample);
        action.apply(port);
    }

    /// The TIM1 break interrupt (MOE is already cleared by the hardware): the flags taken
    /// and the interrupt masked until the control tick re-arms it, the outputs off, the
    /// core told each source (the comparators with their levels, for the attribution),
    /// and only then the flags cleared: until the core has seen a break, its flag keeps
    /// the PWM interrupt from setting MOE ([`PowerPort::break_pending`]).
    #[inline(always)]
    pub fn break_interrupt(&mut self, port: &mut impl BreakPort) {
        let seen = port.break_flags();
        if !seen.any() {
            return;
        }
        port.mask_break_irq();
        port.outputs_off();
        let levels = port.comparator_levels();
        if seen.sto {
            self.sto_break();
        }
        if seen.comparator {
            let _ = self.break_fired(levels);
        }
        if seen.system {
            self.system_break();
        }
        port.clear_break_flags(seen);
    }

    /// The 1 ms task: `STO_IN` and the comparator levels to the break monitor (safety.md
    /// 6: no re-arming while the input is low), each [`TickStep`] in its own
    /// [`ControlPort::with_app`], the threshold DACs written when the core's values
    /// changed (a download), the link task woken when the application has something due,
    /// the break interrupt re-armed when the monitor says so. The application's events
    /// come back for the board's log.
    #[inline(always)]
    pub fn control_tick(port: &mut impl ControlPort) -> TickEvents {
        let levels = port.comparator_levels();
        let sto_low = port.sto_input_low();
        let rearm = port.with_app(|app| {
            app.set_sto_input(sto_low);
            app.break_poll(levels).rearm
        });
        let now = port.now();
        for step in TickStep::ALL {
            port.with_app(|app| app.tick_step(step, now));
        }
        let mut events = TickEvents::new();
        let (dacs, deadline) = port
            .with_app(|app| {
                while !events.is_full() {
                    match app.poll_event() {
                        Some(e) => {
                            let _ = events.push(e);
                        }
                        None => break,
                    }
                }
                (app.dacs_to_write(), app.poll_timeout())
            })
            .unwrap_or((None, None));
        if let Some(v) = dacs {
            port.write_dacs(v);
        }
        if is_due(deadline, port.now()) {
            port.kick_link();
        }
        if rearm == Some(true) {
            port.rearm_break_irq();
        }
        events
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::app::DriveApp;
    use crate::config::{DriveConfig, ResetCause};
    use crate::power_port::PowerPort;
    use crate::timing::PwmTiming;
    use shared_protocol::link::LinkConfig;

    /// Records the calls of the three ports; the break input's flags as TIM1 keeps them.
    #[derive(Default)]
    struct Rec {
        calls: Vec<&'static str>,
        flags: BreakSources,
        sto_low: bool,
        levels: ComparatorLevels,
        t_us: u64,
        app: Option<Box<DriveApp>>,
    }

    impl PowerPort for Rec {
        fn outputs_off(&mut self) {
            self.calls.push("off");
        }
        fn break_pending(&self) -> bool {
            self.flags.any()
        }
        fn set_timing(&mut self, _: &PwmTiming) {
            self.calls.push("timing");
        }
        fn set_compares(&mut self, _: [u16; 3]) {
            self.calls.push("compares");
        }
        fn set_blanking(&mut self, _: u16) {}
        fn set_legs(&mut self, _: [bool; 3]) {}
        fn outputs_on(&mut self) {
            self.calls.push("on");
        }
        fn set_brake(&mut self, _: bool) {}
    }

    impl PwmPort for Rec {
        fn take_update(&mut self) -> bool {
            self.calls.push("update");
            true
        }
        fn sample(&mut self) -> AdcSample {
            AdcSample::default()
        }
    }

    impl BreakPort for Rec {
        fn break_flags(&mut self) -> BreakSources {
            self.flags
        }
        fn mask_break_irq(&mut self) {
            self.calls.push("mask");
        }
        fn outputs_off(&mut self) {
            self.calls.push("off");
        }
        fn comparator_levels(&mut self) -> ComparatorLevels {
            self.levels
        }
        fn clear_break_flags(&mut self, seen: BreakSources) {
            self.calls.push("clear");
            self.flags.sto &= !seen.sto;
            self.flags.comparator &= !seen.comparator;
            self.flags.system &= !seen.system;
        }
    }

    impl ControlPort for Rec {
        fn with_app<R>(&mut self, f: impl FnOnce(&mut DriveApp) -> R) -> Option<R> {
            self.app.as_deref_mut().map(f)
        }
        fn now(&mut self) -> Micros {
            Micros(self.t_us)
        }
        fn sto_input_low(&mut self) -> bool {
            self.sto_low
        }
        fn comparator_levels(&mut self) -> ComparatorLevels {
            self.levels
        }
        fn rearm_break_irq(&mut self) {
            self.calls.push("rearm");
        }
        fn write_dacs(&mut self, _: DacValues) {
            self.calls.push("dacs");
        }
        fn kick_link(&mut self) {}
    }

    fn app() -> Box<DriveApp> {
        Box::new(DriveApp::new(
            DriveConfig::default(),
            ResetCause::PowerOn,
            LinkConfig::default(),
        ))
    }

    fn tick(p: &mut Rec) {
        p.t_us += 1000;
        let _ = DriveApp::control_tick(p);
    }

    #[test]
    fn a_break_masks_takes_the_outputs_off_and_clears_after_the_core_has_seen_it() {
        let mut a = app();
        let mut p = Rec {
            flags: BreakSources {
                comparator: true,
                ..BreakSources::default()
            },
            ..Rec::default()
        };
        a.break_interrupt(&mut p);
        assert_eq!(p.calls, ["mask", "off", "clear"]);
        assert!(a.core().fault().is_some(), "the comparator's fault latched");
        // Nothing set: a spurious entry touches nothing.
        p.calls.clear();
        a.break_interrupt(&mut p);
        assert!(p.calls.is_empty());
    }

    #[test]
    fn the_break_stays_masked_while_sto_in_is_low_and_is_rearmed_once_after() {
        let mut p = Rec {
            app: Some(app()),
            flags: BreakSources {
                sto: true,
                ..BreakSources::default()
            },
            sto_low: true,
            ..Rec::default()
        };
        if let Some(a) = p.app.as_deref_mut() {
            let mut b = Rec {
                flags: p.flags,
                ..Rec::default()
            };
            a.break_interrupt(&mut b);
        }
        for _ in 0..5 {
            tick(&mut p);
        }
        assert!(!p.calls.contains(&"rearm"), "{:?}", p.calls);
        p.sto_low = false;
        tick(&mut p);
        tick(&mut p);
        assert_eq!(p.calls.iter().filter(|c| **c == "rearm").count(), 1);
    }

    #[test]
    fn the_dacs_are_written_at_the_first_tick_and_then_only_when_they_change() {
        let mut p = Rec {
            app: Some(app()),
            ..Rec::default()
        };
        tick(&mut p);
        tick(&mut p);
        assert_eq!(p.calls.iter().filter(|c| **c == "dacs").count(), 1);
        let mut p = Rec {
            app: Some(app()),
            ..Rec::default()
        };
        if let Some(a) = p.app.as_deref_mut() {
            let _ = a.boot_dacs();
        }
        tick(&mut p);
        assert!(!p.calls.contains(&"dacs"), "written at start-up already");
    }

    #[test]
    fn the_pwm_interrupt_takes_the_flag_then_applies_the_action() {
        let mut a = app();
        let mut p = Rec::default();
        a.pwm_interrupt(&mut p);
        // BOOT: outputs off first, then the compares.
        assert_eq!(p.calls.first(), Some(&"update"));
        assert_eq!(p.calls.get(1), Some(&"off"));
        assert!(!p.calls.contains(&"on"));
    }
}
