//! The 4x4 keypad's keys.

/// One key of the 4x4 matrix keypad: `0`-`9`, `A` `B` `C` `D`, `*`, `#`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Key {
    /// `0`..=`9` (values above 9 are never produced by [`Key::from_char`]).
    Digit(u8),
    A,
    B,
    C,
    D,
    Star,
    Hash,
}

impl Key {
    /// The key printed as `c` (case-insensitive letters); `None` for anything else.
    pub fn from_char(c: char) -> Option<Key> {
        Some(match c.to_ascii_uppercase() {
            d @ '0'..='9' => Key::Digit(d as u8 - b'0'),
            'A' => Key::A,
            'B' => Key::B,
            'C' => Key::C,
            'D' => Key::D,
            '*' => Key::Star,
            '#' => Key::Hash,
            _ => return None,
        })
    }

    /// The character printed on the key.
    pub fn to_char(self) -> char {
        match self {
            Key::Digit(d) => char::from(b'0' + d.min(9)),
            Key::A => 'A',
            Key::B => 'B',
            Key::C => 'C',
            Key::D => 'D',
            Key::Star => '*',
            Key::Hash => '#',
        }
    }

    /// All 16 keys in keypad order (rows `123A`, `456B`, `789C`, `*0#D`).
    pub const ALL: [Key; 16] = [
        Key::Digit(1),
        Key::Digit(2),
        Key::Digit(3),
        Key::A,
        Key::Digit(4),
        Key::Digit(5),
        Key::Digit(6),
        Key::B,
        Key::Digit(7),
        Key::Digit(8),
        Key::Digit(9),
        Key::C,
        Key::Star,
        Key::Digit(0),
        Key::Hash,
        Key::D,
    ];
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chars_round_trip() {
        for k in Key::ALL {
            assert_eq!(Key::from_char(k.to_char()), Some(k));
        }
        assert_eq!(Key::from_char('a'), Some(Key::A));
        assert_eq!(Key::from_char('x'), None);
    }
}
