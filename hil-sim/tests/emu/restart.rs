//! The automatic restart (`arc`, `art`, `arn`; `firmware-drive/docs/drive-core.md`
//! "Automatic restart") on the real drive image: a supply dip trips `UV`, and with `arc`
//! naming `UV` the image resets the fault by itself `art` after the DC link is back above
//! `U<` + 1 V, at most `arn` times in a row; without `arc` it stays latched, and a latched
//! class (`STO`) never restarts whatever `arc` says.
//!
//! The motor program with a 0.3 s ramp at 20 Hz and a load, so that the DC link sags below
//! `U<` within milliseconds of the supply's dip (the 1000 uF link feeds the motor). The
//! scenario takes the pot to 0 with each dip, as a PLC program that sees the fault would:
//! the drive resets only with the command below `fmn`.

use hil_sim::sim::Sample;
use shared_protocol::fault::FaultCode;

use crate::common::{emu, ns, MOTOR_PLC};

/// `motor.plc` with a 0.3 s ramp and the drive lines `extra` after its last one.
fn motor_with(extra: &str) -> String {
    let p = MOTOR_PLC.replace("002 LD  K01 2333", "002 LD  K01 0300");
    assert!(p.contains("K01 0300"));
    p.replace(
        "025 frv K20 0200     ; reverse below 20.0 Hz (source: 0020)\n",
        &format!("025 frv K20 0200\n{extra}"),
    )
}

/// 20 Hz with a load, START at 0.3 s; `events` after.
fn scenario(events: &str) -> String {
    format!(
        "[plant]\nload_torque_nm = 0.03\n\n[[event]]\nat_s = 0.0\nset = {{ A00 = 980, A01 = 200 }}\n\n\
         [[event]]\nat_s = 0.3\npress = \"D00\"\n{events}"
    )
}

/// The supply at 18 V (below `U<` 25 V) from `from_s` to `to_s`, the pot at 0 from
/// `from_s`.
fn dip(from_s: f64, to_s: f64) -> String {
    format!(
        "\n[[event]]\nat_s = {from_s}\ndc_link_v = 18.0\n\n[[event]]\nat_s = {from_s}\n\
         set = {{ A01 = 0 }}\n\n[[event]]\nat_s = {to_s}\ndc_link_v = 30.0\n"
    )
}

fn t_s(s: &Sample) -> f64 {
    s.t_ns as f64 * 1e-9
}

/// The times at which the `fault` column changes: (t, from, to).
fn fault_edges(samples: &[Sample]) -> Vec<(f64, u8, u8)> {
    samples
        .windows(2)
        .filter(|w| w[0].fault != w[1].fault)
        .map(|w| (t_s(&w[1]), w[0].fault, w[1].fault))
        .collect()
}

/// The first sample at or after `after_s` with the DC link at or above `U<` + 1 V (26 V).
fn link_back(samples: &[Sample], after_s: f64) -> f64 {
    samples
        .iter()
        .find(|s| t_s(s) >= after_s && s.u_dc_v >= 26.0)
        .map(t_s)
        .expect("the DC link back above U< + 1 V")
}

/// `arc` 1 (`UV`), `art` 0.3 s, `arn` 1: the first dip's `UV` resets by itself 0.3 s after
/// the link is back (the outputs off meanwhile, on again only when the pot asks for speed),
/// the second dip's stays latched. The first dip lasts 0.6 s, so that the command has
/// fallen below `fmn` (0.42 s on the 0.3 s ramp) before the link is back: the link is the
/// last condition, and `art` counts from it.
#[test]
fn uv_restarts_by_itself_after_art_at_most_arn_times() {
    let program = motor_with("026 arc K21 0001\n027 art K22 0003\n028 arn K23 0001\n");
    let events = format!(
        "{}\n[[event]]\nat_s = 2.0\nset = {{ A01 = 200 }}\n{}",
        dip(1.0, 1.6),
        dip(2.4, 2.6)
    );
    let mut sim = emu(&program, &scenario(&events));
    let mut s = Vec::new();
    sim.run_until(ns(3.3), |x| s.push(x.clone()));
    let uv = FaultCode::Uv.code();
    let edges = fault_edges(&s);
    let trips: Vec<f64> = edges
        .iter()
        .filter(|e| e.1 == 0 && e.2 == uv)
        .map(|e| e.0)
        .collect();
    let resets: Vec<f64> = edges.iter().filter(|e| e.2 == 0).map(|e| e.0).collect();
    assert!(
        edges.iter().all(|e| (e.1 == 0 && e.2 == uv) || e.2 == 0),
        "only UV trips and resets: {edges:?}"
    );
    assert_eq!(trips.len(), 2, "{edges:?}");
    assert!(trips[0] > 1.0 && trips[0] < 1.1, "{edges:?}");
    assert!(trips[1] > 2.4 && trips[1] < 2.5, "{edges:?}");
    // One restart, art after the link came back, before the second dip.
    assert_eq!(resets.len(), 1, "{edges:?}");
    // (The samples are 1 ms apart: the image may see the link back within the one
    // before the first sample that shows it.)
    let back = link_back(&s, 1.6);
    assert!(
        resets[0] - back >= 0.298 && resets[0] - back < 0.32,
        "reset at {} s, link back at {back} s",
        resets[0]
    );
    // No switching from the trip to the pot's new setpoint (2.0 s); switching again after.
    for x in s
        .iter()
        .filter(|x| t_s(x) > trips[0] + 0.002 && t_s(x) < 2.0)
    {
        assert!(!x.pwm_on, "switching at {} s", t_s(x));
    }
    assert!(
        s.iter()
            .any(|x| t_s(x) > 2.0 && t_s(x) < trips[1] && x.pwm_on),
        "the motor never ran again after the restart"
    );
    // arn 1: the second UV is still latched 0.7 s after the link is back (art 0.3 s).
    let back2 = link_back(&s, 2.6);
    let last = s.last().expect("samples");
    assert!(t_s(last) - back2 > 0.6, "link back at {back2} s");
    assert_eq!(last.fault, uv);
    assert_eq!(sim.status().and_then(|st| st.fault), Some(FaultCode::Uv));
}

/// Without `arc` (the default) the same dip's `UV` stays latched past `art`'s default
/// 1.0 s: the drive never restarts by itself (drive.md).
#[test]
fn without_arc_uv_stays_latched() {
    let mut sim = emu(&motor_with(""), &scenario(&dip(1.0, 1.3)));
    let mut s = Vec::new();
    sim.run_until(ns(2.6), |x| s.push(x.clone()));
    let edges = fault_edges(&s);
    assert_eq!(edges.len(), 1, "{edges:?}");
    assert_eq!(edges[0].2, FaultCode::Uv.code());
    let back = link_back(&s, 1.3);
    let last = s.last().expect("samples");
    assert!(t_s(last) - back > 1.1, "link back at {back} s");
    assert!(!last.pwm_on && last.f_cmd_hz == 0.0);
    assert_eq!(sim.status().and_then(|st| st.fault), Some(FaultCode::Uv));
}

/// `arc` 7 (every class that has a bit), `art` 0.2 s: `STO_IN` low for 0.1 s latches
/// `STO`, which has no bit: still latched 0.6 s after `STO_IN` is high again with the
/// pot at 0 (everything else an ACK needs is there).
#[test]
fn sto_never_restarts_whatever_arc_says() {
    let program = motor_with("026 arc K21 0007\n027 art K22 0002\n028 arn K23 0003\n");
    let events = "\n[[event]]\nat_s = 1.0\nset = { STO_IN = 0, A01 = 0 }\n\n\
                  [[event]]\nat_s = 1.1\nset = { STO_IN = 1 }\n";
    let mut sim = emu(&program, &scenario(events));
    let mut s = Vec::new();
    sim.run_until(ns(1.7), |x| s.push(x.clone()));
    let edges = fault_edges(&s);
    assert_eq!(edges.len(), 1, "{edges:?}");
    assert_eq!(edges[0].2, FaultCode::Sto.code());
    let st = sim.status().expect("status");
    assert_eq!(st.fault, Some(FaultCode::Sto));
    assert!(!st.sto_in_low);
    assert_eq!(s.last().map(|x| x.f_cmd_hz), Some(0.0));
}
