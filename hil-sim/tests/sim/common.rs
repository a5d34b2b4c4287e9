//! Shared helpers of the scenario tests.

use hil_sim::run::{parse_program, run, RunReport};
use hil_sim::scenario::Scenario;
use hil_sim::sim::{RunOptions, Sample};

/// The source's full motor example as the project ships it.
pub const MOTOR_PLC: &str = include_str!("../../../shared-protocol/programs/motor.plc");

/// Runs `program` under the scenario text for `duration_s`, keeping every 1 ms sample.
pub fn run_text(program: &str, scenario: &str, duration_s: f64) -> RunReport {
    run_sampled(
        program,
        scenario,
        duration_s,
        RunOptions::default().sample_ns,
    )
}

/// [`run_text`] with samples every `sample_ns` (peaks of waveforms need finer samples than
/// 1 ms: at 50 Hz a 1 ms grid can miss a peak by a few per cent, depending on when the
/// drive started).
pub fn run_sampled(program: &str, scenario: &str, duration_s: f64, sample_ns: u64) -> RunReport {
    let p = parse_program(program, "test.plc").expect("program assembles");
    let s = Scenario::parse(scenario).expect("scenario parses");
    run(
        &p,
        s,
        duration_s,
        RunOptions {
            sample_ns,
            ..RunOptions::default()
        },
        hil_sim::decimate::KeepSamples::All,
        |_| {},
        |_| {},
    )
    .expect("run")
}

/// The first sample at or after `t_s`.
pub fn at(samples: &[Sample], t_s: f64) -> &Sample {
    let t_ns = (t_s * 1e9).round() as u64;
    samples
        .iter()
        .find(|s| s.t_ns >= t_ns)
        .expect("sample in range")
}

pub fn t_s(s: &Sample) -> f64 {
    s.t_ns as f64 * 1e-9
}

/// Largest |phase current| over the samples.
pub fn peak_current(samples: &[Sample]) -> f64 {
    samples
        .iter()
        .flat_map(|s| s.i_abc_a)
        .fold(0.0, |m: f64, i| m.max(i.abs()))
}
