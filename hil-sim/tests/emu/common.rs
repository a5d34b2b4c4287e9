//! Shared set-up of the emulator tests.

use std::path::PathBuf;
use std::sync::OnceLock;

use hil_sim::emu::boards::Esc1Sense;
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

/// Both images with `program` in the PLC's EEPROM under `scenario`, on the boards as
/// documented (`g431_emu::boards`).
pub fn emu_on_documented_boards(program: &str, scenario: &str) -> EmuSim {
    let (drive, plc) = images();
    let p = parse_program(program, "test.plc").expect("program assembles");
    let s = Scenario::parse(scenario).expect("scenario parses");
    EmuSim::new(drive, plc, &p, s, RunOptions::default()).expect("images load")
}

/// [`emu_on_documented_boards`], except that the bare ESC1's amplifier pins carry what
/// today's drive image assumes (`Esc1Sense::AsImageAssumes`), not the documented network:
/// with the documented network the image stops at boot (board review N5, shown by
/// `board_findings::n5_*`), and every other test of the image would show only that. When
/// issue 29 fixes the amplifier mode, this becomes [`emu_on_documented_boards`].
pub fn emu(program: &str, scenario: &str) -> EmuSim {
    let sim = emu_on_documented_boards(program, scenario);
    sim.rig_mut().esc1_sense = Esc1Sense::AsImageAssumes;
    sim
}

/// Seconds to ns.
pub fn ns(s: f64) -> u64 {
    (s * 1e9).round() as u64
}

/// Stack bytes each image must never have used (flip-link: an overflow is a HardFault at
/// once; this catches a run that came close, before a new frame or a bigger static makes
/// it a boot loop). The deepest paths: the PLC's power-up under its builder's frame, a
/// storage job and a service answer in RUN.
pub const STACK_HEADROOM_BYTES: u32 = 1024;

/// Both images kept [`STACK_HEADROOM_BYTES`] of their stacks unused so far.
pub fn assert_stack_headroom(sim: &EmuSim) {
    for m in [sim.drive(), sim.plc()] {
        let st = m
            .soc()
            .stack_high_water()
            .expect("a flip-link image: the initial stack pointer is in RAM");
        assert!(
            st.size_bytes - st.used_bytes >= STACK_HEADROOM_BYTES,
            "{}: stack used {} of {} B, less than {STACK_HEADROOM_BYTES} B left",
            m.name,
            st.used_bytes,
            st.size_bytes
        );
    }
}
