//! Shared set-up of the emulator tests.

use std::path::PathBuf;
use std::sync::OnceLock;

use hil_sim::emu::images::build_both;
use hil_sim::emu::sim::EmuSim;
use hil_sim::run::parse_program;
use hil_sim::scenario::{ImageTrouble, Scenario};
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
/// documented (`g431_emu::boards`), checked when the test ends ([`Checked`]).
pub fn emu_on_documented_boards(program: &str, scenario: &str) -> Checked {
    let (drive, plc) = images();
    let p = parse_program(program, "test.plc").expect("program assembles");
    let s = Scenario::parse(scenario).expect("scenario parses");
    let mut sim = EmuSim::new(drive, plc, &p, s, RunOptions::default()).expect("images load");
    for (pattern, reason) in ALLOWED_IN_EVERY_TEST {
        sim.allow(pattern, reason);
    }
    Checked { sim: Some(sim) }
}

/// Diagnostics every run of today's images produces, with why each is not a failure of
/// the test (a model limit) or which finding it is (a defect of the image, to be fixed
/// there; the allowance goes when the fix lands).
pub const ALLOWED_IN_EVERY_TEST: &[(&str, &str)] = &[
    (
        "PWR.CR3 set to 0x0000c000",
        "model limit: embassy's clock init sets UCPD1_DBDIS, which removes the USB-C \
         dead-battery pull-downs of PB4/PB6 (RM0440 PWR_CR3); the model never had them, so \
         from this write on it matches the silicon (before it, during the first \
         microseconds of init, it is kinder: no image reads PB4/PB6 then)",
    ),
    ("plc: input PA6 read while floating", KEYPAD_ROW_RELEASED),
    ("plc: input PA7 read while floating", KEYPAD_ROW_RELEASED),
    ("plc: input PB6 read while floating", KEYPAD_ROW_RELEASED),
    ("plc: input PB7 read while floating", KEYPAD_ROW_RELEASED),
];

/// Why the PLC's keypad rows read as floating: not a defect.
const KEYPAD_ROW_RELEASED: &str = "keypad rows R0-R3 (PA6, PA7, PB6, PB7) are open-drain \
    outputs released between scans; with no key down nothing on the NUCLEO drives them \
    (plc-image/src/pins.rs): a read of GPIOA/GPIOB IDR for the port's other inputs \
    samples them along, and the image ignores those bits";

/// An [`EmuSim`] that fails the test when it is dropped (at the end of a test that passed
/// so far) if an image used its stack past [`assert_stack_headroom`]'s limit or
/// [`EmuSim::problems`] lists anything: an emulator diagnostic the test did
/// not allow by name with a reason (`sim.allow(pattern, reason)`), an allowance that
/// matched nothing, or a HardFault, lockup, watchdog or self reset of an image that the
/// scenario does not expect (`[emu] expect`). Every test gets it through [`emu`], so a
/// new test cannot forget the check.
pub struct Checked {
    sim: Option<EmuSim>,
}

impl Checked {
    /// Runs the check now and gives the simulation up (for a test that needs it by value).
    pub fn finish(mut self) -> EmuSim {
        let sim = self.sim.take().expect("not finished twice");
        check(&sim);
        sim
    }
}

fn check(sim: &EmuSim) {
    // A run that overflows a stack on purpose says so: it expects the lockup.
    if !sim.expects(ImageTrouble::Lockup) {
        assert_stack_headroom(sim);
    }
    let problems = sim.problems();
    assert!(
        problems.is_empty(),
        "the emulator found problems the test does not allow:\n  {}",
        problems.join("\n  ")
    );
}

impl std::ops::Deref for Checked {
    type Target = EmuSim;
    fn deref(&self) -> &EmuSim {
        self.sim.as_ref().expect("not finished")
    }
}

impl std::ops::DerefMut for Checked {
    fn deref_mut(&mut self) -> &mut EmuSim {
        self.sim.as_mut().expect("not finished")
    }
}

impl Drop for Checked {
    fn drop(&mut self) {
        // A test that already failed keeps its own message.
        if std::thread::panicking() {
            return;
        }
        if let Some(sim) = self.sim.take() {
            check(&sim);
        }
    }
}

/// The emulated pair on the boards as documented ([`emu_on_documented_boards`]). Until
/// the ESC1's amplifier mode was fixed, this put on the amplifier pins
/// what the image assumed (`Esc1Sense::AsImageAssumes`), because on the documented network
/// the image stopped at boot; no test needs that any more.
pub fn emu(program: &str, scenario: &str) -> Checked {
    emu_on_documented_boards(program, scenario)
}

/// Seconds to ns.
pub fn ns(s: f64) -> u64 {
    (s * 1e9).round() as u64
}

/// RAM bytes each image must never have used, of its 32 KiB: static RAM plus the deepest
/// stack at most 28 KiB (flip-link puts the stack below the statics, so what
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

/// The motor program at 50 Hz (pot A01 = 500), switching at 9.8 kHz (A00 = 980), started by
/// D00 at 0.3 s.
pub const START_50HZ: &str = r#"
[[event]]
at_s = 0.0
set = { A00 = 980, A01 = 500 }

[[event]]
at_s = 0.3
press = "D00"
"#;

/// TIM1's outputs are on (MOE and the channels' enables): what the gates do.
pub fn outputs_enabled(sim: &EmuSim) -> bool {
    sim.drive()
        .soc()
        .tim1()
        .expect("TIM1")
        .gate()
        .outputs_enabled
}
