//! The seeded fault campaign on the images (`hil-sim campaign --emu`,
//! `hil_sim::campaign::emu`): a generated world runs on the release images with a fault
//! list of the test's own, and the cores' invariants are checked on what the emulated
//! boards show.

use hil_sim::campaign::emu::{run, EmuImages};
use hil_sim::campaign::faults::{Fault, FaultKind};
use hil_sim::campaign::world::{World, WorldOptions};
use hil_sim::scenario::Scenario;
use shared_protocol::fault::FaultCode;

use crate::common::{images, ns};

fn on_images() -> EmuImages {
    let (drive, plc) = images();
    EmuImages {
        drive: drive.clone(),
        plc: plc.clone(),
    }
}

/// Seed 6's world (`motor.plc` on `motor.toml`, the plant as drawn), 1 s, with the
/// template's own events only (START at 0.5 s): the motor runs from about 0.55 s.
fn motor_world() -> World {
    let opts = WorldOptions {
        duration_ns: ns(1.0),
        ..WorldOptions::default()
    };
    let mut w = World::generate(6, &opts).expect("the world generates");
    assert_eq!(w.template.name, "motor");
    w.scenario.actions = Scenario::parse(w.template.scenario)
        .expect("the template parses")
        .actions;
    w
}

/// A 300 us `STO_IN` pulse (shorter than the 1 ms read, safety.md 6) while the images run
/// the motor: the outputs open at once, the image latches `STO` (code 9), and no invariant
/// breaks (the same world with no fault ran with its outputs on, so the check saw them).
#[test]
fn a_sub_period_sto_pulse_on_the_running_images_latches_sto_and_breaks_nothing() {
    let w = motor_world();
    let quiet = run(&w, &[], &on_images());
    assert_eq!(quiet.violation, None);
    assert!(
        quiet.outputs_on_ns > ns(0.1),
        "the motor ran: outputs on {} ns",
        quiet.outputs_on_ns
    );
    let pulse = [Fault {
        at_ns: ns(0.8),
        kind: FaultKind::StoPulse { width_ns: 300_000 },
    }];
    let o = run(&w, &pulse, &on_images());
    assert_eq!(o.violation, None);
    assert_eq!(o.injected, 1);
    assert!(
        o.trips.contains(&(FaultCode::Sto as u8)),
        "STO latched: {:?}",
        o.trips
    );
}
