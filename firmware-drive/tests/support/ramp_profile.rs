//! Commanded-frequency profiles for the reversal's property tests (002 4.2, `frv`): the
//! one generator of `src/reversal.rs`'s unit tests and `tests/properties.rs`, which include
//! this file by `#[path]` (the crate has no `testing` feature, and `proptest` is a
//! dev-dependency only).

use proptest::prelude::*;
use std::vec::Vec;

/// A ramp segment: to `target` (0.1 Hz) by `step` every `every_ms`, then held `hold_ms`.
pub type Segment = (i16, i16, u8, u8);

/// The command every millisecond over `segments`, from 0: slow ramps with plateaus (the
/// motor example's lag), fast ones, steps, stops.
pub fn ramp_profile(segments: &[Segment]) -> Vec<i16> {
    let mut f = 0i16;
    let mut out = Vec::new();
    for &(target, step, every_ms, hold_ms) in segments {
        while f != target {
            f = if f < target {
                (f + step).min(target)
            } else {
                (f - step).max(target)
            };
            out.extend(std::iter::repeat_n(f, usize::from(every_ms)));
        }
        out.extend(std::iter::repeat_n(f, usize::from(hold_ms)));
    }
    out
}

/// 1 to `max_segments - 1` segments: targets mostly below 30.0 Hz (and 0), steps mostly of
/// 0.1 Hz, 1-6 ms each, plateaus up to 60 ms.
pub fn ramp_segments(max_segments: usize) -> impl Strategy<Value = Vec<Segment>> {
    prop::collection::vec(
        (
            prop_oneof![1 => Just(0i16), 3 => 0i16..=300, 1 => 300i16..=600],
            prop_oneof![3 => Just(1i16), 1 => 1i16..=50],
            1u8..=6,
            0u8..=60,
        ),
        1..max_segments,
    )
}
