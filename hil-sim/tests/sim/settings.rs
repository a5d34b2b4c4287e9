//! Drive settings once per section (shared-protocol docs/program-format.md "Settings once
//! per section"): the value a setting has is the same on every line and in every cycle,
//! so the drive never commands more than the `fmx` it reports.

use hil_sim::run::parse_program;
use hil_sim::scenario::Scenario;
use hil_sim::sim::{RunOptions, Simulation};
use shared_protocol::program::assemble;

/// The section an outside fuzz campaign found: `fmx` 90.0 Hz for `SN1`, then 50.0 Hz
/// after it, which is what the drive kept and reported.
const FMX_TWICE: &str = "000 FMX K00 0900\n001 LD K00 0800\n002 LD K00 0800\n\
                         003 LD K00 0000\n004 SN1\n005 FMX K00 0500\n";

#[test]
fn a_second_fmx_is_refused_and_the_drive_never_runs_above_the_fmx_it_reports() {
    // The user types the section on the keypad and presses RUN (A).
    let p = assemble(FMX_TWICE).unwrap();
    let scen = Scenario::parse("[[event]]\nat_s = 0.1\nkeys = \"A\"\n").unwrap();
    let mut sim = Simulation::new(&p, scen, RunOptions::default()).unwrap();
    let mut above: Option<(f64, f64)> = None;
    for ms in 1..=400u64 {
        sim.run_until(ms * 1_000_000, |_| {});
        let vm = sim.drive().core().vm();
        let (f, fmx) = (vm.outputs().f, vm.settings().fmx);
        if f > fmx && above.is_none() {
            above = Some((f64::from(f) / 10.0, f64::from(fmx) / 10.0));
        }
    }
    if let Some((f, fmx)) = above {
        panic!(
            "the section verifies and the drive commands {f:.1} Hz while it reports \
             fmx = {fmx:.1} Hz"
        );
    }
    // Refused: the PLC names the second line on the LCD, the drive never runs.
    assert!(!sim.plc().running());
    assert_eq!(sim.drive().status().state.name(), "IDLE");
    let lcd = sim.plc().lcd();
    assert_eq!(lcd.row(3).trim_end(), "005:fmx twice", "{}", lcd.framed());
    // `hil-sim run` and `asm` name both lines.
    assert_eq!(
        parse_program(FMX_TWICE, "fmx_twice.plc")
            .unwrap_err()
            .to_string(),
        "fmx_twice.plc:6:5: fmx set twice (000)"
    );
}
