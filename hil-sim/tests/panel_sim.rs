//! The panel on the co-simulation: what a new user does: type a
//! short program, run it, see it work; and run the motor example from its file.

use hil_sim::panel::keys::{map_char, Input};
use hil_sim::panel::{open, read_program, PanelApp, SimBackend};
use std::path::Path;

/// The source's motor program, as `hil-sim panel motor.plc` opens it.
const MOTOR: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../shared-protocol/programs/motor.plc"
);

fn type_keys(app: &mut PanelApp, s: &str) {
    for c in s.chars() {
        app.input(map_char(c).unwrap());
        app.advance(20);
    }
}

fn lcd_text(app: &PanelApp) -> String {
    app.lcd().to_string()
}

#[test]
fn type_a_short_program_run_it_and_see_it_work() {
    let mut app = PanelApp::new(SimBackend::new(None).unwrap());
    app.advance(200);
    // 150 LD D00 / 151 WR O00: the output follows the switch.
    type_keys(&mut app, "#150585#151588865");
    assert!(
        lcd_text(&app).contains(">151 WR   O00"),
        "{}",
        lcd_text(&app)
    );
    type_keys(&mut app, "a");
    app.advance(500);
    let s = app.status();
    assert!(s.plc_running, "RUN after A: {}", lcd_text(&app));
    assert!(
        lcd_text(&app).starts_with("RUN"),
        "run page: {}",
        lcd_text(&app)
    );
    assert_eq!(s.digital_out & 1, 0);
    app.input(Input::Toggle(0));
    app.advance(50);
    assert_eq!(app.status().digital_out & 1, 1, "O00 follows D00");
    app.input(Input::Toggle(0));
    app.advance(50);
    assert_eq!(app.status().digital_out & 1, 0);
    // STOP.
    type_keys(&mut app, "a");
    app.advance(100);
    assert!(!app.status().plc_running);
}

#[test]
fn motor_example_runs_from_the_panel() {
    let mut app = open(Some(Path::new(MOTOR)), None).unwrap();
    app.advance(100);
    assert!(
        lcd_text(&app).contains("LOADED SLOT 1"),
        "{}",
        lcd_text(&app)
    );
    assert!(!app.status().plc_running, "waits for A");
    // Pots: switching frequency A00 = 500 (x10 = 5000 Hz), speed A01 = 300 (30.0 Hz).
    for _ in 0..500 / 128 {
        app.input(Input::Analog(0, 128));
    }
    for _ in 0..300 / 32 {
        app.input(Input::Analog(1, 32));
    }
    type_keys(&mut app, "a");
    app.advance(500);
    assert!(app.status().plc_running, "{}", lcd_text(&app));
    // START (push button on D00).
    app.input(Input::Pulse(0));
    app.advance(6000);
    let s = app.status();
    assert_eq!(s.fault, 0, "{}", lcd_text(&app));
    assert!(
        s.f_hz > 15.0,
        "frequency ramps toward the pot's 28.8 Hz: {s:?}"
    );
    assert!(s.speed_rpm > 300.0, "{s:?}");
    let lcd = lcd_text(&app);
    assert!(lcd.contains("1:   288"), "LCD field 1 = A01: {lcd}");
}

#[test]
fn bit_flip_in_the_eeprom_is_reported_on_the_lcd_at_power_up() {
    use firmware_plc::storage::image::{program_image, ImageOptions};
    use firmware_plc::storage::layout::copy_addr;
    use firmware_plc::storage::MemEeprom;
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../shared-protocol/programs/motor.plc"
    );
    let p = read_program(std::path::Path::new(path)).unwrap();
    let image = program_image(&p, &ImageOptions::default()).unwrap();
    let mut eeprom = MemEeprom::from_image(&image);
    eeprom.flip_bit(copy_addr(1, 0).unwrap() + 40, 2);
    let mut app = PanelApp::new(SimBackend::with_eeprom(eeprom));
    // The LCD takes one changed cell per millisecond, as on the board: the status row
    // comes after the three rows above it.
    app.advance(100);
    let lcd = lcd_text(&app);
    assert!(lcd.contains("S1:COPY A BAD,USED B"), "{lcd}");
    // The image asks for RUN at power-up: the program from copy B runs.
    app.advance(500);
    assert!(app.status().plc_running, "{}", lcd_text(&app));
}

/// The RMS phase current stands still in steady state (over whole
/// periods), where the instantaneous peak of the three phases moved by 13 %.
#[test]
fn the_rms_current_is_steady_where_the_instantaneous_peak_is_not() {
    let mut app = open(Some(Path::new(MOTOR)), None).unwrap();
    app.advance(100);
    app.input(Input::Analog(0, 512));
    app.input(Input::Analog(1, 300));
    type_keys(&mut app, "a");
    app.advance(500);
    app.input(Input::Pulse(0));
    // Up to speed (the setpoint's lag is 2.3 s), with some load.
    type_keys(&mut app, ">");
    app.advance(12_000);
    let (mut rms, mut peak) = (Vec::new(), Vec::new());
    for _ in 0..50 {
        app.advance(37);
        let s = app.status();
        rms.push(s.i_rms_a);
        peak.push(s.i_max_a);
    }
    let spread = |v: &[f64]| {
        let (lo, hi) = v
            .iter()
            .fold((f64::MAX, 0.0f64), |(lo, hi), x| (lo.min(*x), hi.max(*x)));
        (hi - lo) / hi
    };
    let s = app.status();
    assert!(s.f_hz > 25.0 && s.fault == 0, "{s:?}");
    assert!(rms[0] > 0.2, "{rms:?}");
    assert!(spread(&rms) < 0.02, "RMS {rms:?}");
    assert!(spread(&peak) > 0.05, "the peak moves: {peak:?}");
    // A sine's peak over its RMS: sqrt(2) (the peak of three phases sits between
    // sqrt(2)*cos(30 deg) and sqrt(2)).
    let ratio = peak.iter().cloned().fold(0.0, f64::max) / rms[0];
    assert!(ratio > 1.3 && ratio < 1.5, "{ratio}");
}
