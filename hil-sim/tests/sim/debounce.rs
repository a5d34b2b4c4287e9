//! The PLC's input debouncing in simulation is the board's: hil-sim hands the
//! raw pin levels to `PlcApp::tick_1ms`, so a pulse shorter than the 5 samples never
//! reaches the scan, as on the board.

use hil_sim::run::parse_program;
use hil_sim::scenario::Scenario;
use hil_sim::sim::{RunOptions, Simulation};

/// O00 follows D00.
const FOLLOW: &str = "150 LD D00\n151 WR O00\n";

/// A 3 ms pulse at 0.5 s, a 6 ms pulse at 0.8 s.
const PULSES: &str = r#"
[[event]]
at_s = 0.5
set = { D00 = 1 }

[[event]]
at_s = 0.503
set = { D00 = 0 }

[[event]]
at_s = 0.8
set = { D00 = 1 }

[[event]]
at_s = 0.806
set = { D00 = 0 }
"#;

/// When O00 was on, in ms (sampled every 0.25 ms).
fn o00_on_ms(from_s: f64, to_s: f64) -> Vec<f64> {
    let p = parse_program(FOLLOW, "follow.plc").unwrap();
    let mut sim =
        Simulation::new(&p, Scenario::parse(PULSES).unwrap(), RunOptions::default()).unwrap();
    sim.run_until((from_s * 1e9) as u64, |_| {});
    assert!(sim.plc().running(), "RUN at power-up");
    let mut on = Vec::new();
    let mut t = (from_s * 1e9) as u64;
    while t < (to_s * 1e9) as u64 {
        t += 250_000;
        sim.run_until(t, |_| {});
        if sim.plc().outputs() & 1 != 0 {
            on.push(t as f64 * 1e-6);
        }
    }
    on
}

#[test]
fn a_3_ms_input_pulse_is_ignored_and_a_6_ms_one_counts_after_5_ms() {
    let on = o00_on_ms(0.4, 0.9);
    // Nothing from the 3 ms pulse.
    assert!(on.iter().all(|&ms| ms >= 800.0), "{on:?}");
    // The 6 ms pulse: on after 5 samples (5 ms, plus up to one tick and one scan), for
    // about as long as it lasted.
    let first = on.first().copied().expect("the 6 ms pulse reaches O00");
    assert!((804.0..=807.5).contains(&first), "first on at {first} ms");
    let last = on.last().copied().unwrap_or(0.0);
    assert!(last - first < 8.0, "on from {first} to {last} ms");
}
