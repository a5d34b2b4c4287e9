//! "Work is never lost in the panel": the EEPROM kept in a file across
//! sessions, export to `.plc`, Esc cancelling an edit, and questions before unsaved work
//! is discarded (quit on the PC, `D` `0` / `D` `n` on the keypad).

use std::path::{Path, PathBuf};

use firmware_plc::storage::image::program_from_image;
use hil_sim::panel::app::{Modal, QuitLoss};
use hil_sim::panel::keys::{map_char, Input, TextKey};
use hil_sim::panel::{open, read_program, PanelApp};
use shared_protocol::program::assemble;

fn tmp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("hil-sim-panel-work-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join(name);
    let _ = std::fs::remove_file(&p);
    p
}

fn motor() -> PathBuf {
    PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../shared-protocol/programs/motor.plc"
    ))
}

fn type_keys(app: &mut PanelApp, s: &str) {
    for c in s.chars() {
        app.input(map_char(c).unwrap());
        app.advance(50);
    }
}

fn lcd(app: &PanelApp) -> String {
    app.lcd().to_string()
}

fn quit(app: &mut PanelApp) {
    app.input(Input::Quit);
    if matches!(app.modal, Some(Modal::ConfirmQuit(_))) {
        app.modal_key(TextKey::Char('y'));
    }
    assert!(app.quit, "{:?}", app.notice);
}

#[test]
fn saved_slots_survive_quitting_and_restarting_the_panel() {
    let file = tmp("slots.bin");
    let mut app = open(Some(&motor()), Some(&file)).unwrap();
    assert_eq!(std::fs::read(&file).unwrap().len(), 32 * 1024, "created");
    app.advance(100);
    assert!(lcd(&app).contains("LOADED SLOT 1"), "{}", lcd(&app));
    // Edit line 150 (LD D00 -> LD D01), save the result into slot 3.
    type_keys(&mut app, "#150568");
    type_keys(&mut app, "5");
    assert!(lcd(&app).contains(">150 LD   D01"), "{}", lcd(&app));
    let edited = app.backend().program().clone();
    type_keys(&mut app, "c3");
    app.advance(1000);
    assert!(lcd(&app).contains("SAVED IN SLOT 3"), "{}", lcd(&app));
    assert!(!app.backend().unsaved());
    quit(&mut app);
    drop(app);

    // A new session on the same file, without a program: the slots are there.
    let mut app = open(None, Some(&file)).unwrap();
    app.advance(100);
    type_keys(&mut app, "d3");
    app.advance(500);
    assert!(lcd(&app).contains("LOADED SLOT 3"), "{}", lcd(&app));
    assert_eq!(app.backend().program(), &edited);
    type_keys(&mut app, "#150");
    assert!(lcd(&app).contains(">150 LD   D01"), "{}", lcd(&app));
    // Slot 1 still holds the program of the first session's command line.
    type_keys(&mut app, "d1");
    app.advance(500);
    assert_eq!(
        app.backend().program(),
        &read_program(&motor()).unwrap(),
        "{}",
        lcd(&app)
    );
}

#[test]
fn a_program_file_with_an_existing_eeprom_file_is_loaded_unsaved_and_overwrites_no_slot() {
    let file = tmp("keep.bin");
    let mut app = open(None, Some(&file)).unwrap();
    app.advance(50);
    type_keys(&mut app, "#150585c2");
    app.advance(1000);
    assert!(lcd(&app).contains("SAVED IN SLOT 2"), "{}", lcd(&app));
    let saved = app.backend().program().clone();
    quit(&mut app);
    let mut app = open(Some(&motor()), Some(&file)).unwrap();
    assert!(
        app.notice.as_deref().unwrap_or("").contains("unsaved"),
        "{:?}",
        app.notice
    );
    assert_eq!(app.backend().program(), &read_program(&motor()).unwrap());
    assert!(app.backend().unsaved());
    app.advance(200);
    // Loading slot 2 asks first: the program from the file is not saved anywhere.
    type_keys(&mut app, "d2");
    assert!(lcd(&app).contains("DISCARD EDITS? #=YES"), "{}", lcd(&app));
    type_keys(&mut app, "#");
    app.advance(500);
    assert!(lcd(&app).contains("LOADED SLOT 2"), "{}", lcd(&app));
    assert_eq!(app.backend().program(), &saved, "slot 2 not overwritten");
}

/// The file is replaced in one step once a save is complete: sampled every millisecond
/// of a save, it only ever holds the image before or the image after.
#[test]
fn the_eeprom_file_changes_only_once_a_save_is_complete() {
    let file = tmp("atomic.bin");
    let mut app = open(Some(&motor()), Some(&file)).unwrap();
    app.advance(100);
    let before = std::fs::read(&file).unwrap();
    type_keys(&mut app, "c2");
    let mut seen = vec![before.clone()];
    for _ in 0..1500 {
        app.advance(1);
        let now = std::fs::read(&file).unwrap();
        if *seen.last().unwrap() != now {
            seen.push(now);
        }
    }
    assert!(lcd(&app).contains("SAVED IN SLOT 2"), "{}", lcd(&app));
    assert_eq!(seen.len(), 2, "one change, at the end of the save");
    let after = seen.last().unwrap();
    assert!(program_from_image(after).is_ok());
    assert!(!Path::new(&format!("{}.tmp", file.display())).exists());
}

#[test]
fn export_writes_a_plc_file_that_assembles_to_the_program() {
    let out = tmp("export.plc");
    let mut app = open(Some(&motor()), None).unwrap();
    app.export_default = out.clone();
    app.advance(100);
    // Change line 151 (LET B00 -> LET B01) and add line 176 WR O00.
    type_keys(&mut app, "#1516585#176588865");
    app.input(Input::Export);
    assert!(matches!(app.modal, Some(Modal::Export { .. })));
    app.modal_key(TextKey::Enter);
    assert_eq!(app.modal, None);
    assert!(
        app.notice.as_deref().unwrap_or("").contains("exported"),
        "{:?}",
        app.notice
    );
    let text = std::fs::read_to_string(&out).unwrap();
    let back = assemble(&text).unwrap();
    assert_eq!(&back, app.backend().program());
    assert_ne!(back, read_program(&motor()).unwrap(), "the edited program");
    assert!(text.contains("151 LET B01"), "{text}");
    assert!(text.contains("176 WR O00"), "{text}");
    // Exporting again onto the same name asks before overwriting; a new name is typed.
    app.input(Input::Export);
    app.modal_key(TextKey::Enter);
    assert!(matches!(
        app.modal,
        Some(Modal::Export {
            overwrite: true,
            ..
        })
    ));
    for _ in 0..4 {
        app.modal_key(TextKey::Backspace);
    }
    for c in "2.plc".chars() {
        app.modal_key(TextKey::Char(c));
    }
    app.modal_key(TextKey::Enter);
    let second = PathBuf::from(format!(
        "{}2.plc",
        out.display().to_string().trim_end_matches(".plc")
    ));
    assert_eq!(
        assemble(&std::fs::read_to_string(&second).unwrap()).unwrap(),
        back
    );
}

#[test]
fn esc_while_editing_cancels_the_edit_and_does_not_quit() {
    let mut app = open(Some(&motor()), None).unwrap();
    app.advance(100);
    type_keys(&mut app, "#15058");
    assert!(lcd(&app).contains(">150 LDC  D00"), "{}", lcd(&app));
    assert!(app.backend().editing());
    app.input(Input::Esc);
    app.advance(100);
    assert!(!app.quit);
    assert_eq!(app.modal, None);
    assert!(lcd(&app).contains(">150 LD   D00"), "{}", lcd(&app));
    assert!(lcd(&app).contains("CANCELLED"), "{}", lcd(&app));
    assert!(!app.backend().unsaved());
    // Esc typed right behind keys waits for them: here it cancels the `#` command.
    app.input(map_char('#').unwrap());
    app.input(Input::Esc);
    app.advance(100);
    assert!(!app.quit);
    assert!(lcd(&app).contains("CANCELLED"), "{}", lcd(&app));
    // With nothing awaited and nothing unsaved, Esc quits.
    app.input(Input::Esc);
    assert!(app.quit);
}

#[test]
fn quitting_with_unsaved_changes_asks() {
    let mut app = open(Some(&motor()), None).unwrap();
    app.advance(100);
    type_keys(&mut app, "#150*0");
    assert!(app.backend().unsaved());
    app.input(Input::Esc);
    app.advance(10);
    let unsaved = Some(Modal::ConfirmQuit(QuitLoss::UnsavedProgram));
    assert_eq!(app.modal, unsaved);
    assert!(!app.quit);
    // Keys answer the question, they do not reach the keypad.
    app.input(map_char('5').unwrap());
    app.modal_key(TextKey::Char('x'));
    assert_eq!(app.modal, unsaved);
    app.modal_key(TextKey::Char('n'));
    assert_eq!(app.modal, None);
    assert!(!app.quit);
    // Saved to slot 4, but without `--eeprom FILE` the slot dies with the panel: Ctrl-C
    // still asks (with a file it does not: the first test).
    type_keys(&mut app, "c4");
    app.advance(1000);
    assert!(!app.backend().unsaved(), "{}", lcd(&app));
    app.input(Input::Quit);
    assert_eq!(app.modal, Some(Modal::ConfirmQuit(QuitLoss::SavedSlots)));
    // Edited again: both losses in one question.
    app.modal_key(TextKey::Char('n'));
    type_keys(&mut app, "#151*0");
    assert!(app.backend().unsaved(), "{}", lcd(&app));
    app.input(Input::Quit);
    assert_eq!(app.modal, Some(Modal::ConfirmQuit(QuitLoss::Both)));
    app.modal_key(TextKey::Char('y'));
    assert!(app.quit);
    drop(app);
    // Unsaved, nothing saved: Ctrl-C asks about the program only, y quits. (One panel at
    // a time: each is ~120 KiB, and a test thread has 2 MiB.)
    {
        let mut app = open(Some(&motor()), None).unwrap();
        app.advance(100);
        type_keys(&mut app, "#150*0");
        app.input(Input::Quit);
        assert_eq!(app.modal, unsaved);
        app.modal_key(TextKey::Char('y'));
        assert!(app.quit);
    }
    // Nothing edited, nothing saved: no question (RUN and STOP write the boot record,
    // not a slot).
    let mut app = open(Some(&motor()), None).unwrap();
    app.advance(100);
    type_keys(&mut app, "a");
    app.advance(500);
    type_keys(&mut app, "a");
    app.advance(500);
    app.input(Input::Quit);
    assert!(app.quit, "{:?}", app.modal);
}

#[test]
fn new_asks_on_the_lcd_before_discarding_unsaved_changes() {
    let mut app = open(Some(&motor()), None).unwrap();
    app.advance(100);
    type_keys(&mut app, "d0");
    assert!(
        lcd(&app).contains("NEW PROGRAM"),
        "unchanged: no question: {}",
        lcd(&app)
    );
    type_keys(&mut app, "#150585");
    let edited = app.backend().program().clone();
    type_keys(&mut app, "d0");
    assert!(lcd(&app).contains("DISCARD EDITS? #=YES"), "{}", lcd(&app));
    type_keys(&mut app, "1");
    assert!(lcd(&app).contains("CANCELLED"), "{}", lcd(&app));
    assert_eq!(app.backend().program(), &edited);
    type_keys(&mut app, "d0#");
    assert!(lcd(&app).contains("NEW PROGRAM"), "{}", lcd(&app));
    assert!(app.backend().program().lines.iter().all(|l| l.is_none()));
}
