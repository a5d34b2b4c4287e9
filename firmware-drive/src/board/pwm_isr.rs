//! The TIM1 update interrupt (once per PWM period, at the valley) and the TIM1 break
//! interrupt.

use embassy_stm32::gpio::Level;
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

/// Per PWM period: sample in, core's per-period function, compares/MOE/brake out.
#[interrupt]
fn TIM1_UP_TIM16() {
    if !power_stage::take_update() {
        return;
    }
    #[cfg(feature = "dwt-cycles")]
    let start = super::cycles::now();
    let sample = analog::read();
    let done = shared::with(|s| {
        let cmd = s.app.pwm_period(&sample);
        if !cmd.enable {
            power_stage::outputs_off();
        }
        let timing = s.app.pwm_timing();
        if timing != s.timing {
            power_stage::apply_timing(&timing, s.min_dead_counts);
            s.timing = timing;
        }
        // `ccr()` writes a 100 % duty as ARR + 1 (CCR = ARR would leave a one-count low
        // pulse at the peak); clamp against the ARR the timer really has so a compare is
        // never above ARR + 1.
        let max = timing.arr.saturating_add(1);
        power_stage::write_duties(cmd.ccr().map(|d| d.min(max)));
        if cmd.enable {
            power_stage::set_legs(cmd.leg_enable);
            power_stage::outputs_on();
        }
        s.brake.set_level(Level::from(cmd.brake));
    });
    if done.is_none() {
        power_stage::outputs_off();
    }
    #[cfg(feature = "dwt-cycles")]
    super::cycles::record_pwm(start);
}

/// The break input fired: MOE is already cleared by hardware. Tell the core which cause.
#[interrupt]
fn TIM1_BRK_TIM15() {
    if !power_stage::take_break() {
        return;
    }
    power_stage::outputs_off();
    let causes = hw_protection::active(firmware_drive::config::DriveConfig::default().board);
    shared::with(|s| {
        let mut any = false;
        for (cause, present) in causes {
            if present {
                s.app.hardware_break(cause, true);
                any = true;
            }
        }
        // The comparator may already be back below its threshold: blame overcurrent, the
        // faster and more dangerous cause.
        if !any {
            s.app
                .hardware_break(firmware_drive::protection::HwBreak::Overcurrent, true);
        }
    });
}
