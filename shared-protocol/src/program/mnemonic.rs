//! The instruction table: every mnemonic of both sections, in one place. Each row gives
//! the mnemonic's binary code, its text, the operand classes it takes in the PLC section
//! and in the drive section (`-`: not in that section), its `K` constant range (`-`:
//! 0000-9999) and its use of the drive section's int stack (`-`: none). The
//! [`Mnemonic`] enum, [`Mnemonic::ALL`] (the editor's order), the text, the verifier's
//! operand sets and constant ranges and the drive's stack tracking are all generated from
//! it, so an instruction is added by one row here plus its execution in the VM that runs
//! it (whose `match` is exhaustive: the compiler names the VM that lacks it). The recipe
//! is `docs/contributing/add-a-plc-instruction.md`.
//!
//! The codes are the binary encoding's mnemonic codes (`encode.rs`): never renumber them
//! (stored EEPROM images and the link download depend on them); a new row takes a code no
//! row has used. `tests/encoding_golden.rs` holds every instruction's bytes.

use super::model::CONSTANT_MAX;
use super::operand::{OperandClass as C, OperandSet};
use super::verify::{I_MAX_HW_LIMIT, U_MAX_HW_LIMIT};
use crate::safety::SafetySetting;

/// The PLC's bit operands (`LDC`).
pub(crate) const PLC_BITS: OperandSet =
    OperandSet::of(&[C::D, C::O, C::B, C::Rdy, C::Flb, C::Sf, C::Sdc]);

/// The operand sets the rows name. A row holds one of these names (one byte in flash per
/// row and section), not the 4-byte set: the table stays as small as the `match`es it
/// replaced.
#[allow(non_camel_case_types, clippy::upper_case_acronyms)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum OperandSetName {
    /// No operand.
    NONE,
    /// The PLC's bit operands (`LDC`).
    PLC_BITS,
    /// Everything the PLC's `LD` reads.
    PLC_LD,
    SF_ONLY,
    PLC_WR,
    B_ONLY,
    B_O,
    K_Q,
    Q_ONLY,
    K_ONLY,
    /// The drive's `WR`: Q and the direct duties.
    DRIVE_WR,
}

impl OperandSetName {
    /// Every name, in discriminant order (a test checks it).
    const ALL: [OperandSetName; 11] = [
        OperandSetName::NONE,
        OperandSetName::PLC_BITS,
        OperandSetName::PLC_LD,
        OperandSetName::SF_ONLY,
        OperandSetName::PLC_WR,
        OperandSetName::B_ONLY,
        OperandSetName::B_O,
        OperandSetName::K_Q,
        OperandSetName::Q_ONLY,
        OperandSetName::K_ONLY,
        OperandSetName::DRIVE_WR,
    ];

    /// The operand classes of the set.
    pub const fn set(self) -> OperandSet {
        match self {
            OperandSetName::NONE => OperandSet::NONE,
            OperandSetName::PLC_BITS => PLC_BITS,
            OperandSetName::PLC_LD => OperandSet::of(&[
                C::D,
                C::O,
                C::B,
                C::A,
                C::K,
                C::Q,
                C::Com,
                C::Vlt,
                C::Amp,
                C::Frq,
                C::Udc,
                C::Imx,
                C::Flt,
                C::Dir,
                C::Rdy,
                C::Flb,
                C::Ihw,
                C::Uhw,
                C::Sf,
                C::Sdc,
                C::Sft,
                C::Sfp,
            ]),
            OperandSetName::SF_ONLY => OperandSet::of(&[C::Sf]),
            OperandSetName::PLC_WR => OperandSet::of(&[C::O, C::B, C::Q]),
            OperandSetName::B_ONLY => OperandSet::of(&[C::B]),
            OperandSetName::B_O => OperandSet::of(&[C::O, C::B]),
            OperandSetName::K_Q => OperandSet::of(&[C::K, C::Q]),
            OperandSetName::Q_ONLY => OperandSet::of(&[C::Q]),
            OperandSetName::K_ONLY => OperandSet::of(&[C::K]),
            OperandSetName::DRIVE_WR => OperandSet::of(&[C::Q, C::Pw1, C::Pw3, C::Pw5]),
        }
    }
}

/// The `K` constant ranges the rows name (`-` in a row: [`Constants::ANY`]).
#[allow(non_camel_case_types, clippy::upper_case_acronyms)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum Constants {
    /// 0000-9999.
    ANY,
    /// 0001-9999 (a divisor, a limit, a trip level that 0 would make meaningless).
    FROM_1,
    /// `PWF`: 0488-9999 Hz (the source's minimum).
    PWF,
    /// `dU=`: 0000-1023.
    DU,
    /// `I>>`: 0001 up to the current sensors' full scale.
    IHW,
    /// `U>>`: 0001 up to the DC-link sensor's full scale.
    UHW,
    /// `ALM`: application faults 0001-0099.
    ALM,
    /// `arc`: a mask of the three restartable fault classes, 0000-0007.
    ARC,
}

impl Constants {
    /// Every name, in discriminant order (a test checks it).
    const ALL: [Constants; 8] = [
        Constants::ANY,
        Constants::FROM_1,
        Constants::PWF,
        Constants::DU,
        Constants::IHW,
        Constants::UHW,
        Constants::ALM,
        Constants::ARC,
    ];

    /// The smallest and largest constant.
    pub const fn limits(self) -> (u16, u16) {
        match self {
            Constants::ANY => (0, CONSTANT_MAX),
            Constants::FROM_1 => (1, CONSTANT_MAX),
            Constants::PWF => (488, CONSTANT_MAX),
            Constants::DU => (0, 1023),
            Constants::IHW => (1, I_MAX_HW_LIMIT),
            Constants::UHW => (1, U_MAX_HW_LIMIT),
            Constants::ALM => (1, 99),
            Constants::ARC => (0, 7),
        }
    }
}

/// How a drive instruction uses the int stack (`-` in a row: [`StackEffect::NONE`]).
#[allow(non_camel_case_types, clippy::upper_case_acronyms)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum StackEffect {
    NONE,
    /// `LD`: pushes one.
    LOAD,
    /// `WR`, `SN2`, `SN3`: read one.
    USE1,
    /// `SN1`: reads three.
    USE3,
    /// `PI`: pops four, pushes one.
    PI,
}

impl StackEffect {
    /// Every name, in discriminant order (a test checks it).
    const ALL: [StackEffect; 5] = [
        StackEffect::NONE,
        StackEffect::LOAD,
        StackEffect::USE1,
        StackEffect::USE3,
        StackEffect::PI,
    ];

    /// Values needed on the stack, popped, pushed.
    pub const fn counts(self) -> (u8, u8, u8) {
        match self {
            StackEffect::NONE => (0, 0, 0),
            StackEffect::LOAD => (0, 0, 1),
            StackEffect::USE1 => (1, 0, 0),
            StackEffect::USE3 => (3, 0, 0),
            StackEffect::PI => (4, 4, 1),
        }
    }
}

/// `-` or an operand set's name.
macro_rules! operands {
    (-) => {
        None
    };
    ($set:ident) => {
        Some(OperandSetName::$set)
    };
}

/// `-` or a name of [`Constants`] / [`StackEffect`].
macro_rules! named {
    ($ty:ident, -) => {
        $ty::ANY_OR_NONE
    };
    ($ty:ident, $name:ident) => {
        $ty::$name
    };
}

macro_rules! mnemonic_table {
    ($(
        $(#[$doc:meta])*
        $v:ident = $code:literal, $text:literal
            plc $plc:tt drive $drive:tt k $k:tt stack $stack:tt;
    )*) => {
        /// Every mnemonic of both sections. `Ld` and `Wr` exist in both with different
        /// meanings. The discriminants are the binary encoding's mnemonic codes.
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
        #[cfg_attr(feature = "defmt", derive(defmt::Format))]
        #[repr(u8)]
        pub enum Mnemonic {
            $( $(#[$doc])* $v = $code, )*
        }

        /// Each mnemonic with its row's text literal (the test of [`Mnemonic::text`]).
        #[cfg(test)]
        const ROW_TEXTS: [(Mnemonic, &str); [$($code),*].len()] = [$((Mnemonic::$v, $text)),*];

        impl Mnemonic {
            /// All mnemonics, in the order the editor offers them (the table's).
            pub const ALL: [Mnemonic; [$($code),*].len()] = [$(Mnemonic::$v),*];

            /// The text form, exactly as program.md writes it (canonical case): its
            /// row of the texts' table up to the first space. Out of line: one copy in
            /// the image.
            #[inline(never)]
            pub fn text(self) -> &'static str {
                let at = self as usize * TEXT_BYTES;
                let len = match TEXTS.as_bytes().get(at + TEXT_BYTES - 1) {
                    Some(b' ') => TEXT_BYTES - 1,
                    _ => TEXT_BYTES,
                };
                TEXTS.get(at..at + len).unwrap_or("")
            }
        }

        /// Every mnemonic's text in [`TEXT_BYTES`] bytes (padded with spaces) at its
        /// code: one 3-byte row per code, instead of a pointer and a length per
        /// mnemonic (the `match` of `&str`s compiled to two 4-byte tables).
        const TEXTS: &str = {
            const ROWS: usize = 1 + {
                let mut max = 0;
                $( if $code > max { max = $code; } )*
                max
            };
            #[allow(clippy::indexing_slicing)] // Evaluated at compile time.
            const BYTES: [u8; ROWS * TEXT_BYTES] = {
                let mut t = [b' '; ROWS * TEXT_BYTES];
                $(
                    let s = $text.as_bytes();
                    assert!(s.len() == TEXT_BYTES || s.len() == TEXT_BYTES - 1);
                    assert!(s[s.len() - 1] != b' ');
                    let mut j = 0;
                    while j < s.len() {
                        t[$code * TEXT_BYTES + j] = s[j];
                        j += 1;
                    }
                )*
                t
            };
            match core::str::from_utf8(&BYTES) {
                Ok(s) => s,
                Err(_) => "",
            }
        };

        impl Mnemonic {

            /// The row's names packed in 16 bits (PLC operand set + 1, drive operand
            /// set + 1, 0 for none, 4 bits each; constant range; stack use): one
            /// two-byte table in flash for the whole table, out of line so that the
            /// fields' decoders do not turn it back into one table per field.
            #[inline(never)]
            const fn row(self) -> u16 {
                match self {
                    $(Mnemonic::$v => pack(
                        operands!($plc),
                        operands!($drive),
                        named!(Constants, $k),
                        named!(StackEffect, $stack),
                    ),)*
                }
            }
        }
    };
}

/// The longest mnemonic's text, in bytes; every text has this length or one less.
const TEXT_BYTES: usize = 3;

impl Constants {
    const ANY_OR_NONE: Constants = Constants::ANY;
}

impl StackEffect {
    const ANY_OR_NONE: StackEffect = StackEffect::NONE;
}

mnemonic_table! {
    // Variant = code, text, PLC operands, drive operands, K range, drive stack use
    // (needs, pops, pushes); rows in the editor's order.
    Ld      =  1, "LD"   plc PLC_LD    drive K_Q       k -       stack LOAD;
    Ldc     =  3, "LDC"  plc PLC_BITS  drive -         k -       stack -;
    Wr      =  2, "WR"   plc PLC_WR    drive DRIVE_WR  k -       stack USE1;
    Wrc     =  4, "WRC"  plc PLC_WR    drive -         k -       stack -;
    Not     =  5, "NOT"  plc NONE      drive -         k -       stack -;
    And     =  6, "AND"  plc NONE      drive -         k -       stack -;
    Or      =  7, "OR"   plc NONE      drive -         k -       stack -;
    Xor     =  8, "XOR"  plc NONE      drive -         k -       stack -;
    Anc     =  9, "ANC"  plc NONE      drive -         k -       stack -;
    Orc     = 10, "ORC"  plc NONE      drive -         k -       stack -;
    Let     = 11, "LET"  plc B_ONLY    drive -         k -       stack -;
    /// `I/O`, the T flip-flop.
    Io      = 12, "I/O"  plc B_O       drive -         k -       stack -;
    Set     = 13, "SET"  plc B_O       drive -         k -       stack -;
    Res     = 14, "RES"  plc B_O       drive -         k -       stack -;
    Eq      = 15, "EQ"   plc K_Q       drive -         k -       stack -;
    Gt      = 16, "GT"   plc K_Q       drive -         k -       stack -;
    Lt      = 17, "LT"   plc K_Q       drive -         k -       stack -;
    Ctu     = 18, "CTU"  plc Q_ONLY    drive -         k -       stack -;
    Ctd     = 19, "CTD"  plc Q_ONLY    drive -         k -       stack -;
    Ton     = 20, "TON"  plc K_Q       drive -         k -       stack -;
    Tof     = 21, "TOF"  plc K_Q       drive -         k -       stack -;
    Imp     = 22, "IMP"  plc K_Q       drive -         k -       stack -;
    Add     = 23, "ADD"  plc K_Q       drive -         k -       stack -;
    Sub     = 24, "SUB"  plc K_Q       drive -         k -       stack -;
    Mul     = 25, "MUL"  plc K_Q       drive -         k -       stack -;
    Div     = 26, "DIV"  plc K_Q       drive -         k FROM_1  stack -;
    Lcd     = 27, "LCD"  plc NONE      drive -         k -       stack -;
    Rev     = 28, "REV"  plc NONE      drive -         k -       stack -;
    Ack     = 29, "ACK"  plc NONE      drive -         k -       stack -;
    /// `ALM K`: on a rising edge of S0, log application fault K (program-format.md).
    Alm     = 31, "ALM"  plc K_ONLY    drive -         k ALM     stack -;
    /// `SFR x`: safety function x's control bit = S0 (0 = requested, safety.md 5).
    Sfr     = 30, "SFR"  plc SF_ONLY   drive -         k -       stack -;
    Pwf     = 40, "PWF"  plc -         drive K_Q       k PWF     stack -;
    Pr0     = 41, "PR0"  plc -         drive NONE      k -       stack -;
    Pr1     = 42, "PR1"  plc -         drive NONE      k -       stack -;
    Pr2     = 43, "PR2"  plc -         drive NONE      k -       stack -;
    Pi      = 44, "PI"   plc -         drive K_ONLY    k FROM_1  stack PI;
    Sn1     = 45, "SN1"  plc -         drive NONE      k -       stack USE3;
    Sn2     = 46, "SN2"  plc -         drive NONE      k -       stack USE1;
    Sn3     = 47, "SN3"  plc -         drive NONE      k -       stack USE1;
    RsSet   = 48, "Rs="  plc -         drive K_ONLY    k -       stack -;
    UcSet   = 49, "Uc="  plc -         drive K_ONLY    k FROM_1  stack -;
    IzSet   = 50, "Iz="  plc -         drive K_ONLY    k -       stack -;
    CalcDu  = 51, "=dU"  plc -         drive NONE      k -       stack -;
    DuSet   = 52, "dU="  plc -         drive K_ONLY    k DU      stack -;
    UMax    = 53, "U>"   plc -         drive K_ONLY    k FROM_1  stack -;
    UMin    = 54, "U<"   plc -         drive K_ONLY    k -       stack -;
    IMax    = 55, "I>"   plc -         drive K_ONLY    k FROM_1  stack -;
    /// `I>>`: hardware overcurrent threshold (the source's current trimmers), 0.01 A.
    IMaxHw  = 60, "I>>"  plc -         drive K_ONLY    k IHW     stack -;
    /// `U>>`: hardware overvoltage threshold (the source's DC-link trimmer), V.
    UMaxHw  = 61, "U>>"  plc -         drive K_ONLY    k UHW     stack -;
    Fmn     = 56, "fmn"  plc -         drive K_ONLY    k -       stack -;
    Fjm     = 57, "fjm"  plc -         drive K_ONLY    k FROM_1  stack -;
    Fmx     = 58, "fmx"  plc -         drive K_ONLY    k FROM_1  stack -;
    Frv     = 59, "frv"  plc -         drive K_ONLY    k -       stack -;
    /// `arc`: the fault classes that restart automatically (bit 0 `UV`, 1 `OV`, 2 `OC`;
    /// 0 = none), `firmware-drive/docs/drive-core.md` "Automatic restart".
    Arc     = 86, "arc"  plc -         drive K_ONLY    k ARC     stack -;
    /// `art`: the automatic restart's delay after the cause has gone, 0.1 s.
    Art     = 87, "art"  plc -         drive K_ONLY    k -       stack -;
    /// `arn`: automatic restarts in a row before the fault stays latched.
    Arn     = 88, "arn"  plc -         drive K_ONLY    k -       stack -;
    /// The safety settings (safety.md 4), in signature order: see
    /// [`crate::safety::SafetySetting`] for each one's meaning and unit.
    Fss     = 62, "fss"  plc -         drive K_ONLY    k -       stack -;
    Pss     = 63, "pss"  plc -         drive K_ONLY    k -       stack -;
    Trd     = 64, "trd"  plc -         drive K_ONLY    k -       stack -;
    Ard     = 65, "ard"  plc -         drive K_ONLY    k -       stack -;
    Tel     = 66, "tel"  plc -         drive K_ONLY    k -       stack -;
    Ts1     = 67, "ts1"  plc -         drive K_ONLY    k -       stack -;
    Ts2     = 68, "ts2"  plc -         drive K_ONLY    k -       stack -;
    Fl1     = 69, "fl1"  plc -         drive K_ONLY    k -       stack -;
    Fl2     = 70, "fl2"  plc -         drive K_ONLY    k -       stack -;
    Fl3     = 71, "fl3"  plc -         drive K_ONLY    k -       stack -;
    Fl4     = 72, "fl4"  plc -         drive K_ONLY    k -       stack -;
    Tl1     = 73, "tl1"  plc -         drive K_ONLY    k -       stack -;
    Tl2     = 74, "tl2"  plc -         drive K_ONLY    k -       stack -;
    Tl3     = 75, "tl3"  plc -         drive K_ONLY    k -       stack -;
    Tl4     = 76, "tl4"  plc -         drive K_ONLY    k -       stack -;
    Pli     = 77, "pli"  plc -         drive K_ONLY    k -       stack -;
    Tli     = 78, "tli"  plc -         drive K_ONLY    k -       stack -;
    Tdi     = 79, "tdi"  plc -         drive K_ONLY    k -       stack -;
    Aap     = 80, "aap"  plc -         drive K_ONLY    k -       stack -;
    Adp     = 81, "adp"  plc -         drive K_ONLY    k -       stack -;
    Aan     = 82, "aan"  plc -         drive K_ONLY    k -       stack -;
    Adn     = 83, "adn"  plc -         drive K_ONLY    k -       stack -;
    Tla     = 84, "tla"  plc -         drive K_ONLY    k -       stack -;
    Asr     = 85, "asr"  plc -         drive K_ONLY    k -       stack -;
}

/// A row's names in 16 bits (see `Mnemonic::row`).
const fn pack(
    plc: Option<OperandSetName>,
    drive: Option<OperandSetName>,
    k: Constants,
    stack: StackEffect,
) -> u16 {
    set_field(plc) | set_field(drive) << 4 | (k as u16) << 8 | (stack as u16) << 12
}

const fn set_field(o: Option<OperandSetName>) -> u16 {
    match o {
        Some(o) => o as u16 + 1,
        None => 0,
    }
}

/// The operand set of a packed 4-bit field (0: not in the section).
// Indexed after the bounds check just above it (`get` is not `const`).
#[allow(clippy::indexing_slicing)]
const fn unpack_set(field: u16) -> Option<OperandSet> {
    match (field & 0xF).checked_sub(1) {
        Some(i) if (i as usize) < OperandSetName::ALL.len() => {
            Some(OperandSetName::ALL[i as usize].set())
        }
        _ => None,
    }
}

impl Mnemonic {
    /// The operand classes this mnemonic takes in the PLC section; `None` when it is not
    /// a PLC instruction.
    #[inline(never)]
    pub const fn plc_operands(self) -> Option<OperandSet> {
        unpack_set(self.row())
    }

    /// The operand classes this mnemonic takes in the drive section; `None` when it is
    /// not a drive instruction.
    #[inline(never)]
    pub const fn drive_operands(self) -> Option<OperandSet> {
        unpack_set(self.row() >> 4)
    }

    /// The smallest and largest constant a `K` operand of this mnemonic accepts.
    #[inline(never)]
    // Indexed after the bounds check just above it (`get` is not `const`).
    #[allow(clippy::indexing_slicing)]
    pub const fn constant_limits(self) -> (u16, u16) {
        let i = ((self.row() >> 8) & 0xF) as usize;
        if i < Constants::ALL.len() {
            Constants::ALL[i].limits()
        } else {
            Constants::ANY.limits()
        }
    }

    /// Drive section: values it needs on the int stack, pops, pushes.
    #[inline(never)]
    // Indexed after the bounds check just above it (`get` is not `const`).
    #[allow(clippy::indexing_slicing)]
    pub const fn stack_effect(self) -> (u8, u8, u8) {
        let i = (self.row() >> 12) as usize;
        if i < StackEffect::ALL.len() {
            StackEffect::ALL[i].counts()
        } else {
            StackEffect::NONE.counts()
        }
    }

    /// The binary encoding's code of this mnemonic (its `repr(u8)` discriminant).
    pub const fn code(self) -> u8 {
        self as u8
    }

    /// The mnemonic with this binary code, `None` for an unused code (0 means an empty
    /// line in stored images, 255 is erased EEPROM).
    pub fn from_code(code: u8) -> Option<Mnemonic> {
        Mnemonic::ALL.iter().copied().find(|m| m.code() == code)
    }

    /// The drive parameter this drive-section line sets, named by the first mnemonic that
    /// sets it; `None` for a line that is not a setting. A setting is a drive instruction
    /// that leaves the int stack alone (everything but `LD`, `WR`, `PI`, `SNx`); `PR0`,
    /// `PR1`, `PR2` all set the prescaler (`PR0`) and `=dU`, `dU=` both set dU (`=dU`), the
    /// source's "second option" (002 4.2). The verifier lets each parameter be set by one
    /// line only, so the value in force is the same on every line and in every cycle
    /// (docs/program-format.md "Settings once per section").
    pub fn drive_setting(self) -> Option<Mnemonic> {
        if self.drive_operands().is_none() || self.stack_effect() != (0, 0, 0) {
            return None;
        }
        Some(match self {
            Mnemonic::Pr1 | Mnemonic::Pr2 => Mnemonic::Pr0,
            Mnemonic::DuSet => Mnemonic::CalcDu,
            m => m,
        })
    }

    /// The name of the parameter [`Mnemonic::drive_setting`] returns `self` for, in a
    /// verifier error: `PRx` for the prescaler, `dU` for dU, the text otherwise.
    pub fn setting_name(self) -> &'static str {
        match self {
            Mnemonic::Pr0 | Mnemonic::Pr1 | Mnemonic::Pr2 => "PRx",
            Mnemonic::CalcDu | Mnemonic::DuSet => "dU",
            m => m.text(),
        }
    }

    /// The verifier's bit of the drive parameter this line sets, other than the safety
    /// settings ([`Mnemonic::safety_setting`] gives theirs), 0 when it sets none
    /// ([`Mnemonic::drive_setting`], from the codes alone: `PWF` .. `U>>` are codes 40-61,
    /// and `PI`, `SN1`-`SN3` the four after the prescalers, bits 0-21; the restart settings
    /// `arc` .. `arn`, codes 86-88, bits 22-24; a test checks it against `drive_setting`
    /// for every mnemonic). Small: the drive's verifier runs it.
    pub const fn setting_bit(self) -> u32 {
        let c = self
            .same_setting()
            .code()
            .wrapping_sub(Mnemonic::Pwf.code());
        let sn3 = Mnemonic::Sn3.code() - Mnemonic::Pwf.code();
        let pi = Mnemonic::Pi.code() - Mnemonic::Pwf.code();
        let last = Mnemonic::UMaxHw.code() - Mnemonic::Pwf.code();
        let arc = Mnemonic::Arc.code() - Mnemonic::Pwf.code();
        let arn = Mnemonic::Arn.code() - Mnemonic::Pwf.code();
        if c >= arc && c <= arn {
            1u32 << (c - arc + last + 1)
        } else if c > last || (c >= pi && c <= sn3) {
            0
        } else {
            1u32 << c
        }
    }

    /// The mnemonic that names the parameter this one sets: `PR0` for `PR1`/`PR2`, `=dU`
    /// for `dU=`, itself otherwise (for the error path of the verifier).
    pub const fn same_setting(self) -> Mnemonic {
        match self {
            Mnemonic::Pr1 | Mnemonic::Pr2 => Mnemonic::Pr0,
            Mnemonic::DuSet => Mnemonic::CalcDu,
            m => m,
        }
    }

    /// The safety setting this mnemonic sets (drive section, safety.md 4). The settings'
    /// codes are consecutive in signature order (62 `fss` .. 85 `asr`): one table lookup,
    /// which keeps the drive's verifier small.
    pub fn safety_setting(self) -> Option<SafetySetting> {
        let i = self.code().checked_sub(Mnemonic::Fss.code())?;
        SafetySetting::ALL.get(usize::from(i)).copied()
    }

    /// The mnemonic of a safety setting.
    pub const fn of_setting(s: SafetySetting) -> Mnemonic {
        match s {
            SafetySetting::Fss => Mnemonic::Fss,
            SafetySetting::Pss => Mnemonic::Pss,
            SafetySetting::Trd => Mnemonic::Trd,
            SafetySetting::Ard => Mnemonic::Ard,
            SafetySetting::Tel => Mnemonic::Tel,
            SafetySetting::Ts1 => Mnemonic::Ts1,
            SafetySetting::Ts2 => Mnemonic::Ts2,
            SafetySetting::Fl1 => Mnemonic::Fl1,
            SafetySetting::Fl2 => Mnemonic::Fl2,
            SafetySetting::Fl3 => Mnemonic::Fl3,
            SafetySetting::Fl4 => Mnemonic::Fl4,
            SafetySetting::Tl1 => Mnemonic::Tl1,
            SafetySetting::Tl2 => Mnemonic::Tl2,
            SafetySetting::Tl3 => Mnemonic::Tl3,
            SafetySetting::Tl4 => Mnemonic::Tl4,
            SafetySetting::Pli => Mnemonic::Pli,
            SafetySetting::Tli => Mnemonic::Tli,
            SafetySetting::Tdi => Mnemonic::Tdi,
            SafetySetting::Aap => Mnemonic::Aap,
            SafetySetting::Adp => Mnemonic::Adp,
            SafetySetting::Aan => Mnemonic::Aan,
            SafetySetting::Adn => Mnemonic::Adn,
            SafetySetting::Tla => Mnemonic::Tla,
            SafetySetting::Asr => Mnemonic::Asr,
        }
    }
}

/// Walks the table: each row is a whole instruction for every part that reads programs.
#[cfg(test)]
mod tests {
    use super::super::{
        assemble, constant_range, decode_line, encode_line, line_string, operands_for, verify_line,
        Instruction, Section, PLC_FIRST_LINE,
    };
    use super::*;

    /// Codes are unique, not 0 (empty line) nor 255 (erased EEPROM); texts are unique in
    /// any case (the assembler is case-insensitive) and fit the editor's 4-column field.
    #[test]
    fn codes_and_texts_are_unique() {
        for (n, a) in Mnemonic::ALL.iter().enumerate() {
            assert!(a.code() != 0 && a.code() != 255, "{a:?}");
            assert_eq!(Mnemonic::from_code(a.code()), Some(*a));
            assert!(a.text().len() <= 3, "{a:?}: LCD field");
            for b in Mnemonic::ALL.iter().skip(n + 1) {
                assert_ne!(a.code(), b.code(), "{a:?} {b:?}");
                assert!(!a.text().eq_ignore_ascii_case(b.text()), "{a:?} {b:?}");
            }
        }
    }

    /// Every mnemonic belongs to a section, and in each of its sections its first and
    /// last operand with the smallest and largest constant verify, encode and decode back,
    /// and disassemble to text that assembles back to the same line.
    #[test]
    fn every_text_is_its_rows_literal() {
        for (m, text) in ROW_TEXTS {
            assert_eq!(m.text(), text, "{m:?}");
        }
    }

    #[test]
    fn every_row_verifies_encodes_and_round_trips_through_text() {
        for m in Mnemonic::ALL {
            assert!(
                m.plc_operands().is_some() || m.drive_operands().is_some(),
                "{m:?} is in no section"
            );
            for (section, line) in [(Section::Plc, PLC_FIRST_LINE), (Section::Drive, 0)] {
                let ops: std::vec::Vec<_> = operands_for(m, section).collect();
                let (Some(first), Some(last)) = (ops.first(), ops.last()) else {
                    continue;
                };
                for op in [*first, *last] {
                    let range = constant_range(m, section, op);
                    let constants = range.map_or([0, 0], |r| [*r.start(), *r.end()]);
                    for constant in constants {
                        let i = Instruction {
                            mnemonic: m,
                            operand: op,
                            constant,
                        };
                        assert_eq!(verify_line(line, &i), Ok(()), "{i:?}");
                        assert_eq!(decode_line(&encode_line(&i)), Ok(i));
                        let text = line_string(line, &i);
                        let p = assemble(&text).unwrap_or_else(|e| panic!("{text}: {e:?}"));
                        assert_eq!(p.get(line), Some(&i), "{text}");
                    }
                }
            }
        }
    }

    /// The format doc (`docs/program-format.md`, operand table and decisions) names every
    /// mnemonic: a row added here without its documentation fails.
    #[test]
    fn every_mnemonic_is_in_the_program_format_doc() {
        let doc = include_str!("../../docs/program-format.md");
        for m in Mnemonic::ALL {
            let quoted = std::format!("`{}`", m.text());
            assert!(
                doc.contains(&quoted),
                "{quoted} missing in docs/program-format.md"
            );
        }
    }

    /// The packed row decodes every name (the `ALL` lists are in discriminant order).
    #[test]
    fn name_lists_are_in_discriminant_order() {
        for (i, n) in OperandSetName::ALL.iter().enumerate() {
            assert_eq!(*n as usize, i);
            assert_eq!(unpack_set(set_field(Some(*n))), Some(n.set()));
        }
        for (i, n) in Constants::ALL.iter().enumerate() {
            assert_eq!(*n as usize, i);
        }
        for (i, n) in StackEffect::ALL.iter().enumerate() {
            assert_eq!(*n as usize, i);
        }
        assert_eq!(Mnemonic::Div.constant_limits(), (1, 9999));
        assert_eq!(Mnemonic::Pi.stack_effect(), (4, 4, 1));
        assert_eq!(Mnemonic::Pwf.plc_operands(), None);
    }

    /// The settings: every drive instruction that leaves the stack alone, each with a
    /// bit of its own but the prescaler's and dU's alternatives; no other mnemonic.
    #[test]
    fn drive_settings_have_distinct_bits_but_the_alternatives() {
        let mut seen: std::vec::Vec<(u64, Mnemonic)> = std::vec::Vec::new();
        for m in Mnemonic::ALL {
            let Some(p) = m.drive_setting() else {
                assert_eq!(m.setting_bit(), 0, "{m:?}");
                assert!(
                    m.drive_operands().is_none()
                        || matches!(
                            m,
                            Mnemonic::Ld
                                | Mnemonic::Wr
                                | Mnemonic::Pi
                                | Mnemonic::Sn1
                                | Mnemonic::Sn2
                                | Mnemonic::Sn3
                        ),
                    "{m:?}"
                );
                continue;
            };
            assert_eq!(p.drive_setting(), Some(p));
            assert_eq!(m.same_setting(), p);
            assert_eq!(m.setting_bit(), p.setting_bit());
            assert_eq!(m.setting_bit() != 0, m.safety_setting().is_none(), "{m:?}");
            assert_eq!(p.setting_name(), m.setting_name());
            let bit = match p.safety_setting() {
                Some(s) => 1u64 << (32 + s.index()),
                None => u64::from(p.setting_bit()),
            };
            match seen.iter().find(|(b, _)| *b == bit) {
                Some((_, q)) => assert_eq!(*q, p, "{m:?}"),
                None => seen.push((bit, p)),
            }
        }
        assert_eq!(Mnemonic::Pr2.drive_setting(), Some(Mnemonic::Pr0));
        assert_eq!(Mnemonic::DuSet.drive_setting(), Some(Mnemonic::CalcDu));
        assert_eq!(Mnemonic::Fmx.drive_setting(), Some(Mnemonic::Fmx));
        assert_eq!(Mnemonic::Fss.drive_setting(), Some(Mnemonic::Fss));
        assert_eq!(Mnemonic::Pwf.drive_setting(), Some(Mnemonic::Pwf));
        assert_eq!(Mnemonic::Sn1.drive_setting(), None);
        assert_eq!(Mnemonic::Alm.drive_setting(), None);
        // 15 drive parameters (`PWF` .. `frv`, `I>>`, `U>>`), 3 restart settings (`arc`,
        // `art`, `arn`), 24 safety settings.
        assert_eq!(seen.len(), 15 + 3 + 24);
    }

    /// The drive's stack use is declared only for drive instructions.
    #[test]
    fn stack_use_only_in_the_drive_section() {
        for m in Mnemonic::ALL {
            if m.drive_operands().is_none() {
                assert_eq!(m.stack_effect(), (0, 0, 0), "{m:?}");
            }
            let (needs, pops, _) = m.stack_effect();
            assert!(pops <= needs, "{m:?}");
        }
    }
}
