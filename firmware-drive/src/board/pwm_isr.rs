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

/// The break input fired: MOE is already cleared by hardware. The application attributes
/// it from the comparator levels.
#[interrupt]
fn TIM1_BRK_TIM15() {
    match power_stage::take_break() {
        power_stage::BreakKind::None => return,
        // STO_IN (break 2): the hardware has opened the outputs; the tick reads the input.
        power_stage::BreakKind::StoOnly => {
            power_stage::outputs_off();
            return;
        }
        power_stage::BreakKind::Comparator => {}
    }
    power_stage::outputs_off();
    let levels = hw_protection::levels();
    shared::with(|s| s.app.break_fired(levels));
}
