//! Why the MCU restarted, read from RCC_CSR before anything else touches it.

use embassy_stm32::pac;
pub use firmware_drive::config::ResetCause;

/// Reads and clears the reset flags (a watchdog reset becomes the core's fault `WDG`).
pub fn take() -> ResetCause {
    let csr = pac::RCC.csr().read();
    let cause = if csr.iwdgrstf() || csr.wwdgrstf() {
        ResetCause::Watchdog
    } else if csr.borrstf() {
        // Power-on and brown-out both set BORRSTF on the G4.
        ResetCause::PowerOn
    } else {
        ResetCause::Other
    };
    pac::RCC.csr().modify(|w| w.set_rmvf(true));
    cause
}
