//! `lift.plc` on the real images: a fault of the lift reaches the PLC's fault log (004
//! §2.3.3, appendix B; `hil-sim/docs/lift.md`), read through the service port with
//! `plcctl faults --json`.
//!
//! The emulator has no lift model (`hil-sim emu` refuses `[lift]`), so the scenario sets
//! the shaft's signals itself, in the order the car would produce them: the vanes of
//! floor 1 on the initialisation run down, the car call to floor 3, the vanes off as the
//! car leaves floor 1's zone, then the door contact opening in travel (L6).

use std::path::PathBuf;

use crate::common::{emu, ns};
use crate::service::plcctl_on_the_image;

const LIFT_PLC: &str = include_str!("../../../shared-protocol/programs/lift.plc");

/// Door closed and safety chain closed from power-up, outside a floor zone: the program
/// starts its initialisation run down with its first scan (at about 1.3 s on the images:
/// the PLC loads its 860 lines from the EEPROM and downloads the drive section first).
/// Floor 1's left vane at 2.0 s (its signature going down: creep), both vanes at 2.3 s
/// (level: floor 1, idle); car call 3 at 2.8 s (departure up); out of the zone at 3.3 s;
/// the door contact open at 3.6 s.
const DOOR_IN_TRAVEL: &str = r#"
[[event]]
at_s = 0.0
set = { D12 = 1, D15 = 1 }

[[event]]
at_s = 2.0
set = { D10 = 1 }

[[event]]
at_s = 2.3
set = { D11 = 1 }

[[event]]
at_s = 2.8
press = "D02"

[[event]]
at_s = 3.3
set = { D10 = 0, D11 = 0 }

[[event]]
at_s = 3.6
set = { D12 = 0 }
"#;

/// L6 on the real images: the door contact opening in travel is the latched fault 10
/// (state 10, the lamp O05, the outputs off) and one entry in the PLC's fault log: code
/// 110 (`ALM`), the floor (1) and the target (3), with the profile's text.
#[test]
fn a_door_opened_in_travel_is_logged_with_code_floor_and_target() {
    let mut sim = emu(LIFT_PLC, DOOR_IN_TRAVEL);
    let mut s = Vec::new();
    sim.run_until(ns(4.0), |x| s.push(x.clone()));
    let state_at = |t: f64| {
        s.iter()
            .find(|x| x.t_ns >= ns(t))
            .map(|x| (x.q[7], x.q[4], x.q[5]))
            .expect("a sample")
    };
    // Initialised at floor 1, then travelling up to 3.
    assert_eq!(state_at(1.9), (1, 0, 1), "the initialisation run");
    assert_eq!(state_at(2.7), (2, 1, 1));
    assert_eq!(state_at(3.5), (3, 1, 3));
    let fault = s
        .iter()
        .find(|x| x.q[7] == 10)
        .expect("state 10: the door opened in travel");
    let t = fault.t_ns as f64 * 1e-9;
    // The program's 0.2 s filter on the door contact, a scan either side.
    assert!((3.79..3.83).contains(&t), "state 10 at {t} s");
    let last = s.last().expect("samples");
    assert!(last.digital_out & (1 << 5) != 0, "fault lamp O05 off");
    assert!(last.digital_out & (1 << 1) == 0, "brake released (O01)");
    assert!(!last.pwm_on, "the drive switches after the fault");
    // The PLC's fault log, through the service port.
    let profile = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../shared-protocol/programs/lift.profile.toml");
    let (st, out, err) = plcctl_on_the_image(
        &mut sim,
        &["faults", "--json", "--profile", profile.to_str().unwrap()],
    );
    assert!(st.success(), "plcctl faults: {st}\n{out}\n{err}");
    let rows: Vec<serde_json::Value> = serde_json::from_str(&out).expect("JSON rows");
    assert_eq!(rows.len(), 1, "{out}");
    let r = &rows[0];
    assert_eq!(r["code"], 110, "{r}");
    assert_eq!(r["name"], "ALM", "{r}");
    assert_eq!(r["text"], "door open in travel", "{r}");
    assert_eq!(r["values"], serde_json::json!([1, 3]), "{r}");
    assert_eq!(
        r["value_names"],
        serde_json::json!(["floor", "target"]),
        "{r}"
    );
}
