//! The PLC image's 16 inputs and 8 outputs (lift.md 1) on the pins of `pins.rs`: an input of
//! the second bank reaches the VM, and O06/O07 reach their pins (PB9, PB8).

use crate::common::{emu, ns, MOTOR_PLC};

/// The motor program plus four lines copying D08 to O06 and D15 to O07.
fn program() -> String {
    format!("{MOTOR_PLC}\n990 LD  D08\n991 WR  O06\n992 LD  D15\n993 WR  O07\n")
}

/// D08 on from 0.5 s to 1.0 s, D15 on from 1.5 s.
const SCENARIO: &str = r#"
[[event]]
at_s = 0.5
set = { D08 = 1 }

[[event]]
at_s = 1.0
set = { D08 = 0 }

[[event]]
at_s = 1.5
set = { D15 = 1 }
"#;

#[test]
fn inputs_d08_d15_reach_the_vm_and_o06_o07_reach_their_pins() {
    let mut sim = emu(&program(), SCENARIO);
    let mut last = (0u16, 0u8);
    let mut grab = |t: f64, sim: &mut hil_sim::emu::sim::EmuSim| {
        sim.run_until(ns(t), |s| last = (s.digital_in, s.digital_out));
        last
    };
    let (d, o) = grab(0.45, &mut sim);
    assert_eq!((d >> 8, o >> 6), (0, 0), "all off before the events");
    let (d, o) = grab(0.6, &mut sim);
    assert_eq!(d, 1 << 8, "D08 at its pin");
    assert_eq!(o >> 6, 0b01, "O06 (PB9) follows D08 within 100 ms");
    let (_, o) = grab(1.1, &mut sim);
    assert_eq!(o >> 6, 0, "O06 off again");
    let (d, o) = grab(1.6, &mut sim);
    assert_eq!(d, 1 << 15, "D15 at its pin");
    assert_eq!(o >> 6, 0b10, "O07 (PB8) follows D15");
}
