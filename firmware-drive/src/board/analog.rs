//! Measurements: ADC1 and ADC2 injected sequences, both started by TIM1 TRGO2 (OC4REF, just
//! below the top of the centre-aligned count, while the low-side switches conduct). The
//! PWM interrupt runs at the next valley, half a period later, and reads the finished
//! conversions straight from the JDR registers.
//!
//! | ADC | rank | channel | signal |
//! | --- | --- | --- | --- |
//! | ADC1 | 1 | IN2 (PA1) | phase current a |
//! | ADC1 | 2 | IN1 (PA0) | DC link |
//! | ADC1 | 3 | IN11 (PB12) | aux `COM` |
//! | ADC2 | 1 | IN4 (PA7) | phase current b |
//!
//! The counts go to the core unscaled ([`firmware_drive::measure::AdcSample`]).

use embassy_stm32::adc::{Adc, AdcChannel, AdcConfig, Exten, InjectedAdc, SampleTime};
use embassy_stm32::pac;
use embassy_stm32::peripherals::{ADC1, ADC2};
use embassy_stm32::triggers::TIM1_TRGO2;
use firmware_drive::measure::AdcSample;

use crate::pins::Analog;

/// Sample time of every channel: 12.5 ADC clocks (0.3 us at 42.5 MHz) settles the
/// low-impedance sensor outputs; the whole ADC1 sequence takes about 2 us.
const SAMPLE_TIME: SampleTime = SampleTime::CYCLES12_5;

/// The running injected sequences (dropping them would stop the converters).
pub struct Converters {
    _adc1: InjectedAdc<'static, ADC1, 3>,
    _adc2: InjectedAdc<'static, ADC2, 1>,
}

/// Calibrates both ADCs and arms their injected sequences on TIM1 TRGO2.
///
/// The comparators share the current and DC-link pins; they only need the pins in analog
/// mode, which the ADC channels set up here as well.
pub fn init(a: Analog) -> Converters {
    let adc1 = Adc::new(a.adc1, AdcConfig::default());
    let adc2 = Adc::new(a.adc2, AdcConfig::default());
    let adc1 = adc1.setup_injected_conversions(
        [
            (a.current_a.degrade_adc(), SAMPLE_TIME),
            (a.dc_link.degrade_adc(), SAMPLE_TIME),
            (a.aux.degrade_adc(), SAMPLE_TIME),
        ],
        TIM1_TRGO2,
        Exten::RISING_EDGE,
        false,
    );
    let adc2 = adc2.setup_injected_conversions(
        [(a.current_b.degrade_adc(), SAMPLE_TIME)],
        TIM1_TRGO2,
        Exten::RISING_EDGE,
        false,
    );
    Converters {
        _adc1: adc1,
        _adc2: adc2,
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
