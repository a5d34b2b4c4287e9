//! The program model: 1000 lines, each empty or one instruction (program.md section 1).
//!
//! These types are the contract between the assembler, the keypad editor, the EEPROM
//! storage, the link download, and both VMs. A [`Program`] can hold anything the types
//! allow; only [`super::verify`] decides whether it may run.

use crate::safety::{SafetyFunction, SafetySetting};

/// Number of program lines (000-999).
pub const LINES: usize = 1000;
/// First line of the PLC section; lines below it are the drive section.
pub const PLC_FIRST_LINE: u16 = 150;
/// Number of drive-section lines (000-149).
pub const DRIVE_LINES: usize = PLC_FIRST_LINE as usize;
/// Largest value of a line's 4-digit constant.
pub const CONSTANT_MAX: u16 = 9999;
/// Digital inputs D00-D15 (lift.md 1; the source design had 8). The one count every part
/// uses: the assembler's range check and error text, the verifier, the keypad editor's
/// operand lists, the PLC VM's input image, the board's pin table and hil-sim (scenario
/// names, CSV columns, panel toggles).
pub const DIGITAL_INPUTS: u8 = 16;
/// Digital outputs O00-O07 (lift.md 1; the source design had 6), used like
/// [`DIGITAL_INPUTS`].
pub const DIGITAL_OUTPUTS: u8 = 8;

/// Which MCU a line belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Section {
    /// Lines 000-149, executed by the drive MCU every 1 ms.
    Drive,
    /// Lines 150-999, executed by the PLC MCU scan after scan.
    Plc,
}

impl Section {
    /// The section a line number falls in (`None` for 1000 and above).
    pub const fn of_line(line: u16) -> Option<Section> {
        if line < PLC_FIRST_LINE {
            Some(Section::Drive)
        } else if (line as usize) < LINES {
            Some(Section::Plc)
        } else {
            None
        }
    }
}

/// Every mnemonic of both sections. `Ld` and `Wr` exist in both with different meanings.
///
/// The discriminants are the binary encoding's mnemonic codes: never renumber them
/// (stored EEPROM images and the link download depend on them).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[repr(u8)]
pub enum Mnemonic {
    // Both sections.
    Ld = 1,
    Wr = 2,
    // PLC section.
    Ldc = 3,
    Wrc = 4,
    Not = 5,
    And = 6,
    Or = 7,
    Xor = 8,
    Anc = 9,
    Orc = 10,
    Let = 11,
    /// `I/O`, the T flip-flop.
    Io = 12,
    Set = 13,
    Res = 14,
    Eq = 15,
    Gt = 16,
    Lt = 17,
    Ctu = 18,
    Ctd = 19,
    Ton = 20,
    Tof = 21,
    Imp = 22,
    Add = 23,
    Sub = 24,
    Mul = 25,
    Div = 26,
    Lcd = 27,
    Rev = 28,
    Ack = 29,
    /// `SFR x`: safety function x's control bit = S0 (0 = requested, safety.md 5).
    Sfr = 30,
    // Drive section.
    Pwf = 40,
    Pr0 = 41,
    Pr1 = 42,
    Pr2 = 43,
    Pi = 44,
    Sn1 = 45,
    Sn2 = 46,
    Sn3 = 47,
    /// `Rs=`
    RsSet = 48,
    /// `Uc=`
    UcSet = 49,
    /// `Iz=`
    IzSet = 50,
    /// `=dU`
    CalcDu = 51,
    /// `dU=`
    DuSet = 52,
    /// `U>`
    UMax = 53,
    /// `U<`
    UMin = 54,
    /// `I>`
    IMax = 55,
    Fmn = 56,
    Fjm = 57,
    Fmx = 58,
    Frv = 59,
    /// `I>>`: hardware overcurrent threshold (the source's current trimmers), 0.01 A.
    IMaxHw = 60,
    /// `U>>`: hardware overvoltage threshold (the source's DC-link trimmer), V.
    UMaxHw = 61,
    /// The safety settings (safety.md 4), in signature order: see
    /// [`crate::safety::SafetySetting`] for each one's meaning and unit.
    Fss = 62,
    Pss = 63,
    Trd = 64,
    Ard = 65,
    Tel = 66,
    Ts1 = 67,
    Ts2 = 68,
    Fl1 = 69,
    Fl2 = 70,
    Fl3 = 71,
    Fl4 = 72,
    Tl1 = 73,
    Tl2 = 74,
    Tl3 = 75,
    Tl4 = 76,
    Pli = 77,
    Tli = 78,
    Tdi = 79,
    Aap = 80,
    Adp = 81,
    Aan = 82,
    Adn = 83,
    Tla = 84,
    Asr = 85,
}

impl Mnemonic {
    /// All mnemonics, in the order the editor offers them.
    pub const ALL: [Mnemonic; 76] = [
        Mnemonic::Ld,
        Mnemonic::Ldc,
        Mnemonic::Wr,
        Mnemonic::Wrc,
        Mnemonic::Not,
        Mnemonic::And,
        Mnemonic::Or,
        Mnemonic::Xor,
        Mnemonic::Anc,
        Mnemonic::Orc,
        Mnemonic::Let,
        Mnemonic::Io,
        Mnemonic::Set,
        Mnemonic::Res,
        Mnemonic::Eq,
        Mnemonic::Gt,
        Mnemonic::Lt,
        Mnemonic::Ctu,
        Mnemonic::Ctd,
        Mnemonic::Ton,
        Mnemonic::Tof,
        Mnemonic::Imp,
        Mnemonic::Add,
        Mnemonic::Sub,
        Mnemonic::Mul,
        Mnemonic::Div,
        Mnemonic::Lcd,
        Mnemonic::Rev,
        Mnemonic::Ack,
        Mnemonic::Sfr,
        Mnemonic::Pwf,
        Mnemonic::Pr0,
        Mnemonic::Pr1,
        Mnemonic::Pr2,
        Mnemonic::Pi,
        Mnemonic::Sn1,
        Mnemonic::Sn2,
        Mnemonic::Sn3,
        Mnemonic::RsSet,
        Mnemonic::UcSet,
        Mnemonic::IzSet,
        Mnemonic::CalcDu,
        Mnemonic::DuSet,
        Mnemonic::UMax,
        Mnemonic::UMin,
        Mnemonic::IMax,
        Mnemonic::IMaxHw,
        Mnemonic::UMaxHw,
        Mnemonic::Fmn,
        Mnemonic::Fjm,
        Mnemonic::Fmx,
        Mnemonic::Frv,
        Mnemonic::Fss,
        Mnemonic::Pss,
        Mnemonic::Trd,
        Mnemonic::Ard,
        Mnemonic::Tel,
        Mnemonic::Ts1,
        Mnemonic::Ts2,
        Mnemonic::Fl1,
        Mnemonic::Fl2,
        Mnemonic::Fl3,
        Mnemonic::Fl4,
        Mnemonic::Tl1,
        Mnemonic::Tl2,
        Mnemonic::Tl3,
        Mnemonic::Tl4,
        Mnemonic::Pli,
        Mnemonic::Tli,
        Mnemonic::Tdi,
        Mnemonic::Aap,
        Mnemonic::Adp,
        Mnemonic::Aan,
        Mnemonic::Adn,
        Mnemonic::Tla,
        Mnemonic::Asr,
    ];

    /// The binary encoding's code of this mnemonic (its `repr(u8)` discriminant).
    pub const fn code(self) -> u8 {
        self as u8
    }

    /// The mnemonic with this binary code, `None` for an unused code (0 means an empty
    /// line in stored images, 255 is erased EEPROM).
    pub fn from_code(code: u8) -> Option<Mnemonic> {
        Mnemonic::ALL.iter().copied().find(|m| m.code() == code)
    }

    /// The text form, exactly as program.md writes it (canonical case). Out of line: the
    /// PLC image had two copies of its 340-byte table.
    #[inline(never)]
    pub const fn text(self) -> &'static str {
        match self {
            Mnemonic::Ld => "LD",
            Mnemonic::Wr => "WR",
            Mnemonic::Ldc => "LDC",
            Mnemonic::Wrc => "WRC",
            Mnemonic::Not => "NOT",
            Mnemonic::And => "AND",
            Mnemonic::Or => "OR",
            Mnemonic::Xor => "XOR",
            Mnemonic::Anc => "ANC",
            Mnemonic::Orc => "ORC",
            Mnemonic::Let => "LET",
            Mnemonic::Io => "I/O",
            Mnemonic::Set => "SET",
            Mnemonic::Res => "RES",
            Mnemonic::Eq => "EQ",
            Mnemonic::Gt => "GT",
            Mnemonic::Lt => "LT",
            Mnemonic::Ctu => "CTU",
            Mnemonic::Ctd => "CTD",
            Mnemonic::Ton => "TON",
            Mnemonic::Tof => "TOF",
            Mnemonic::Imp => "IMP",
            Mnemonic::Add => "ADD",
            Mnemonic::Sub => "SUB",
            Mnemonic::Mul => "MUL",
            Mnemonic::Div => "DIV",
            Mnemonic::Lcd => "LCD",
            Mnemonic::Rev => "REV",
            Mnemonic::Ack => "ACK",
            Mnemonic::Sfr => "SFR",
            Mnemonic::Pwf => "PWF",
            Mnemonic::Pr0 => "PR0",
            Mnemonic::Pr1 => "PR1",
            Mnemonic::Pr2 => "PR2",
            Mnemonic::Pi => "PI",
            Mnemonic::Sn1 => "SN1",
            Mnemonic::Sn2 => "SN2",
            Mnemonic::Sn3 => "SN3",
            Mnemonic::RsSet => "Rs=",
            Mnemonic::UcSet => "Uc=",
            Mnemonic::IzSet => "Iz=",
            Mnemonic::CalcDu => "=dU",
            Mnemonic::DuSet => "dU=",
            Mnemonic::UMax => "U>",
            Mnemonic::UMin => "U<",
            Mnemonic::IMax => "I>",
            Mnemonic::Fmn => "fmn",
            Mnemonic::Fjm => "fjm",
            Mnemonic::Fmx => "fmx",
            Mnemonic::Frv => "frv",
            Mnemonic::IMaxHw => "I>>",
            Mnemonic::UMaxHw => "U>>",
            Mnemonic::Fss => "fss",
            Mnemonic::Pss => "pss",
            Mnemonic::Trd => "trd",
            Mnemonic::Ard => "ard",
            Mnemonic::Tel => "tel",
            Mnemonic::Ts1 => "ts1",
            Mnemonic::Ts2 => "ts2",
            Mnemonic::Fl1 => "fl1",
            Mnemonic::Fl2 => "fl2",
            Mnemonic::Fl3 => "fl3",
            Mnemonic::Fl4 => "fl4",
            Mnemonic::Tl1 => "tl1",
            Mnemonic::Tl2 => "tl2",
            Mnemonic::Tl3 => "tl3",
            Mnemonic::Tl4 => "tl4",
            Mnemonic::Pli => "pli",
            Mnemonic::Tli => "tli",
            Mnemonic::Tdi => "tdi",
            Mnemonic::Aap => "aap",
            Mnemonic::Adp => "adp",
            Mnemonic::Aan => "aan",
            Mnemonic::Adn => "adn",
            Mnemonic::Tla => "tla",
            Mnemonic::Asr => "asr",
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

/// An operand: an area letter with a two-digit index, or a named operand.
///
/// `K` operands are labels only; the value is the line's constant.
///
/// The tag's values are spread (`Sft = 100`, order unchanged) only for the layout of
/// [`Program`]: with fewer free tag values here than in [`Mnemonic`] (1..=67), an empty
/// line (`None`) is stored as mnemonic byte 0, so that an empty program is zero bytes
/// (see [`Program::default`]). Nothing stores or sends this tag (the line format is
/// `program::encode`'s).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[repr(u8)]
pub enum Operand {
    /// Digital input D00-D15 (bit; [`DIGITAL_INPUTS`]).
    D(u8),
    /// Digital output O00-O07 (bit; [`DIGITAL_OUTPUTS`]).
    O(u8),
    /// Bit memory B00-B99 (bit).
    B(u8),
    /// Analog input A00-A03 (int).
    A(u8),
    /// Constant label K00-K99 (int; value from the line's constant).
    K(u8),
    /// Integer variable Q00-Q63 (int).
    Q(u8),
    /// Drive's aux ADC channel (int).
    Com,
    /// Convert P from DC-link ADC counts to 0.1 V (only with `LD`).
    Vlt,
    /// Convert P from current ADC counts to 0.1 A (only with `LD`).
    Amp,
    /// Direct duty of phase pair 1 (drive `WR` only).
    Pw1,
    /// Direct duty of phase pair 2 (drive `WR` only).
    Pw3,
    /// Direct duty of phase pair 3 (drive `WR` only).
    Pw5,
    /// Extension: drive's output frequency, 0.1 Hz (int, read-only).
    Frq,
    /// Extension: DC-link voltage, 0.1 V (int, read-only).
    Udc,
    /// Extension: largest |phase current| in the last 10 ms, 0.01 A (int, read-only).
    Imx,
    /// Extension: latched drive fault code (int, read-only).
    Flt,
    /// Extension: applied direction, 0 forward 1 reverse (int, read-only).
    Dir,
    /// Extension: drive ready (bit, LD/LDC only).
    Rdy,
    /// Extension: any fault latched (bit, LD/LDC only).
    Flb,
    /// Extension: hardware overcurrent threshold in effect (`I>>`), 0.01 A (int, read-only).
    Ihw,
    /// Extension: hardware overvoltage threshold in effect (`U>>`), V (int, read-only).
    Uhw,
    /// Safety function x (`SFR x`, `LD x`, `LDC x`; bit, read-only status, safety.md 5).
    Sf(SafetyFunction),
    /// `SDC`: a ramp function is in its delay or ramp phase (bit, read-only).
    Sdc,
    /// `SFT`: the safety stopwatch, 0.1 s (int, read-only).
    Sft = 100,
}

/// One program line's instruction.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Instruction {
    pub mnemonic: Mnemonic,
    pub operand: Option<Operand>,
    /// The 4-digit constant (0..=9999); meaningful only when the operand is `K`, and 0
    /// otherwise.
    pub constant: u16,
}

/// A whole program: 1000 lines, each empty (`None`) or one instruction.
#[derive(Clone, PartialEq, Eq)]
pub struct Program {
    pub lines: [Option<Instruction>; LINES],
}

impl Default for Program {
    /// No line. Zero bytes (an empty line is a zero mnemonic byte, see [`Operand`]), made
    /// from a constant: the compiler writes it with one `memset` straight where it goes
    /// (the PLC image builds its application in its static slot, never in a 6 KB
    /// temporary on the stack; CI's stack step fails on a frame over 2 KiB), where a
    /// `[None; LINES]` expression is a loop into a temporary and then a copy.
    fn default() -> Self {
        Self::EMPTY
    }
}

impl Program {
    const EMPTY: Program = Program {
        lines: [None; LINES],
    };
}

impl core::fmt::Debug for Program {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let mut list = f.debug_map();
        for (n, line) in self.lines.iter().enumerate() {
            if let Some(i) = line {
                list.entry(&n, i);
            }
        }
        list.finish()
    }
}

impl Program {
    /// The instruction on `line`, `None` when empty or out of range.
    pub fn get(&self, line: u16) -> Option<&Instruction> {
        self.lines.get(line as usize).and_then(|l| l.as_ref())
    }

    /// The non-empty lines of one section, in ascending order.
    pub fn section(&self, section: Section) -> impl Iterator<Item = (u16, &Instruction)> {
        let range = match section {
            Section::Drive => 0..DRIVE_LINES,
            Section::Plc => DRIVE_LINES..LINES,
        };
        self.lines
            .get(range.clone())
            .unwrap_or(&[])
            .iter()
            .zip(range)
            .filter_map(|(l, n)| l.as_ref().map(|i| (n as u16, i)))
    }

    /// The drive section as the drive MCU holds it.
    pub fn drive_section(&self) -> DriveSection {
        let mut d = DriveSection::default();
        for (n, i) in self.section(Section::Drive) {
            if let Some(slot) = d.lines.get_mut(n as usize) {
                *slot = Some(*i);
            }
        }
        d
    }
}

/// Lines 000-149 only: what the drive MCU stores and executes.
#[derive(Clone, PartialEq, Eq, Debug)]
pub struct DriveSection {
    pub lines: [Option<Instruction>; DRIVE_LINES],
}

impl Default for DriveSection {
    fn default() -> Self {
        DriveSection {
            lines: [None; DRIVE_LINES],
        }
    }
}
