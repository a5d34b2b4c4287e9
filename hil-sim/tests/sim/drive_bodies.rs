//! hil-sim runs the drive's interrupt and task bodies (`firmware_drive::bodies`) at the
//! board's cadence: what the board does, shown on the simulator.

use super::common::*;
use hil_sim::plant::UdcSenseSpike;
use hil_sim::scenario::Scenario;
use hil_sim::sim::{RunOptions, Simulation};

const COM_MONITOR: &str = include_str!("../../../shared-protocol/programs/com_monitor.plc");

/// A comparator break while `STO_IN` is low waits: the STO break masked the break
/// interrupt, and the control tick re-arms it only once `STO_IN` is high and every
/// comparator is low. The break's flag stays set meanwhile, so the break reaches the core
/// then (delayed, not lost).
#[test]
fn a_comparator_break_during_sto_is_held_until_sto_in_is_high() {
    let scen = "\
[[event]]\nat_s = 0.1\nset = { STO_IN = 0 }\n\
[[event]]\nat_s = 0.4\nset = { STO_IN = 1 }\n";
    let p = hil_sim::run::parse_program(MOTOR_PLC, "motor.plc").expect("assembles");
    let s = Scenario::parse(scen).expect("scenario");
    let mut sim = Simulation::new(&p, s, RunOptions::default()).expect("sim");
    let mut seen_ns = None;
    let mut t = 0;
    while t < 600_000_000 && seen_ns.is_none() {
        t += 100_000;
        if t == 200_000_000 {
            // An overvoltage pulse on the DC-link comparator, one PWM period long.
            sim.plant_mut().inject_udc_sense_spike(UdcSenseSpike {
                volts: 20.0,
                from_ns: 0,
                to_ns: u64::MAX,
            });
        }
        sim.run_until(t, |_| {});
        if sim.drive().core().hw_break_active().any() {
            seen_ns = Some(t);
        }
    }
    let seen_ns = seen_ns.expect("the held break reaches the core once STO_IN is high");
    assert!(
        (400_000_000..410_000_000).contains(&seen_ns),
        "the comparator break reached the core at {seen_ns} ns (STO_IN low 0.1-0.4 s)"
    );
}

/// The threshold DACs are written by the 1 ms task, as on the board: new values (the boot
/// calibration's, a download's `I>>`/`U>>`) reach the comparators at a millisecond tick,
/// never in between.
#[test]
fn the_threshold_dacs_change_at_a_millisecond_tick() {
    let p = hil_sim::run::parse_program(COM_MONITOR, "com_monitor.plc").expect("assembles");
    let s = Scenario::parse("").expect("scenario");
    let mut sim = Simulation::new(&p, s, RunOptions::default()).expect("sim");
    let start = *sim.plant().comparators();
    let step_ns = 5_000;
    let mut t = 0;
    while *sim.plant().comparators() == start {
        t += step_ns;
        assert!(t < 2_000_000_000, "the download's DAC values never arrived");
        sim.run_until(t, |_| {});
    }
    // The change happened between t - step and t; the drive's ticks are at whole
    // milliseconds.
    let tick = t / 1_000_000 * 1_000_000;
    assert!(
        tick >= t - step_ns,
        "DACs changed between {} and {t} ns, no tick in between",
        t - step_ns
    );
}

/// The power stage's dead-time floor is the core's boot check, on the board and here: a
/// minimum beyond what TIM1's DTG can encode (10 us is 1 700 counts at 170 MHz, DTG stops
/// at 1 008) latches `BOOT`, and the outputs never come on.
#[test]
fn a_dead_time_below_the_floor_latches_boot() {
    use firmware_drive::{DriveConfig, DriveState, FaultCode};
    use hil_sim::mcu::SimDrive;
    use hil_sim::plant::{Plant, RigParams};
    use hil_sim::tim1::SimTim1;
    use shared_protocol::link::LinkConfig;
    use shared_protocol::units::Micros;

    let floor = |min_dead_time_ns| {
        let cfg = DriveConfig {
            min_dead_time_ns,
            ..DriveConfig::default()
        };
        let mut drive = SimDrive::with_config(LinkConfig::default(), cfg);
        let mut plant = Plant::new(RigParams::default());
        let mut tim = SimTim1::new(drive.pwm_timing(), drive.timer_clock_hz());
        drive.boot_dacs(&mut plant);
        for ms in 1..=20u64 {
            let _ = drive.control_tick(&mut tim, &mut plant, Micros(ms * 1000));
            tim.update();
            drive.pwm_interrupt(&mut tim, &mut plant, Default::default());
        }
        (drive.core().state(), drive.core().fault(), tim.moe())
    };
    assert_eq!(floor(500).0, DriveState::Idle, "the default floor passes");
    assert_eq!(
        floor(10_000),
        (DriveState::Fault, Some(FaultCode::Boot), false)
    );
}
