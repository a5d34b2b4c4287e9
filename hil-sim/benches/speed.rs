//! Simulation speed: simulated seconds per wall-clock second for the full motor example
//! (the scenario `hil-sim/scenarios/motor.toml`, 25 s: start, run-up, REV, braking,
//! reversal, run-up) at 16 kHz PWM, with the averaged and the switching inverter model.
//!
//! The motor program sets the switching frequency from the pot A00 x 10, at most
//! 10230 Hz, and a `K` constant has only 4 digits; so the 16 kHz variant replaces line 171
//! (`LD A00`) with `LD K18 1600`: the PLC then writes 1600 x 10 = 16000 Hz into Q00 as
//! before. Everything else is the shipped program.
//!
//! Also prints the end-to-end `WR Q` latency measured in the co-simulation (link.md).
//!
//! `cargo bench -p hil-sim --bench speed` (one core; the simulation is single-threaded).
//! `cargo bench -p hil-sim --bench speed -- avg16` runs the 16 kHz averaged case alone
//! (for a profiler, or side by side with another build).

use std::time::Instant;

use hil_sim::plant::PwmMode;
use hil_sim::run::{parse_program, run};
use hil_sim::scenario::Scenario;
use hil_sim::sim::RunOptions;

const MOTOR_PLC: &str = include_str!("../../shared-protocol/programs/motor.plc");
const MOTOR_TOML: &str = include_str!("../scenarios/motor.toml");
const REPEAT: usize = 3;

fn motor_16khz() -> String {
    MOTOR_PLC
        .lines()
        .map(|l| {
            if l.starts_with("171 ") {
                "171 LD  K18 1600     ; 16 kHz variant (benchmark)"
            } else {
                l
            }
        })
        .collect::<Vec<_>>()
        .join("\n")
}

fn measure(label: &str, program: &str, mode: PwmMode) -> f64 {
    let p = parse_program(program, "motor.plc").expect("program");
    let mut scen = Scenario::parse(MOTOR_TOML).expect("scenario");
    scen.rig.pwm_mode = mode;
    let duration = scen.duration_s(None);
    let mut speeds = Vec::new();
    let mut pwm_hz = 0.0;
    for _ in 0..REPEAT {
        let start = Instant::now();
        let mut last_pwm = 0u32;
        let report = run(
            &p,
            scen.clone(),
            duration,
            RunOptions::default(),
            hil_sim::decimate::KeepSamples::None,
            |s| last_pwm = s.lcd[1].map_or(0, |v| v as u32),
            |_| {},
        )
        .expect("run");
        let wall = start.elapsed().as_secs_f64();
        assert!(report.faults.is_empty(), "{:?}", report.faults);
        pwm_hz = f64::from(last_pwm);
        speeds.push(duration / wall);
    }
    let mean = speeds.iter().sum::<f64>() / speeds.len() as f64;
    let min = speeds.iter().cloned().fold(f64::INFINITY, f64::min);
    println!(
        "{label:<34} PWM {pwm_hz:>6.0} Hz  {duration:.0} s simulated: {mean:7.1}x real time (mean of {REPEAT}, min {min:.1}x)"
    );
    mean
}

fn main() {
    println!("hil-sim speed, full motor example (scenarios/motor.toml)");
    let p16 = motor_16khz();
    if std::env::args().any(|a| a == "avg16") {
        measure("16 kHz, averaged inverter", &p16, PwmMode::Averaged);
        return;
    }
    let avg = measure("16 kHz, averaged inverter", &p16, PwmMode::Averaged);
    let sw = measure("16 kHz, switching inverter", &p16, PwmMode::Switching);
    measure(
        "9.8 kHz (as shipped), averaged",
        MOTOR_PLC,
        PwmMode::Averaged,
    );
    println!(
        "target >= 50x real time averaged: {}",
        if avg >= 50.0 { "met" } else { "NOT met" }
    );
    let _ = sw;
    println!("WR Q latency (scan that writes -> drive's copy updated), clean link, 200 writes:");
    let runs: [(&str, u32, Option<u64>); 3] = [
        ("", 115_200, None),
        ("", 1_000_000, None),
        (", service port flooded", 115_200, Some(7)),
    ];
    for (what, baud, flood) in runs {
        let l = match flood {
            None => hil_sim::latency::q_write_latencies_ns(baud, 200, 1.0),
            Some(seed) => hil_sim::latency::q_write_latencies_flooded_ns(baud, 200, 1.0, seed),
        }
        .expect("latency");
        let max = l.iter().max().copied().unwrap_or(0);
        let min = l.iter().min().copied().unwrap_or(0);
        let mean = l.iter().sum::<u64>() as f64 / l.len().max(1) as f64;
        println!(
            "  {baud:>7} baud{what}: min {:.0} us, mean {:.0} us, max {:.0} us (link.md: < 2 ms at 115200)",
            min as f64 / 1e3,
            mean / 1e3,
            max as f64 / 1e3
        );
    }
}
