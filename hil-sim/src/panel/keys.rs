//! The PC keyboard as keypad, switches and pots.

use firmware_plc::editor::Key;
use ratatui::crossterm::event::{KeyCode, KeyEvent, KeyModifiers};

/// What a PC key does on the panel.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Input {
    Keypad(Key),
    /// Toggle digital input Dn.
    Toggle(u8),
    /// Press Dn like a push button (on for [`PULSE_MS`], then off).
    Pulse(u8),
    /// Move analog input An by the given counts.
    Analog(u8, i16),
    /// Esc: cancels what the editor waits for (an edit, a two-key command, a question:
    /// sends `*`), else quits (asking first when the program is unsaved).
    Esc,
    /// Ctrl-C: quit (asking first when the program is unsaved).
    Quit,
    /// Ctrl-E: export the program in RAM to a `.plc` file (asks for the name).
    Export,
}

/// A key while the panel asks something (quit? file name?): typed text and answers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TextKey {
    Char(char),
    Backspace,
    Enter,
    Esc,
}

/// The PC key as an answer to the panel's question, if it is one.
pub fn map_text_key(ev: KeyEvent) -> Option<TextKey> {
    let ctrl = ev.modifiers.contains(KeyModifiers::CONTROL);
    Some(match ev.code {
        KeyCode::Char('c') if ctrl => TextKey::Esc,
        KeyCode::Char(c) if !ctrl => TextKey::Char(c),
        KeyCode::Backspace => TextKey::Backspace,
        KeyCode::Enter => TextKey::Enter,
        KeyCode::Esc => TextKey::Esc,
        _ => return None,
    })
}

/// How long a push-button press lasts.
pub const PULSE_MS: u32 = 200;

/// Keys toggling (lower case) or pulsing (upper case) D00..D07.
pub const DIGITAL_KEYS: [char; 8] = ['q', 'w', 'e', 'r', 't', 'y', 'u', 'i'];
/// (down, up) keys of A00..A03.
pub const ANALOG_KEYS: [(char, char); 4] = [('z', 'x'), ('n', 'm'), ('j', 'k'), ('o', 'p')];
/// Counts per analog key press (upper case: 4 times as much).
pub const ANALOG_STEP: i16 = 32;

/// The panel action of a PC key, if any.
pub fn map_key(ev: KeyEvent) -> Option<Input> {
    let ctrl = ev.modifiers.contains(KeyModifiers::CONTROL);
    Some(match ev.code {
        KeyCode::Char('c') if ctrl => Input::Quit,
        KeyCode::Char('e') if ctrl => Input::Export,
        KeyCode::Char(_) if ctrl => return None,
        KeyCode::Esc => Input::Esc,
        KeyCode::Up => Input::Keypad(Key::Digit(2)),
        KeyCode::Down => Input::Keypad(Key::Digit(8)),
        KeyCode::Left => Input::Keypad(Key::Digit(4)),
        KeyCode::Right => Input::Keypad(Key::Digit(6)),
        KeyCode::Enter => Input::Keypad(Key::Digit(5)),
        KeyCode::PageUp => Input::Keypad(Key::Digit(1)),
        KeyCode::PageDown => Input::Keypad(Key::Digit(7)),
        KeyCode::F(n) if (1..=8).contains(&n) => Input::Toggle(n - 1),
        KeyCode::Char(c) => return map_char(c),
        _ => return None,
    })
}

/// The panel action of a typed character.
pub fn map_char(c: char) -> Option<Input> {
    if let Some(k) = Key::from_char(c) {
        return Some(Input::Keypad(k));
    }
    if let Some(n) = DIGITAL_KEYS.iter().position(|&d| d == c) {
        return Some(Input::Toggle(n as u8));
    }
    if let Some(n) = DIGITAL_KEYS
        .iter()
        .position(|&d| d.to_ascii_uppercase() == c)
    {
        return Some(Input::Pulse(n as u8));
    }
    for (n, (down, up)) in ANALOG_KEYS.iter().enumerate() {
        let step = if c.is_ascii_uppercase() {
            4 * ANALOG_STEP
        } else {
            ANALOG_STEP
        };
        let lc = c.to_ascii_lowercase();
        if lc == *down {
            return Some(Input::Analog(n as u8, -step));
        }
        if lc == *up {
            return Some(Input::Analog(n as u8, step));
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mapping_has_no_clashes() {
        assert_eq!(map_char('a'), Some(Input::Keypad(Key::A)));
        assert_eq!(map_char('D'), Some(Input::Keypad(Key::D)));
        assert_eq!(map_char('#'), Some(Input::Keypad(Key::Hash)));
        assert_eq!(map_char('q'), Some(Input::Toggle(0)));
        assert_eq!(map_char('W'), Some(Input::Pulse(1)));
        assert_eq!(map_char('x'), Some(Input::Analog(0, 32)));
        assert_eq!(map_char('M'), Some(Input::Analog(1, 128)));
        assert_eq!(map_char('g'), None);
    }
}
