//! The RMS phase current the panel shows: over a window of whole periods of the output
//! frequency, so that it stands still in steady state (an instantaneous peak, or an RMS
//! over a fraction of a period, moves with where the window ends on the sine).

use std::collections::VecDeque;

/// How long the panel keeps current samples, ns: one period at 1 Hz.
const KEEP_NS: u64 = 1_000_000_000;
/// The window aims at this length, in whole periods (at least one).
const WINDOW_NS: f64 = 200e6;

/// Phase-current samples of the last second, evenly spaced.
#[derive(Debug, Clone, Default)]
pub struct RmsWindow {
    samples: VecDeque<(u64, [f64; 3])>,
}

impl RmsWindow {
    pub fn push(&mut self, t_ns: u64, i_abc_a: [f64; 3]) {
        self.samples.push_back((t_ns, i_abc_a));
        while self
            .samples
            .front()
            .is_some_and(|(t, _)| t_ns.saturating_sub(*t) > KEEP_NS)
        {
            self.samples.pop_front();
        }
    }

    /// The RMS of the three phase currents (their quadratic mean), A, over the whole
    /// periods of `f_hz` that fit in about 200 ms of the kept samples (one period at
    /// least, when the samples cover it); below 1 Hz (or with the outputs off) over the
    /// last 200 ms. 0 without samples.
    pub fn rms_a(&self, f_hz: f64) -> f64 {
        let (Some((first, _)), Some((last, _))) = (self.samples.front(), self.samples.back())
        else {
            return 0.0;
        };
        // The samples are evenly spaced: the span covered is n * dt, n the sample count.
        let n = self.samples.len() as f64;
        let dt = if n > 1.0 {
            (last - first) as f64 / (n - 1.0)
        } else {
            1.0
        };
        let span = n * dt;
        let f = f_hz.abs();
        let window = if f >= 1.0 {
            let period = 1e9 / f;
            let periods = (WINDOW_NS / period).ceil().max(1.0);
            let fit = (span / period).floor();
            if fit >= 1.0 {
                periods.min(fit) * period
            } else {
                span
            }
        } else {
            WINDOW_NS.min(span)
        };
        let take = ((window / dt).round() as usize).clamp(1, self.samples.len());
        let sum: f64 = self
            .samples
            .iter()
            .rev()
            .take(take)
            .map(|(_, i)| i.iter().map(|x| x * x).sum::<f64>())
            .sum();
        (sum / (3.0 * take as f64)).sqrt()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn three_phase(w: &mut RmsWindow, f_hz: f64, amp: f64, from_ns: u64, to_ns: u64) {
        let dt = 500_000;
        let mut t = from_ns;
        while t <= to_ns {
            let th = 2.0 * std::f64::consts::PI * f_hz * t as f64 * 1e-9;
            let third = 2.0 * std::f64::consts::PI / 3.0;
            w.push(
                t,
                [
                    amp * th.sin(),
                    amp * (th - third).sin(),
                    amp * (th + third).sin(),
                ],
            );
            t += dt;
        }
    }

    #[test]
    fn a_sine_reads_its_rms_wherever_the_window_ends() {
        for f in [5.0, 28.8, 50.0, 70.0] {
            let mut w = RmsWindow::default();
            three_phase(&mut w, f, 2.0, 0, 600_000_000);
            let mut seen = Vec::new();
            for k in 0..40u64 {
                three_phase(
                    &mut w,
                    f,
                    2.0,
                    600_500_000 + k * 500_000,
                    600_500_000 + k * 500_000,
                );
                seen.push(w.rms_a(f));
            }
            let want = 2.0 / 2f64.sqrt();
            for r in &seen {
                assert!((r / want - 1.0).abs() < 0.005, "{f} Hz: {r} vs {want}");
            }
        }
    }

    #[test]
    fn one_phase_over_whole_periods_is_steady_too() {
        // A single phase (the others 0): RMS/sqrt(3), and steady although the window's
        // end moves along the sine.
        let mut w = RmsWindow::default();
        let f = 33.0;
        let mut t = 0;
        let mut seen = Vec::new();
        while t < 800_000_000 {
            let th = 2.0 * std::f64::consts::PI * f * t as f64 * 1e-9;
            w.push(t, [1.5 * th.sin(), 0.0, 0.0]);
            if t > 500_000_000 {
                seen.push(w.rms_a(f));
            }
            t += 500_000;
        }
        let want = 1.5 / 2f64.sqrt() / 3f64.sqrt();
        let (lo, hi) = seen
            .iter()
            .fold((f64::MAX, 0.0f64), |(lo, hi), r| (lo.min(*r), hi.max(*r)));
        assert!(
            (lo / want - 1.0).abs() < 0.01 && (hi / want - 1.0).abs() < 0.01,
            "{lo}..{hi} vs {want}"
        );
    }

    #[test]
    fn dc_and_empty() {
        let mut w = RmsWindow::default();
        assert_eq!(w.rms_a(50.0), 0.0);
        for k in 0..100 {
            w.push(k * 500_000, [1.0, -0.5, -0.5]);
        }
        assert!((w.rms_a(0.0) - (1.5f64 / 3.0).sqrt()).abs() < 1e-9);
    }
}
