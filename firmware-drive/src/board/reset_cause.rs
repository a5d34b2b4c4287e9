//! Why the MCU restarted, read from RCC_CSR before anything else touches it.

use embassy_stm32::pac;

/// The reset causes the drive reports (a watchdog reset becomes fault `WDG`).
#[derive(Clone, Copy, PartialEq, Eq, defmt::Format)]
pub enum ResetCause {
    /// The independent or window watchdog expired.
    Watchdog,
    /// Power-on, brown-out, reset pin or software reset.
    Other,
}

/// Reads and clears the reset flags.
pub fn take() -> ResetCause {
    let csr = pac::RCC.csr().read();
    let cause = if csr.iwdgrstf() || csr.wwdgrstf() {
        ResetCause::Watchdog
    } else {
        ResetCause::Other
    };
    pac::RCC.csr().modify(|w| w.set_rmvf(true));
    cause
}
