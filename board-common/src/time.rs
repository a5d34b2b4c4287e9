//! The monotonic clock the cores take (embassy-time's, 1 MHz ticks).

use embassy_time::Instant;
use shared_protocol::units::Micros;

/// Microseconds since boot. Not inlined: link-time optimisation otherwise copies the time
/// driver's read (TIM4's counter and period, the 64-bit merge) into every call site
/// (`docs/size.md`).
#[inline(never)]
pub fn now() -> Micros {
    Micros(Instant::now().as_micros())
}

/// The embassy instant of a core deadline.
pub fn instant(t: Micros) -> Instant {
    Instant::from_micros(t.0)
}
