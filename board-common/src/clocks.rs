//! System clock: HSI16 / 4 * 85 / 2 = 170 MHz on PLL R, with range-1 boost mode, which the
//! G4 requires above 150 MHz (embassy then sets 4 flash wait states). PLL P = 42.5 MHz
//! clocks ADC1/ADC2 (below their 60 MHz limit).
//!
//! Range 1 boost mode and the switch to 170 MHz are embassy's G4 clock set-up, from the
//! vendored embassy-stm32 0.6.0 with two fixes (`vendor/README.md`): stm32-metapac 21
//! places R1MODE at bit 0 of PWR_CR5, where RM0440 ("PWR control register 5 (PWR_CR5)":
//! bit 8 R1MODE, reset value 0x0000_0100) and ST's CMSIS header (`PWR_CR5_R1MODE_Pos` 8)
//! have it, so upstream never entered boost mode; and upstream switched
//! SW = PLL and HPRE = /1 in one CFGR write, where RM0440 §6.1.5 keeps HPRE = /2 across
//! the switch and for 1 us after it. One `embassy_stm32::init` with
//! [`config`] does both.

use embassy_stm32::pac;
use embassy_stm32::rcc::{
    self, mux, AHBPrescaler, APBPrescaler, Pll, PllMul, PllPDiv, PllPreDiv, PllRDiv, PllSource,
    Sysclk,
};

/// Core clock both board layers assume (the drive's TIM1 counts at this rate: APB2 prescaler 1).
pub const SYSCLK_HZ: u32 = 170_000_000;

/// Turns the flash prefetch on (FLASH_ACR.PRFTEN, RM0440 §3.3.4 "Read access latency" /
/// "Adaptive real-time memory accelerator (ART Accelerator)"): at 4 wait states every
/// instruction fetch that misses the ART's instruction cache otherwise stalls the core for
/// the full latency. The instruction and data caches (ICEN, DCEN) are on from reset
/// (FLASH_ACR reset value 0x0000_0600) and embassy-stm32 0.6 never sets PRFTEN (
/// with it, the longest critical sections fit one PWM period at 20 kHz,
/// `firmware-drive/docs/critical-sections.md`). Call after embassy set the wait states.
pub fn enable_prefetch() {
    pac::FLASH.acr().modify(|w| w.set_prften(true));
}

/// The embassy clock configuration for 170 MHz.
pub fn config() -> rcc::Config {
    let mut config = rcc::Config::default();
    config.hsi = true;
    config.pll = Some(Pll {
        source: PllSource::HSI,
        prediv: PllPreDiv::DIV4,
        mul: PllMul::MUL85,
        divp: Some(PllPDiv::DIV8),
        divq: None,
        divr: Some(PllRDiv::DIV2),
    });
    config.sys = Sysclk::PLL1_R;
    config.ahb_pre = AHBPrescaler::DIV1;
    config.apb1_pre = APBPrescaler::DIV1;
    config.apb2_pre = APBPrescaler::DIV1;
    config.boost = true;
    config.mux.adc12sel = mux::Adcsel::PLL1_P;
    config
}
