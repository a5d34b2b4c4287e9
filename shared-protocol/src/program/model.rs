//! The program model: 1000 lines, each empty or one instruction (program.md section 1).
//!
//! These types are the contract between the assembler, the keypad editor, the EEPROM
//! storage, the link download, and both VMs. A [`Program`] can hold anything the types
//! allow; only [`super::verify`] decides whether it may run.

// Re-exported: the program's types in one place for `super::model::*` users.
pub use super::mnemonic::Mnemonic;
use crate::safety::SafetyFunction;

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
    /// `SFP`: commanded field turns since the safety request (int, read-only).
    Sfp,
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
