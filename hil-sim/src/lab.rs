//! The source's lab chapter (its Obr 5.1-5.7) measured on simulated runs: the programs
//! `shared-protocol/programs/lab_*.plc` with the scenarios `hil-sim/scenarios/lab_*.toml`,
//! ramp durations and the current ripple at a switching frequency. Used by the acceptance
//! tests (`tests/sim/lab.rs`) and the figure generator (`examples/lab_figures.rs`);
//! results in `docs/lab.md`.

use anyhow::Result;

use crate::run::parse_program;
use crate::scenario::Scenario;
use crate::sim::{RunOptions, Sample, Simulation};

/// The time (s) of the first sample at or after `after_s` for which `pred` holds.
pub fn first(samples: &[Sample], after_s: f64, pred: impl Fn(&Sample) -> bool) -> Option<f64> {
    samples
        .iter()
        .filter(|s| s.t_ns as f64 * 1e-9 >= after_s)
        .find(|s| pred(s))
        .map(|s| s.t_ns as f64 * 1e-9)
}

/// Runs `program` under `scenario` to `until_s` sampling every `coarse_ms`, then samples
/// every `fine_us` for `window_s` more: the fine window's samples (the coarse ones are
/// dropped). For the current ripple of a PWM period late in a long run.
pub fn fine_window(
    program: &str,
    scenario: &str,
    until_s: f64,
    window_s: f64,
    fine_us: f64,
) -> Result<Vec<Sample>> {
    let p = parse_program(program, "lab.plc")?;
    let s = Scenario::parse(scenario)?;
    let mut sim = Simulation::new(&p, s, RunOptions::default())?;
    let t0 = (until_s * 1e9).round() as u64;
    sim.run_until(t0, |_| {});
    sim.set_sample_ns((fine_us * 1e3).round() as u64);
    let mut out = Vec::new();
    let t1 = t0 + (window_s * 1e9).round() as u64;
    sim.run_until(t1, |s| {
        if s.t_ns > t0 && s.t_ns <= t1 {
            out.push(s.clone());
        }
    });
    Ok(out)
}

/// `x` minus its Fourier components below `cut_hz`, over a window of equally spaced
/// samples `dt_s` apart that holds whole cycles of every component removed (the DFT
/// basis is orthogonal there).
pub fn high_pass(x: &[f64], dt_s: f64, cut_hz: f64) -> Vec<f64> {
    let n = x.len();
    if n == 0 {
        return Vec::new();
    }
    let t_win = n as f64 * dt_s;
    let k_max = (cut_hz * t_win).ceil() as usize;
    let mut low = vec![x.iter().sum::<f64>() / n as f64; n];
    for k in 1..k_max.min(n / 2) {
        let w = std::f64::consts::TAU * k as f64 / n as f64;
        let (mut a, mut b) = (0.0, 0.0);
        for (j, v) in x.iter().enumerate() {
            a += v * (w * j as f64).cos();
            b += v * (w * j as f64).sin();
        }
        let (a, b) = (2.0 * a / n as f64, 2.0 * b / n as f64);
        for (j, l) in low.iter_mut().enumerate() {
            *l += a * (w * j as f64).cos() + b * (w * j as f64).sin();
        }
    }
    x.iter().zip(low).map(|(v, l)| v - l).collect()
}

/// The ripple of a phase current: RMS and the mean peak-to-peak per PWM period of what is
/// left above half the switching frequency.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ripple {
    pub rms_a: f64,
    pub pp_a: f64,
}

/// The current ripple of phase `k` in `window` (fine samples, whole cycles of the output
/// frequency) at switching frequency `f_sw_hz`.
pub fn current_ripple(window: &[Sample], k: usize, f_sw_hz: f64) -> Ripple {
    let dt = match window {
        [a, b, ..] => (b.t_ns - a.t_ns) as f64 * 1e-9,
        _ => {
            return Ripple {
                rms_a: 0.0,
                pp_a: 0.0,
            }
        }
    };
    let i: Vec<f64> = window.iter().map(|s| s.i_abc_a[k]).collect();
    let r = high_pass(&i, dt, 0.5 * f_sw_hz);
    let rms_a = (r.iter().map(|v| v * v).sum::<f64>() / r.len() as f64).sqrt();
    let per = ((1.0 / f_sw_hz) / dt).round().max(1.0) as usize;
    let pps: Vec<f64> = r
        .chunks(per)
        .filter(|c| c.len() == per)
        .map(|c| {
            let hi = c.iter().copied().fold(f64::MIN, f64::max);
            let lo = c.iter().copied().fold(f64::MAX, f64::min);
            hi - lo
        })
        .collect();
    let pp_a = pps.iter().sum::<f64>() / pps.len().max(1) as f64;
    Ripple { rms_a, pp_a }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn high_pass_keeps_only_the_ripple() {
        // 50 Hz + its 5th harmonic + a 5 kHz "ripple", 40 ms at 2 us.
        let dt = 2e-6;
        let x: Vec<f64> = (0..20_000)
            .map(|n| {
                let t = n as f64 * dt;
                let w = std::f64::consts::TAU;
                1.0 * (w * 50.0 * t).sin()
                    + 0.1 * (w * 250.0 * t).cos()
                    + 0.02 * (w * 5000.0 * t).sin()
            })
            .collect();
        let r = high_pass(&x, dt, 2500.0);
        let rms = (r.iter().map(|v| v * v).sum::<f64>() / r.len() as f64).sqrt();
        assert!((rms - 0.02 / 2f64.sqrt()).abs() < 1e-4, "{rms}");
    }
}
