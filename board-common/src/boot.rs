//! The boot sequence both images start with.

use embassy_stm32::interrupt::{self, InterruptExt, Priority};
use embassy_stm32::Peripherals;
use shared_protocol::supervision::ResetCause;

use crate::{banner, clocks, reset_cause};

/// NVIC priority of every interrupt except the drive's TIM1 (P0): DMA, the link USART,
/// the embassy time driver (TIM4). TIM1's update and break interrupts
/// then preempt all of them. The PLC has no TIM1 interrupt; the same
/// priorities there cost nothing.
pub const BACKGROUND: Priority = Priority::P2;

/// Reads the reset cause, starts embassy at 170 MHz in range 1 boost mode with the DMA
/// interrupts (the G4's DMA1/DMA2 are embassy's `bdma`) at [`BACKGROUND`] (one clock set-up:
/// [`clocks::config`], through the vendored embassy-stm32's fixed G4 sequence), turns the
/// flash prefetch on ([`clocks::enable_prefetch`]), lowers the time driver's TIM4 to
/// [`BACKGROUND`] (embassy-stm32 0.6 enables it at P0 and has no setting for it), prints
/// the boot line and, with `dwt-cycles`, starts the cycle counter.
pub fn init(image: &str, version: &str) -> (Peripherals, ResetCause) {
    init_with(image, version, embassy_stm32::rcc::LsConfig::default())
}

/// [`init`] with the backup domain's clocks `ls` (embassy resets the backup domain when
/// RCC_BDCR differs from them: the PLC passes what its RTC runs on), the RTC's clock mux
/// the same (embassy writes the mux's RTCSEL after the check).
pub fn init_with(
    image: &str,
    version: &str,
    ls: embassy_stm32::rcc::LsConfig,
) -> (Peripherals, ResetCause) {
    let cause = reset_cause::take();
    let mut config = embassy_stm32::Config::default();
    config.bdma_interrupt_priority = BACKGROUND;
    config.rcc = clocks::config();
    config.rcc.ls = ls;
    config.rcc.mux.rtcsel = ls.rtc;
    let p = embassy_stm32::init(config);
    clocks::enable_prefetch();
    interrupt::TIM4.set_priority(BACKGROUND);
    banner::boot(image, version, cause);
    #[cfg(feature = "dwt-cycles")]
    crate::cycles::enable();
    (p, cause)
}
