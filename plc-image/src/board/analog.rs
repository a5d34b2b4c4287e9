//! The analog inputs A00..A03 on ADC1, converted at 10 bits so the counts are the
//! source's 0..1023 without any scaling.

use embassy_stm32::adc::{Adc, AdcChannel, AdcConfig, AnyAdcChannel, Resolution, SampleTime};
use embassy_stm32::peripherals::ADC1;

use crate::pins::Analog;

/// Long enough for the input dividers' source impedance (about 10 kOhm).
const SAMPLE_TIME: SampleTime = SampleTime::CYCLES47_5;

/// ADC1 with the four channels.
pub struct AnalogInputs {
    adc: Adc<'static, ADC1>,
    channels: [AnyAdcChannel<'static, ADC1>; 4],
}

impl AnalogInputs {
    pub fn new(a: Analog) -> Self {
        let config = AdcConfig {
            resolution: Some(Resolution::BITS10),
            ..AdcConfig::default()
        };
        Self {
            adc: Adc::new(a.adc, config),
            channels: [
                a.a00.degrade_adc(),
                a.a01.degrade_adc(),
                a.a02.degrade_adc(),
                a.a03.degrade_adc(),
            ],
        }
    }

    /// One conversion of each channel (about 4 us in all), counts 0..1023.
    pub fn sample(&mut self) -> [u16; 4] {
        let adc = &mut self.adc;
        let mut out = [0u16; 4];
        for (o, ch) in out.iter_mut().zip(self.channels.iter_mut()) {
            *o = adc.blocking_read(ch, SAMPLE_TIME);
        }
        out
    }
}
