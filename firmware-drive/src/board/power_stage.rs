//! Power stage outputs.
//!
//! Until the PWM is bound to TIM1 the six gate signals are plain GPIO outputs held low: the
//! ESC1 gate driver's inputs are active high, so low on all six opens every switch.

use embassy_stm32::gpio::{AnyPin, Level, Output, Speed};
use embassy_stm32::Peri;

use crate::pins::PowerStage;

/// The six gate outputs, all held off.
pub struct GatesOff {
    _pins: [Output<'static>; 6],
}

/// Drives all six gate inputs low.
pub fn hold_off(p: PowerStage) -> GatesOff {
    let low = |pin: Peri<'static, AnyPin>| Output::new(pin, Level::Low, Speed::Low);
    GatesOff {
        _pins: [
            low(p.u_high.into()),
            low(p.u_low.into()),
            low(p.v_high.into()),
            low(p.v_low.into()),
            low(p.w_high.into()),
            low(p.w_low.into()),
        ],
    }
}
