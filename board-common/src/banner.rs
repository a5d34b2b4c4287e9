//! The boot line both images print first.

use shared_protocol::supervision::ResetCause;

use crate::clocks::SYSCLK_HZ;

/// `<image> <version> boot: 170 MHz, reset cause <cause>`.
pub fn boot(image: &str, version: &str, cause: ResetCause) {
    defmt::info!(
        "{=str} {=str} boot: {} MHz, reset cause {}",
        image,
        version,
        SYSCLK_HZ / 1_000_000,
        cause
    );
}
