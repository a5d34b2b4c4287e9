//! Why the MCU restarted: RCC_CSR read before anything else touches it, then cleared
//! (RMVF). The meaning of the flags is `shared_protocol::supervision::ResetCause::decode`.

use embassy_stm32::pac;
pub use shared_protocol::supervision::ResetCause;
use shared_protocol::supervision::ResetFlags;

/// Reads and clears the reset flags. Call before `embassy_stm32::init`.
pub fn take() -> ResetCause {
    let csr = pac::RCC.csr().read();
    let cause = ResetCause::decode(ResetFlags {
        iwdg: csr.iwdgrstf(),
        wwdg: csr.wwdgrstf(),
        bor: csr.borrstf(),
    });
    pac::RCC.csr().modify(|w| w.set_rmvf(true));
    cause
}
