//! The safety functions' codes 9-16: in the panel they are
//! caused by a program, not by the rig. Each test loads `safety_lab.plc` into the panel,
//! plays the inputs of that function's hil-sim scenario (`hil-sim/scenarios/safety/`,
//! which turns on the function's selection switch) through the panel's own inputs
//! (toggles in both banks, push buttons, pots, keypad), sees the code on the LCD, and after the scenario's Reset
//! (field clear, D05), STOP, RUN and START sees the drive running again without a fault.

use hil_sim::panel::keys::{Input, BANK_SIZE};
use hil_sim::panel::{PanelApp, SimBackend};
use hil_sim::scenario::ScenarioFile;
use shared_protocol::fault::FaultCode;
use shared_protocol::program::assemble;

const LAB: &str = include_str!("../../shared-protocol/programs/safety_lab.plc");

/// `safety_lab.plc` with `edit` applied to its text.
fn lab_panel(edit: impl Fn(String) -> String) -> PanelApp {
    let text = edit(LAB.to_string());
    let p = assemble(&text).unwrap();
    let mut app = PanelApp::new(SimBackend::new(Some(&p)).unwrap());
    app.advance(100);
    app
}

/// Toggles Dn, switching the panel's keys to D08-D15 and back for those.
fn toggle(app: &mut PanelApp, n: u8) {
    if n < BANK_SIZE {
        app.input(Input::Toggle(n));
    } else {
        app.input(Input::Bank);
        app.input(Input::Toggle(n - BANK_SIZE));
        app.input(Input::Bank);
    }
}

fn lcd(app: &PanelApp) -> String {
    app.lcd().to_string()
}

/// Plays scenario `name` through the panel until the LCD shows `F<code>` with the drive
/// reporting that code; returns that time (s, scenario time), or `None` at the
/// scenario's end. The curtain is left clear (D06 = D07 = 1) either way.
fn play(app: &mut PanelApp, name: &str, code: FaultCode) -> Option<f64> {
    let path = format!(
        "{}/scenarios/safety/{name}.toml",
        env!("CARGO_MANIFEST_DIR")
    );
    let file: ScenarioFile = toml::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    let mut events = file.events.clone();
    events.sort_by(|a, b| a.at_s.total_cmp(&b.at_s));
    // The scenario's duration and 3 s more for the LCD's status rotation.
    let end_ms = (file.duration_s.unwrap() * 1000.0) as u32 + 3000;
    let mut digital = [0i64; 16];
    let mut analog = [0i64; 4];
    let mut next = events.iter().peekable();
    let want = format!("F{} ", code.code());
    let mut seen = None;
    for t_ms in (0..end_ms).step_by(10) {
        while let Some(e) = next.next_if(|e| (e.at_s * 1000.0).round() as u32 <= t_ms) {
            for (input, value) in e.set.iter().flatten() {
                let n: usize = input[1..].parse().unwrap();
                match &input[..1] {
                    "D" if digital[n] != *value => {
                        toggle(app, n as u8);
                        digital[n] = *value;
                    }
                    "A" => {
                        app.input(Input::Analog(n as u8, (value - analog[n]) as i16));
                        analog[n] = *value;
                    }
                    _ => {}
                }
            }
            if let Some(p) = &e.press {
                app.input(Input::Pulse(p[1..].parse().unwrap()));
            }
            for c in e.keys.iter().flat_map(|k| k.chars()) {
                let key = firmware_plc::editor::Key::from_char(c).unwrap();
                app.input(Input::Keypad(key));
                app.advance(60);
            }
        }
        app.advance(10);
        if app.status().fault == code.code() && lcd(app).contains(&want) {
            seen = Some(f64::from(t_ms) / 1000.0);
            break;
        }
    }
    for n in [6u8, 7] {
        if digital[usize::from(n)] == 0 {
            app.input(Input::Toggle(n));
        }
    }
    seen
}

/// The code was shown; then, with the field clear and the speed pot at 0, the Reset
/// button (D05) acknowledges it (the drive needs the frequency command below `fmn`:
/// `FLB` cleared the run request, the PI ramp brings the setpoint down).
fn caused_and_cleared(app: &mut PanelApp, name: &str, code: FaultCode) {
    let seen = play(app, name, code);
    assert!(
        seen.is_some(),
        "{code:?} never on the LCD (fault {})\n{}",
        app.status().fault,
        lcd(app)
    );
    app.advance(10_000);
    app.input(Input::Pulse(5));
    app.advance(500);
    let s = app.status();
    assert_eq!(s.fault, 0, "still latched after the Reset\n{}", lcd(app));
}

#[test]
fn sto_requested_in_run_from_the_panel() {
    let mut app = lab_panel(|t| t);
    wait_for_fault_on_lcd(&mut app, FaultCode::Sto, "sto");
}

#[test]
fn ss1_ends_in_sto_from_the_panel() {
    let mut app = lab_panel(|t| t);
    wait_for_fault_on_lcd(&mut app, FaultCode::Ss1, "ss1_lab");
}

#[test]
fn ramp_violated_from_the_panel() {
    let mut app = lab_panel(|t| t);
    wait_for_fault_on_lcd(&mut app, FaultCode::Ramp, "sls_no_decel");
}

#[test]
fn standstill_lost_from_the_panel() {
    let mut app = lab_panel(|t| t);
    wait_for_fault_on_lcd(&mut app, FaultCode::Sos, "sos_speed");
}

#[test]
fn over_the_sls_limit_from_the_panel() {
    let mut app = lab_panel(|t| t);
    wait_for_fault_on_lcd(&mut app, FaultCode::Sls, "sls1");
}

#[test]
fn sli_turns_exceeded_from_the_panel() {
    let mut app = lab_panel(|t| t);
    wait_for_fault_on_lcd(&mut app, FaultCode::Sli, "sli_running");
}

#[test]
fn wrong_direction_from_the_panel() {
    let mut app = lab_panel(|t| t);
    wait_for_fault_on_lcd(&mut app, FaultCode::Sdi, "sdp");
}

#[test]
fn over_the_sla_limit_from_the_panel() {
    // The forward acceleration limit only (as the hil-sim test of sla_accel).
    let mut app = lab_panel(|t| {
        t.replace("043 aap K34 2000", "043 aap K34 0100")
            .replace("044 adp K35 2000", "044 adp K35 9999")
            .replace("045 aan K36 2000", "045 aan K36 9999")
            .replace("046 adn K37 2000", "046 adn K37 9999")
    });
    wait_for_fault_on_lcd(&mut app, FaultCode::Sla, "sla_accel");
}

/// Named as in `panel_faults.rs`, whose guard test looks for one call per fault code.
fn wait_for_fault_on_lcd(app: &mut PanelApp, code: FaultCode, scenario: &str) {
    caused_and_cleared(app, scenario, code);
}
