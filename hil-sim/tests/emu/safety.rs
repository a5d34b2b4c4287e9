//! safety.md 6 on the real drive image: `STO_IN` (PA11) low opens the outputs through
//! TIM1's second break input (BKIN2), without software; the image reads the level, latches
//! code 9 and keeps the outputs off after the input returns (NOT RATED).

use crate::common::{emu, ns, MOTOR_PLC};

/// The motor program at 50 Hz, then STO_IN low at 1.5 s and high again at 1.6 s.
const STO_IN_AT_1_5: &str = r#"
[[event]]
at_s = 0.0
set = { A00 = 980, A01 = 500 }

[[event]]
at_s = 0.3
press = "D00"

[[event]]
at_s = 1.5
set = { STO_IN = 0 }

[[event]]
at_s = 1.6
set = { STO_IN = 1 }
"#;

fn tim1_gate(sim: &hil_sim::emu::sim::EmuSim) -> g431_emu::periph::tim_adv::GateState {
    sim.drive().soc().tim1().expect("TIM1").gate()
}

#[test]
fn sto_in_low_opens_the_outputs_through_the_break_and_latches_code_9() {
    let mut sim = emu(MOTOR_PLC, STO_IN_AT_1_5);
    sim.run_until(ns(1.5) - 1_000, |_| {});
    assert!(tim1_gate(&sim).outputs_enabled, "running before STO_IN");
    // 1 us after the edge: no 1 ms tick and no PWM interrupt could have acted; the
    // break did (MOE cleared in hardware).
    sim.run_until(ns(1.5) + 1_000, |_| {});
    let g = tim1_gate(&sim);
    assert!(!g.moe && !g.outputs_enabled, "{g:?}");
    // The image reads the level in its tick: code 9, STO requested, STO_IN reported low.
    sim.run_until(ns(1.55), |_| {});
    let st = sim.status().expect("status");
    assert_eq!(st.fault.map(|f| f.code()), Some(9));
    assert!(st.sto_in_low);
    assert_eq!(st.sf_requested & 1, 1);
    // STO_IN high again: the outputs stay off (ACK and a new RUN are needed).
    sim.run_until(ns(1.8), |_| {});
    assert!(!tim1_gate(&sim).outputs_enabled);
    let st = sim.status().expect("status");
    assert_eq!(st.fault.map(|f| f.code()), Some(9));
    assert!(!st.sto_in_low);
}

/// `safety_lab.plc` with a 0.2 s ramp (the lab's 2.0 Hz within a short run; the selection
/// lines are the stock program's).
fn lab_fast_ramp() -> String {
    const LAB: &str = include_str!("../../../shared-protocol/programs/safety_lab.plc");
    let p = LAB.replace("002 LD  K01 2333", "002 LD  K01 0200");
    assert!(p.contains("K01 0200"));
    p
}

/// SOS's selection switch (D10), RUN typed at 0.6 s (the image's keypad is scanned
/// from about 0.5 s), START at 0.9 s, 2.0 Hz; the curtain interrupted at 1.1 s (SOS
/// requested, the request latched); SS2's switch (D09) on at 2.0 s, SOS's off at 2.1 s;
/// the Reset (D05) at 2.5 s with the field clear.
const SELECTION: &str = r#"
[[event]]
at_s = 0.0
set = { D10 = 1, D06 = 1, D07 = 1, A00 = 800, A01 = 20 }

[[event]]
at_s = 0.6
keys = "A"

[[event]]
at_s = 0.9
press = "D00"

[[event]]
at_s = 1.1
set = { D06 = 0, D07 = 0 }

[[event]]
at_s = 1.2
set = { D06 = 1, D07 = 1 }

[[event]]
at_s = 2.0
set = { D09 = 1 }

[[event]]
at_s = 2.1
set = { D10 = 0 }

[[event]]
at_s = 2.5
press = "D05"
"#;

/// 001 4.2.1 and A.3-A.8 on the real images: the selection switches choose the function
/// at run time (SOS, then SS2, the program unchanged), and `SFP` counts the field's whole
/// turns since the request, in the drive's status and through the PLC's `LD SFP` on LCD
/// field 3; the stopwatch runs for SS2 (a ramp function) and not for SOS; both are 0 once
/// the Reset has released the request.
#[test]
fn the_selection_switches_choose_the_function_and_sfp_counts_from_the_request() {
    const SOS: u16 = 1 << 3;
    const SS2: u16 = 1 << 2;
    let mut sim = emu(&lab_fast_ramp(), SELECTION);
    let mut s = Vec::new();
    sim.run_until(ns(2.9), |x| s.push(x.clone()));
    let at = |t: f64| s.iter().find(|x| x.t_ns >= ns(t)).expect("a sample");
    let req = s
        .iter()
        .find(|x| x.sf_req != 0)
        .expect("the curtain requests");
    let t_req = req.t_ns as f64 * 1e-9;
    assert!((1.1..1.13).contains(&t_req), "requested at {t_req} s");
    assert_eq!(req.sf_req, SOS, "SOS's switch chose SOS");
    assert!(s
        .iter()
        .filter(|x| x.t_ns < req.t_ns)
        .all(|x| x.sf_turns == 0));
    // The field's turns since the request, from the commanded frequency the drive reports
    // (0.1 Hz steps): SFP is their whole part, within a turn for the status's age.
    let mut turns = 0.0;
    let mut checked = 0;
    for w in s
        .windows(2)
        .filter(|w| w[0].t_ns >= req.t_ns && w[1].t_ns < ns(2.0))
    {
        turns += w[0].f_cmd_hz * (w[1].t_ns - w[0].t_ns) as f64 * 1e-9;
        let sfp = f64::from(w[1].sf_turns);
        assert!(
            sfp <= turns.floor() + 1.0 && sfp >= turns.floor() - 1.0,
            "SFP {sfp} at {} s, turns since the request {turns:.3}",
            w[1].t_ns as f64 * 1e-9
        );
        checked += 1;
    }
    assert!(
        checked > 100 && turns > 1.0,
        "{checked} samples, {turns} turns"
    );
    let n = at(1.99).sf_turns;
    let lcd = at(1.99).lcd[2].expect("LCD field 3");
    assert!((n - 1..=n).contains(&lcd), "LCD field 3 {lcd}, SFP {n}");
    // SS2's switch on: both; SOS's off: SS2 alone, chosen without a program edit.
    assert_eq!(at(2.05).sf_req, SOS | SS2);
    assert_eq!(at(2.2).sf_req, SS2);
    // The stopwatch (001 4.2.4) runs for the ramp function only: 0 under SOS, from 0 at
    // SS2's request (2.1 s, 0.1 s steps).
    assert!(s
        .iter()
        .filter(|x| x.t_ns < ns(2.09))
        .all(|x| x.sft_ds == 0));
    assert!((3..=4).contains(&at(2.45).sft_ds), "{}", at(2.45).sft_ds);
    // The Reset releases the request: SFP and the stopwatch 0, in the drive and on the LCD.
    assert_eq!(at(2.6).sf_req, 0);
    assert_eq!((at(2.6).sf_turns, at(2.6).sft_ds), (0, 0));
    assert_eq!(at(2.85).lcd[2], Some(0));
    assert!(sim.faults().is_empty(), "{:?}", sim.faults());
}
