//! The safety functions' vocabulary (safety.md), one copy for both images and hil-sim:
//! the twelve functions and their mask bits, the 24 drive-section settings in signature
//! order, the parameter signature and the needed-settings rule.
//!
//! **NOT RATED**: these functions monitor the *commanded* motion of a single-channel,
//! encoder-less drive (safety.md 1). They are no safety functions in the sense of
//! IEC 61800-5-2, ISO 13849 or IEC 62061.

/// The monitoring functions; the discriminant is the function's bit in every mask (the
/// link's `SafetyRequest`, the status, hil-sim's CSV).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[repr(u8)]
pub enum SafetyFunction {
    Sto = 0,
    Ss1 = 1,
    Ss2 = 2,
    Sos = 3,
    Sl1 = 4,
    Sl2 = 5,
    Sl3 = 6,
    Sl4 = 7,
    Sli = 8,
    Sdp = 9,
    Sdn = 10,
    Sla = 11,
}

/// Every mask bit a function uses (bits 12-15 are never set).
pub const FUNCTION_MASK: u16 = 0x0FFF;

impl SafetyFunction {
    /// In bit order (the order the monitor evaluates them, safety.md 3.1).
    pub const ALL: [SafetyFunction; 12] = [
        SafetyFunction::Sto,
        SafetyFunction::Ss1,
        SafetyFunction::Ss2,
        SafetyFunction::Sos,
        SafetyFunction::Sl1,
        SafetyFunction::Sl2,
        SafetyFunction::Sl3,
        SafetyFunction::Sl4,
        SafetyFunction::Sli,
        SafetyFunction::Sdp,
        SafetyFunction::Sdn,
        SafetyFunction::Sla,
    ];

    /// The function's bit number.
    pub const fn bit(self) -> u8 {
        self as u8
    }

    /// The function's mask (`1 << bit`).
    pub const fn mask(self) -> u16 {
        1 << (self as u8)
    }

    /// The `SFR` operand and LCD name (safety.md 2).
    pub const fn name(self) -> &'static str {
        match self {
            SafetyFunction::Sto => "STO",
            SafetyFunction::Ss1 => "SS1",
            SafetyFunction::Ss2 => "SS2",
            SafetyFunction::Sos => "SOS",
            SafetyFunction::Sl1 => "SL1",
            SafetyFunction::Sl2 => "SL2",
            SafetyFunction::Sl3 => "SL3",
            SafetyFunction::Sl4 => "SL4",
            SafetyFunction::Sli => "SLI",
            SafetyFunction::Sdp => "SDP",
            SafetyFunction::Sdn => "SDN",
            SafetyFunction::Sla => "SLA",
        }
    }

    /// The function with this bit number, [`SafetyFunction::Sla`] above 11 (for the
    /// operand tables, which check the range themselves).
    pub const fn from_bit_saturating(bit: u8) -> SafetyFunction {
        match bit {
            0 => SafetyFunction::Sto,
            1 => SafetyFunction::Ss1,
            2 => SafetyFunction::Ss2,
            3 => SafetyFunction::Sos,
            4 => SafetyFunction::Sl1,
            5 => SafetyFunction::Sl2,
            6 => SafetyFunction::Sl3,
            7 => SafetyFunction::Sl4,
            8 => SafetyFunction::Sli,
            9 => SafetyFunction::Sdp,
            10 => SafetyFunction::Sdn,
            _ => SafetyFunction::Sla,
        }
    }

    /// The function with this bit number.
    pub fn from_bit(bit: u8) -> Option<SafetyFunction> {
        SafetyFunction::ALL.get(usize::from(bit)).copied()
    }

    /// The settings this function needs, in the order safety.md 4 names them (the
    /// verifier reports the first one missing). SS1 needs `fss` only when the early
    /// limit (`tel`) or ramp monitoring (`ard`) is on: `ss1_needs_fss`.
    pub const fn needed(self, ss1_needs_fss: bool) -> &'static [SafetySetting] {
        use SafetySetting as S;
        match self {
            SafetyFunction::Sto => &[],
            SafetyFunction::Ss1 if ss1_needs_fss => &[S::Ts1, S::Fss],
            SafetyFunction::Ss1 => &[S::Ts1],
            SafetyFunction::Ss2 => &[S::Ts2, S::Fss, S::Pss],
            SafetyFunction::Sos => &[S::Fss, S::Pss],
            SafetyFunction::Sl1 => &[S::Fl1, S::Tl1],
            SafetyFunction::Sl2 => &[S::Fl2, S::Tl2],
            SafetyFunction::Sl3 => &[S::Fl3, S::Tl3],
            SafetyFunction::Sl4 => &[S::Fl4, S::Tl4],
            SafetyFunction::Sli => &[S::Fss, S::Pli],
            SafetyFunction::Sdp | SafetyFunction::Sdn => &[S::Pss],
            SafetyFunction::Sla => &[S::Fss, S::Aap, S::Adp, S::Aan, S::Adn],
        }
    }
}

/// The drive-section safety settings (safety.md 4); the discriminant is the position in
/// the signature (safety.md 8) and in [`SafetySettings`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[repr(u8)]
pub enum SafetySetting {
    /// Standstill speed tolerance, 0.1 Hz.
    Fss = 0,
    /// Standstill position tolerance (SOS, SS2, SDI), turns.
    Pss,
    /// Ramp monitoring enable delay, 0.1 s.
    Trd,
    /// Ramp monitoring deceleration limit, 0.1 Hz/s (0 = off).
    Ard,
    /// Early limit monitoring time, 0.1 s (0 = off).
    Tel,
    /// SS1 / SS2 ramp monitoring time, 0.1 s.
    Ts1,
    Ts2,
    /// SLS1-4 speed limits, 0.1 Hz.
    Fl1,
    Fl2,
    Fl3,
    Fl4,
    /// SLS1-4 ramp monitoring times, 0.1 s.
    Tl1,
    Tl2,
    Tl3,
    Tl4,
    /// SLI position limit, turns.
    Pli,
    /// SLI disable delay, 0.1 s.
    Tli,
    /// SDI enable delay, 0.1 s.
    Tdi,
    /// SLA limits, 0.1 Hz/s: accelerating / decelerating forward, accelerating /
    /// decelerating reverse.
    Aap,
    Adp,
    Aan,
    Adn,
    /// SLA enable delay, 0.1 s.
    Tla,
    /// Drive-controlled stop ramp for SS1/SS2, 0.1 Hz/s (0 = off).
    Asr,
}

/// Number of safety settings.
pub const SETTINGS: usize = 24;

impl SafetySetting {
    /// In signature order.
    pub const ALL: [SafetySetting; SETTINGS] = [
        SafetySetting::Fss,
        SafetySetting::Pss,
        SafetySetting::Trd,
        SafetySetting::Ard,
        SafetySetting::Tel,
        SafetySetting::Ts1,
        SafetySetting::Ts2,
        SafetySetting::Fl1,
        SafetySetting::Fl2,
        SafetySetting::Fl3,
        SafetySetting::Fl4,
        SafetySetting::Tl1,
        SafetySetting::Tl2,
        SafetySetting::Tl3,
        SafetySetting::Tl4,
        SafetySetting::Pli,
        SafetySetting::Tli,
        SafetySetting::Tdi,
        SafetySetting::Aap,
        SafetySetting::Adp,
        SafetySetting::Aan,
        SafetySetting::Adn,
        SafetySetting::Tla,
        SafetySetting::Asr,
    ];

    /// Position in signature order.
    pub const fn index(self) -> usize {
        self as usize
    }

    /// The drive-section mnemonic (lower case, as safety.md 4 writes it).
    pub const fn text(self) -> &'static str {
        match self {
            SafetySetting::Fss => "fss",
            SafetySetting::Pss => "pss",
            SafetySetting::Trd => "trd",
            SafetySetting::Ard => "ard",
            SafetySetting::Tel => "tel",
            SafetySetting::Ts1 => "ts1",
            SafetySetting::Ts2 => "ts2",
            SafetySetting::Fl1 => "fl1",
            SafetySetting::Fl2 => "fl2",
            SafetySetting::Fl3 => "fl3",
            SafetySetting::Fl4 => "fl4",
            SafetySetting::Tl1 => "tl1",
            SafetySetting::Tl2 => "tl2",
            SafetySetting::Tl3 => "tl3",
            SafetySetting::Tl4 => "tl4",
            SafetySetting::Pli => "pli",
            SafetySetting::Tli => "tli",
            SafetySetting::Tdi => "tdi",
            SafetySetting::Aap => "aap",
            SafetySetting::Adp => "adp",
            SafetySetting::Aan => "aan",
            SafetySetting::Adn => "adn",
            SafetySetting::Tla => "tla",
            SafetySetting::Asr => "asr",
        }
    }
}

/// The raw value of an absent setting (also its value in the signature).
pub const ABSENT: u16 = 0xFFFF;

/// The 24 settings of one drive section, as written (0..=9999, or [`ABSENT`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SafetySettings {
    raw: [u16; SETTINGS],
}

impl Default for SafetySettings {
    fn default() -> Self {
        SafetySettings {
            raw: [ABSENT; SETTINGS],
        }
    }
}

impl SafetySettings {
    /// The setting as written, `None` when absent.
    pub fn get(&self, s: SafetySetting) -> Option<u16> {
        match self.raw.get(s.index()).copied() {
            Some(ABSENT) | None => None,
            v => v,
        }
    }

    /// The setting, 0 when absent: what the monitor uses (safety.md 4's "absent" column
    /// is 0 for every optional setting; a needed one that is absent is refused by the
    /// verifier, and should a request reach the drive anyway, 0 is the strictest value).
    pub fn or_zero(&self, s: SafetySetting) -> u16 {
        self.get(s).unwrap_or(0)
    }

    /// Set one setting (`None` = absent). Values above 9999 are stored as written: the
    /// verifier keeps them out of programs (the constant column has 4 digits).
    pub fn set(&mut self, s: SafetySetting, value: Option<u16>) {
        if let Some(r) = self.raw.get_mut(s.index()) {
            *r = value.unwrap_or(ABSENT);
        }
    }

    /// Any setting present (the program shows its signature, safety.md 8).
    pub fn any(&self) -> bool {
        self.raw.iter().any(|&r| r != ABSENT)
    }

    /// The parameter signature (safety.md 8): CRC-16/IBM-3740 over 2 bytes per setting,
    /// big-endian, 0xFFFF when absent, in [`SafetySetting::ALL`] order.
    pub fn signature(&self) -> u16 {
        crate::crc16::of_be_words(&self.raw)
    }

    /// Does SS1 need `fss` (early limit or ramp monitoring on)?
    pub fn ss1_needs_fss(&self) -> bool {
        self.or_zero(SafetySetting::Tel) > 0 || self.or_zero(SafetySetting::Ard) > 0
    }

    /// The first needed setting `f` lacks (safety.md 4), `None` when it has them all.
    pub fn missing_for(&self, f: SafetyFunction) -> Option<SafetySetting> {
        f.needed(self.ss1_needs_fss())
            .iter()
            .copied()
            .find(|&s| self.get(s).is_none())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::crc16::IBM_3740 as SIGNATURE_CRC;

    #[test]
    fn the_signature_crc_is_ibm_3740() {
        assert_eq!(SIGNATURE_CRC.checksum(b"123456789"), 0x29B1);
        // All absent: 48 bytes of 0xFF.
        assert_eq!(
            SafetySettings::default().signature(),
            SIGNATURE_CRC.checksum(&[0xFF; 48])
        );
    }

    #[test]
    fn any_one_change_changes_the_signature() {
        let mut s = SafetySettings::default();
        for (i, k) in SafetySetting::ALL.into_iter().enumerate() {
            s.set(k, Some(i as u16 * 100));
        }
        let base = s.signature();
        for k in SafetySetting::ALL {
            let v = s.get(k).unwrap_or(0);
            for w in [Some(v + 1), Some(v.wrapping_sub(1).min(9999)), None] {
                let mut t = s;
                t.set(k, w);
                assert_ne!(t.signature(), base, "{k:?} -> {w:?}");
            }
        }
        // Big-endian pairs in signature order: the first setting leads.
        let mut one = SafetySettings::default();
        one.set(SafetySetting::Fss, Some(0x0102));
        let mut bytes = [0xFFu8; 48];
        bytes[0] = 1;
        bytes[1] = 2;
        assert_eq!(one.signature(), SIGNATURE_CRC.checksum(&bytes));
    }

    #[test]
    fn functions_and_settings_are_in_bit_and_signature_order() {
        for (i, f) in SafetyFunction::ALL.into_iter().enumerate() {
            assert_eq!(usize::from(f.bit()), i);
            assert_eq!(SafetyFunction::from_bit(f.bit()), Some(f));
            assert_eq!(f.mask() & FUNCTION_MASK, f.mask());
        }
        assert_eq!(SafetyFunction::from_bit(12), None);
        for (i, s) in SafetySetting::ALL.into_iter().enumerate() {
            assert_eq!(s.index(), i);
        }
        let texts: Vec<_> = SafetySetting::ALL.iter().map(|s| s.text()).collect();
        assert_eq!(
            texts.join(" "),
            "fss pss trd ard tel ts1 ts2 fl1 fl2 fl3 fl4 tl1 tl2 tl3 tl4 pli tli tdi \
             aap adp aan adn tla asr"
        );
        let names: Vec<_> = SafetyFunction::ALL.iter().map(|f| f.name()).collect();
        assert_eq!(
            names.join(" "),
            "STO SS1 SS2 SOS SL1 SL2 SL3 SL4 SLI SDP SDN SLA"
        );
    }

    #[test]
    fn needed_settings_name_the_first_missing_in_spec_order() {
        use SafetyFunction as F;
        use SafetySetting as S;
        let none = SafetySettings::default();
        let firsts: Vec<_> = F::ALL.iter().map(|&f| none.missing_for(f)).collect();
        assert_eq!(
            firsts,
            [
                None,
                Some(S::Ts1),
                Some(S::Ts2),
                Some(S::Fss),
                Some(S::Fl1),
                Some(S::Fl2),
                Some(S::Fl3),
                Some(S::Fl4),
                Some(S::Fss),
                Some(S::Pss),
                Some(S::Pss),
                Some(S::Fss)
            ]
        );
        let mut s = SafetySettings::default();
        s.set(S::Ts1, Some(100));
        assert_eq!(s.missing_for(F::Ss1), None);
        // The early limit makes SS1 need fss; `tel` 0 counts as off.
        s.set(S::Tel, Some(0));
        assert_eq!(s.missing_for(F::Ss1), None);
        s.set(S::Tel, Some(50));
        assert_eq!(s.missing_for(F::Ss1), Some(S::Fss));
        s.set(S::Tel, None);
        s.set(S::Ard, Some(1));
        assert_eq!(s.missing_for(F::Ss1), Some(S::Fss));
        s.set(S::Fss, Some(40));
        assert_eq!(s.missing_for(F::Ss1), None);
        // SLA: the limits in the order aap adp aan adn.
        for (k, next) in [
            (S::Aap, Some(S::Adp)),
            (S::Adp, Some(S::Aan)),
            (S::Aan, Some(S::Adn)),
            (S::Adn, None),
        ] {
            s.set(k, Some(2000));
            assert_eq!(s.missing_for(F::Sla), next);
        }
    }
}
