//! Speed of the emulator: both real release images co-simulated with the plant, in
//! emulated seconds per wall-clock second, for the full motor example at 16 kHz PWM (the
//! variant of `benches/speed.rs`: line 171 writes 1600 x 10 Hz into Q00), with the
//! averaged and the switching inverter model. Target: at least 0.5x real time
//! on one core.
//!
//! `cargo bench -p hil-sim --bench emu_speed` (builds the images first if needed).

use std::time::Instant;

use hil_sim::emu::images::build_both;
use hil_sim::emu::sim::EmuSim;
use hil_sim::plant::PwmMode;
use hil_sim::run::parse_program;
use hil_sim::scenario::Scenario;
use hil_sim::sim::RunOptions;

const MOTOR_PLC: &str = include_str!("../../shared-protocol/programs/motor.plc");
const MOTOR_TOML: &str = include_str!("../scenarios/motor.toml");

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

fn main() {
    let (drive, plc) = build_both().expect("firmware images");
    let program = parse_program(&motor_16khz(), "motor.plc").expect("program");
    println!("hil-sim emu speed, full motor example (scenarios/motor.toml) on the real images");
    for (label, mode) in [
        ("16 kHz, averaged inverter", PwmMode::Averaged),
        ("16 kHz, switching inverter", PwmMode::Switching),
    ] {
        let mut scen = Scenario::parse(MOTOR_TOML).expect("scenario");
        scen.rig.pwm_mode = mode;
        let duration = scen.duration_s(None);
        let mut sim =
            EmuSim::new(&drive, &plc, &program, scen, RunOptions::default()).expect("images");
        let start = Instant::now();
        let mut pwm_hz = 0i16;
        sim.run_until((duration * 1e9) as u64, |s| pwm_hz = s.lcd[1].unwrap_or(0));
        let wall = start.elapsed().as_secs_f64();
        let tim1 = sim.drive().cpu().irq_entries("TIM1_UP_TIM16");
        println!(
            "{label:<28} PWM {pwm_hz:>6} Hz ({tim1} PWM interrupts): {duration:.0} s emulated in {wall:.1} s: {:.2}x real time (target >= 0.5x: {})",
            duration / wall,
            if duration / wall >= 0.5 { "met" } else { "NOT met" }
        );
        assert!(sim.faults().is_empty(), "{:?}", sim.faults());
    }
}
