//! 64-bit unsigned division by shift and subtract, for the image's `__udivmoddi4`
//! (`plc-image`'s `board::wide_div`).
//!
//! Why: `compiler_builtins`' 64-bit division (`u64_div_rem`, 864 B, unrolled for speed) is
//! linked by the PLC's time arithmetic (the link's and the service's timeouts, the
//! clock's seconds). None of it is on the scan (`plc-vm` divides in 32 bits) and the PLC
//! has no interrupt a division would lengthen; this loop runs once per quotient bit (at
//! most 64), and a dividend that fits 32 bits takes the hardware divider.

/// `(n / d, n % d)`; `d == 0` gives `(u64::MAX, n)` (the compiler never calls the
/// helpers with 0: a division by zero panics before).
pub fn udivmod(n: u64, d: u64) -> (u64, u64) {
    if d == 0 {
        return (u64::MAX, n);
    }
    if d > n {
        return (0, n);
    }
    if let (Ok(n32), Ok(d32)) = (u32::try_from(n), u32::try_from(d)) {
        return match (n32.checked_div(d32), n32.checked_rem(d32)) {
            (Some(q), Some(r)) => (u64::from(q), u64::from(r)),
            _ => (u64::MAX, n),
        };
    }
    // d <= n: the divisor shifted up to the dividend's top bit does not overflow.
    let shift = d.leading_zeros() - n.leading_zeros();
    let mut d = d << shift;
    let (mut q, mut r) = (0u64, n);
    for _ in 0..shift + 1 {
        q <<= 1;
        if r >= d {
            r -= d;
            q |= 1;
        }
        d >>= 1;
    }
    (q, r)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    const EDGES: [u64; 14] = [
        0,
        1,
        2,
        3,
        7,
        1000,
        1_000_000,
        u32::MAX as u64 - 1,
        u32::MAX as u64,
        u32::MAX as u64 + 1,
        1 << 63,
        (1 << 63) + 1,
        u64::MAX - 1,
        u64::MAX,
    ];

    #[test]
    fn unsigned_edges_match_the_operators() {
        for &n in &EDGES {
            for &d in EDGES.iter().filter(|&&d| d != 0) {
                assert_eq!(udivmod(n, d), (n / d, n % d), "{n} / {d}");
            }
        }
    }

    #[test]
    fn by_zero_is_all_ones_and_the_dividend() {
        assert_eq!(udivmod(12345, 0), (u64::MAX, 12345));
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(20_000))]

        #[test]
        fn unsigned_matches_the_operators(n: u64, d in 1u64.., shift in 0u32..64) {
            let d = (d >> shift).max(1);
            prop_assert_eq!(udivmod(n, d), (n / d, n % d));
        }
    }
}
