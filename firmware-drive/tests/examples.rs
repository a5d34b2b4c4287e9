//! The source's drive examples (seed chapter 4.2, program.md section 5), run on the core
//! with the behaviour their text documents.

mod common;

use common::{dft_bin, Rig};
use firmware_drive::drive::DriveWarning;
use firmware_drive::vm::VmWarning;
use firmware_drive::{DriveCommand, DriveEvent, DriveState};

// The project's copies of the source's examples (shared-protocol/programs, program.md 5).
const PI_RAMP: &str = include_str!("../../shared-protocol/programs/pi_ramp.plc");
const THREE_PHASE_SINE: &str = include_str!("../../shared-protocol/programs/three_phase_sine.plc");
/// The full motor program; the drive takes lines 000-025 (with `frv K20 0200`).
const MOTOR: &str = include_str!("../../shared-protocol/programs/motor.plc");
const DIRECT_PWM: &str = include_str!("../../shared-protocol/programs/direct_pwm.plc");
const IR_BOOST: &str = include_str!("../../shared-protocol/programs/ir_boost.plc");
const PROTECTIONS: &str = include_str!("../../shared-protocol/programs/protections.plc");

#[test]
fn pi_ramp_is_a_first_order_lag_from_0_to_500_on_pw1() {
    let mut rig = Rig::new(PI_RAMP);
    rig.cmd(DriveCommand::Run);
    let arr = rig.core.pwm_timing().arr;
    assert_eq!(arr, 8673, "PWF 9800 Hz");
    let mut worst = 0f64;
    for t in 1..=20_000u64 {
        rig.step_ms(|_| {});
        let q = rig.core.vm().q(0);
        let ideal = 500.0 * (1.0 - (-(t as f64) / 2000.0).exp());
        worst = worst.max((f64::from(q) - ideal).abs());
        // The next millisecond's periods output Q00 in 0.1 %.
        let mut c = None;
        if t % 997 == 0 {
            rig.step_ms(|x| c = Some(*x));
            let c = c.expect("periods ran");
            let q_used = f64::from(q) / 1000.0 * f64::from(arr);
            assert!(c.enable);
            assert!((f64::from(c.duty[0]) - q_used).abs() <= 1.0 || c.duty[0] == 0);
            assert_eq!(&c.duty[1..], &[0, 0]);
        }
    }
    assert!(worst < 1.5, "largest deviation from the ideal lag {worst}");
    assert_eq!(rig.core.vm().q(0), 500);
}

#[test]
fn three_phase_sine_is_50_hz_with_120_degree_phases() {
    let mut rig = Rig::new(THREE_PHASE_SINE);
    rig.cmd(DriveCommand::Run);
    rig.step_ms(|_| {});
    let n = f64::from(rig.core.pwm_timing().arr);
    let mut v: [Vec<f64>; 3] = Default::default();
    for _ in 0..1000 {
        rig.step_ms(|c| {
            assert!(c.enable);
            for (vk, d) in v.iter_mut().zip(c.duty) {
                vk.push(f64::from(d) / n - 0.5);
            }
        });
    }
    // 1 s of samples at the real PWM rate (1500 Hz): 50 cycles per record.
    let len = v[0].len();
    assert!((1499..=1501).contains(&len), "{len}");
    let mut crossings = 0;
    for w in v[0].windows(2) {
        if w[0] < 0.0 && w[1] >= 0.0 {
            crossings += 1;
        }
    }
    assert!((49..=51).contains(&crossings), "{crossings}");
    let (a0, p0) = dft_bin(&v[0], 50.0);
    let (a1, p1) = dft_bin(&v[1], 50.0);
    let (a2, p2) = dft_bin(&v[2], 50.0);
    // m = A / fjm = 1.0: amplitude 0.5 of the period.
    for a in [a0, a1, a2] {
        assert!((a - 0.5).abs() < 0.005, "{a}");
    }
    let deg = |x: f64| (x.to_degrees() + 360.0).rem_euclid(360.0);
    assert!((deg(p1 - p0) - 120.0).abs() < 1.0, "{}", deg(p1 - p0));
    assert!((deg(p2 - p0) - 240.0).abs() < 1.0, "{}", deg(p2 - p0));
}

fn motor_rig() -> Rig {
    let mut rig = Rig::new(MOTOR);
    // The PLC's first scan: PWF (A00 * 10) and the setpoint (A01).
    rig.cmd(DriveCommand::SetQ {
        addr: 0,
        value: 5000,
    });
    rig.cmd(DriveCommand::SetQ {
        addr: 2,
        value: 400,
    });
    rig.cmd(DriveCommand::Run);
    rig
}

#[test]
fn motor_frequency_follows_the_setpoint_as_a_2333_ms_lag_with_fmn_and_v_per_f() {
    let mut rig = motor_rig();
    rig.step_ms(|_| {});
    assert_eq!(rig.core.pwm_timing().pwm_millihertz, 5_000_000);
    // dU = round(1023 * 1.95 * 0.5 / 15) = 66.
    assert_eq!(rig.core.vm().settings().du, 66);
    let mut first_on = None;
    let mut worst = 0f64;
    for t in 2..=12_000u64 {
        let mut on = false;
        let mut all_off = true;
        rig.step_ms(|c| {
            on |= c.enable;
            all_off &= !c.enable;
        });
        let s = rig.core.status();
        let f = f64::from(s.f_command.0);
        let ideal = 400.0 * (1.0 - (-(t as f64) / 2333.0).exp());
        worst = worst.max((f - ideal).abs());
        if s.f_command.0 < 50 {
            assert_eq!(s.f_applied.0, 0);
        } else {
            assert_eq!(s.f_applied, s.f_command);
            // V/f with the IR boost: m = f / fjm + dU / 1023.
            let m = f / 500.0 + 66.0 / 1023.0;
            assert!(
                (f64::from(s.modulation_permille) - m * 1000.0).abs() <= 1.0,
                "{} vs {m}",
                s.modulation_permille
            );
        }
        if on && first_on.is_none() {
            first_on = Some(t);
        }
        if first_on.is_none() {
            assert!(all_off);
        }
    }
    assert!(
        worst < 1.5,
        "largest deviation from the 2.333 s lag: {worst}"
    );
    // fmn: the outputs start when f reaches 5.0 Hz: t = -2333 ln(1 - 50/400) = 311 ms.
    let t_on = first_on.expect("outputs came on");
    assert!((305..=320).contains(&t_on), "{t_on}");
    let s = rig.core.status();
    assert_eq!(s.state, DriveState::Run);
    assert!((390..=400).contains(&s.f_applied.0));
}

#[test]
fn motor_pwf_from_q_below_range_is_clamped_with_a_warning() {
    let mut rig = Rig::new(MOTOR);
    rig.cmd(DriveCommand::SetQ { addr: 0, value: 30 });
    rig.cmd(DriveCommand::Run);
    rig.run_ms(5);
    // The source's minimum 488 Hz is 170 MHz / (2 * 58060 * 3): 488.001 Hz.
    assert_eq!(rig.core.pwm_timing().pwm_millihertz, 488_001);
    let warnings: Vec<_> = rig
        .events
        .iter()
        .filter(|(_, e)| matches!(e, DriveEvent::Warning(_)))
        .collect();
    assert_eq!(
        warnings,
        vec![&(
            1,
            DriveEvent::Warning(DriveWarning::Vm(VmWarning::PwfClamped {
                line: 0,
                requested: 30,
                applied: 488
            }))
        )]
    );
}

/// Phase of legs 0 and 1 over 100 ms at the current frequency: +120 means leg 1 leads.
fn phase_order(rig: &mut Rig) -> f64 {
    let n = f64::from(rig.core.pwm_timing().arr);
    let f = f64::from(rig.core.status().f_applied.0) / 10.0;
    let mut v: [Vec<f64>; 2] = Default::default();
    for _ in 0..100 {
        rig.step_ms(|c| {
            v[0].push(f64::from(c.duty[0]) / n);
            v[1].push(f64::from(c.duty[1]) / n);
        });
    }
    let cycles = f * v[0].len() as f64 / 5000.0;
    let (_, p0) = dft_bin(&v[0], cycles);
    let (_, p1) = dft_bin(&v[1], cycles);
    ((p1 - p0).to_degrees() + 540.0).rem_euclid(360.0) - 180.0
}

#[test]
fn motor_reversal_happens_at_the_turning_point_below_frv() {
    let mut rig = motor_rig();
    rig.run_ms(15_000);
    assert!((phase_order(&mut rig) - 120.0).abs() < 2.0);
    // REV: the PLC sends the request and the zero setpoint, 7 s later the setpoint again.
    rig.cmd(DriveCommand::Direction { reverse: true });
    rig.cmd(DriveCommand::SetQ { addr: 2, value: 0 });
    let mut prev = rig.core.status().f_command.0;
    for _ in 0..7000 {
        rig.step_ms(|_| {});
        let s = rig.core.status();
        assert!(
            !s.reverse,
            "reversed while braking down at f = {}",
            s.f_command.0
        );
        assert!(s.f_command.0 <= prev);
        prev = s.f_command.0;
    }
    // 40 Hz * exp(-7 / 2.333) = 2 Hz.
    assert!((19..=21).contains(&prev), "{prev}");
    rig.cmd(DriveCommand::SetQ {
        addr: 2,
        value: 400,
    });
    let mut t_rise = None;
    for _ in 0..50 {
        let before = rig.core.status().f_command.0;
        rig.step_ms(|_| {});
        let now = rig.core.status();
        if now.f_command.0 > before && t_rise.is_none() {
            t_rise = Some(rig.ms - 1);
        }
        if t_rise.is_none() {
            assert!(!now.reverse, "reversed before f rose");
        }
    }
    let t_rise = t_rise.expect("f rises again");
    let rev: Vec<_> = rig
        .events
        .iter()
        .filter(|(_, e)| matches!(e, DriveEvent::Reversed(_)))
        .collect();
    assert_eq!(rev.len(), 1);
    let (t, e) = rev[0];
    assert_eq!(*e, DriveEvent::Reversed(true));
    assert_eq!(*t, t_rise, "reversal in the first millisecond f rises");
    assert!(rig.core.status().reverse);
    rig.run_ms(10_000);
    assert!((phase_order(&mut rig) + 120.0).abs() < 2.0);
}

#[test]
fn direct_pwm_outputs_the_q00_duty_on_pw1() {
    let mut rig = Rig::new(DIRECT_PWM);
    rig.cmd(DriveCommand::SetQ {
        addr: 0,
        value: 250,
    });
    rig.cmd(DriveCommand::Run);
    rig.step_ms(|_| {});
    let arr = rig.core.pwm_timing().arr;
    // 170 MHz / (2 * 5620 Hz) = 15125 counts.
    assert_eq!(arr, 15125);
    let mut seen = 0;
    rig.step_ms(|c| {
        assert!(c.enable);
        assert_eq!(c.duty, [3781, 0, 0]); // 25.0 % of 15125, rounded
        seen += 1;
    });
    assert!(seen >= 5);
}

#[test]
fn ir_boost_computes_du() {
    let rig = Rig::new(IR_BOOST);
    // round(1023 * 1.95 * 0.6 / 15) = round(79.79) = 80, applied when loaded.
    assert_eq!(rig.core.vm().settings().du, 80);
}

#[test]
fn protections_brake_above_30_v_and_trip_above_1_a() {
    let mut rig = Rig::new(PROTECTIONS);
    rig.sample.u_dc = 2800; // 30.8 V
    let mut brake = false;
    rig.step_ms(|c| brake |= c.brake);
    assert!(brake, "chopper on above U> even in IDLE");
    rig.sample.u_dc = 2700; // 29.7 V: inside the 1 V hysteresis
    rig.step_ms(|c| assert!(c.brake));
    rig.sample.u_dc = 2600; // 28.6 V
    rig.step_ms(|c| assert!(!c.brake));
    rig.cmd(DriveCommand::Run);
    rig.sample.i_a = 2048 + 206; // 1.005 A
    rig.step_ms(|c| assert!(!c.enable));
    assert_eq!(rig.core.fault(), Some(firmware_drive::FaultCode::Oc));
}
