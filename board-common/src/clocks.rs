//! System clock: HSI16 / 4 * 85 / 2 = 170 MHz on PLL R, with range-1 boost mode, which the
//! G4 requires above 150 MHz (embassy then sets 4 flash wait states). PLL P = 42.5 MHz
//! clocks ADC1/ADC2 (below their 60 MHz limit).

use embassy_stm32::rcc::{
    mux, AHBPrescaler, APBPrescaler, Pll, PllMul, PllPDiv, PllPreDiv, PllRDiv, PllSource, Sysclk,
};
use embassy_stm32::Config;

/// Core clock both board layers assume (the drive's TIM1 counts at this rate: APB2 prescaler 1).
pub const SYSCLK_HZ: u32 = 170_000_000;

/// The embassy configuration for 170 MHz.
pub fn config() -> Config {
    let mut config = Config::default();
    config.rcc.hsi = true;
    config.rcc.pll = Some(Pll {
        source: PllSource::HSI,
        prediv: PllPreDiv::DIV4,
        mul: PllMul::MUL85,
        divp: Some(PllPDiv::DIV8),
        divq: None,
        divr: Some(PllRDiv::DIV2),
    });
    config.rcc.sys = Sysclk::PLL1_R;
    config.rcc.ahb_pre = AHBPrescaler::DIV1;
    config.rcc.apb1_pre = APBPrescaler::DIV1;
    config.rcc.apb2_pre = APBPrescaler::DIV1;
    config.rcc.boost = true;
    config.rcc.mux.adc12sel = mux::Adcsel::PLL1_P;
    config
}
