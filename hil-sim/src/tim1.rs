//! TIM1 as hil-sim's drive board programs it: the registers the firmware's
//! [`PowerPort`] writes (MOE, CCxE/CCxNE, preloaded CCR1-3, PSC/ARR/DTG), the update
//! event that loads the preloads, and the break flag with its interrupt mask. The plant
//! ([`Plant`]) holds what the hardware does asynchronously: the comparators, the break
//! input clearing MOE, and the gates.
//!
//! The rules are RM0440's, as in `g431-emu`'s register model: compares (CCR1-3 and the
//! blanking window's CCR5), PSC, ARR and the dead time take effect at the update event; MOE and the output enables at once; MOE
//! cannot be set while the break input is active; the break flag stays set while it is.

use firmware_drive::bodies::{BreakPort, PwmPort};
use firmware_drive::power_port::{BreakSources, ComparatorLevels, PowerPort};
use firmware_drive::{AdcSample, PwmTiming};

use crate::plant::{GateCommand, Leg, Plant};

/// The timer's registers.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimTim1 {
    /// PSC/ARR/DTG in effect (loaded at the last update event).
    active: PwmTiming,
    /// Written, loaded at the next update event.
    preload: Option<PwmTiming>,
    ccr_active: [u16; 3],
    ccr_preload: [u16; 3],
    /// CCR5 (OC5, the comparators' blanking window), preloaded like the compares.
    ccr5_active: u16,
    ccr5_preload: u16,
    legs: [bool; 3],
    moe: bool,
    /// BIE: the break interrupt is unmasked.
    break_irq_enabled: bool,
    timer_clock_hz: u32,
}

impl SimTim1 {
    /// As the board's init leaves it: counting with `timing`, MOE = 0, all compares 0,
    /// every leg enabled, the break interrupt unmasked.
    pub fn new(timing: PwmTiming, timer_clock_hz: u32) -> Self {
        SimTim1 {
            active: timing,
            preload: None,
            ccr_active: [0; 3],
            ccr_preload: [0; 3],
            ccr5_active: 0,
            ccr5_preload: 0,
            legs: [true; 3],
            moe: false,
            break_irq_enabled: true,
            timer_clock_hz,
        }
    }

    /// The update event: preloaded timing and compares take effect.
    pub fn update(&mut self) {
        if let Some(t) = self.preload.take() {
            self.active = t;
        }
        self.ccr_active = self.ccr_preload;
        self.ccr5_active = self.ccr5_preload;
    }

    /// CCR5 in effect: OC5 (PWM mode 1) is active while CNT < CCR5, the comparators
    /// with BLANKSEL = TIM1_OC5 are blanked then (the plant applies it,
    /// [`Plant::set_blanking`]).
    pub fn blanking_ccr5(&self) -> u16 {
        self.ccr5_active
    }

    /// CCR1-3 in effect (loaded at the last update event), timer counts.
    pub fn compares(&self) -> [u16; 3] {
        self.ccr_active
    }

    pub fn timing(&self) -> &PwmTiming {
        &self.active
    }

    pub fn timer_clock_hz(&self) -> u32 {
        self.timer_clock_hz
    }

    pub fn moe(&self) -> bool {
        self.moe
    }

    /// What the gates do under these registers (ignoring a break, which the plant applies).
    pub fn gate(&self) -> GateCommand {
        if !self.moe {
            return GateCommand::OFF;
        }
        let n = f64::from(self.active.arr.max(1));
        let mut legs = [Leg::Off; 3];
        for ((leg, c), on) in legs.iter_mut().zip(self.ccr_active).zip(self.legs) {
            if on {
                *leg = Leg::Duty((f64::from(c) / n).min(1.0));
            }
        }
        let f = u64::from(self.timer_clock_hz.max(1));
        GateCommand {
            legs,
            dead_time_ns: (u64::from(self.active.dead_time_counts) * 1_000_000_000).div_ceil(f),
        }
    }

    /// The break interrupt would run now: unmasked and a break flag set (BIF or B2IF).
    pub fn break_irq_pending(&self, plant: &Plant) -> bool {
        self.break_irq_enabled && (plant.break_flag() || plant.sto_flag())
    }

    /// BIE: the break interrupt is unmasked.
    pub fn break_irq_enabled(&self) -> bool {
        self.break_irq_enabled
    }

    /// BIE = 1 (the control tick's re-arm): no flag is cleared.
    pub fn unmask_break_irq(&mut self) {
        self.break_irq_enabled = true;
    }

    /// The firmware's power port on these registers and `plant`.
    pub fn port<'a>(&'a mut self, plant: &'a mut Plant) -> SimPowerPort<'a> {
        SimPowerPort { tim: self, plant }
    }

    /// The PWM interrupt's port: these registers, `plant` and the ADC's `sample` of this
    /// period (the update event has happened: [`SimTim1::update`]).
    pub fn pwm_port<'a>(&'a mut self, plant: &'a mut Plant, sample: AdcSample) -> SimPwmPort<'a> {
        SimPwmPort {
            power: SimPowerPort { tim: self, plant },
            sample,
            update: true,
        }
    }

    /// The break interrupt's port on these registers and `plant`.
    pub fn break_port<'a>(&'a mut self, plant: &'a mut Plant) -> SimBreakPort<'a> {
        SimBreakPort {
            power: SimPowerPort { tim: self, plant },
        }
    }
}

/// [`PwmPort`] over [`SimTim1`], the plant and the period's ADC sample, as the board's
/// `Tim1Port` is over TIM1 and the ADC.
pub struct SimPwmPort<'a> {
    power: SimPowerPort<'a>,
    sample: AdcSample,
    /// UIF (the simulator calls the interrupt at the update event).
    update: bool,
}

impl PwmPort for SimPwmPort<'_> {
    fn take_update(&mut self) -> bool {
        core::mem::take(&mut self.update)
    }

    fn sample(&mut self) -> AdcSample {
        self.sample
    }
}

impl PowerPort for SimPwmPort<'_> {
    fn outputs_off(&mut self) {
        self.power.outputs_off();
    }
    fn break_pending(&self) -> bool {
        self.power.break_pending()
    }
    fn set_timing(&mut self, t: &PwmTiming) {
        self.power.set_timing(t);
    }
    fn set_compares(&mut self, ccr: [u16; 3]) {
        self.power.set_compares(ccr);
    }
    fn set_blanking(&mut self, ccr5: u16) {
        self.power.set_blanking(ccr5);
    }
    fn set_legs(&mut self, on: [bool; 3]) {
        self.power.set_legs(on);
    }
    fn outputs_on(&mut self) {
        self.power.outputs_on();
    }
    fn set_brake(&mut self, on: bool) {
        self.power.set_brake(on);
    }
}

/// [`BreakPort`] over [`SimTim1`] and the plant (BIF: `STO_IN`, B2IF: the comparators; no
/// system break in the simulator), as the board's `Tim1Break` is over TIM1.
pub struct SimBreakPort<'a> {
    power: SimPowerPort<'a>,
}

impl BreakPort for SimBreakPort<'_> {
    fn break_flags(&mut self) -> BreakSources {
        BreakSources {
            sto: self.power.plant.sto_flag(),
            comparator: self.power.plant.break_flag(),
            system: false,
        }
    }

    fn mask_break_irq(&mut self) {
        self.power.tim.break_irq_enabled = false;
    }

    fn outputs_off(&mut self) {
        PowerPort::outputs_off(&mut self.power);
    }

    fn comparator_levels(&mut self) -> ComparatorLevels {
        self.power.plant.comparator_levels()
    }

    fn clear_break_flags(&mut self, seen: BreakSources) {
        if seen.sto {
            self.power.plant.clear_sto_flag();
        }
        if seen.comparator {
            self.power.plant.clear_break_flag();
        }
    }
}

/// [`PowerPort`] over [`SimTim1`] and the plant, as `firmware-drive`'s `Tim1Port` is over
/// the real registers.
pub struct SimPowerPort<'a> {
    tim: &'a mut SimTim1,
    plant: &'a mut Plant,
}

impl SimPowerPort<'_> {
    /// MOE and the output enables act at once: the gates follow now.
    fn drive_gates(&mut self) {
        self.plant.set_command(self.tim.gate());
    }
}

impl PowerPort for SimPowerPort<'_> {
    fn outputs_off(&mut self) {
        self.tim.moe = false;
        self.drive_gates();
    }

    fn break_pending(&self) -> bool {
        self.plant.break_flag()
            || self.plant.sto_flag()
            || self.plant.break_input_active()
            || self.plant.sto_in_low()
    }

    fn set_timing(&mut self, t: &PwmTiming) {
        self.tim.preload = Some(*t);
    }

    fn set_compares(&mut self, ccr: [u16; 3]) {
        self.tim.ccr_preload = ccr;
    }

    fn set_blanking(&mut self, ccr5: u16) {
        self.tim.ccr5_preload = ccr5;
    }

    fn set_legs(&mut self, on: [bool; 3]) {
        self.tim.legs = on;
        if self.tim.moe {
            self.drive_gates();
        }
    }

    fn outputs_on(&mut self) {
        // RM0440 29.3.18: MOE cannot be set while a break input is active (break 2: the
        // comparators, break 1: `STO_IN` low).
        if self.plant.break_input_active() || self.plant.sto_in_low() {
            return;
        }
        self.tim.moe = true;
        self.plant.release_break();
        self.drive_gates();
    }

    fn set_brake(&mut self, on: bool) {
        self.plant.set_brake(on);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plant::RigParams;
    use firmware_drive::power_port::PeriodAction;
    use firmware_drive::PwmCommand;

    fn timing(pwf: u32) -> PwmTiming {
        PwmTiming::compute(170_000_000, pwf, 1, 1000, 500)
    }

    fn run_cmd(duty: u16, arr: u16) -> PwmCommand {
        PwmCommand {
            enable: true,
            leg_enable: [true; 3],
            duty: [duty; 3],
            period_counts: arr,
            brake: false,
        }
    }

    #[test]
    fn compares_and_timing_wait_for_the_update_event_moe_acts_at_once() {
        let t = timing(16_000);
        let mut tim = SimTim1::new(t, 170_000_000);
        let mut plant = Plant::new(RigParams::default());
        PeriodAction::from_command(&run_cmd(t.arr / 2, t.arr), &t, &t)
            .apply(&mut tim.port(&mut plant));
        assert!(tim.moe());
        // MOE is on, the compares of this period are still the old ones (0).
        assert_eq!(tim.gate().legs, [Leg::Duty(0.0); 3]);
        tim.update();
        let half = f64::from(t.arr / 2) / f64::from(t.arr);
        assert_eq!(tim.gate().legs, [Leg::Duty(half); 3]);
        // A new timing: outputs off at once, the new ARR only after the update.
        let t2 = timing(8_000);
        PeriodAction::from_command(&run_cmd(t.arr / 2, t.arr), &t, &t2)
            .apply(&mut tim.port(&mut plant));
        assert!(!tim.moe());
        assert_eq!(tim.timing().arr, t.arr);
        tim.update();
        assert_eq!(tim.timing().arr, t2.arr);
    }

    #[test]
    fn the_blanking_window_is_preloaded_and_blanks_the_phase_comparators() {
        let t = timing(16_000);
        let mut tim = SimTim1::new(t, 170_000_000);
        let mut plant = Plant::new(RigParams::default());
        let a = PeriodAction::from_command(&run_cmd(1000, t.arr), &t, &t);
        assert_eq!(a.blanking, 1000 + t.blank_counts);
        a.apply(&mut tim.port(&mut plant));
        assert_eq!(tim.blanking_ccr5(), 0, "CCR5 waits for the update event");
        tim.update();
        assert_eq!(tim.blanking_ccr5(), 1000 + t.blank_counts);
        // In the plant: a window of 2 x CCR5 counts around the valley (mid-period).
        let period_ns = 62_500;
        plant.start_period(period_ns, tim.gate());
        plant.set_blanking(tim.blanking_ccr5(), t.arr);
        let half = u64::from(1000 + t.blank_counts) * (period_ns / 2) / u64::from(t.arr);
        assert!(plant.blanking_at(period_ns / 2));
        assert!(plant.blanking_at(period_ns / 2 + half - 1));
        assert!(!plant.blanking_at(period_ns / 2 + half));
        assert!(!plant.blanking_at(0), "live at the peak");
    }
}
