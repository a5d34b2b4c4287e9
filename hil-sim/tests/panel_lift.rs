//! The lift in the virtual front panel: `lift.plc` on the rig with the lift plant; the
//! panel shows the car, the door and the brake, and a car call is a digital key.

use firmware_plc::storage::image::{program_image, ImageOptions};
use firmware_plc::storage::MemEeprom;
use hil_sim::panel::keys::map_char;
use hil_sim::panel::{ui, PanelApp, SimBackend};
use hil_sim::run::parse_program;
use ratatui::backend::TestBackend;
use ratatui::Terminal;

const LIFT: &str = include_str!("../../shared-protocol/programs/lift.plc");

fn text(app: &PanelApp) -> String {
    let mut term = Terminal::new(TestBackend::new(120, 40)).unwrap();
    term.draw(|f| ui::draw(f, app)).unwrap();
    let buf = term.backend().buffer();
    let w = buf.area.width as usize;
    buf.content
        .chunks(w)
        .map(|row| row.iter().map(|c| c.symbol()).collect::<String>())
        .collect::<Vec<_>>()
        .join("\n")
}

#[test]
fn the_panel_runs_the_lift_and_a_key_calls_it() {
    let p = parse_program(LIFT, "lift.plc").unwrap();
    let image = program_image(
        &p,
        &ImageOptions {
            slot: 1,
            run_at_power_up: true,
        },
    )
    .unwrap();
    let mut app = PanelApp::new(SimBackend::with_lift(MemEeprom::from_image(&image)));
    let t = text(&app);
    assert!(t.contains("LIFT car   450.0 mm"), "{t}");
    // The initialisation run ends level at floor 1 (about 6.1 s).
    app.advance(7000);
    let l = app.status().lift.unwrap();
    assert!(l.at_floor == 1 && l.brake_engaged, "{l:?}");
    let t = text(&app);
    assert!(t.contains("floor 1") && t.contains("brake on"), "{t}");
    // The D08-D15 row shows what the PLC reads from the plant (it showed the
    // keys' toggles, all off): at rest at floor 1 the door-closed switch (D12) and the
    // safety chain (D15) are on, and no key was touched.
    let d = app.status().digital_in;
    for n in [12, 15] {
        assert!(d & (1 << n) != 0, "D{n} off in {d:016b}");
    }
    // `E` pushes D02: the car call for floor 3; it arrives and the door opens.
    app.input(map_char('E').unwrap());
    app.advance(11_500);
    let l = app.status().lift.unwrap();
    assert_eq!(l.at_floor, 3, "{l:?}");
    assert!(l.door > 0.0);
    let t = text(&app);
    assert!(t.contains("floor 3") && t.contains("open"), "{t}");
}

/// `hil-sim panel --lift --eeprom FILE`: the lift on the shaft and the EEPROM in the file
/// (created with lift.plc in slot 1); RUN with `A` runs the lift.
#[test]
fn the_lift_panel_keeps_its_eeprom_in_a_file() {
    let dir = std::env::temp_dir().join(format!("panel-lift-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let eeprom = dir.join("lift.eeprom");
    let program = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../shared-protocol/programs/lift.plc");
    let mut app = hil_sim::panel::open_with(Some(&program), Some(&eeprom), true, None).unwrap();
    assert_eq!(std::fs::metadata(&eeprom).unwrap().len(), 32 * 1024);
    assert!(text(&app).contains("LIFT car   450.0 mm"));
    app.input(map_char('A').unwrap());
    app.advance(7000);
    let l = app.status().lift.unwrap();
    assert!(l.at_floor == 1 && l.brake_engaged, "{l:?}");
    std::fs::remove_dir_all(&dir).unwrap();
}
