//! Whatever keys are pressed, the editor never panics, never leaves the screen, and every
//! line of the program it builds verifies ("only valid combinations can be entered").
//! The whole-program rules (the drive stack depth; safety.md 4's settings set twice and
//! the settings an `SFR` needs) depend on lines entered in any order; they are checked
//! when RUN starts (`PlcApp::run` names the line) and by `*` `5`.

use firmware_plc::editor::{Editor, Key, Request, RunView, View};
use firmware_plc::storage::FaultEntry;
use proptest::prelude::*;
use shared_protocol::link::DriveState;
use shared_protocol::program::{verify, Program, VerifyError, VerifyErrorKind};

/// Every line verifies; only the whole-program rules may fail.
fn lines_valid(p: &Program) -> Result<(), VerifyError> {
    match verify(p) {
        Err(VerifyError {
            kind:
                VerifyErrorKind::StackUnderflow { .. }
                | VerifyErrorKind::SettingTwice { .. }
                | VerifyErrorKind::SafetyNeeds { .. }
                | VerifyErrorKind::SafetyNeedsSine { .. },
            ..
        }) => Ok(()),
        other => other,
    }
}

fn arb_key() -> impl Strategy<Value = Key> {
    // Digits weighted up: they do the editing.
    prop_oneof![
        8 => (0u8..10).prop_map(Key::Digit),
        1 => prop::sample::select(vec![Key::A, Key::B, Key::C, Key::D, Key::Star, Key::Hash]),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]
    #[test]
    fn random_keys_keep_the_program_valid(
        keys in prop::collection::vec((arb_key(), any::<bool>()), 1..400),
        cols in prop::sample::select(vec![16u8, 20]),
        now_ms in 0u32..100_000,
    ) {
        let rows = if cols == 20 { 4 } else { 2 };
        let mut ed = Editor::new(cols, rows);
        let mut p = Program::default();
        let log = [FaultEntry::new(3, 2, 77)];
        for (k, running) in keys {
            if let Some(Request::Run { .. }) = ed.key(k, &mut p, running) {
                prop_assert!(lines_valid(&p).is_ok());
            }
            prop_assert!(lines_valid(&p).is_ok(), "after {k:?}: {:?}", verify(&p));
            let run = RunView {
                running,
                link_up: running,
                drive_state: DriveState::Run,
                freq_dhz: -123,
                fault: Some(9),
                lcd: [Some(i16::MIN), None, Some(i16::MAX), Some(0)],
                ..RunView::default()
            };
            let mut s = ed.screen();
            ed.render(&View { program: &p, run, fault_log: &log, now_ms }, &mut s);
            for r in 0..rows {
                prop_assert_eq!(s.row(r).len(), usize::from(cols));
            }
            if let Some((r, c)) = s.cursor {
                prop_assert!(r < rows && c < cols, "cursor {:?}", s.cursor);
            }
        }
    }
}
