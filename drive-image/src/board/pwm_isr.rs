//! The TIM1 update interrupt (once per PWM period, at the valley) and the TIM1 break
//! interrupt: each runs the application's body (`firmware_drive::bodies`) over the
//! registers ([`power_stage::Tim1Port`], [`power_stage::Tim1Break`]).

use embassy_stm32::interrupt;
use embassy_stm32::interrupt::{InterruptExt, Priority};

use super::{power_stage, shared};

/// Unmasks both TIM1 interrupts at the highest priority.
pub fn enable() {
    for irq in [interrupt::TIM1_UP_TIM16, interrupt::TIM1_BRK_TIM15] {
        irq.set_priority(Priority::P0);
        // SAFETY: the handlers below only touch the shared state through its mutex and the
        // TIM1/ADC registers nobody else writes after init.
        unsafe { irq.enable() };
    }
}

/// Per PWM period: [`DriveApp::pwm_interrupt`]. Before the application is installed (the
/// interrupt is unmasked only after that) the outputs stay off.
///
/// [`DriveApp::pwm_interrupt`]: firmware_drive::app::DriveApp::pwm_interrupt
#[interrupt]
fn TIM1_UP_TIM16() {
    #[cfg(feature = "dwt-cycles")]
    let start = super::cycles::now();
    let done = shared::with(|s| {
        s.app.pwm_interrupt(&mut power_stage::Tim1Port {
            brake: &mut s.brake,
        })
    });
    if done.is_none() {
        power_stage::outputs_off();
    }
    #[cfg(feature = "dwt-cycles")]
    super::cycles::record_pwm(start);
}

/// A break fired (MOE is already cleared by hardware): [`DriveApp::break_interrupt`].
///
/// [`DriveApp::break_interrupt`]: firmware_drive::app::DriveApp::break_interrupt
#[interrupt]
fn TIM1_BRK_TIM15() {
    let done = shared::with(|s| s.app.break_interrupt(&mut power_stage::Tim1Break));
    if done.is_none() {
        power_stage::outputs_off();
    }
}
