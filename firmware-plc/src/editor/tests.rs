use super::*;
use crate::storage::{OtherCopy, ProgramUse, SlotCopy};
use shared_protocol::program::{mnemonics_for, verify_line, Mnemonic, Operand};

fn press(ed: &mut Editor, p: &mut Program, running: bool, keys: &str) -> Vec<Request> {
    keys.chars()
        .filter_map(|c| ed.key(Key::from_char(c).unwrap(), p, running))
        .collect()
}

fn draw(ed: &Editor, p: &Program, run: RunView<'_>, log: &[FaultEntry], now_ms: u32) -> Screen {
    let mut s = ed.screen();
    ed.render(
        &View {
            program: p,
            run,
            fault_log: log,
            now_ms,
        },
        &mut s,
    );
    s
}

fn ins(m: Mnemonic, op: Option<Operand>, c: u16) -> Instruction {
    Instruction {
        mnemonic: m,
        operand: op,
        constant: c,
    }
}

#[test]
fn empty_listing_with_cursor_and_help() {
    let ed = Editor::new(20, 4);
    let p = Program::default();
    let s = draw(&ed, &p, RunView::default(), &[], 0);
    assert_eq!(s.row(0), ">000                ");
    assert_eq!(s.row(1), " 001                ");
    assert_eq!(s.row(3).trim_end(), "A=RUN C=SAVE D=LOAD");
    assert_eq!(s.cursor, Some((0, 5)));
    assert!(s.blink);
    // The hints rotate: new and the page key come next.
    let s = draw(&ed, &p, RunView::default(), &[], 2000);
    assert_eq!(s.row(3).trim_end(), "D0=NEW B=NEXT PAGE");
}

#[test]
fn enter_a_line_with_only_valid_choices() {
    let mut ed = Editor::new(20, 4);
    let mut p = Program::default();
    assert!(press(&mut ed, &mut p, false, "#150").is_empty());
    assert_eq!(ed.line(), 150);
    press(&mut ed, &mut p, false, "58");
    assert!(ed.editing());
    let s = draw(&ed, &p, RunView::default(), &[], 0);
    assert_eq!(s.row(0), ">150 LD   D00       ");
    assert!(!s.blink, "steady cursor while editing");
    assert_eq!(p.lines[150], None, "not written before leaving the field");
    // To the operand, next area (O), then next area (B), then B05.
    press(&mut ed, &mut p, false, "69988888");
    press(&mut ed, &mut p, false, "25");
    assert_eq!(
        p.lines[150],
        Some(ins(Mnemonic::Ld, Some(Operand::B(4)), 0))
    );
    assert!(ed.modified());
    // K operand: constant field appears, digits step within range.
    press(&mut ed, &mut p, false, "8");
    assert_eq!(ed.line(), 151);
    press(&mut ed, &mut p, false, "5");
    // DIV is in the PLC section; its K constant must be at least 1.
    for _ in 0..mnemonics_for(Section::Plc)
        .position(|m| m == Mnemonic::Div)
        .unwrap()
        + 1
    {
        press(&mut ed, &mut p, false, "8");
    }
    // Operand K00 first; 9 jumps between the areas K and Q.
    press(&mut ed, &mut p, false, "6999");
    let s = draw(&ed, &p, RunView::default(), &[], 0);
    assert!(s.row(1).starts_with(">151 DIV  "), "{s:?}");
    press(&mut ed, &mut p, false, "5");
    let i = p.lines[151].unwrap();
    assert_eq!(verify_line(151, &i), Ok(()));
}

#[test]
fn drive_lines_offer_drive_mnemonics_only() {
    let mut ed = Editor::new(20, 4);
    let mut p = Program::default();
    press(&mut ed, &mut p, false, "5");
    let mut seen = Vec::new();
    loop {
        press(&mut ed, &mut p, false, "8");
        let s = draw(&ed, &p, RunView::default(), &[], 0);
        let m = s.row(0)[5..9].trim().to_string();
        if m.is_empty() {
            break;
        }
        seen.push(m);
    }
    let expect: Vec<String> = mnemonics_for(Section::Drive)
        .map(|m| m.text().to_string())
        .collect();
    assert_eq!(seen, expect);
    assert!(seen.contains(&"PWF".to_string()) && !seen.contains(&"LET".to_string()));
}

/// Every mnemonic of the instruction table can be entered from the keypad on a line of
/// its section, and the line it makes verifies (a new table row is offered without any
/// change to the editor).
#[test]
fn every_mnemonic_can_be_entered_on_its_section() {
    for (section, line) in [(Section::Plc, "#150"), (Section::Drive, "#000")] {
        let n: u16 = line[1..].parse().unwrap();
        for (pos, m) in mnemonics_for(section).enumerate() {
            let mut ed = Editor::new(20, 4);
            let mut p = Program::default();
            press(&mut ed, &mut p, false, line);
            press(&mut ed, &mut p, false, "5");
            press(&mut ed, &mut p, false, &"8".repeat(pos + 1));
            press(&mut ed, &mut p, false, "5");
            let i = p.lines[usize::from(n)].unwrap_or_else(|| panic!("{m:?} not entered"));
            assert_eq!(i.mnemonic, m);
            assert_eq!(verify_line(n, &i), Ok(()), "{i:?}");
        }
    }
}

#[test]
fn fast_scrolling_and_next_used_line() {
    let mut ed = Editor::new(20, 4);
    let mut p = Program::default();
    press(&mut ed, &mut p, false, "999999999");
    assert_eq!(ed.line(), 900);
    press(&mut ed, &mut p, false, "7777777777");
    assert_eq!(ed.line(), 999);
    let s = draw(&ed, &p, RunView::default(), &[], 0);
    assert_eq!(&s.row(2)[..4], ">999", "last line at the bottom: {s:?}");
    press(&mut ed, &mut p, false, "31");
    assert_eq!(ed.line(), 889);
    p.lines[20] = Some(ins(Mnemonic::Sn1, None, 0));
    p.lines[300] = Some(ins(Mnemonic::Lcd, None, 0));
    press(&mut ed, &mut p, false, "0");
    assert_eq!(ed.line(), 20, "wraps round");
    press(&mut ed, &mut p, false, "0");
    assert_eq!(ed.line(), 300);
    press(&mut ed, &mut p, false, "#42#");
    assert_eq!(ed.line(), 42);
}

#[test]
fn insert_and_delete_stay_inside_the_section() {
    let mut ed = Editor::new(20, 4);
    let mut p = Program::default();
    p.lines[148] = Some(ins(Mnemonic::Sn1, None, 0));
    p.lines[150] = Some(ins(Mnemonic::Lcd, None, 0));
    press(&mut ed, &mut p, false, "#100*1");
    assert_eq!(p.lines[149], Some(ins(Mnemonic::Sn1, None, 0)));
    assert_eq!(p.lines[150], Some(ins(Mnemonic::Lcd, None, 0)));
    press(&mut ed, &mut p, false, "*1");
    assert_eq!(ed.message(), Some("SECTION FULL"));
    assert_eq!(p.lines[149], Some(ins(Mnemonic::Sn1, None, 0)));
    press(&mut ed, &mut p, false, "*3*3");
    assert_eq!(p.lines[147], Some(ins(Mnemonic::Sn1, None, 0)));
    assert_eq!(p.lines[149], None);
    assert_eq!(p.lines[150], Some(ins(Mnemonic::Lcd, None, 0)));
    press(&mut ed, &mut p, false, "#147*0");
    assert_eq!(p.lines[147], None);
}

#[test]
fn run_verifies_first_and_shows_the_error_with_its_line() {
    let mut ed = Editor::new(20, 4);
    let mut p = Program::default();
    // A drive mnemonic in the PLC section (only possible from outside the editor).
    p.lines[163] = Some(ins(Mnemonic::Sn1, None, 0));
    assert!(press(&mut ed, &mut p, false, "A").is_empty());
    assert_eq!(ed.line(), 163);
    let s = draw(&ed, &p, RunView::default(), &[], 0);
    assert_eq!(s.row(3).trim_end(), "163:wrong section");
    p.lines[163] = Some(ins(Mnemonic::Lcd, None, 0));
    assert_eq!(
        press(&mut ed, &mut p, false, "A"),
        vec![Request::Run { slot: None }]
    );
    assert_eq!(press(&mut ed, &mut p, true, "A"), vec![Request::Stop]);
}

#[test]
fn save_load_new_are_two_keys_on_every_page() {
    let mut ed = Editor::new(20, 4);
    let mut p = Program::default();
    p.lines[150] = Some(ins(Mnemonic::Lcd, None, 0));
    for page_keys in ["", "B", "B"] {
        press(&mut ed, &mut p, false, page_keys);
        assert_eq!(press(&mut ed, &mut p, false, "C2"), vec![Request::Save(2)]);
        assert_eq!(press(&mut ed, &mut p, false, "D3"), vec![Request::Load(3)]);
        assert_eq!(press(&mut ed, &mut p, true, "D1"), vec![]);
        assert_eq!(ed.message(), Some("STOP FIRST (A)"));
    }
    ed.notify(Notice::Saved { slot: 2 });
    assert_eq!(ed.slot(), Some(2));
    assert_eq!(
        press(&mut ed, &mut p, false, "A"),
        vec![Request::Run { slot: Some(2) }]
    );
    assert_eq!(press(&mut ed, &mut p, false, "D0"), vec![Request::New]);
    assert_eq!(p, Program::default());
    // Prompt shown while the second key is awaited.
    press(&mut ed, &mut p, false, "D");
    let s = draw(&ed, &p, RunView::default(), &[], 0);
    assert_eq!(s.row(3).trim_end(), "LOAD SLOT 1-4 0=NEW");
    press(&mut ed, &mut p, false, "B");
    assert_eq!(ed.message(), Some("CANCELLED"));
}

#[test]
fn editing_refused_while_running() {
    let mut ed = Editor::new(20, 4);
    let mut p = Program::default();
    press(&mut ed, &mut p, true, "58");
    assert!(!ed.editing());
    assert_eq!(p, Program::default());
}

#[test]
fn star_cancels_an_edit() {
    let mut ed = Editor::new(20, 4);
    let mut p = Program::default();
    p.lines[0] = Some(ins(Mnemonic::Sn2, None, 0));
    press(&mut ed, &mut p, false, "588*");
    assert_eq!(p.lines[0], Some(ins(Mnemonic::Sn2, None, 0)));
    assert!(!ed.modified());
}

#[test]
fn narrow_lcd_shows_the_same_listing() {
    let mut ed = Editor::new(16, 2);
    let mut p = Program::default();
    p.lines[5] = Some(ins(Mnemonic::Pi, Some(Operand::K(2)), 1000));
    press(&mut ed, &mut p, false, "#005");
    let s = draw(&ed, &p, RunView::default(), &[], 0);
    assert_eq!(s.row(0), "005 PI  K02 1000");
    assert_eq!(s.row(1).trim_end(), "A RUN C SV D LD");
    press(&mut ed, &mut p, false, "66");
    let s = draw(&ed, &p, RunView::default(), &[], 0);
    assert_eq!(s.cursor, Some((0, 12)));
}

#[test]
fn run_page_shows_fields_state_and_faults_without_lcd_instructions() {
    let mut ed = Editor::new(20, 4);
    let p = Program::default();
    ed.show_page(Page::Run);
    let run = RunView {
        running: true,
        link_up: true,
        drive_state: DriveState::Run,
        freq_dhz: 423,
        reverse: true,
        fault: None,
        lcd: [Some(812), Some(-32768), None, None],
        warning: None,
        drive_warning: None,
        safety: None,
        remote: false,
    };
    let s = draw(&ed, &p, run, &[], 0);
    assert_eq!(s.row(0), "RUN  RUN    42.3Hz R");
    assert_eq!(s.row(1), "1:   812   2:-32768 ");
    assert_eq!(s.row(2), "3:     -   4:     - ");
    assert_eq!(s.row(3).trim_end(), "A=STOP B=NEXT PAGE");
    assert_eq!(s.cursor, None);
    let faulted = RunView {
        running: false,
        drive_state: DriveState::Fault,
        fault: Some(2),
        warning: Some(Warning {
            text: "DIV0",
            line: Some(163),
        }),
        ..run
    };
    let rows: Vec<String> = (0..3)
        .map(|k| {
            draw(&ed, &p, faulted, &[], k * 2000)
                .row(3)
                .trim_end()
                .to_string()
        })
        .collect();
    assert_eq!(
        rows,
        ["F2 overcurrent (HW)", "W:DIV0 @ 163", "*9=ACK FAULT A=RUN"]
    );
    // The drive's warning (a clamped PWF) takes its turn too.
    let both = RunView {
        drive_warning: Some(Warning {
            text: "PWF 488Hz @ 000",
            line: None,
        }),
        ..faulted
    };
    let rows: Vec<String> = (0..4)
        .map(|k| {
            draw(&ed, &p, both, &[], k * 2000)
                .row(3)
                .trim_end()
                .to_string()
        })
        .collect();
    assert_eq!(
        rows,
        [
            "F2 overcurrent (HW)",
            "W:DIV0 @ 163",
            "W:PWF 488Hz @ 000",
            "*9=ACK FAULT A=RUN"
        ]
    );
    let lost = RunView {
        link_up: false,
        ..run
    };
    assert_eq!(
        draw(&ed, &p, lost, &[], 0).row(0).trim_end(),
        "RUN  LINK LOST"
    );
    // The fault also shows on the listing page.
    ed.show_page(Page::Listing);
    assert_eq!(
        draw(&ed, &p, faulted, &[], 0).row(3).trim_end(),
        "F2 overcurrent (HW)"
    );
}

#[test]
fn fault_log_page_newest_first_with_time() {
    let mut ed = Editor::new(20, 4);
    let mut p = Program::default();
    let log = [
        FaultEntry::new(4, 12, 3 * 3600 + 25 * 60 + 7),
        FaultEntry::new(1, 11, 59),
    ];
    press(&mut ed, &mut p, false, "BB");
    assert_eq!(ed.page(), Page::FaultLog);
    let s = draw(&ed, &p, RunView::default(), &log, 0);
    assert_eq!(s.row(0).trim_end(), "LOG 01/02 F4 UV");
    assert_eq!(s.row(1).trim_end(), "undervoltage");
    assert_eq!(s.row(2).trim_end(), "CLOCK NOT SET");
    // 2 s later: the power-up and uptime (no values: the text stays).
    let s = draw(&ed, &p, RunView::default(), &log, 2000);
    assert_eq!(s.row(1).trim_end(), "undervoltage");
    assert_eq!(s.row(2).trim_end(), "PWR 12 UP 3:25:07");
    press(&mut ed, &mut p, false, "888");
    let s = draw(&ed, &p, RunView::default(), &log, 0);
    assert_eq!(s.row(0).trim_end(), "LOG 02/02 F1 OC");
    press(&mut ed, &mut p, false, "2");
    let s = draw(&ed, &p, RunView::default(), &log, 0);
    assert_eq!(s.row(0).trim_end(), "LOG 01/02 F4 UV");
    assert_eq!(
        press(&mut ed, &mut p, false, "*0"),
        vec![Request::ClearFaultLog]
    );
    let s = draw(&ed, &p, RunView::default(), &[], 0);
    assert_eq!(s.row(0).trim_end(), "FAULT LOG EMPTY");
}

#[test]
fn bad_copy_on_load_is_shown() {
    let mut ed = Editor::new(20, 4);
    let p = Program::default();
    ed.notify(Notice::Loaded(LoadReport {
        slot: 2,
        used: SlotCopy::B,
        generation: 4,
        other: OtherCopy::Bad(crate::storage::CopyError::Crc),
    }));
    let s = draw(&ed, &p, RunView::default(), &[], 0);
    assert_eq!(s.row(3), "S2:COPY A BAD,USED B");
    let mut narrow = Editor::new(16, 2);
    narrow.notify(Notice::Loaded(LoadReport {
        slot: 2,
        used: SlotCopy::A,
        generation: 4,
        other: OtherCopy::Bad(crate::storage::CopyError::Crc),
    }));
    let s = draw(&narrow, &p, RunView::default(), &[], 0);
    assert_eq!(s.row(1), "S2 B BAD,USED A ");
}

#[test]
fn narrow_run_and_log_pages_rotate_what_does_not_fit() {
    let mut ed = Editor::new(16, 2);
    let p = Program::default();
    ed.show_page(Page::Run);
    let run = RunView {
        running: true,
        link_up: true,
        drive_state: DriveState::Run,
        freq_dhz: 500,
        reverse: false,
        fault: Some(1),
        lcd: [Some(12), Some(-5), Some(7), None],
        warning: None,
        drive_warning: None,
        safety: None,
        remote: false,
    };
    let rows: Vec<String> = (0..5)
        .map(|k| draw(&ed, &p, run, &[], k * 2000).to_string())
        .collect();
    assert_eq!(rows[0], "RUN RUN   50.0 F\n1=12    2=-5    ");
    assert_eq!(rows[1].lines().nth(1), Some("3=7     4=-     "));
    assert_eq!(rows[2].lines().nth(1), Some("F1 overcurrent  "));
    assert_eq!(rows[3].lines().nth(1), Some("*9 ACK A STOP   "));
    assert_eq!(rows[4], rows[0]);
    ed.show_page(Page::FaultLog);
    let log = [FaultEntry::new(5, 3, 61)];
    let s = draw(&ed, &p, run, &log, 0);
    assert_eq!(s.row(0), "01/01 F5 LINK   ");
    assert_eq!(s.row(1), "link lost       ");
    // No values: the text again, then the clock, the uptime and the hint.
    assert_eq!(draw(&ed, &p, run, &log, 2000).row(1), "link lost       ");
    assert_eq!(draw(&ed, &p, run, &log, 4000).row(1), "CLOCK NOT SET   ");
    assert_eq!(draw(&ed, &p, run, &log, 6000).row(1), "PWR 3 UP 0:01:01");
}

#[test]
fn a_message_gives_way_to_a_fault_but_stays_without_one() {
    let mut ed = Editor::new(20, 4);
    let p = Program::default();
    ed.notify(Notice::Text("LOADED SLOT 1"));
    let quiet = RunView::default();
    // Without alerts the message stays until a key.
    assert_eq!(
        draw(&ed, &p, quiet, &[], 0).row(3).trim_end(),
        "LOADED SLOT 1"
    );
    assert_eq!(
        draw(&ed, &p, quiet, &[], 60_000).row(3).trim_end(),
        "LOADED SLOT 1"
    );
    // A fault appearing later: the message has been up for 60 s, so the fault shows now.
    let faulted = RunView {
        drive_state: DriveState::Fault,
        fault: Some(1),
        ..quiet
    };
    assert_eq!(
        draw(&ed, &p, faulted, &[], 60_000).row(3).trim_end(),
        "F1 overcurrent"
    );
    // A new message shows first, then yields to the fault after MESSAGE_MS.
    ed.notify(Notice::Text("SAVED IN SLOT 2"));
    let t0 = 61_000;
    assert_eq!(
        draw(&ed, &p, faulted, &[], t0).row(3).trim_end(),
        "SAVED IN SLOT 2"
    );
    let later: Vec<String> = (0..3)
        .map(|k| {
            draw(&ed, &p, faulted, &[], t0 + pages::MESSAGE_MS + k * 2000)
                .row(3)
                .trim_end()
                .to_string()
        })
        .collect();
    assert!(later.iter().any(|r| r == "F1 overcurrent"), "{later:?}");
    assert!(later.iter().all(|r| r != "SAVED IN SLOT 2"), "{later:?}");
}

#[test]
fn a_fault_arriving_while_a_message_is_up_shows_at_once() {
    let mut ed = Editor::new(20, 4);
    let p = Program::default();
    ed.notify(Notice::Text("LOADED SLOT 1"));
    let quiet = RunView::default();
    assert_eq!(
        draw(&ed, &p, quiet, &[], 0).row(3).trim_end(),
        "LOADED SLOT 1"
    );
    // The drive restarts and reports WDG 500 ms after the message went up.
    let faulted = RunView {
        drive_state: DriveState::Fault,
        fault: Some(7),
        ..quiet
    };
    assert_eq!(
        draw(&ed, &p, faulted, &[], 500).row(3).trim_end(),
        "F7 watchdog reset"
    );
}

#[test]
fn load_and_new_are_refused_while_running_save_is_not() {
    let mut ed = Editor::new(20, 4);
    let mut p = Program::default();
    p.lines[150] = Some(ins(Mnemonic::Ld, Some(Operand::D(0)), 0));
    let before = p.clone();
    for keys in ["D2", "D0"] {
        assert_eq!(press(&mut ed, &mut p, true, keys), vec![], "{keys}");
        assert_eq!(ed.message(), Some("STOP FIRST (A)"), "{keys}");
    }
    assert_eq!(p, before);
    // A save runs a page per pass: allowed in RUN.
    assert_eq!(press(&mut ed, &mut p, true, "C1"), vec![Request::Save(1)]);
    // Stopped, the same keys work.
    assert_eq!(press(&mut ed, &mut p, false, "D2"), vec![Request::Load(2)]);
}

#[test]
fn edits_save_and_load_wait_for_a_storage_job_holding_the_program() {
    let mut ed = Editor::new(20, 4);
    let mut p = Program::default();
    p.lines[0] = Some(ins(Mnemonic::Ld, Some(Operand::K(1)), 1));
    let before = p.clone();
    for u in [ProgramUse::Reads, ProgramUse::Writes] {
        ed.set_program_use(Some(u));
        for keys in ["C1", "D2", "D0", "*1", "*3", "*0", "5"] {
            assert_eq!(press(&mut ed, &mut p, false, keys), vec![], "{keys}");
            assert_eq!(ed.message(), Some("EEPROM BUSY"), "{u:?} {keys}");
        }
        assert_eq!(p, before);
    }
    // RUN may start during a save (it does not change the program), not during a load.
    ed.set_program_use(Some(ProgramUse::Writes));
    assert_eq!(press(&mut ed, &mut p, false, "A"), vec![]);
    assert_eq!(ed.message(), Some("EEPROM BUSY"));
    ed.set_program_use(Some(ProgramUse::Reads));
    assert!(matches!(
        press(&mut ed, &mut p, false, "A")[..],
        [Request::Run { .. }]
    ));
    ed.set_program_use(None);
    assert_eq!(press(&mut ed, &mut p, false, "C1"), vec![Request::Save(1)]);
}

/// `keys` ask for `request` on every page, stopped or running, and leave the program alone.
fn same_request_on_every_page(ed: &mut Editor, keys: &str, request: Request) {
    let mut p = Program::default();
    for page in [Page::Listing, Page::Run, Page::FaultLog] {
        ed.show_page(page);
        for running in [false, true] {
            assert_eq!(
                press(ed, &mut p, running, keys),
                vec![request],
                "{keys} on {page:?} running={running}"
            );
        }
    }
    assert_eq!(p, Program::default());
}

#[test]
fn star_9_acknowledges_faults_on_every_page() {
    same_request_on_every_page(&mut Editor::new(20, 4), "*9", Request::AckFaults);
}

/// service.md 4: `*` `7` toggles remote service on every page, stopped or running,
/// and never touches the program; the run page marks it after the PLC state.
#[test]
fn star_7_toggles_remote_service_on_every_page_and_the_run_page_marks_it() {
    let mut ed = Editor::new(20, 4);
    same_request_on_every_page(&mut ed, "*7", Request::ToggleRemote);
    let p = Program::default();
    ed.show_page(Page::Run);
    let mut run = RunView {
        running: true,
        link_up: true,
        drive_state: DriveState::Run,
        freq_dhz: 423,
        remote: true,
        ..RunView::default()
    };
    assert_eq!(draw(&ed, &p, run, &[], 0).row(0), "RUN *RUN    42.3Hz F");
    run.remote = false;
    assert_eq!(draw(&ed, &p, run, &[], 0).row(0), "RUN  RUN    42.3Hz F");
    run.remote = true;
    run.link_up = false;
    assert_eq!(
        draw(&ed, &p, run, &[], 0).row(0).trim_end(),
        "RUN *LINK LOST"
    );
    let mut narrow = Editor::new(16, 2);
    narrow.show_page(Page::Run);
    run.link_up = true;
    assert_eq!(draw(&narrow, &p, run, &[], 0).row(0), "RUN RUN   42.3*F");
}

/// With a fault standing, `*` `9` is offered in the `*` prompt (listing
/// and fault log) and in the hint that takes turns with the fault.
#[test]
fn acknowledging_is_offered_wherever_a_fault_is_shown() {
    let mut ed = Editor::new(20, 4);
    let mut p = Program::default();
    let faulted = RunView {
        drive_state: DriveState::Fault,
        fault: Some(3),
        ..RunView::default()
    };
    let rows: Vec<String> = (0..2)
        .map(|k| {
            draw(&ed, &p, faulted, &[], k * 2000)
                .row(3)
                .trim_end()
                .to_string()
        })
        .collect();
    assert!(rows[0].starts_with("F3 "), "{rows:?}");
    assert_eq!(rows[1], "*9=ACK FAULT A=RUN");
    press(&mut ed, &mut p, false, "*");
    assert_eq!(
        draw(&ed, &p, faulted, &[], 0).row(3).trim_end(),
        "9=ACK 1INS 3DEL 0CLR"
    );
    // Without a fault the prompt keeps its editing commands.
    assert_eq!(
        draw(&ed, &p, RunView::default(), &[], 0).row(3).trim_end(),
        "1INS 3DEL 0CLR 5CHK"
    );
    press(&mut ed, &mut p, false, "*");
    ed.show_page(Page::FaultLog);
    press(&mut ed, &mut p, false, "*");
    assert_eq!(
        draw(&ed, &p, faulted, &[], 0).row(3).trim_end(),
        "0=CLR LOG 9=ACK"
    );
}

#[test]
fn the_dirty_flag_follows_edits_saves_loads_and_new() {
    let mut ed = Editor::new(20, 4);
    let mut p = Program::default();
    assert!(!ed.modified());
    // Browsing and a cancelled edit change nothing.
    press(&mut ed, &mut p, false, "#150888588*");
    assert!(!ed.modified());
    // A committed edit does.
    press(&mut ed, &mut p, false, "585");
    assert!(ed.modified());
    assert_eq!(ed.slot(), None);
    ed.notify(Notice::Saved { slot: 3 });
    assert!(!ed.modified());
    assert_eq!(ed.slot(), Some(3));
    // Clearing a line, insert and delete count as changes.
    for keys in ["*0", "*1", "*3"] {
        ed.notify(Notice::Saved { slot: 3 });
        press(&mut ed, &mut p, false, keys);
        assert!(ed.modified(), "{keys}");
    }
    ed.notify(Notice::Loaded(LoadReport {
        slot: 2,
        used: SlotCopy::A,
        generation: 1,
        other: OtherCopy::Same,
    }));
    assert!(!ed.modified());
    ed.mark_modified();
    assert!(ed.modified());
    assert_eq!(ed.slot(), None);
}

#[test]
fn new_and_load_ask_before_discarding_unsaved_changes() {
    let mut ed = Editor::new(20, 4);
    let mut p = Program::default();
    press(&mut ed, &mut p, false, "#150585");
    assert!(ed.modified());
    let edited = p.clone();
    // D 0: asked on the LCD; any key but # cancels and keeps the program.
    assert_eq!(press(&mut ed, &mut p, false, "D0"), vec![]);
    assert!(ed.awaiting_keys());
    let s = draw(&ed, &p, RunView::default(), &[], 0);
    assert_eq!(s.row(3).trim_end(), "DISCARD EDITS? #=YES");
    assert_eq!(press(&mut ed, &mut p, false, "*"), vec![]);
    assert_eq!(ed.message(), Some("CANCELLED"));
    assert!(!ed.awaiting_keys());
    assert_eq!(p, edited);
    assert!(ed.modified());
    // D 2 then #: the load goes ahead.
    assert_eq!(press(&mut ed, &mut p, false, "D2"), vec![]);
    assert_eq!(press(&mut ed, &mut p, false, "#"), vec![Request::Load(2)]);
    // D 0 then #: the program is emptied.
    assert_eq!(press(&mut ed, &mut p, false, "D0#"), vec![Request::New]);
    assert_eq!(p, Program::default());
    assert!(!ed.modified());
    // Nothing unsaved: no question.
    assert_eq!(press(&mut ed, &mut p, false, "D1"), vec![Request::Load(1)]);
    // RUN started while the question was up: the answer is refused, nothing discarded.
    press(&mut ed, &mut p, false, "#150585D0");
    let edited = p.clone();
    assert_eq!(press(&mut ed, &mut p, true, "#"), vec![]);
    assert_eq!(ed.message(), Some("STOP FIRST (A)"));
    assert_eq!(p, edited);
    // Narrow LCD: a shorter question.
    let mut ed = Editor::new(16, 2);
    ed.mark_modified();
    press(&mut ed, &mut p, false, "D3");
    let s = draw(&ed, &p, RunView::default(), &[], 0);
    assert_eq!(s.row(1).trim_end(), "DISCARD? #=YES");
}

#[test]
fn star_cancels_whatever_awaits_keys() {
    let mut ed = Editor::new(20, 4);
    let mut p = Program::default();
    p.lines[0] = Some(ins(Mnemonic::Sn2, None, 0));
    for keys in ["58", "C", "D", "*", "#1"] {
        press(&mut ed, &mut p, false, keys);
        assert!(ed.awaiting_keys(), "{keys}");
        assert_eq!(press(&mut ed, &mut p, false, "*"), vec![], "{keys}");
        assert!(!ed.awaiting_keys(), "{keys}");
        assert_eq!(ed.message(), Some("CANCELLED"), "{keys}");
    }
    assert_eq!(p.lines[0], Some(ins(Mnemonic::Sn2, None, 0)));
    assert!(!ed.modified());
}

/// `*` `5` (safety.md 4, 8): the needed-settings rule at the `SFR` line, and the signature
/// of a program that uses the safety functions.
#[test]
fn star_5_checks_the_safety_rules_and_shows_the_signature() {
    use shared_protocol::safety::{SafetyFunction, SafetySetting};
    let mut ed = Editor::new(20, 4);
    let mut p = Program::default();
    p.lines[10] = Some(ins(Mnemonic::Fss, Some(Operand::K(0)), 40));
    p.lines[11] = Some(ins(Mnemonic::Pss, Some(Operand::K(1)), 200));
    p.lines[197] = Some(ins(
        Mnemonic::Sfr,
        Some(Operand::Sf(SafetyFunction::Ss2)),
        0,
    ));
    press(&mut ed, &mut p, false, "*5");
    assert_eq!(ed.message(), Some("197:SS2 needs ts2"));
    assert_eq!(ed.line(), 197);
    p.lines[12] = Some(ins(Mnemonic::Ts2, Some(Operand::K(2)), 100));
    press(&mut ed, &mut p, false, "*5");
    let mut s = shared_protocol::safety::SafetySettings::default();
    s.set(SafetySetting::Fss, Some(40));
    s.set(SafetySetting::Pss, Some(200));
    s.set(SafetySetting::Ts2, Some(100));
    let want = std::format!("PROGRAM OK SIG {:04X}", s.signature());
    assert_eq!(ed.message(), Some(want.as_str()));
    // A setting twice: at the second line.
    p.lines[13] = Some(ins(Mnemonic::Fss, Some(Operand::K(3)), 41));
    press(&mut ed, &mut p, false, "*5");
    assert_eq!(ed.message(), Some("013:fss twice"));
    // 16 columns: the signature first.
    p.lines[13] = None;
    let mut ed = Editor::new(16, 2);
    press(&mut ed, &mut p, false, "*5");
    let want = std::format!("OK SIG {:04X}", s.signature());
    assert_eq!(ed.message(), Some(want.as_str()));
}

/// safety.md 10: one `S:` item per requested function in bit order after a latched code;
/// `ON` for STO, `OK` in the safe state, `NOK` with a fault, `DEC n.ns` while stopping.
#[test]
fn the_status_row_rotates_one_item_per_requested_safety_function() {
    let ed = Editor::new(20, 4);
    let p = Program::default();
    let mut since = [0u32; 12];
    since[1] = 1_000; // SS1 requested at 1.0 s
    let rows = |fault: Option<u8>, status: u16| -> Vec<String> {
        (0..8)
            .map(|k| {
                let run = RunView {
                    running: true,
                    link_up: true,
                    drive_state: DriveState::Run,
                    fault,
                    safety: Some(SafetyView {
                        requested: 0b1011, // STO, SS1, SOS
                        status,
                        since_ms: since,
                    }),
                    ..RunView::default()
                };
                // 2 s per item; 4.2 s after the SS1 request at the first one.
                let now = 4_200 + k * 2_000;
                draw(&ed, &p, run, &[], now).row(3).trim_end().to_string()
            })
            .collect()
    };
    let r = rows(None, 0b1000);
    assert!(r.contains(&"S:STO ON".to_string()), "{r:?}");
    assert!(r.contains(&"S:SOS OK".to_string()), "{r:?}");
    assert!(
        r.iter()
            .any(|l| l.starts_with("S:SS1 DEC ") && l.ends_with('s')),
        "{r:?}"
    );
    let dec: Vec<_> = r.iter().filter(|l| l.starts_with("S:SS1 DEC")).collect();
    // 3 items and the main hint rotate every 2 s: SS1 is item 1, shown at 10.2 s, 9.2 s
    // after its request.
    assert!(dec.contains(&&"S:SS1 DEC 9.2s".to_string()), "{dec:?}");
    // With code 13 latched: the fault first, then the items; status 0 shows NOK.
    let r = rows(Some(13), 0b0001);
    assert!(r.contains(&"F13 over SLS limit".to_string()), "{r:?}");
    assert!(r.contains(&"S:SS1 NOK".to_string()), "{r:?}");
    assert!(r.contains(&"S:SOS NOK".to_string()), "{r:?}");
}

/// Every status-row message with numbers in it, on 20 and 16 columns: the text the LCD
/// gets, character for character (the messages are built without `core::fmt`).
#[test]
fn messages_with_numbers_are_exact() {
    use crate::storage::StorageError;
    use shared_protocol::program::ShortText;
    use shared_protocol::safety::{SafetyFunction, SafetySetting};
    let cases: [(Notice, &str, &str); 11] = [
        (
            Notice::Saved { slot: 3 },
            "SAVED IN SLOT 3",
            "SAVED IN SLOT 3",
        ),
        (
            Notice::Written { slot: 4 },
            "SLOT 4 WRITTEN (SVC)",
            "S4 WRITTEN (SVC)",
        ),
        (
            Notice::SaveFailed {
                slot: 1,
                error: StorageError::Damaged(1),
            },
            "SAVE S1 FAILED DAMAG",
            "SAVE S1 FAILED D",
        ),
        (
            Notice::LoadFailed {
                slot: 2,
                error: StorageError::Empty(2),
            },
            "S2 EMPTY",
            "S2 EMPTY",
        ),
        (
            Notice::Loaded(LoadReport {
                slot: 4,
                used: SlotCopy::A,
                generation: 9,
                other: OtherCopy::Same,
            }),
            "LOADED SLOT 4",
            "LOADED SLOT 4",
        ),
        (
            Notice::RunRefused {
                line: Some(7),
                reason: ShortText::Needs(SafetyFunction::Ss2, SafetySetting::Ts2),
            },
            "007:SS2 needs ts2",
            "007:SS2 needs ts",
        ),
        (
            Notice::RunRefused {
                line: Some(999),
                reason: ShortText::Twice(Mnemonic::Fss),
            },
            "999:fss twice",
            "999:fss twice",
        ),
        (
            Notice::RunRefused {
                line: None,
                reason: ShortText::NeedsSine(SafetyFunction::Sos),
            },
            "NO RUN:SOS needs sin",
            "NO RUN:SOS needs",
        ),
        (
            Notice::NotRated { signature: 0x3A7F },
            "NOT RATED SIG 3A7F",
            "NOT RATED 3A7F",
        ),
        (
            Notice::NotRated { signature: 0x000B },
            "NOT RATED SIG 000B",
            "NOT RATED 000B",
        ),
        (Notice::Text("SIG MISMATCH"), "SIG MISMATCH", "SIG MISMATCH"),
    ];
    for (notice, wide, narrow) in cases {
        let mut ed = Editor::new(20, 4);
        ed.notify(notice);
        assert_eq!(ed.message(), Some(wide), "{notice:?}");
        let mut ed = Editor::new(16, 2);
        ed.notify(notice);
        assert_eq!(ed.message(), Some(narrow), "{notice:?}");
    }
    // A verifier error found by `*` `5`, and the signature of a program using safety.
    let mut ed = Editor::new(20, 4);
    let mut p = Program::default();
    p.lines[151] = Some(ins(Mnemonic::Wr, Some(Operand::Pw1), 0));
    press(&mut ed, &mut p, false, "*5");
    assert_eq!(ed.message(), Some("151:wrong operand"));
}

/// The run page's numbers at their edges (frequency, the LCD fields), both widths.
#[test]
fn run_page_numbers_are_exact() {
    let p = Program::default();
    let rows = |cols: u8, rows: u8, run: RunView<'_>| -> Vec<String> {
        let mut ed = Editor::new(cols, rows);
        ed.show_page(Page::Run);
        let s = draw(&ed, &p, run, &[], 0);
        (0..rows).map(|r| s.row(r).to_string()).collect()
    };
    let base = RunView {
        running: true,
        link_up: true,
        drive_state: DriveState::Run,
        remote: true,
        ..RunView::default()
    };
    let zero = RunView {
        freq_dhz: 0,
        lcd: [Some(0), Some(-5), Some(32767), Some(9)],
        ..base
    };
    assert_eq!(
        rows(20, 4, zero)[..3],
        [
            "RUN *RUN     0.0Hz F",
            "1:     0   2:    -5 ",
            "3: 32767   4:     9 "
        ]
    );
    assert_eq!(
        rows(16, 2, zero)[..2],
        ["RUN RUN    0.0*F", "1=0     2=-5    "]
    );
    let edge = RunView {
        running: false,
        drive_state: DriveState::Fault,
        freq_dhz: -32768,
        reverse: true,
        lcd: [Some(-32768), None, Some(1000), Some(-1)],
        remote: false,
        ..base
    };
    assert_eq!(
        rows(20, 4, edge)[..3],
        [
            "STOP FAULT 3276.8Hz ",
            "1:-32768   2:     - ",
            "3:  1000   4:    -1 "
        ]
    );
    assert_eq!(
        rows(16, 2, edge)[..2],
        ["STOPFAULT3276.8 ", "1=-327682=-     "]
    );
    let small = RunView {
        freq_dhz: 7,
        ..base
    };
    assert_eq!(rows(20, 4, small)[0], "RUN *RUN     0.7Hz F");
    assert_eq!(rows(16, 3, small)[0], "RUN RUN    0.7*F");
}

/// The listing's numbers and the `#` prompt: line numbers, operands, constants.
#[test]
fn listing_numbers_and_goto_prompt_are_exact() {
    use shared_protocol::safety::SafetyFunction;
    let mut ed = Editor::new(20, 4);
    let mut p = Program::default();
    p.lines[0] = Some(ins(Mnemonic::Ld, Some(Operand::K(9)), 0));
    p.lines[1] = Some(ins(Mnemonic::Ld, Some(Operand::K(0)), 9999));
    p.lines[2] = Some(ins(Mnemonic::Ld, Some(Operand::K(1)), 65535));
    let s = draw(&ed, &p, RunView::default(), &[], 0);
    assert_eq!(s.row(0), ">000 LD   K09 0000  ");
    assert_eq!(s.row(1), " 001 LD   K00 9999  ");
    assert_eq!(s.row(2), " 002 LD   K01 65535 ");
    p.lines[997] = Some(ins(Mnemonic::Wr, Some(Operand::Q(63)), 0));
    p.lines[998] = Some(ins(Mnemonic::Ld, Some(Operand::Com), 0));
    p.lines[999] = Some(ins(
        Mnemonic::Sfr,
        Some(Operand::Sf(SafetyFunction::Ss1)),
        0,
    ));
    press(&mut ed, &mut p, false, "#997");
    let s = draw(&ed, &p, RunView::default(), &[], 0);
    assert_eq!(s.row(0), ">997 WR   Q63       ");
    assert_eq!(s.row(1), " 998 LD   COM       ");
    assert_eq!(s.row(2), " 999 SFR  SS1       ");
    press(&mut ed, &mut p, false, "#");
    assert_eq!(
        draw(&ed, &p, RunView::default(), &[], 0).row(3),
        "GOTO LINE ___       "
    );
    press(&mut ed, &mut p, false, "4");
    assert_eq!(
        draw(&ed, &p, RunView::default(), &[], 0).row(3),
        "GOTO LINE 4__       "
    );
    press(&mut ed, &mut p, false, "2");
    assert_eq!(
        draw(&ed, &p, RunView::default(), &[], 0).row(3),
        "GOTO LINE 42_       "
    );
}

/// The fault log's numbers at their edges.
#[test]
fn fault_log_numbers_are_exact() {
    let log: Vec<FaultEntry> = (0..12)
        .map(|k| FaultEntry::new(if k == 0 { 255 } else { 4 }, 65535, 1_000_000 + k))
        .collect();
    let mut ed = Editor::new(20, 4);
    let p = Program::default();
    ed.show_page(Page::FaultLog);
    let s = draw(&ed, &p, RunView::default(), &log, 2000);
    assert_eq!(s.row(0).trim_end(), "LOG 01/12 F255 ?");
    assert_eq!(s.row(2).trim_end(), "PWR 65535 UP 277:46:");
    let mut narrow = Editor::new(16, 2);
    narrow.show_page(Page::FaultLog);
    let s = draw(&narrow, &p, RunView::default(), &log, 6000);
    assert_eq!(s.row(0), "01/12 F255 ?    ");
    assert_eq!(s.row(1), "PWR 65535 UP 277");
}

/// An application fault with its time of day and values (the lift's floor and target):
/// 20 x 4 shows the text and the date, then the values and the uptime; 16 x 2 rotates
/// them one by one; the largest values and the last second of a u32 fit.
#[test]
fn fault_log_shows_the_time_of_day_and_the_values() {
    let mut e = FaultEntry::new(110, 7, 3725);
    // 2026-11-29 10:15:07 UTC.
    e.wall_s = 9829 * 86_400 + 10 * 3600 + 15 * 60 + 7;
    e.values = [2, 3];
    let log = [e];
    let p = Program::default();
    let mut ed = Editor::new(20, 4);
    ed.show_page(Page::FaultLog);
    let s = draw(&ed, &p, RunView::default(), &log, 0);
    assert_eq!(s.row(0).trim_end(), "LOG 01/01 F110 ALM");
    assert_eq!(s.row(1).trim_end(), "application fault 10");
    assert_eq!(s.row(2).trim_end(), "2026-11-29 10:15:07");
    let s = draw(&ed, &p, RunView::default(), &log, 2000);
    assert_eq!(s.row(1).trim_end(), "1:     2   2:     3");
    assert_eq!(s.row(2).trim_end(), "PWR 7 UP 1:02:05");
    let mut narrow = Editor::new(16, 2);
    narrow.show_page(Page::FaultLog);
    let rows: Vec<String> = (0..5)
        .map(|k| {
            draw(&narrow, &p, RunView::default(), &log, k * 2000)
                .row(1)
                .to_string()
        })
        .collect();
    assert_eq!(rows[0], "application faul");
    assert_eq!(rows[1], "1=2     2=3     ");
    assert_eq!(rows[2], "2026-11-29 10:15");
    assert_eq!(rows[3], "PWR 7 UP 1:02:05");
    // One value only; extremes.
    let mut x = FaultEntry::new(240, 0, 0);
    x.wall_s = u32::MAX - 1;
    x.values = [i16::MIN + 1, firmware_none()];
    let s = draw(&ed, &p, RunView::default(), &[x], 0);
    assert_eq!(s.row(0), "LOG 01/01 F240 LOGCL");
    assert_eq!(s.row(1).trim_end(), "fault log cleared");
    assert_eq!(s.row(2).trim_end(), "2136-02-07 06:28:14");
    let s = draw(&ed, &p, RunView::default(), &[x], 2000);
    assert_eq!(s.row(1).trim_end(), "1:-32767   2:     -");
}

fn firmware_none() -> i16 {
    crate::storage::NO_VALUE
}
