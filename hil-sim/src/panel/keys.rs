//! The PC keyboard as keypad, switches and pots.

use firmware_plc::editor::Key;
use ratatui::crossterm::event::{KeyCode, KeyEvent, KeyModifiers};

/// What a PC key does on the panel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Input {
    Keypad(Key),
    /// Toggle the n-th digital input of the selected bank (D00-D07 or D08-D15).
    Toggle(u8),
    /// Press the n-th input of the selected bank like a push button (on for
    /// [`PULSE_MS`], then off).
    Pulse(u8),
    /// Switch the digital keys between D00-D07 and D08-D15 ([`BANK_KEY`]).
    Bank,
    /// Move analog input An by the given counts.
    Analog(u8, i16),
    /// Esc: cancels what the editor waits for (an edit, a two-key command, a question:
    /// sends `*`), else quits (asking first when the program is unsaved).
    Esc,
    /// Ctrl-C: quit (asking first when the program is unsaved).
    Quit,
    /// Ctrl-E: export the program in RAM to a `.plc` file (asks for the name).
    Export,
    /// A change to the rig behind the drive.
    Rig(RigAction),
}

/// What the panel does to the rig (the plant, the wires, the drive board).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RigAction {
    /// DC-link supply voltage up/down by this many volts.
    SupplyV(f64),
    /// Load torque up/down by this many N m.
    LoadNm(f64),
    LockedRotor,
    /// Cut the UART wires, or restore them.
    Link,
    /// A phase-current spike the overcurrent comparator sees (OC_HW).
    CurrentSpike,
    /// A DC-link voltage spike the overvoltage comparator sees (OV_HW).
    VoltageSpike,
    /// Phase 1's current sensor offset on/off (BOOT at the next drive restart).
    SensorFault,
    /// Cycle the drive board's supply (restart; clears BOOT once the sensor is fine).
    PowerCycleDrive,
    /// The drive's watchdog resets it (WDG).
    WatchdogReset,
    /// Garble the next program download, or not (PROG).
    GarbleDownload,
}

/// The rig's keys: (character, action, what the key box says).
pub const RIG_KEYS: [(char, RigAction); 14] = [
    ('[', RigAction::SupplyV(-1.0)),
    (']', RigAction::SupplyV(1.0)),
    ('{', RigAction::SupplyV(-5.0)),
    ('}', RigAction::SupplyV(5.0)),
    (',', RigAction::LoadNm(-0.01)),
    ('.', RigAction::LoadNm(0.01)),
    ('<', RigAction::LoadNm(-0.05)),
    ('>', RigAction::LoadNm(0.05)),
    ('l', RigAction::LockedRotor),
    ('s', RigAction::Link),
    ('h', RigAction::CurrentSpike),
    ('H', RigAction::VoltageSpike),
    ('f', RigAction::SensorFault),
    ('g', RigAction::GarbleDownload),
];

/// Keys that restart the drive board (upper case only: not hit by accident).
pub const DRIVE_RESET_KEYS: [(char, RigAction); 2] = [
    ('V', RigAction::PowerCycleDrive),
    ('G', RigAction::WatchdogReset),
];

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

/// Keys toggling (lower case) or pulsing (upper case) the eight inputs of the selected
/// bank: D00..D07, or D08..D15 after [`BANK_KEY`].
pub const DIGITAL_KEYS: [char; 8] = ['q', 'w', 'e', 'r', 't', 'y', 'u', 'i'];
/// Inputs per bank of [`DIGITAL_KEYS`].
pub const BANK_SIZE: u8 = DIGITAL_KEYS.len() as u8;
/// Switches [`DIGITAL_KEYS`] (and F1-F8) between the banks D00-D07 and D08-D15.
pub const BANK_KEY: char = '`';
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
    if let Some((_, a)) = RIG_KEYS
        .iter()
        .chain(DRIVE_RESET_KEYS.iter())
        .find(|(k, _)| *k == c)
    {
        return Some(Input::Rig(*a));
    }
    if c == BANK_KEY {
        return Some(Input::Bank);
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
        assert_eq!(map_char('v'), None);
        assert_eq!(map_char('`'), Some(Input::Bank));
        assert_eq!(map_char('V'), Some(Input::Rig(RigAction::PowerCycleDrive)));
        assert_eq!(map_char(']'), Some(Input::Rig(RigAction::SupplyV(1.0))));
    }

    #[test]
    fn every_key_does_one_thing() {
        let mut all: Vec<char> = Vec::new();
        for c in "0123456789abcdABCD*#".chars() {
            all.push(c);
        }
        all.push(BANK_KEY);
        for d in DIGITAL_KEYS {
            all.push(d);
            all.push(d.to_ascii_uppercase());
        }
        for (d, u) in ANALOG_KEYS {
            all.extend([d, u, d.to_ascii_uppercase(), u.to_ascii_uppercase()]);
        }
        all.extend(
            RIG_KEYS
                .iter()
                .chain(DRIVE_RESET_KEYS.iter())
                .map(|(c, _)| *c),
        );
        let n = all.len();
        all.sort();
        all.dedup();
        assert_eq!(all.len(), n, "a key with two meanings");
    }
}
