//! Time: every model counts CPU cycles at [`HCLK_HZ`].
//!
//! The CPU's side of time is the approximate Cortex-M4 cycle model of `cycles.rs` (TRM
//! cycles per instruction, flash wait states as FLASH_ACR sets them, exception latencies),
//! and every bus and kernel clock the images configure is derived from the same 170 MHz, so a
//! peripheral's timing (baud rate, timer tick, I2C bit time) is a whole or rational number of
//! cycles. The clock tree itself is not modelled: see `docs/emulator.md`.

/// Core clock the images configure (HSI16 / 4 * 85 / 2).
pub const HCLK_HZ: u64 = 170_000_000;

/// A point in time or a duration, in CPU cycles since power-on.
pub type Cycles = u64;

/// Cycles in one microsecond.
pub const CYCLES_PER_US: Cycles = HCLK_HZ / 1_000_000;

/// Nanoseconds at cycle `c` (rounded down; exact and drift-free because it is computed from
/// the absolute count, never accumulated).
pub fn cycles_to_ns(c: Cycles) -> u64 {
    ((u128::from(c) * 1_000_000_000) / u128::from(HCLK_HZ)) as u64
}

/// The first cycle at or after `ns` nanoseconds.
pub fn ns_to_cycles(ns: u64) -> Cycles {
    ((u128::from(ns) * u128::from(HCLK_HZ)).div_ceil(1_000_000_000)) as u64
}

/// Cycles of `n` periods of a clock at `hz` (rounded up), e.g. a UART frame or an I2C bit.
pub fn cycles_for(n: u64, hz: u64) -> Cycles {
    (u128::from(n) * u128::from(HCLK_HZ))
        .div_ceil(u128::from(hz.max(1)))
        .try_into()
        .unwrap_or(Cycles::MAX)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn conversions_round_trip_at_whole_microseconds() {
        for us in [0u64, 1, 7, 1000, 1_000_000, 3_600_000_000] {
            let c = ns_to_cycles(us * 1000);
            assert_eq!(c, us * CYCLES_PER_US);
            assert_eq!(cycles_to_ns(c), us * 1000);
        }
    }

    #[test]
    fn ns_to_cycles_rounds_up_and_back_down() {
        // 1 ns is less than one 5.88 ns cycle: the first cycle at or after it is cycle 1.
        assert_eq!(ns_to_cycles(1), 1);
        assert_eq!(cycles_to_ns(1), 5);
    }

    #[test]
    fn uart_frame_at_115200() {
        // 10 bits at 115200 baud = 86.8 us = 14756.9 cycles, rounded up.
        assert_eq!(cycles_for(10, 115_200), 14_757);
    }
}
