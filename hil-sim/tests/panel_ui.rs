//! The virtual front panel drawn into a test terminal: LCD, keypad, key map, rig. The
//! panel runs the co-simulation: its keys reach the firmware's `PlcApp` on hil-sim's PLC
//! board.

use firmware_plc::editor::Key;
use firmware_plc::storage::MemEeprom;
use hil_sim::panel::keys::{map_char, Input};
use hil_sim::panel::{open, ui, PanelApp, SimBackend};
use ratatui::backend::TestBackend;
use ratatui::Terminal;
use std::path::Path;

/// The source's motor program, as `hil-sim panel motor.plc` opens it.
const MOTOR: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../shared-protocol/programs/motor.plc"
);

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
    // Acknowledging a fault is discoverable in the key box.
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
    let mut app = open(Some(Path::new(MOTOR)), None).unwrap();
    type_keys(&mut app, "#150");
    let mut term = Terminal::new(TestBackend::new(110, 30)).unwrap();
    term.draw(|f| ui::draw(f, &app)).unwrap();
    let t = text(&term);
    assert!(t.contains(">150 LD   D00"), "{t}");
    assert!(t.contains(" 151 LET  B00"), "{t}");
}

/// A terminal too small for the LCD and the key box gets one message
/// with the size needed, not a clipped LCD; at the minimum size everything is drawn.
#[test]
fn a_too_small_terminal_says_so_instead_of_clipping() {
    let app = PanelApp::new(SimBackend::with_eeprom(MemEeprom::new()));
    for (w, h) in [(80, 24), (89, 40), (120, 28), (40, 10), (20, 3)] {
        let mut term = Terminal::new(TestBackend::new(w, h)).unwrap();
        term.draw(|f| ui::draw(f, &app)).unwrap();
        let t = text(&term);
        assert!(
            t.contains("Terminal too small") && t.contains("needs 90x29"),
            "{w}x{h}:\n{t}"
        );
        assert!(!t.contains("Keypad") && !t.contains("LCD"), "{w}x{h}:\n{t}");
    }
    let mut term = Terminal::new(TestBackend::new(ui::MIN_WIDTH, ui::MIN_HEIGHT)).unwrap();
    term.draw(|f| ui::draw(f, &app)).unwrap();
    let t = text(&term);
    assert!(!t.contains("too small"), "{t}");
    for want in [
        "LCD",
        "Keypad",
        "*9 acknowledge the drive's fault",
        "V drive power cycle  G drive watchdog",
        "q..i F1-F8 inputs",
        "A03",
        "EEPROM in memory",
        "limits U<",
    ] {
        assert!(t.contains(want), "{want}:\n{t}");
    }
}

/// The rig box shows outputs on/off, the frequency setpoint, torque and the RMS current,
/// and the rig's keys change what it shows.
#[test]
fn the_rig_box_shows_setpoint_outputs_torque_rms_and_the_rig_settings() {
    let mut app = open(Some(Path::new(MOTOR)), None).unwrap();
    app.advance(100);
    app.input(Input::Analog(0, 512));
    app.input(Input::Analog(1, 300));
    type_keys(&mut app, "a");
    app.advance(500);
    app.input(Input::Pulse(0));
    // One step up (31 V): the bare ESC1's default U>> is 32 V (drive-core.md).
    type_keys(&mut app, "]..l");
    app.advance(300);
    let mut term = Terminal::new(TestBackend::new(110, 32)).unwrap();
    term.draw(|f| ui::draw(f, &app)).unwrap();
    let t = text(&term);
    assert!(t.contains("outputs ON"), "{t}");
    assert!(t.contains("(set "), "{t}");
    assert!(t.contains("Irms") && t.contains(" Nm"), "{t}");
    assert!(t.contains("supply 31.0 V   load 0.020 Nm"), "{t}");
    assert!(t.contains("LOCKED ROTOR"), "{t}");
    let s = app.status();
    assert_eq!(s.supply_v, 31.0);
    assert_eq!(s.load_nm, 0.02);
    assert!(s.locked_rotor);
}
