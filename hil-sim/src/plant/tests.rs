//! Plant tests: the dynamic model against the steady-state equivalent circuit, the DC link
//! energy paths, the comparators and the switching model.

use super::*;
use std::f64::consts::PI;

/// A rig whose DC link is stiff, so the phase voltage is exactly m · Udc / 2.
fn stiff_rig() -> RigParams {
    RigParams {
        supply_r_ohm: 1e-3,
        dc_capacitor_f: 1.0,
        hw_defaults: HwDefaults {
            oc_hw_a: 9.99,
            ov_hw_v: 45.0,
        },
        ..RigParams::default()
    }
}

/// Sine PWM as the drive generates it (phase k at +k·120°: forward).
fn sine_command(theta: f64, m: f64) -> GateCommand {
    let leg = |k: f64| Leg::Duty(0.5 + 0.5 * m * (theta + k * 2.0 * PI / 3.0).sin());
    GateCommand {
        legs: [leg(0.0), leg(1.0), leg(2.0)],
        dead_time_ns: 0,
    }
}

/// Drives the plant with sine PWM (duties taken at mid-period so the staircase has no
/// delay) for `duration_ns`, calling `observe` after every period.
fn drive_sine(
    plant: &mut Plant,
    f_hz: f64,
    m: f64,
    period_ns: u64,
    duration_ns: u64,
    mut observe: impl FnMut(&Plant, u64),
) {
    let mut t = 0u64;
    while t < duration_ns {
        let mid = (t as f64 + period_ns as f64 / 2.0) * 1e-9;
        plant.start_period(period_ns, sine_command(2.0 * PI * f_hz * mid, m));
        plant.advance(period_ns);
        t += period_ns;
        observe(plant, t);
    }
}

/// Torque (mean) and stator current (rms) in steady state at a fixed slip.
fn measure_at_slip(slip: f64, f_hz: f64, m: f64) -> (f64, f64) {
    let mut rig = stiff_rig();
    rig.motor.locked_rotor = true; // holds the speed set below
    let mut plant = Plant::new(rig);
    let w_sync = 2.0 * PI * f_hz / f64::from(rig.motor.pole_pairs);
    plant.set_speed_rad_s((1.0 - slip) * w_sync);
    let period = 20_000;
    let settle = 1_500_000_000;
    // Whole electrical periods for the averages.
    let window = (10.0 / f_hz * 1e9) as u64;
    let mut torque_sum = 0.0;
    let mut i2_sum = 0.0;
    let mut n = 0.0;
    drive_sine(&mut plant, f_hz, m, period, settle + window, |p, t| {
        if t > settle {
            let o = p.outputs();
            torque_sum += o.torque_nm;
            i2_sum += o.i_abc_a.iter().map(|i| i * i).sum::<f64>() / 3.0;
            n += 1.0;
        }
    });
    (torque_sum / n, (i2_sum / n).sqrt())
}

#[test]
fn dynamic_model_matches_equivalent_circuit_within_1_percent() {
    let m = 0.9;
    let rig = stiff_rig();
    for (slip, f_hz) in [(0.03, 50.0), (0.1, 50.0), (0.3, 25.0)] {
        let (torque, i_rms) = measure_at_slip(slip, f_hz, m);
        let v_rms = m * rig.supply_v / 2.0 / 2.0_f64.sqrt();
        let ec = motor::equivalent_circuit(&rig.motor, v_rms, f_hz, slip);
        let e_t = (torque - ec.torque_nm) / ec.torque_nm;
        let e_i = (i_rms - ec.i_s_rms_a) / ec.i_s_rms_a;
        println!(
            "slip {slip} f {f_hz} Hz: torque {torque:.5} vs {:.5} N·m ({:+.3} %), current {i_rms:.4} vs {:.4} A ({:+.3} %)",
            ec.torque_nm,
            100.0 * e_t,
            ec.i_s_rms_a,
            100.0 * e_i
        );
        assert!(e_t.abs() < 0.01, "torque error {e_t} at slip {slip}");
        assert!(e_i.abs() < 0.01, "current error {e_i} at slip {slip}");
    }
}

#[test]
fn supply_cannot_sink_so_regeneration_charges_the_capacitor() {
    let mut rig = RigParams::default();
    rig.motor.locked_rotor = true;
    rig.hw_defaults.ov_hw_v = 45.0;
    let mut plant = Plant::new(rig);
    // Above synchronous speed: generating.
    plant.set_speed_rad_s(1.2 * 2.0 * PI * 25.0 / 2.0);
    let mut max_u: f64 = 0.0;
    drive_sine(&mut plant, 25.0, 0.5, 62_500, 300_000_000, |p, _| {
        max_u = max_u.max(p.outputs().u_dc_v);
    });
    assert!(max_u > rig.supply_v + 1.0, "udc only reached {max_u}");
    assert_eq!(plant.brake_energy_j(), 0.0);
    // Chopper on: the resistor takes the energy and the link falls back.
    plant.set_brake(true);
    let before = plant.outputs().u_dc_v;
    drive_sine(&mut plant, 25.0, 0.5, 62_500, 100_000_000, |_, _| {});
    assert!(plant.outputs().u_dc_v < before);
    assert!(plant.brake_energy_j() > 0.0);
}

#[test]
fn motoring_draws_from_the_supply_and_accelerates() {
    let mut plant = Plant::new(RigParams::default());
    drive_sine(&mut plant, 10.0, 0.25, 62_500, 1_000_000_000, |_, _| {});
    let o = plant.outputs();
    let w_sync = 2.0 * PI * 10.0 / 2.0;
    assert!(
        o.speed_rad_s > 0.8 * w_sync && o.speed_rad_s < w_sync,
        "{o:?}"
    );
    assert!(o.u_dc_v < 30.0);
}

#[test]
fn hardware_comparator_breaks_and_outputs_float() {
    let mut rig = RigParams::default();
    rig.motor.locked_rotor = true;
    rig.hw_defaults.oc_hw_a = 2.0;
    let mut plant = Plant::new(rig);
    let mut peak: f64 = 0.0;
    drive_sine(&mut plant, 50.0, 1.0, 62_500, 200_000_000, |p, _| {
        let i = p.outputs().i_abc_a;
        peak = peak.max(i[0]).max(i[1]).max(i[2]);
    });
    assert!(plant.hw_break() && plant.break_flag());
    // The bare ESC1's comparators trip within the DAC step (0.47 A) that holds the setting
    // (2.0 A: the step up to ~2.35 A, drive-core.md "comparator trim"), and the break acts
    // within one integration step: hardly any overshoot of that level on the positive
    // half-wave the board's comparators watch.
    assert!((1.8..2.4).contains(&peak), "peak {peak}");
    // Long after the break the current has decayed through the diodes.
    let o = plant.outputs();
    assert!(o.i_abc_a.iter().all(|i| i.abs() < 0.05), "{o:?}");
    // The flag clears and MOE comes back only once no comparator is high.
    assert!(!plant.break_input_active());
    plant.clear_break_flag();
    plant.release_break();
    assert!(!plant.hw_break() && !plant.break_flag());
}

#[test]
fn the_rl_load_variant_is_a_star_rl() {
    // Leg 1 at a DC duty d against legs 2 and 3 low: i_a = d Udc / (R + R/2) after L/R.
    let rig = RigParams {
        load: Load::Rl {
            r_ohm: 10.0,
            l_h: 0.02,
        },
        ..stiff_rig()
    };
    let mut plant = Plant::new(rig);
    let cmd = GateCommand {
        legs: [Leg::Duty(0.5), Leg::Duty(0.0), Leg::Duty(0.0)],
        dead_time_ns: 0,
    };
    for _ in 0..2000 {
        plant.start_period(100_000, cmd);
        plant.advance(100_000);
    }
    let o = plant.outputs();
    let expect = 0.5 * 30.0 / 15.0;
    assert!((o.i_abc_a[0] - expect).abs() < 0.01, "{o:?}");
    assert!((o.i_abc_a[1] + expect / 2.0).abs() < 0.01, "{o:?}");
    assert_eq!((o.speed_rad_s, o.torque_nm), (0.0, 0.0));
    // Period averages: the leg duties and the line voltage a-b.
    assert!((o.duty_abc[0] - 0.5).abs() < 1e-9 && o.duty_abc[1] == 0.0);
    assert!((o.u_ab_v - 15.0).abs() < 0.01, "{o:?}");
    // Sine at 50 Hz, m = 1: |Z| = |10 + j 6.28| = 11.8 ohm, 15 V peak per phase.
    let mut plant = Plant::new(rig);
    let mut peak: f64 = 0.0;
    drive_sine(&mut plant, 50.0, 1.0, 20_000, 200_000_000, |p, t| {
        if t > 100_000_000 {
            peak = peak.max(p.outputs().i_abc_a[0]);
        }
    });
    let z = (10.0f64).hypot(2.0 * PI * 50.0 * 0.02);
    assert!(
        (peak - 15.0 / z).abs() < 0.02,
        "peak {peak} vs {}",
        15.0 / z
    );
}

#[test]
fn outputs_off_lets_the_motor_coast_with_no_current() {
    let mut plant = Plant::new(RigParams::default());
    drive_sine(&mut plant, 20.0, 0.45, 62_500, 1_000_000_000, |_, _| {});
    let w0 = plant.outputs().speed_rad_s;
    plant.start_period(62_500, GateCommand::OFF);
    plant.advance(200_000_000);
    let o = plant.outputs();
    assert_eq!(o.i_abc_a, [0.0; 3]);
    assert_eq!(o.torque_nm, 0.0);
    assert!(o.speed_rad_s > 0.0 && o.speed_rad_s < w0);
}

#[test]
fn switching_model_agrees_with_averaged_on_the_fundamental() {
    let run = |mode| {
        let mut rig = stiff_rig();
        rig.pwm_mode = mode;
        rig.motor.locked_rotor = true;
        let mut plant = Plant::new(rig);
        plant.set_speed_rad_s(0.9 * 2.0 * PI * 25.0 / 2.0);
        let mut sum = 0.0;
        let mut n = 0.0;
        drive_sine(&mut plant, 25.0, 0.5, 100_000, 1_400_000_000, |p, t| {
            if t > 1_000_000_000 {
                sum += p.outputs().torque_nm;
                n += 1.0;
            }
        });
        sum / n
    };
    let avg = run(PwmMode::Averaged);
    let sw = run(PwmMode::Switching);
    assert!(
        (sw - avg).abs() / avg < 0.02,
        "switching {sw} vs averaged {avg}"
    );
}

#[test]
fn dead_time_loses_voltage_in_the_switching_model() {
    let run = |dead| {
        let mut rig = stiff_rig();
        rig.pwm_mode = PwmMode::Switching;
        rig.motor.locked_rotor = true;
        let mut plant = Plant::new(rig);
        let mut sum = 0.0;
        let mut n = 0.0;
        let mut t = 0u64;
        while t < 600_000_000 {
            let mid = (t as f64 + 50_000.0) * 1e-9;
            let mut cmd = sine_command(2.0 * PI * 25.0 * mid, 0.5);
            cmd.dead_time_ns = dead;
            plant.start_period(100_000, cmd);
            plant.advance(100_000);
            t += 100_000;
            if t > 400_000_000 {
                let o = plant.outputs();
                sum += o.i_abc_a.iter().map(|i| i * i).sum::<f64>();
                n += 1.0;
            }
        }
        (sum / n).sqrt()
    };
    assert!(run(3_000) < 0.97 * run(0));
}

#[test]
fn freewheeling_current_dies_out_within_a_few_milliseconds() {
    // The source's board: its comparators (3 A on both boards) let the direct start at
    // 50 Hz through, the ESC1's (3 A rounded down to its 0.47 A step) trip on it.
    let mut plant = Plant::new(RigParams {
        board: &firmware_drive::comparators::SOURCE_SENSORS,
        ..RigParams::default()
    });
    drive_sine(&mut plant, 50.0, 1.0, 1_000_000, 1_500_000_000, |_, _| {});
    let before = plant.outputs();
    assert!(before.i_abc_a.iter().any(|i| i.abs() > 0.3), "{before:?}");
    plant.start_period(1_000_000, GateCommand::OFF);
    plant.advance(5_000_000);
    let o = plant.outputs();
    assert_eq!(o.i_abc_a, [0.0; 3], "{o:?}");
}

mod lift_shaft {
    use super::*;
    use crate::plant::lift::LiftParams;

    fn lift_plant(brake_engaged: bool) -> (Plant, LiftParams) {
        let lp = LiftParams::default();
        let mut rig = RigParams::default();
        rig.motor.friction_nms = 0.0;
        let mut plant = Plant::new(rig);
        plant.set_lift_shaft(Some(crate::plant::lift::LiftShaft {
            brake_engaged,
            ..lp.shaft()
        }));
        plant.start_period(100_000, GateCommand::OFF);
        (plant, lp)
    }

    #[test]
    fn the_brake_holds_the_car_against_gravity() {
        let (mut plant, lp) = lift_plant(true);
        assert!(lp.gravity_torque_nm().abs() < lp.brake_torque_nm);
        plant.advance(1_000_000_000);
        assert_eq!(plant.outputs().speed_rad_s, 0.0);
        assert_eq!(plant.angle_rad(), 0.0);
    }

    #[test]
    fn a_brake_weaker_than_gravity_slips_and_a_moving_shaft_is_braked_to_rest() {
        let (mut plant, lp) = lift_plant(true);
        let weak = crate::plant::lift::LiftShaft {
            brake_engaged: true,
            brake_torque_nm: 0.01,
            ..lp.shaft()
        };
        plant.set_lift_shaft(Some(weak));
        plant.advance(100_000_000);
        let w = plant.outputs().speed_rad_s;
        // (T_g + T_b) / J for 0.1 s, downwards.
        let j = MotorParams::DEFAULT_RIG.inertia_kgm2 + lp.reflected_inertia_kgm2();
        let expect = (lp.gravity_torque_nm() + 0.01) / j * 0.1;
        assert!((w - expect).abs() < 1e-3 * expect.abs(), "{w} vs {expect}");
        // The full brake stops it and holds it.
        plant.set_lift_shaft(Some(crate::plant::lift::LiftShaft {
            brake_engaged: true,
            ..lp.shaft()
        }));
        plant.advance(200_000_000);
        assert_eq!(plant.outputs().speed_rad_s, 0.0);
        let a = plant.angle_rad();
        plant.advance(500_000_000);
        assert_eq!(plant.angle_rad(), a);
    }

    #[test]
    fn a_car_lowered_with_the_outputs_off_gains_the_energy_gravity_provides() {
        let (mut plant, lp) = lift_plant(false);
        plant.advance(300_000_000);
        let w = plant.outputs().speed_rad_s;
        let theta = plant.angle_rad();
        assert!(w < 0.0 && theta < 0.0, "the car goes down: {w} rad/s");
        let j = MotorParams::DEFAULT_RIG.inertia_kgm2 + lp.reflected_inertia_kgm2();
        let kinetic = 0.5 * j * w * w;
        // Work of gravity: m g h = |T_g| |θ| (the car fell h = |θ| r / i).
        let h_m = theta.abs() * lp.m_per_rad();
        let work = lp.unbalance_kg * crate::plant::lift::G_M_S2 * h_m;
        assert!((work - lp.gravity_torque_nm().abs() * theta.abs()).abs() < 1e-12);
        assert!(
            (kinetic - work).abs() < 1e-4 * work,
            "kinetic {kinetic} J vs gravity's work {work} J"
        );
    }

    #[test]
    fn an_open_contactor_gives_no_torque() {
        let (mut plant, lp) = lift_plant(false);
        plant.set_lift_shaft(Some(crate::plant::lift::LiftShaft {
            contactor_open: true,
            brake_engaged: true,
            ..lp.shaft()
        }));
        drive_sine(&mut plant, 10.0, 0.5, 100_000, 200_000_000, |p, _| {
            assert_eq!(p.outputs().i_abc_a, [0.0; 3]);
            assert_eq!(p.outputs().torque_nm, 0.0);
        });
    }
}
