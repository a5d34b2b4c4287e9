//! Measurements: ADC1 and ADC2 injected sequences, both started by TIM1 TRGO2 (OC4REF, just
//! below the top of the centre-aligned count, while the low-side switches conduct). The
//! PWM interrupt runs at the next valley, half a period later, and reads the finished
//! conversions straight from the JDR registers.
//!
//! | ADC | rank | channel | signal |
//! | --- | --- | --- | --- |
//! | ADC1 | 1 | the profile's `current_a`: IN13 (OPAMP1, ESC1) or IN2 (PA1) | phase current a |
//! | ADC1 | 2 | IN1 (PA0) | DC link |
//! | ADC1 | 3 | IN11 (PB12) | aux `COM` |
//! | ADC2 | 1 | the profile's `current_b`: IN16 (OPAMP2, ESC1) or IN4 (PA7) | phase current b |
//!
//! Which channel carries the currents is the board profile's table
//! (`firmware_drive::front_end`); this module only binds it. The counts go to the core
//! unscaled ([`firmware_drive::measure::AdcSample`]).

use embassy_stm32::adc::{
    Adc, AdcChannel, AdcConfig, AnyAdcChannel, Exten, InjectedAdc, SampleTime,
};
use embassy_stm32::opamp::{OpAmp, OpAmpGain, OpAmpSpeed};
use embassy_stm32::peripherals::{ADC1, ADC2, OPAMP1, OPAMP2, OPAMP3};
use embassy_stm32::triggers::TIM1_TRGO2;
use embassy_stm32::{pac, Peri};
use firmware_drive::front_end::{AdcInput, FrontEndSpec};
use firmware_drive::measure::AdcSample;
use static_cell::StaticCell;

use crate::pins::Analog;

/// Sample time of every channel: 12.5 ADC clocks (0.3 us at 42.5 MHz) settles the
/// low-impedance sensor and amplifier outputs; the whole ADC1 sequence takes about 2 us.
const SAMPLE_TIME: SampleTime = SampleTime::CYCLES12_5;

/// The running injected sequences (dropping them would stop the converters).
pub struct Converters {
    _adc1: InjectedAdc<'static, ADC1, 3>,
    _adc2: InjectedAdc<'static, ADC2, 1>,
    /// Configured through the PAC only (its output is not sampled): owned so that nothing
    /// else claims it.
    _opamp3: Peri<'static, OPAMP3>,
}

/// Calibrates both ADCs, arms their injected sequences on TIM1 TRGO2 with the channels of
/// the front end `fe`, then enables its amplifiers ([`super::opamps::apply`]).
///
/// The comparators share the current and DC-link pins; they only need the pins in analog
/// mode, which the ADC channels set up here as well.
pub fn init(a: Analog, fe: &FrontEndSpec) -> Converters {
    static OPAMP1_DRV: StaticCell<OpAmp<'static, OPAMP1>> = StaticCell::new();
    static OPAMP2_DRV: StaticCell<OpAmp<'static, OPAMP2>> = StaticCell::new();
    let adc1 = Adc::new(a.adc1, AdcConfig::default());
    let adc2 = Adc::new(a.adc2, AdcConfig::default());
    let mut current_a = a.current_a;
    let mut current_b = a.current_b;
    // The ADC channel of an amplifier's internal output can only be had from embassy's
    // OPAMP driver; the CSR it writes (and clears again when the token is dropped) is
    // rewritten from the table by `opamps::apply` below.
    let ch_a: AnyAdcChannel<'static, ADC1> = match fe.current_a {
        AdcInput::Pin {
            adc: 1, channel: 2, ..
        } => current_a.degrade_adc(),
        AdcInput::Opamp(1) => OPAMP1_DRV
            .init(OpAmp::new(a.opamp1, OpAmpSpeed::HighSpeed))
            .pga_int(current_a.reborrow(), OpAmpGain::Mul16)
            .degrade_adc(),
        _ => super::fault::fatal(super::fault::UNBINDABLE_PROFILE),
    };
    let ch_b: AnyAdcChannel<'static, ADC2> = match fe.current_b {
        AdcInput::Pin {
            adc: 2, channel: 4, ..
        } => current_b.degrade_adc(),
        AdcInput::Opamp(2) => OPAMP2_DRV
            .init(OpAmp::new(a.opamp2, OpAmpSpeed::HighSpeed))
            .pga_int(current_b.reborrow(), OpAmpGain::Mul16)
            .degrade_adc(),
        _ => super::fault::fatal(super::fault::UNBINDABLE_PROFILE),
    };
    let adc1 = adc1.setup_injected_conversions(
        [
            (ch_a, SAMPLE_TIME),
            (a.dc_link.degrade_adc(), SAMPLE_TIME),
            (a.aux.degrade_adc(), SAMPLE_TIME),
        ],
        TIM1_TRGO2,
        Exten::RISING_EDGE,
        false,
    );
    let adc2 = adc2.setup_injected_conversions(
        [(ch_b, SAMPLE_TIME)],
        TIM1_TRGO2,
        Exten::RISING_EDGE,
        false,
    );
    super::opamps::apply(fe);
    Converters {
        _adc1: adc1,
        _adc2: adc2,
        _opamp3: a.opamp3,
    }
}

/// The latest injected conversions of both ADCs.
#[inline(always)]
pub fn read() -> AdcSample {
    AdcSample {
        i_a: pac::ADC1.jdr(0).read().jdata(),
        u_dc: pac::ADC1.jdr(1).read().jdata(),
        aux: pac::ADC1.jdr(2).read().jdata(),
        i_b: pac::ADC2.jdr(0).read().jdata(),
    }
}
