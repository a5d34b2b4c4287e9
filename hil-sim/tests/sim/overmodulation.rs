//! Overmodulation as the source did it (program.md 4.3): the motor
//! example at 70 Hz asks for m = 1.4 + dU/1023 = 1.465; the duties clip at the carrier
//! limits and the fundamental keeps rising.

use super::common::*;
use hil_sim::sim::Sample;

/// Amplitude of the `f_hz` component of `y` over `samples` (whole cycles of 1 ms samples).
pub fn fundamental(samples: &[&Sample], f_hz: f64, y: impl Fn(&Sample) -> f64) -> f64 {
    let (mut re, mut im) = (0.0, 0.0);
    for s in samples {
        let a = std::f64::consts::TAU * f_hz * t_s(s);
        re += y(s) * a.cos();
        im += y(s) * a.sin();
    }
    2.0 * re.hypot(im) / samples.len() as f64
}

#[test]
fn motor_example_at_70_hz_gets_more_than_1_15_x_the_m_1_voltage() {
    let scen = "[[event]]\nat_s = 0.0\nset = { A00 = 980, A01 = 700 }\n\
                [[event]]\nat_s = 0.5\npress = \"D00\"\n";
    let r = run_text(MOTOR_PLC, scen, 20.0);
    assert!(r.faults.is_empty(), "{:?}", r.faults);
    // Settled at exactly 70.0 Hz (the lag reaches its setpoint 17 s after START): one
    // second = 70 whole cycles.
    let window: Vec<&Sample> = r
        .samples
        .iter()
        .filter(|s| (18.5..19.5).contains(&t_s(s)))
        .collect();
    assert!(window.iter().all(|s| s.f_cmd_hz == 70.0 && s.pwm_on));
    let m = window[0].m;
    assert!((m - 1.465).abs() < 0.0015, "m requested {m}");
    let u_dc = window.iter().map(|s| s.u_dc_v).sum::<f64>() / window.len() as f64;
    // The m = 1.0 line voltage amplitude is sqrt(3)/2 U_dc.
    let v1 = fundamental(&window, 70.0, |s| s.u_ab_v);
    let ratio = v1 / (3f64.sqrt() / 2.0 * u_dc);
    assert!(
        ratio >= 1.15,
        "fundamental {v1:.2} V = {ratio:.3} x the m = 1.0 value"
    );
    // Clipped at the carrier: each leg sits at 0 or 1 for part of the cycle.
    assert!(window.iter().any(|s| s.duty_abc[0] >= 0.9999));
    assert!(window.iter().any(|s| s.duty_abc[0] <= 0.0001));
    println!("motor example at 70 Hz: m = {m}, u_ab fundamental {v1:.2} V = {ratio:.3} x sqrt(3)/2 U_dc ({u_dc:.2} V)");
}
