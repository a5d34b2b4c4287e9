//! Shared set-up of the emulator tests.

use std::ops::{Deref, DerefMut};
use std::path::PathBuf;
use std::sync::OnceLock;

use hil_sim::emu::images::build_both;
use hil_sim::emu::sim::EmuSim;
use hil_sim::run::parse_program;
use hil_sim::scenario::Scenario;
use hil_sim::sim::RunOptions;

/// The source's full motor example as the project ships it.
pub const MOTOR_PLC: &str = include_str!("../../../shared-protocol/programs/motor.plc");
/// Its scenario.
pub const MOTOR_TOML: &str = include_str!("../../scenarios/motor.toml");

/// The release images (drive, PLC), built if needed.
pub fn images() -> &'static (PathBuf, PathBuf) {
    static IMAGES: OnceLock<(PathBuf, PathBuf)> = OnceLock::new();
    IMAGES.get_or_init(|| build_both().expect("the firmware images build"))
}

/// Both images with `program` in the PLC's EEPROM under `scenario`.
pub fn emu(program: &str, scenario: &str) -> Emu {
    let (drive, plc) = images();
    let p = parse_program(program, "test.plc").expect("program assembles");
    let s = Scenario::parse(scenario).expect("scenario parses");
    Emu(EmuSim::new(drive, plc, &p, s, RunOptions::default()).expect("images load"))
}

/// A run of both images ([`emu`]); used as an [`EmuSim`]. When the test is done with it
/// (dropped at the end of the test, unless the test already failed), it checks the end
/// of every run: [`assert_stack_headroom`].
pub struct Emu(pub EmuSim);

impl Deref for Emu {
    type Target = EmuSim;
    fn deref(&self) -> &EmuSim {
        &self.0
    }
}

impl DerefMut for Emu {
    fn deref_mut(&mut self) -> &mut EmuSim {
        &mut self.0
    }
}

impl Drop for Emu {
    fn drop(&mut self) {
        if !std::thread::panicking() {
            assert_stack_headroom(&self.0);
        }
    }
}

/// Seconds to ns.
pub fn ns(s: f64) -> u64 {
    (s * 1e9).round() as u64
}

/// RAM bytes each image must never have used, of its 32 KiB: static RAM plus the deepest
/// stack at most 28 KiB (issue 28; flip-link puts the stack below the statics, so what
/// the stack never reached is the RAM never used). An overflow is a HardFault at once;
/// this catches a run that came close, before a new frame or a bigger static makes it a
/// boot loop. Every emulator test checks it at its end ([`Emu`]).
pub const STACK_HEADROOM_BYTES: u32 = 4 * 1024;

/// Both images kept [`STACK_HEADROOM_BYTES`] of their stacks unused so far.
pub fn assert_stack_headroom(sim: &EmuSim) {
    for m in [sim.drive(), sim.plc()] {
        let st = m
            .soc()
            .stack_high_water()
            .expect("a flip-link image: the initial stack pointer is in RAM");
        // The suite's figure (`--nocapture`): the deepest of these lines per image.
        eprintln!(
            "stack high-water {}: {} of {} B",
            m.name, st.used_bytes, st.size_bytes
        );
        assert!(
            st.size_bytes - st.used_bytes >= STACK_HEADROOM_BYTES,
            "{}: stack used {} of {} B, less than {STACK_HEADROOM_BYTES} B left",
            m.name,
            st.used_bytes,
            st.size_bytes
        );
    }
}
