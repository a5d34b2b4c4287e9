//! The board around the MCU as the SoC sees it: pin levels, analog voltages, the power
//! stage, and the steps of its analog inputs.

use crate::periph::comp::CompConfig;
use crate::periph::gpio::{Drive, PinReader};
use crate::periph::tim_adv::TimEvent;
use crate::time::Cycles;

/// The board around the MCU: pin levels, analog voltages, the power stage.
pub trait Board: PinReader {
    /// Output pins changed at `now`; `drives(port, pin)` is how the MCU drives each pin.
    fn outputs_changed(&mut self, _now: Cycles, _drives: &dyn Fn(u8, u8) -> Drive) {}

    /// Volts on pin `pin` ("PA1") at `at` (ADC sampling, comparator inputs, OPAMP inputs).
    fn pin_volts(&mut self, _pin: &str, _at: Cycles) -> f64 {
        0.0
    }

    /// TIM1 changed its outputs (an update with new compares, MOE, a break, the debug
    /// freeze): the power stage follows from `ev.at`.
    fn power_stage(&mut self, _ev: &TimEvent) {}

    /// Whether comparator `config.comp`'s non-inverting input is above `level` now: the level
    /// it must pass next (INM with the part's input offset and, while the comparator is high,
    /// its hysteresis below INM: `CompBank::threshold`). A board that knows of a crossing
    /// between two calls may report it (a short overcurrent between two samples trips the
    /// hardware). The default compares the pin's volts now.
    fn comparator_above(&mut self, config: &CompConfig, level: f64, at: Cycles) -> bool {
        self.pin_volts(config.inp, at) > level
    }

    /// The first cycle after `after` at which the board's analog inputs change by a step
    /// (a disturbance that starts or ends), `None` when none is known. The SoC samples the
    /// comparators there, as it does at TIM1's events: the silicon's comparator follows its
    /// input continuously, so a step between two TIM1 events reaches its output tD after
    /// the step, not at the next event (a spike that ended inside a blanking window does
    /// not show when the window closes).
    fn next_input_change(&self, _after: Cycles) -> Option<Cycles> {
        None
    }

    /// The frequency of the crystal on OSC32_IN/OSC32_OUT, `None` where the board fits none:
    /// the LSE then never becomes ready.
    fn lse_hz(&self) -> Option<u64> {
        None
    }
}

/// VREFINT (DS12589 typical), for the comparators' scaled references and the ADC.
pub const VREFINT_VOLTS: f64 = 1.212;

/// A bare board: nothing connected.
pub struct BareBoard;

impl PinReader for BareBoard {}

impl Board for BareBoard {}

/// A pin as (port, number): `(1, 8)` is PB8.
pub type PinId = (u8, u8);

/// An I2C bus's (SCL, SDA) pins on the board.
pub type BusPins = (PinId, PinId);
