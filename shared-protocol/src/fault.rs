//! The drive's fault vocabulary, one copy for both images and hil-sim: the latched fault
//! codes (drive.md "Trips"), their names and texts, and the causes of the hardware break.
//!
//! The code is what `FLT` reads, what the fault log stores and what the link carries (one
//! byte, see `docs/link.md` "Fault codes on the wire").

use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// Latched fault codes (drive.md table; `Boot` is this project's addition, drive.md's
/// code 8).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[repr(u8)]
pub enum FaultCode {
    /// Software overcurrent: |i_a| or |i_b| above `I>`.
    Oc = 1,
    /// Hardware comparator on a phase current (TIM1 break input).
    OcHw = 2,
    /// Hardware comparator on the DC link (TIM1 break input).
    OvHw = 3,
    /// DC link below `U<` while the PWM is on.
    Uv = 4,
    /// No valid frame from the PLC within the link timeout in RUN.
    Link = 5,
    /// Drive section rejected on download.
    Prog = 6,
    /// The drive restarted through its watchdog.
    Wdg = 7,
    /// The boot self-test failed (sine table, timer setup or current-sensor offset out of
    /// tolerance).
    Boot = 8,
    /// Safety (NOT RATED, safety.md 7): STO requested in RUN (`SFR STO` or `STO_IN` low).
    Sto = 9,
    /// SS1 reached its end (time or early limit): STO.
    Ss1 = 10,
    /// Ramp envelope exceeded, or an SS2/SLS target missed at the end of the ramp.
    Ramp = 11,
    /// Standstill lost (SOS, or SS2 in standstill).
    Sos = 12,
    /// Over an SLS limit in its safe state.
    Sls = 13,
    /// SLI: moved more than `pli`, or requested while moving.
    Sli = 14,
    /// SDI: moved more than `pss` against the allowed direction.
    Sdi = 15,
    /// SLA: acceleration or deceleration above its limit.
    Sla = 16,
}

/// A byte that is no [`FaultCode`] (0 is "no fault", 17.. are not defined by this
/// protocol version).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct UnknownFaultCode(pub u8);

impl core::fmt::Display for UnknownFaultCode {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "unknown drive fault code {}", self.0)
    }
}

impl FaultCode {
    pub const ALL: [FaultCode; 16] = [
        FaultCode::Oc,
        FaultCode::OcHw,
        FaultCode::OvHw,
        FaultCode::Uv,
        FaultCode::Link,
        FaultCode::Prog,
        FaultCode::Wdg,
        FaultCode::Boot,
        FaultCode::Sto,
        FaultCode::Ss1,
        FaultCode::Ramp,
        FaultCode::Sos,
        FaultCode::Sls,
        FaultCode::Sli,
        FaultCode::Sdi,
        FaultCode::Sla,
    ];

    /// The code shown by `FLT`, stored in the fault log and sent over the link.
    pub const fn code(self) -> u8 {
        self as u8
    }

    /// The fault with this code; 0 ("no fault") and undefined codes are errors.
    pub const fn from_code(c: u8) -> Result<FaultCode, UnknownFaultCode> {
        Ok(match c {
            1 => FaultCode::Oc,
            2 => FaultCode::OcHw,
            3 => FaultCode::OvHw,
            4 => FaultCode::Uv,
            5 => FaultCode::Link,
            6 => FaultCode::Prog,
            7 => FaultCode::Wdg,
            8 => FaultCode::Boot,
            9 => FaultCode::Sto,
            10 => FaultCode::Ss1,
            11 => FaultCode::Ramp,
            12 => FaultCode::Sos,
            13 => FaultCode::Sls,
            14 => FaultCode::Sli,
            15 => FaultCode::Sdi,
            16 => FaultCode::Sla,
            _ => return Err(UnknownFaultCode(c)),
        })
    }

    /// Short name (drive.md), for the fault log screen and hil-sim's reports.
    pub const fn name(self) -> &'static str {
        match self {
            FaultCode::Oc => "OC",
            FaultCode::OcHw => "OC_HW",
            FaultCode::OvHw => "OV_HW",
            FaultCode::Uv => "UV",
            FaultCode::Link => "LINK",
            FaultCode::Prog => "PROG",
            FaultCode::Wdg => "WDG",
            FaultCode::Boot => "BOOT",
            FaultCode::Sto => "STO",
            FaultCode::Ss1 => "SS1",
            FaultCode::Ramp => "RAMP",
            FaultCode::Sos => "SOS",
            FaultCode::Sls => "SLS",
            FaultCode::Sli => "SLI",
            FaultCode::Sdi => "SDI",
            FaultCode::Sla => "SLA",
        }
    }

    /// The text the LCD status line (`F2 overcurrent (HW)`), the fault log and hil-sim
    /// show. At most [`FAULT_TEXT_MAX`] characters, so that `Fnn text` fits one 20-column
    /// row. `link lost`, not `PLC link lost`: the text is read on the PLC's own LCD,
    /// where "PLC" would point at the wrong end.
    pub const fn text(self) -> &'static str {
        match self {
            FaultCode::Oc => "overcurrent",
            FaultCode::OcHw => "overcurrent (HW)",
            FaultCode::OvHw => "overvoltage (HW)",
            FaultCode::Uv => "undervoltage",
            FaultCode::Link => "link lost",
            FaultCode::Prog => "program rejected",
            FaultCode::Wdg => "watchdog reset",
            FaultCode::Boot => "self-test failed",
            FaultCode::Sto => "STO requested",
            FaultCode::Ss1 => "SS1 done: STO",
            FaultCode::Ramp => "ramp violated",
            FaultCode::Sos => "standstill lost",
            FaultCode::Sls => "over SLS limit",
            FaultCode::Sli => "SLI turns exceed",
            FaultCode::Sdi => "wrong direction",
            FaultCode::Sla => "over SLA limit",
        }
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
                &"a drive fault code 1..=16",
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
                    &"0 (no fault) or a drive fault code 1..=16",
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
        let names: Vec<_> = FaultCode::ALL
            .iter()
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
        assert_eq!(FaultCode::from_code(17), Err(UnknownFaultCode(17)));
        assert_eq!(
            UnknownFaultCode(17).to_string(),
            "unknown drive fault code 17"
        );
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
        assert_eq!(fault_name(17), "?");
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
        for c in [0u8, 17, 127, 255] {
            assert!(postcard::from_bytes::<FaultCode>(&[c]).is_err(), "{c}");
        }
    }
}
