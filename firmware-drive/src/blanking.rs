//! Comparator blanking around the switching edges: TIM1's OC5 as a window in
//! which COMP1/2/4 (the phase currents) are forced low, so that the current spike and
//! ringing at each turn-on do not trip `OC_HW` (RM0440 §24.3 "Comparator output blanking
//! function": BLANKSEL = TIM1_OC5, the output is 0 while OC5 is active).
//!
//! TIM1 has one OC5 for three legs, and in centre-aligned mode one compare gives one
//! window per period, centred on the valley or the peak (the asymmetric and combined
//! modes pair CH1-CH4 only). OC5 runs in PWM mode 1: active while CNT < CCR5, a window
//! around the valley. Every transition of a switching leg lies at CNT = CCRx (± the dead
//! time), so with CCR5 = max(CCRx) + [`PwmTiming::blank_counts`] every edge of every leg
//! falls inside the window, with at least the dead time plus [`RINGING_NS`] of it after
//! the last turn-on on the way up and before the first turn-off on the way down. The
//! comparators are live around the peak, while all three low-side switches conduct and
//! the low-side shunts carry the phase currents: that is the stretch in which the ESC1's
//! shunts see all three currents at once (and where the ADC samples). The price: a leg's
//! current is watched only while the leg with the largest duty also has its low switch on.
//!
//! At least [`MIN_LIVE_NS`] of live time either side of the peak is kept (CCR5 is capped):
//! a leg switching closer to the peak than that is not blanked, but the hardware trip is
//! never switched off. With the outputs off, or no leg switching, CCR5 = 0: no window.

use crate::timing::PwmTiming;

/// Turn-on ringing allowed after each transition, ns, on top of the dead time. The ESC1's
/// gate drivers switch its MOSFETs in tens of ns; the drain-source ringing of a low-voltage
/// half-bridge with its layout inductance is in the 10-100 MHz range and decays within a
/// few periods. 500 ns covers that with margin and is short against the 62.5 us period at
/// 16 kHz (1.6 %); with the 1 us dead time the window extends 1.5 us past the last edge.
/// Measure it on the bench (`docs/bench-check.md`) and shorten it if the ringing allows.
pub const RINGING_NS: u32 = 500;

/// Live time of the comparators kept either side of the counter's peak, ns (at least
/// 2 us per period in which a sustained overcurrent trips, whatever the duties).
pub const MIN_LIVE_NS: u32 = 1000;

/// Counter counts of `ns` at `timer_clock_hz` (taken in whole kHz) with prescaler `psc`,
/// rounded up. 32-bit arithmetic (the image's flash is tight); exact for the durations
/// here (ns x kHz stays far below 2^32).
pub fn counts_of_ns(ns: u32, timer_clock_hz: u32, psc: u16) -> u32 {
    let ticks = ns.saturating_mul(timer_clock_hz / 1000).div_ceil(1_000_000);
    ticks.div_ceil(u32::from(psc) + 1)
}

/// CCR5 for a period with the compares `ccr` (as written: 0 is the low switch always on,
/// above ARR the high switch always on) on the legs `legs` that switch, under `t`; 0 (no
/// window) when no leg switches.
#[inline(always)]
pub fn ccr5(ccr: [u16; 3], legs: [bool; 3], t: &PwmTiming) -> u16 {
    // The last edge: the largest compare of a leg that switches (0 < CCR <= ARR); 0 when
    // none does.
    // Written out, not a loop over the legs: the drive's crate is built for size, and the
    // PWM interrupt runs this every period (`docs/size.md`).
    let edge = |c: u16, on: bool| if on && c <= t.arr { c } else { 0 };
    let [c0, c1, c2] = ccr;
    let [on0, on1, on2] = legs;
    let last = edge(c0, on0).max(edge(c1, on1)).max(edge(c2, on2));
    if last == 0 {
        return 0;
    }
    last.saturating_add(t.blank_counts)
        .min(t.arr.saturating_sub(t.live_counts))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn t16k() -> PwmTiming {
        PwmTiming::compute(170_000_000, 16_000, 1, 1000, 500)
    }

    #[test]
    fn the_window_covers_every_edge_plus_dead_time_and_ringing() {
        let t = t16k();
        // 1 us dead time (170 counts) + 500 ns (85 counts) at PSC 0.
        assert_eq!(t.dead_time_counts, 170);
        assert_eq!(t.blank_counts, 255);
        assert_eq!(t.live_counts, 170);
        assert_eq!(ccr5([1000, 2000, 3000], [true; 3], &t), 3255);
        // Only the legs that switch count.
        assert_eq!(ccr5([1000, 2000, 3000], [true, true, false], &t), 2255);
        // 0 % and 100 % legs do not switch.
        assert_eq!(ccr5([0, t.arr + 1, 700], [true; 3], &t), 955);
        assert_eq!(ccr5([0, t.arr + 1, 0], [true; 3], &t), 0);
        assert_eq!(ccr5([500; 3], [false; 3], &t), 0);
    }

    #[test]
    fn the_comparators_stay_live_near_the_peak() {
        let t = t16k();
        let c = ccr5([t.arr - 10, 100, 100], [true; 3], &t);
        assert_eq!(c, t.arr - t.live_counts);
        // 1 us either side of the peak at 170 MHz.
        assert_eq!(counts_of_ns(MIN_LIVE_NS, 170_000_000, 0), 170);
    }

    #[test]
    fn counts_follow_the_prescaler() {
        // 488 Hz: PSC 2, three CK_INT ticks per count.
        let t = PwmTiming::compute(170_000_000, 488, 1, 1000, 500);
        assert_eq!(t.psc, 2);
        assert_eq!(t.blank_counts, 57 + 29);
        assert_eq!(counts_of_ns(1, 170_000_000, 2), 1);
    }
}
