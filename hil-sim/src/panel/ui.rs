//! Drawing the panel: LCD, keypad with its key map, and the rig beside them.

use super::app::{Modal, PanelApp, QuitLoss};
use super::keys::{ANALOG_KEYS, BANK_KEY, BANK_SIZE, DIGITAL_KEYS};
use firmware_plc::editor::{Key, Screen};
use ratatui::layout::{Constraint, Layout, Rect};
use ratatui::style::{Color, Modifier, Style};
use ratatui::text::{Line, Span};
use ratatui::widgets::{Block, Paragraph};
use ratatui::Frame;
use shared_protocol::fault::fault_text;
use shared_protocol::program::{DIGITAL_INPUTS, DIGITAL_OUTPUTS};

const LCD_BG: Color = Color::Rgb(150, 190, 70);
const LCD_FG: Color = Color::Rgb(20, 30, 10);
/// Half period of the blinking cursor.
const BLINK_MS: u64 = 400;

/// The smallest terminal that shows the whole panel (LCD, keypad, key box, rig);
/// below it the panel says so instead of clipping.
pub const MIN_WIDTH: u16 = 90;
pub const MIN_HEIGHT: u16 = 29;

/// Key map lines shown under the keypad (the PC key in brackets where it differs), then
/// the rig's keys.
const KEYMAP: [&str; 20] = [
    "2/8 up/down   4/6 field   5 edit/ok",
    "1/7 -+10 lines 3/9 -+100  0 next used",
    "A RUN/STOP   B next page",
    "C n save slot n   D n load, D 0 new",
    "# nnn go to line  * cancel edit",
    "*1 insert *3 delete *0 clear *5 check",
    "*9 acknowledge the drive's fault",
    "editing: 2/8 value, 1/7 -+10,",
    "  3/9 operand area, 4/6 field/digit",
    "PC: arrows=2/4/6/8 Enter=5 PgUp/Dn=1/7",
    "Esc cancel edit/command (*), else quit",
    "Ctrl-E: export the program to .plc",
    "-- rig --",
    "[ ] supply -/+1 V    { } -/+5 V",
    ", . load -/+0.01 Nm  < > -/+0.05 Nm",
    "l locked rotor   s link cut/restore",
    "h current spike (OC_HW)  H Udc (OV_HW)",
    "f sensor offset fault  g garble download",
    "V drive power cycle  G drive watchdog",
    "q..i F1-F8 inputs  z/x n/m j/k o/p pots",
];

fn lcd_lines(s: &Screen, blink_on: bool) -> Vec<Line<'static>> {
    let base = Style::default().fg(LCD_FG).bg(LCD_BG);
    (0..s.rows())
        .map(|r| {
            let text = s.row(r);
            let spans: Vec<Span<'static>> = text
                .chars()
                .enumerate()
                .map(|(c, ch)| {
                    let at_cursor = s.cursor == Some((r, c as u8));
                    let style = match (at_cursor, s.blink) {
                        (true, true) if blink_on => base.add_modifier(Modifier::REVERSED),
                        (true, false) => base.add_modifier(Modifier::UNDERLINED),
                        _ => base,
                    };
                    Span::styled(ch.to_string(), style)
                })
                .collect();
            Line::from(spans)
        })
        .collect()
}

fn keypad_lines(last: Option<Key>) -> Vec<Line<'static>> {
    Key::ALL
        .chunks(4)
        .map(|row| {
            let spans: Vec<Span<'static>> = row
                .iter()
                .map(|k| {
                    let style = if Some(*k) == last {
                        Style::default().add_modifier(Modifier::REVERSED | Modifier::BOLD)
                    } else if matches!(k, Key::Digit(_)) {
                        Style::default().add_modifier(Modifier::BOLD)
                    } else {
                        Style::default()
                            .fg(Color::Yellow)
                            .add_modifier(Modifier::BOLD)
                    };
                    Span::styled(format!("[{}]", k.to_char()), style)
                })
                .collect();
            Line::from(spans)
        })
        .collect()
}

fn on_off(on: bool) -> Span<'static> {
    if on {
        Span::styled("1", Style::default().fg(Color::Black).bg(Color::Green))
    } else {
        Span::styled("0", Style::default().fg(Color::DarkGray))
    }
}

fn rig_lines(app: &PanelApp) -> Vec<Line<'static>> {
    let s = app.status();
    let mut v = Vec::new();
    v.push(Line::from(format!("t = {:.1} s", s.t_s)));
    v.push(Line::from(format!(
        "PLC {}   drive {}",
        if s.plc_running { "RUN" } else { "STOP" },
        s.drive_state
    )));
    v.push(Line::from(format!(
        "f {:5.1} Hz {} (set {:5.1} Hz)",
        s.f_hz,
        if s.reverse { "REV" } else { "FWD" },
        s.f_set_hz
    )));
    v.push(Line::from(vec![
        Span::raw("outputs "),
        if s.pwm_on {
            Span::styled("ON", Style::default().fg(Color::Black).bg(Color::Green))
        } else {
            Span::raw("off")
        },
        Span::raw(format!(
            "  brake {}  speed {:5.0} rpm",
            if s.brake { "ON" } else { "off" },
            s.speed_rpm
        )),
    ]));
    v.push(Line::from(format!(
        "Udc {:5.1} V  Irms {:5.2} A  T {:6.3} Nm",
        s.u_dc_v, s.i_rms_a, s.torque_nm
    )));
    let fault = if s.fault == 0 {
        Span::raw("fault: none")
    } else {
        Span::styled(
            format!("fault: F{} {}", s.fault, fault_text(s.fault)),
            Style::default().fg(Color::Red).add_modifier(Modifier::BOLD),
        )
    };
    v.push(Line::from(fault));
    let l = s.limits;
    // 0 = not set by the program (no check).
    let lim = |x: f64, decimals: usize| {
        if x > 0.0 {
            format!("{x:.decimals$}")
        } else {
            "off".to_string()
        }
    };
    v.push(Line::from(Span::styled(
        format!(
            "limits U< {} U> {} I> {}  U>> {:.0} I>> {:.2}",
            lim(l.u_min_v, 0),
            lim(l.u_max_v, 0),
            lim(l.i_max_a, 2),
            l.ov_hw_v,
            l.oc_hw_a
        ),
        Style::default().fg(Color::DarkGray),
    )));
    let flag = |on: bool, text: &'static str| {
        if on {
            Span::styled(text, Style::default().fg(Color::Black).bg(Color::Yellow))
        } else {
            Span::styled(text, Style::default().fg(Color::DarkGray))
        }
    };
    v.push(Line::from(format!(
        "supply {:4.1} V   load {:5.3} Nm",
        s.supply_v, s.load_nm
    )));
    v.push(Line::from(vec![
        flag(s.locked_rotor, "LOCKED ROTOR"),
        Span::raw(" "),
        flag(s.link_cut, "LINK CUT"),
        Span::raw(" "),
        flag(s.sensor_offset != 0, "SENSOR FAULT"),
        Span::raw(" "),
        flag(s.garble_download, "GARBLE DL"),
    ]));
    v.push(Line::from(Span::styled(
        match app.backend().eeprom_file() {
            Some(p) => format!("EEPROM file {}", p.display()),
            None => "EEPROM in memory (--eeprom FILE keeps it)".to_string(),
        },
        Style::default().fg(Color::DarkGray),
    )));
    for first in (0..DIGITAL_INPUTS).step_by(usize::from(BANK_SIZE)) {
        let last = (first + BANK_SIZE).min(DIGITAL_INPUTS) - 1;
        let active = first / BANK_SIZE == app.bank();
        let mut d = vec![Span::raw(format!(
            "{}D{first:02}-{last:02} ",
            if active { ">" } else { " " }
        ))];
        for n in first..=last {
            d.push(on_off(s.digital_in & (1 << n) != 0));
            d.push(Span::raw(" "));
        }
        v.push(Line::from(d));
    }
    let keys: String = DIGITAL_KEYS.iter().map(|c| format!("{c} ")).collect();
    v.push(Line::from(Span::styled(
        format!("  keys {keys}(Q..I: push 0.2 s, {BANK_KEY}: bank)"),
        Style::default().fg(Color::DarkGray),
    )));
    let mut o = vec![Span::raw(format!(" O00-{:02} ", DIGITAL_OUTPUTS - 1))];
    for n in 0..DIGITAL_OUTPUTS {
        o.push(on_off(s.digital_out & (1 << n) != 0));
        o.push(Span::raw(" "));
    }
    v.push(Line::from(o));
    if let Some(l) = s.lift {
        // The lift (lift.md 4): car, floor, door, brake, vanes; calls are the D keys.
        v.push(Line::from(format!(
            "LIFT car {:7.1} mm {:6.1} mm/s floor {}",
            l.car_mm,
            l.car_mms,
            if l.at_floor == 0 {
                "-".to_string()
            } else {
                l.at_floor.to_string()
            }
        )));
        v.push(Line::from(format!(
            "     door {:3.0} % {} brake {} vanes {}{} chain {}",
            100.0 * l.door,
            if l.door_closed { "closed" } else { "open  " },
            if l.brake_engaged { "on " } else { "off" },
            if l.vane_l { 'L' } else { '.' },
            if l.vane_r { 'R' } else { '.' },
            if l.chain_closed { "ok" } else { "OPEN" }
        )));
        v.push(Line::from(Span::styled(
            "     calls: Q W E R car 1-4, T Y U I hall 1u 2u 2d 3u (` bank: 3d 4d)",
            Style::default().fg(Color::DarkGray),
        )));
    }
    v.push(Line::from(""));
    for (n, (down, up)) in ANALOG_KEYS.iter().enumerate() {
        v.push(Line::from(vec![
            Span::raw(format!("A{n:02} {:4}  ", s.analog[n])),
            Span::styled(
                format!(
                    "{down}/{up} -/+32, {}/{} -/+128",
                    down.to_ascii_uppercase(),
                    up.to_ascii_uppercase()
                ),
                Style::default().fg(Color::DarkGray),
            ),
        ]));
    }
    v
}

/// Draw the whole panel, or, in a terminal too small for it, one message saying so.
pub fn draw(frame: &mut Frame<'_>, app: &PanelApp) {
    let area = frame.area();
    if area.width < MIN_WIDTH || area.height < MIN_HEIGHT {
        let text = format!(
            "Terminal too small ({}x{}): the panel needs {}x{}. Enlarge the window (Esc quits).",
            area.width, area.height, MIN_WIDTH, MIN_HEIGHT
        );
        let y = area.height / 2;
        frame.render_widget(
            Paragraph::new(text)
                .wrap(ratatui::widgets::Wrap { trim: true })
                .style(
                    Style::default()
                        .fg(Color::Yellow)
                        .add_modifier(Modifier::BOLD),
                ),
            Rect {
                y: area.y + y.saturating_sub(1),
                height: area.height - y.saturating_sub(1),
                ..area
            },
        );
        return;
    }
    let [main, footer] = Layout::vertical([Constraint::Min(10), Constraint::Length(1)]).areas(area);
    let [left, right] =
        Layout::horizontal([Constraint::Length(42), Constraint::Min(30)]).areas(main);
    let lcd = app.lcd();
    let lcd_h = u16::from(lcd.rows()) + 2;
    let [top_area, map_area] =
        Layout::vertical([Constraint::Length(lcd_h.max(6)), Constraint::Min(3)]).areas(left);
    let lcd_w = u16::from(lcd.cols()) + 2;
    let [lcd_area, pad_area] =
        Layout::horizontal([Constraint::Length(lcd_w + 1), Constraint::Min(14)]).areas(top_area);
    let lcd_rect = Rect {
        width: lcd_w.min(lcd_area.width),
        height: lcd_h.min(lcd_area.height),
        ..lcd_area
    };
    let blink_on = (app.blink_ms / BLINK_MS).is_multiple_of(2);
    frame.render_widget(
        Paragraph::new(lcd_lines(&lcd, blink_on)).block(Block::bordered().title("LCD")),
        lcd_rect,
    );
    frame.render_widget(
        Paragraph::new(keypad_lines(app.last_key)).block(Block::bordered().title("Keypad")),
        Rect {
            width: 14.min(pad_area.width),
            height: 6.min(pad_area.height),
            ..pad_area
        },
    );
    let map: Vec<Line<'static>> = KEYMAP.iter().map(|l| Line::from(*l)).collect();
    frame.render_widget(
        Paragraph::new(map).block(Block::bordered().title("Key map")),
        map_area,
    );
    frame.render_widget(
        Paragraph::new(rig_lines(app)).block(Block::bordered().title("Rig")),
        right,
    );
    frame.render_widget(Paragraph::new(footer_line(app)), footer);
}

/// The bottom line: the question being asked, else the panel's last message, else help.
fn footer_line(app: &PanelApp) -> Line<'static> {
    let ask = Style::default()
        .fg(Color::Black)
        .bg(Color::Yellow)
        .add_modifier(Modifier::BOLD);
    match &app.modal {
        Some(Modal::ConfirmQuit(loss)) => Line::from(Span::styled(
            match loss {
                QuitLoss::UnsavedProgram => {
                    " The program has unsaved changes (C n saves it). Quit anyway? y/n "
                }
                QuitLoss::SavedSlots => {
                    " Saved slots are lost: no --eeprom FILE (Ctrl-E exports). Quit anyway? y/n "
                }
                QuitLoss::Both => {
                    " Unsaved changes, and saved slots without --eeprom FILE. Quit anyway? y/n "
                }
            },
            ask,
        )),
        Some(Modal::Export { name, overwrite }) => {
            let text = if *overwrite {
                format!(" {name} exists: Enter overwrites it, Backspace edits, Esc cancels ")
            } else {
                format!(" Export the program to: {name}_  (Enter writes, Esc cancels) ")
            };
            Line::from(Span::styled(text, ask))
        }
        None => match (&app.notice, &app.backend().persist_error) {
            (_, Some(e)) => Line::from(Span::styled(
                format!(" {e}"),
                Style::default().fg(Color::Red).add_modifier(Modifier::BOLD),
            )),
            (Some(n), None) => Line::from(Span::styled(
                format!(" {n}"),
                Style::default().fg(Color::Cyan),
            )),
            (None, None) => Line::from(Span::styled(
                " Esc quits | keypad 0-9 a-d * # | inputs q..i F1-F8 | pots z/x n/m j/k o/p",
                Style::default().fg(Color::DarkGray),
            )),
        },
    }
}
