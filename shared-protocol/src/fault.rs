//! The drive's fault vocabulary, one copy for both images and hil-sim: the latched fault
//! codes (drive.md "Trips"), their names and texts, and the causes of the hardware break.
//!
//! The code is what `FLT` reads, what the fault log stores and what the link carries (one
//! byte, see `docs/link.md` "Fault codes on the wire").
//!
//! **One table.** `fault_table!` below is the only list of codes: it makes the enum,
//! [`FaultCode::ALL`], [`FaultCode::COUNT`], [`FaultCode::from_code`], the names, the texts
//! and the automatic-restart bits ([`FaultCode::restart_bit`]). Everything sized per code
//! follows [`FaultCode::COUNT`]: the PLC's trip counters
//! (`firmware_plc::storage::counters::TRIP_CODES`, its EEPROM record), the service's
//! [`crate::service::Trips`], plcctl's and hil-sim's texts (they call [`fault_name`] and
//! [`fault_text`]), and `docs/fault-codes.md` (a test walks the table against it). A new
//! code is one line here; what else it needs is in `docs/contributing/add-a-trip.md`.

use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// The table: `Variant = code, "NAME", "text", arc bit;` with the doc comment of the code.
/// Codes are consecutive from 1 (a test checks it), so that per-code arrays index
/// `code - 1`. `arc bit`: the bit of the drive section's `arc` setting that lets the code
/// restart by itself ([`FaultCode::restart_bit`]), 0 for a latched class; every code
/// states it, so that a new one is placed knowingly.
macro_rules! fault_table {
    ($($(#[$doc:meta])* $v:ident = $code:literal, $name:literal, $text:literal, arc $arc:literal;)+) => {
        /// Latched fault codes (drive.md table; `Boot` is this project's addition,
        /// drive.md's code 8; `Ov` is this project's, `docs/fault-codes.md`).
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
        #[cfg_attr(feature = "defmt", derive(defmt::Format))]
        #[repr(u8)]
        pub enum FaultCode {
            $($(#[$doc])* $v = $code,)+
        }

        impl FaultCode {
            /// Every code, in the order of their numbers (index `code - 1`).
            pub const ALL: [FaultCode; FaultCode::COUNT] = [$(FaultCode::$v,)+];

            /// How many codes this protocol version defines (the highest code).
            pub const COUNT: usize = [$($code,)+].len();

            /// The fault with this code; 0 ("no fault") and undefined codes are errors.
            pub const fn from_code(c: u8) -> Result<FaultCode, UnknownFaultCode> {
                match c {
                    $($code => Ok(FaultCode::$v),)+
                    _ => Err(UnknownFaultCode(c)),
                }
            }

            /// Short name (drive.md), for the fault log screen and hil-sim's reports.
            pub const fn name(self) -> &'static str {
                match self {
                    $(FaultCode::$v => $name,)+
                }
            }

            /// The text the LCD status line (`F2 overcurrent (HW)`), the fault log and
            /// hil-sim show. At most [`FAULT_TEXT_MAX`] characters, so that `Fnn text`
            /// fits one 20-column row. `link lost`, not `PLC link lost`: the text is read
            /// on the PLC's own LCD, where "PLC" would point at the wrong end.
            pub const fn text(self) -> &'static str {
                match self {
                    $(FaultCode::$v => $text,)+
                }
            }

            /// The bit of the drive section's `arc` that lets this code restart by itself
            /// (`firmware-drive` `docs/drive-core.md` "Automatic restart"): only the
            /// software trips whose cause lies outside the drive and goes by itself, `UV`
            /// 1, `OV` 2, `OC` 4. 0: a latched class, never restarted whatever `arc` says
            /// (the hardware trips, `STO` and the safety functions, `LINK`, `PROG`, `WDG`,
            /// `BOOT`).
            pub const fn restart_bit(self) -> u16 {
                match self {
                    $(FaultCode::$v => $arc,)+
                }
            }
        }
    };
}

fault_table! {
    /// Software overcurrent: |i_a| or |i_b| above `I>`.
    Oc = 1, "OC", "overcurrent", arc 4;
    /// Hardware comparator on a phase current (TIM1 break input).
    OcHw = 2, "OC_HW", "overcurrent (HW)", arc 0;
    /// Hardware comparator on the DC link (TIM1 break input), and its software twin at
    /// `U>>` every PWM period.
    OvHw = 3, "OV_HW", "overvoltage (HW)", arc 0;
    /// DC link below `U<` while the PWM is on.
    Uv = 4, "UV", "undervoltage", arc 1;
    /// No valid frame from the PLC within the link timeout in RUN.
    Link = 5, "LINK", "link lost", arc 0;
    /// Drive section rejected on download.
    Prog = 6, "PROG", "program rejected", arc 0;
    /// The drive restarted through its watchdog.
    Wdg = 7, "WDG", "watchdog reset", arc 0;
    /// The boot self-test failed (sine table, timer setup or current-sensor offset out of
    /// tolerance).
    Boot = 8, "BOOT", "self-test failed", arc 0;
    /// Safety (NOT RATED, safety.md 7): STO requested in RUN (`SFR STO` or `STO_IN` low).
    Sto = 9, "STO", "STO requested", arc 0;
    /// SS1 reached its end (time or early limit): STO.
    Ss1 = 10, "SS1", "SS1 done: STO", arc 0;
    /// Ramp envelope exceeded, or an SS2/SLS target missed at the end of the ramp.
    Ramp = 11, "RAMP", "ramp violated", arc 0;
    /// Standstill lost (SOS, or SS2 in standstill).
    Sos = 12, "SOS", "standstill lost", arc 0;
    /// Over an SLS limit in its safe state.
    Sls = 13, "SLS", "over SLS limit", arc 0;
    /// SLI: moved more than `pli`, or requested while moving.
    Sli = 14, "SLI", "SLI turns exceed", arc 0;
    /// SDI: moved more than `pss` against the allowed direction.
    Sdi = 15, "SDI", "wrong direction", arc 0;
    /// SLA: acceleration or deceleration above its limit.
    Sla = 16, "SLA", "over SLA limit", arc 0;
    /// Software overvoltage: the DC link above `U>` while the outputs switch, on a board
    /// without a brake chopper (`docs/fault-codes.md`): between the overvoltage
    /// controller's level and `U>>`.
    Ov = 17, "OV", "overvoltage", arc 2;
}

/// A byte that is no [`FaultCode`] (0 is "no fault", codes above [`FaultCode::COUNT`] are
/// not defined by this protocol version).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct UnknownFaultCode(pub u8);

impl core::fmt::Display for UnknownFaultCode {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "unknown drive fault code {}", self.0)
    }
}

impl core::error::Error for UnknownFaultCode {}

impl FaultCode {
    /// The code shown by `FLT`, stored in the fault log and sent over the link.
    pub const fn code(self) -> u8 {
        self as u8
    }

    /// Position in per-code arrays (trip counters): `code - 1`.
    pub const fn index(self) -> usize {
        self as usize - 1
    }
}

impl TryFrom<u8> for FaultCode {
    type Error = UnknownFaultCode;

    fn try_from(c: u8) -> Result<Self, Self::Error> {
        FaultCode::from_code(c)
    }
}

impl From<FaultCode> for u8 {
    fn from(f: FaultCode) -> u8 {
        f.code()
    }
}

/// Longest [`FaultCode::text`] (safety.md's texts for codes 9-16 keep the same limit):
/// `F16 ` plus the text fill the LCD's 20 columns.
pub const FAULT_TEXT_MAX: usize = 16;

/// Name of a raw fault code (`FLT`, a fault log entry): `none` for 0, `?` for a code this
/// version does not define.
pub const fn fault_name(code: u8) -> &'static str {
    match FaultCode::from_code(code) {
        Ok(f) => f.name(),
        Err(_) if code == 0 => "none",
        Err(_) => "?",
    }
}

/// Text of a raw fault code (service.md: "the shared `fault_text`"): `no fault` for 0,
/// `unknown fault` for a code this version does not define.
pub const fn fault_text(code: u8) -> &'static str {
    match FaultCode::from_code(code) {
        Ok(f) => f.text(),
        Err(_) if code == 0 => "no fault",
        Err(_) => "unknown fault",
    }
}

/// On the wire a fault code is its byte (postcard: one raw byte, as the `u8` it replaced).
impl Serialize for FaultCode {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_u8(self.code())
    }
}

/// An undefined code does not parse: the frame is refused (`FrameError::Message`).
impl<'de> Deserialize<'de> for FaultCode {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let c = u8::deserialize(d)?;
        FaultCode::from_code(c).map_err(|_| {
            serde::de::Error::invalid_value(
                serde::de::Unexpected::Unsigned(u64::from(c)),
                &"a drive fault code (fault::FaultCode)",
            )
        })
    }
}

/// `Option<FaultCode>` as one byte, 0 = none (the status's `fault` field), for
/// `#[serde(with = "...")]`.
pub mod wire_option {
    use super::FaultCode;
    use serde::{Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(f: &Option<FaultCode>, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_u8(f.map_or(0, FaultCode::code))
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Option<FaultCode>, D::Error> {
        match u8::deserialize(d)? {
            0 => Ok(None),
            c => FaultCode::from_code(c).map(Some).map_err(|_| {
                serde::de::Error::invalid_value(
                    serde::de::Unexpected::Unsigned(u64::from(c)),
                    &"0 (no fault) or a drive fault code (fault::FaultCode)",
                )
            }),
        }
    }
}

/// Causes of the drive's TIM1 break input: the G4's comparators, or hil-sim's model of
/// the same comparators.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum HwBreak {
    Overcurrent,
    Overvoltage,
}

impl HwBreak {
    /// In the order of [`HwBreak::index`] (the drive's per-cause arrays).
    pub const ALL: [HwBreak; 2] = [HwBreak::Overcurrent, HwBreak::Overvoltage];

    /// The fault a break of this cause latches.
    pub const fn fault(self) -> FaultCode {
        match self {
            HwBreak::Overcurrent => FaultCode::OcHw,
            HwBreak::Overvoltage => FaultCode::OvHw,
        }
    }

    /// Position in per-cause arrays (`ALL[i].index() == i`).
    pub const fn index(self) -> usize {
        match self {
            HwBreak::Overcurrent => 0,
            HwBreak::Overvoltage => 1,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_round_trip_and_match_drive_md() {
        for f in FaultCode::ALL {
            assert_eq!(FaultCode::from_code(f.code()), Ok(f));
            assert_eq!(FaultCode::try_from(u8::from(f)), Ok(f));
        }
        // drive.md's codes 1-16 keep their numbers and names.
        let names: Vec<_> = FaultCode::ALL
            .iter()
            .take(16)
            .map(|f| (f.code(), f.name()))
            .collect();
        assert_eq!(
            names,
            [
                (1, "OC"),
                (2, "OC_HW"),
                (3, "OV_HW"),
                (4, "UV"),
                (5, "LINK"),
                (6, "PROG"),
                (7, "WDG"),
                (8, "BOOT"),
                (9, "STO"),
                (10, "SS1"),
                (11, "RAMP"),
                (12, "SOS"),
                (13, "SLS"),
                (14, "SLI"),
                (15, "SDI"),
                (16, "SLA")
            ]
        );
        assert_eq!(FaultCode::from_code(0), Err(UnknownFaultCode(0)));
        assert_eq!(
            UnknownFaultCode(200).to_string(),
            "unknown drive fault code 200"
        );
    }

    /// The table is the vocabulary: codes 1..=COUNT without a gap, `ALL` in code order,
    /// `index` its position, every other byte unknown, names unique.
    #[test]
    fn the_table_has_consecutive_codes_and_nothing_else_parses() {
        assert_eq!(FaultCode::ALL.len(), FaultCode::COUNT);
        for (i, f) in FaultCode::ALL.into_iter().enumerate() {
            assert_eq!(usize::from(f.code()), i + 1, "{f:?}");
            assert_eq!(f.index(), i, "{f:?}");
        }
        for c in 0..=u8::MAX {
            let known = (1..=FaultCode::COUNT).contains(&usize::from(c));
            assert_eq!(FaultCode::from_code(c).is_ok(), known, "{c}");
        }
        let mut names: Vec<_> = FaultCode::ALL.iter().map(|f| f.name()).collect();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), FaultCode::COUNT, "two codes share a name");
    }

    /// `docs/fault-codes.md` lists every code with its name and text, and no other.
    #[test]
    fn the_docs_table_lists_every_code() {
        let doc = include_str!("../docs/fault-codes.md");
        for f in FaultCode::ALL {
            let row = format!("| {} | `{}` | {} |", f.code(), f.name(), f.text());
            assert!(doc.contains(&row), "docs/fault-codes.md has no row {row}");
        }
        let rows = doc
            .lines()
            .filter(|l| {
                l.split('|')
                    .nth(1)
                    .is_some_and(|c| c.trim().parse::<u8>().is_ok())
            })
            .count();
        assert_eq!(rows, FaultCode::COUNT, "docs/fault-codes.md rows");
    }

    #[test]
    fn texts_fit_the_lcd_row_and_raw_codes_have_texts() {
        assert!(FaultCode::ALL
            .iter()
            .all(|f| !f.text().is_empty() && f.text().len() <= FAULT_TEXT_MAX));
        assert_eq!(fault_text(2), "overcurrent (HW)");
        assert_eq!(fault_text(5), "link lost");
        assert_eq!(fault_text(0), "no fault");
        assert_eq!(fault_text(200), "unknown fault");
        assert_eq!(fault_name(0), "none");
        assert_eq!(fault_name(8), "BOOT");
        assert_eq!(fault_name(9), "STO");
        assert_eq!(fault_text(13), "over SLS limit");
        assert_eq!(fault_name(FaultCode::COUNT as u8 + 1), "?");
    }

    #[test]
    fn hardware_breaks_index_their_arrays_and_latch_the_hw_codes() {
        for (i, c) in HwBreak::ALL.into_iter().enumerate() {
            assert_eq!(c.index(), i);
        }
        assert_eq!(HwBreak::Overcurrent.fault(), FaultCode::OcHw);
        assert_eq!(HwBreak::Overvoltage.fault(), FaultCode::OvHw);
    }

    #[test]
    fn a_fault_code_is_one_byte_on_the_wire_and_undefined_codes_do_not_parse() {
        let mut buf = [0u8; 4];
        for f in FaultCode::ALL {
            assert_eq!(postcard::to_slice(&f, &mut buf).unwrap(), [f.code()]);
            assert_eq!(postcard::from_bytes::<FaultCode>(&[f.code()]), Ok(f));
        }
        for c in [0u8, FaultCode::COUNT as u8 + 1, 127, 255] {
            assert!(postcard::from_bytes::<FaultCode>(&[c]).is_err(), "{c}");
        }
    }
}
