//! System clock: HSI16 / 4 * 85 / 2 = 170 MHz on PLL R, with range-1 boost mode, which the
//! G4 requires above 150 MHz (embassy then sets 4 flash wait states). PLL P = 42.5 MHz
//! clocks ADC1/ADC2 (below their 60 MHz limit).
//!
//! Boost mode is entered by [`enter_boost_mode`] before the switch to 170 MHz (review E7):
//! embassy-stm32 0.6 clears R1MODE with `PWR.cr5().modify(|w| w.set_r1mode(false))`, but
//! stm32-metapac 21 places R1MODE at bit 0 of PWR_CR5, where RM0440 ("PWR control register
//! 5 (PWR_CR5)": bits 31:9 and 7:0 reserved, bit 8 R1MODE, reset value 0x0000_0100) and
//! ST's CMSIS header (`PWR_CR5_R1MODE_Pos` 8) have it. R1MODE is the register's only field,
//! so nothing else in it is misplaced; embassy's write then clears a reserved bit that
//! reads 0. Review N9 (embassy switches SW = PLL and HPRE = /1 in one write, without the
//! /2 step RM0440 §6.1.5 asks for) stays open: `firmware-drive/docs/board.md`.

use embassy_stm32::rcc::{
    self, mux, AHBPrescaler, APBPrescaler, Pll, PllMul, PllPDiv, PllPreDiv, PllRDiv, PllSource,
    Sysclk,
};
use embassy_stm32::{pac, peripherals, Peri};

/// Range 1 boost mode (RM0440 §6.1.5 "Dynamic voltage scaling management": range 1 normal
/// mode allows 150 MHz at most, boost 170 MHz): PWR clocked, then PWR_CR5 written whole
/// with R1MODE (bit 8) = 0. Called at 16 MHz (HSI16), after `embassy_stm32::init` (which
/// resets PWR through RCC_APB1RSTR1.PWRRST, so a write before it is lost) and before
/// [`raise`] switches to 170 MHz: the order §6.1.5 gives (R1MODE cleared, then the wait
/// states, then the switch).
pub fn enter_boost_mode() {
    pac::RCC.apb1enr1().modify(|w| w.set_pwren(true));
    // The read-back makes the enable take effect before the PWR access (RM0440 "Peripheral
    // clock enable register": a delay after enabling a peripheral clock).
    let _ = pac::RCC.apb1enr1().read();
    pac::PWR.cr5().write_value(pac::pwr::regs::Cr5(0));
}

/// Core clock both board layers assume (the drive's TIM1 counts at this rate: APB2 prescaler 1).
pub const SYSCLK_HZ: u32 = 170_000_000;

/// Turns the flash prefetch on (FLASH_ACR.PRFTEN, RM0440 §3.3.4 "Read access latency" /
/// "Adaptive real-time memory accelerator (ART Accelerator)"): at 4 wait states every
/// instruction fetch that misses the ART's instruction cache otherwise stalls the core for
/// the full latency. The instruction and data caches (ICEN, DCEN) are on from reset
/// (FLASH_ACR reset value 0x0000_0600) and embassy-stm32 0.6 never sets PRFTEN (review N8:
/// with it, the longest critical sections fit one PWM period at 20 kHz,
/// `firmware-drive/docs/critical-sections.md`). Call after embassy set the wait states.
pub fn enable_prefetch() {
    pac::FLASH.acr().modify(|w| w.set_prften(true));
}

/// Switches from HSI16 (embassy's default set-up) to 170 MHz with embassy's clock set-up
/// (`rcc::reinit`, which also restarts the time driver at the new clock). PWR is not reset
/// on this path, so the boost mode [`enter_boost_mode`] set stays.
pub fn raise(rcc_peri: &mut Peri<'static, peripherals::RCC>) {
    rcc::reinit(config(), rcc_peri);
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
