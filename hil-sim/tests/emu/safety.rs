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
