//! The virtual front panel drawn into a test terminal: LCD, keypad, key map, rig. The
//! panel runs the co-simulation: its keys reach the firmware's `PlcApp` on hil-sim's PLC
//! board.

use firmware_plc::editor::Key;
use firmware_plc::storage::MemEeprom;
use hil_sim::panel::keys::{map_char, Input};
use hil_sim::panel::{read_program, ui, PanelApp, SimBackend};
use ratatui::backend::TestBackend;
use ratatui::Terminal;

fn text(term: &Terminal<TestBackend>) -> String {
    let buf = term.backend().buffer();
    let w = buf.area.width as usize;
    buf.content
        .chunks(w)
        .map(|row| row.iter().map(|c| c.symbol()).collect::<String>())
        .collect::<Vec<_>>()
        .join("\n")
}

fn type_keys(app: &mut PanelApp, s: &str) {
    for c in s.chars() {
        app.input(map_char(c).unwrap());
        app.advance(50);
    }
}

#[test]
fn typing_a_short_program_shows_on_the_lcd() {
    let mut app = PanelApp::new(SimBackend::with_eeprom(MemEeprom::new()));
    // Line 150: LD D00; line 151: WR O00 (5 = edit, 8 = next value: empty, LD, LDC, WR;
    // 6 = operand field; 5 = done). Then back to line 150.
    type_keys(&mut app, "#150585#151588865#150");
    let mut term = Terminal::new(TestBackend::new(110, 30)).unwrap();
    term.draw(|f| ui::draw(f, &app)).unwrap();
    let t = text(&term);
    assert!(t.contains(">150 LD   D00"), "{t}");
    assert!(t.contains(" 151 WR   O00"), "{t}");
    assert!(
        t.contains("Keypad") && t.contains("[A]") && t.contains("Key map"),
        "{t}"
    );
    assert!(t.contains("D00-07"), "{t}");
    // Acknowledging a fault is discoverable in the key box (issue 20 item 3).
    assert!(t.contains("*9 acknowledge the drive's fault"), "{t}");
    // Save into slot 2 (the board's storage writes a page per millisecond): the LCD says
    // so.
    type_keys(&mut app, "c2");
    app.advance(500);
    term.draw(|f| ui::draw(f, &app)).unwrap();
    assert!(text(&term).contains("SAVED IN SLOT 2"));
    // RUN: verified, the drive section downloaded, both run; D00 on lights O00.
    type_keys(&mut app, "a");
    app.advance(300);
    term.draw(|f| ui::draw(f, &app)).unwrap();
    assert!(text(&term).contains("PLC RUN"), "{}", text(&term));
    assert_eq!(app.status().digital_out & 1, 0);
    app.input(map_char('q').unwrap());
    app.advance(50);
    assert_eq!(
        app.status().digital_out & 1,
        1,
        "D00 -> O00 through the scan"
    );
}

#[test]
fn switches_and_pots_follow_their_keys() {
    let mut app = PanelApp::new(SimBackend::with_eeprom(MemEeprom::new()));
    app.input(map_char('q').unwrap());
    app.input(map_char('x').unwrap());
    app.input(map_char('X').unwrap());
    assert_eq!(app.status().digital_in, 1);
    assert_eq!(app.status().analog[0], 160);
    app.input(Input::Pulse(3));
    assert_eq!(app.status().digital_in, 0b1001);
    app.advance(150);
    assert_eq!(app.status().digital_in, 0b1001);
    app.advance(60);
    assert_eq!(
        app.status().digital_in,
        1,
        "push button released after 0.2 s"
    );
    app.input(Input::Keypad(Key::B));
    assert_eq!(app.last_key, Some(Key::B));
}

#[test]
fn program_file_loads_into_the_panel() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../shared-protocol/programs/motor.plc"
    );
    let p = read_program(std::path::Path::new(path)).unwrap();
    let mut app = PanelApp::new(SimBackend::new(Some(&p)).unwrap());
    type_keys(&mut app, "#150");
    let mut term = Terminal::new(TestBackend::new(110, 30)).unwrap();
    term.draw(|f| ui::draw(f, &app)).unwrap();
    let t = text(&term);
    assert!(t.contains(">150 LD   D00"), "{t}");
    assert!(t.contains(" 151 LET  B00"), "{t}");
}
