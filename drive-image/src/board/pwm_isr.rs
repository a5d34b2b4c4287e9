//! The TIM1 update interrupt (once per PWM period, at the valley) and the TIM1 break
//! interrupt: registers in, the application's decision out, performed over
//! [`power_stage::Tim1Port`].

use embassy_stm32::interrupt;
use embassy_stm32::interrupt::{InterruptExt, Priority};

use super::{analog, hw_protection, power_stage, shared};

/// Unmasks both TIM1 interrupts at the highest priority.
pub fn enable() {
    for irq in [interrupt::TIM1_UP_TIM16, interrupt::TIM1_BRK_TIM15] {
        irq.set_priority(Priority::P0);
        // SAFETY: the handlers below only touch the shared state through its mutex and the
        // TIM1/ADC registers nobody else writes after init.
        unsafe { irq.enable() };
    }
}

/// Per PWM period: the sample in, the application's [`PeriodAction`] performed on TIM1.
///
/// [`PeriodAction`]: firmware_drive::power_port::PeriodAction
#[interrupt]
fn TIM1_UP_TIM16() {
    if !power_stage::take_update() {
        return;
    }
    #[cfg(feature = "dwt-cycles")]
    let start = super::cycles::now();
    let sample = analog::read();
    let done = shared::with(|s| {
        let action = s.app.pwm_period(&sample);
        action.apply(&mut power_stage::Tim1Port {
            brake: &mut s.brake,
            min_dead_counts: s.min_dead_counts,
        });
    });
    if done.is_none() {
        power_stage::outputs_off();
    }
    #[cfg(feature = "dwt-cycles")]
    super::cycles::record_pwm(start);
}

/// A break fired: MOE is already cleared by hardware. The application is told each source
/// whose flag is set (the comparators with their levels, for the attribution), and only
/// then are those flags cleared: until the core has seen a break, its flag keeps the PWM
/// interrupt from setting MOE (`Tim1Port::break_pending`).
#[interrupt]
fn TIM1_BRK_TIM15() {
    let seen = power_stage::take_break();
    if seen.none() {
        return;
    }
    power_stage::outputs_off();
    let levels = hw_protection::levels();
    shared::with(|s| {
        if seen.sto() {
            s.app.sto_break();
        }
        if seen.comparator() {
            let _ = s.app.break_fired(levels);
        }
        if seen.system() {
            s.app.system_break();
        }
    });
    power_stage::clear_break_flags(seen);
}
