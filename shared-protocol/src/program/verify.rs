//! The single source of truth on what may run: which mnemonics a section has, which
//! operands each takes, and which constants. The assembler, the keypad editor ("offer only
//! valid choices"), the PLC before RUN and the drive before accepting a download all ask
//! this module, so they can never disagree.
//!
//! Decisions where program.md is silent (also in `docs/program-format.md`):
//! * Compare, arithmetic and timer instructions take `K` or `Q` only, as the spec's table
//!   says. Analog inputs, `COM` and the extension ints (`FRQ UDC IMX FLT DIR`) are read
//!   with `LD` into P and then compared (`LD FRQ` / `GT K00 0200`), the instruction-list
//!   way. `RDY`/`FLB` are bit operands for `LD`/`LDC` only.
//! * `WR`/`WRC` write `O`, `B`, `Q` (never `D`, `A`, `K` or read-only operands).
//! * Every 4-digit constant is 0000-9999 unless the instruction needs more: `DIV` needs
//!   1-9999 (a constant divisor of 0 is a program error, a `Q` divisor of 0 is the run-time
//!   warning), drive `PWF` 0488-9999 Hz (the source's 488 Hz minimum), `PI` limit 0001-9999, `Uc=` 0001-9999 (divisor
//!   of `=dU`), `dU=` 0000-1023, `U>` 0001-9999 (0 would brake permanently), `I>`
//!   0001-9999 (0 would trip at once), `I>>` 0001-0999 and `U>>` 0001-0045 (the hardware
//!   comparator thresholds: within the sensors' full scale, +-10 A and 45 V), `fjm` 0001-9999 (divisor of the V/f ratio), `fmx`
//!   0001-9999. `Rs=`, `Iz=`, `U<` (0 = no undervoltage trip), `fmn`, `frv` and timers
//!   (0.1 s units, 0000-9999 = 0-999.9 s) take 0000-9999.
//! * A constant on a line without a `K` operand must be 0 (the text format has no column
//!   for it).
//! * Every drive parameter is set by one line at most ([`Mnemonic::drive_setting`]; the
//!   safety settings were the first, safety.md 4): a second line is
//!   [`VerifyErrorKind::SettingTwice`], naming the first. The section runs every cycle and
//!   its settings are applied once at load, so the value in force is then the same on
//!   every line and in every cycle, and what the drive reports is what it uses (a second
//!   `fmx` after `SN1` made the drive run above the `fmx` it reported).
//! * The drive section's int stack (program.md 4.1) is tracked line by line
//!   ([`drive_stack_use`]): each 1 ms cycle starts counting from 0 values, `LD` adds one
//!   (at most 5 are kept), `PI` needs four and leaves one, `SN1` needs three, `SN2`/`SN3`
//!   and `WR` need one. The first line that needs more values than the cycle has loaded
//!   before it is the error [`VerifyErrorKind::StackUnderflow`]: such a section would read
//!   zeros or the previous cycle's leftovers (a `SN1` with two values never turns the
//!   motor). There are no jumps in the drive section, so this static count is exactly
//!   what every cycle does.

use core::ops::RangeInclusive;

use super::model::{
    DriveSection, Instruction, Mnemonic, Operand, Program, Section, PLC_FIRST_LINE,
};
use super::operand::{OperandClass, OperandSet};
use crate::safety::{SafetyFunction, SafetySetting, SafetySettings};

use super::mnemonic::PLC_BITS;

/// The operand classes `m` accepts in `section`; `None` when the mnemonic does not exist
/// in that section, [`OperandSet::NONE`] when it takes no operand (the table in
/// `mnemonic.rs`).
pub fn operand_set(m: Mnemonic, section: Section) -> Option<OperandSet> {
    match section {
        Section::Plc => m.plc_operands(),
        Section::Drive => m.drive_operands(),
    }
}

/// The mnemonics of a section, in editor order ([`Mnemonic::ALL`]).
pub fn mnemonics_for(section: Section) -> impl Iterator<Item = Mnemonic> + Clone {
    Mnemonic::ALL
        .into_iter()
        .filter(move |m| operand_set(*m, section).is_some())
}

/// Every valid operand of `m` in `section`, in editor order (classes as in
/// [`OperandClass::ALL`], indices ascending). Yields a single `None` when the mnemonic
/// takes no operand, nothing when the mnemonic is not in the section.
pub fn operands_for(m: Mnemonic, section: Section) -> Operands {
    match operand_set(m, section) {
        None => Operands {
            set: OperandSet::NONE,
            class: 0,
            index: 0,
            none_pending: false,
        },
        Some(set) => Operands {
            set,
            class: 0,
            index: 0,
            none_pending: set.is_empty(),
        },
    }
}

/// Iterator of [`operands_for`].
#[derive(Debug, Clone)]
pub struct Operands {
    set: OperandSet,
    class: usize,
    index: u8,
    none_pending: bool,
}

impl Iterator for Operands {
    type Item = Option<Operand>;

    fn next(&mut self) -> Option<Option<Operand>> {
        if self.none_pending {
            self.none_pending = false;
            return Some(None);
        }
        loop {
            let class = *OperandClass::ALL.get(self.class)?;
            if self.set.contains(class) {
                if let Some(op) = class.operand(self.index) {
                    self.index = self.index.saturating_add(1);
                    return Some(Some(op));
                }
            }
            self.class = self.class.saturating_add(1);
            self.index = 0;
        }
    }
}

/// The constants `m` accepts with operand `op` in `section`; `None` when the line has no
/// constant (no `K` operand, or `K` not valid there).
pub fn constant_range(
    m: Mnemonic,
    section: Section,
    op: Option<Operand>,
) -> Option<RangeInclusive<u16>> {
    if !op.is_some_and(|o| o.is_k()) || !operand_set(m, section)?.contains(OperandClass::K) {
        return None;
    }
    let (min, max) = m.constant_limits();
    Some(min..=max)
}

/// Largest `I>>` (0.01 A): the current sensors' full scale is +-10 A (drive.md
/// "Measurements"), so a comparator threshold at or above it could never be reached.
pub const I_MAX_HW_LIMIT: u16 = 999;
/// Largest `U>>` (V): the DC-link sensor's full scale is 45 V.
pub const U_MAX_HW_LIMIT: u16 = 45;

/// Depth of the drive section's int stack (program.md 4.1).
pub const DRIVE_STACK_DEPTH: u8 = 5;

/// How a drive-section instruction uses the int stack: values it needs on the stack
/// (read or popped), values it pops, values it pushes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StackUse {
    pub needs: u8,
    pub pops: u8,
    pub pushes: u8,
}

/// The stack use of a drive-section mnemonic (program.md 4.2).
pub const fn drive_stack_use(m: Mnemonic) -> StackUse {
    let (needs, pops, pushes) = m.stack_effect();
    StackUse {
        needs,
        pops,
        pushes,
    }
}

/// The number of values loaded in this cycle after a drive instruction, from the number
/// before it (at most [`DRIVE_STACK_DEPTH`]); `Err(depth)` when the instruction needs
/// more than `depth`.
pub const fn drive_stack_step(depth: u8, m: Mnemonic) -> Result<u8, u8> {
    let u = drive_stack_use(m);
    if depth < u.needs {
        return Err(depth);
    }
    let after = depth - u.pops + u.pushes;
    Ok(if after > DRIVE_STACK_DEPTH {
        DRIVE_STACK_DEPTH
    } else {
        after
    })
}

/// Why a line may not run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum VerifyErrorKind {
    /// Line number 1000 or above.
    LineOutOfRange,
    /// The mnemonic belongs to the other section.
    WrongSection {
        mnemonic: Mnemonic,
        section: Section,
    },
    /// The mnemonic needs an operand.
    OperandMissing {
        mnemonic: Mnemonic,
        section: Section,
    },
    /// The mnemonic takes no operand.
    OperandNotAllowed {
        mnemonic: Mnemonic,
        operand: Operand,
    },
    /// The operand's kind is not accepted by this mnemonic in this section.
    OperandWrongKind {
        mnemonic: Mnemonic,
        section: Section,
        operand: Operand,
    },
    /// `LDC` on an int operand (only bits can be loaded complemented).
    LdcOnInt { operand: Operand },
    /// The operand's index is outside its area (`D16`).
    OperandOutOfRange { operand: Operand },
    /// The constant is outside the instruction's range.
    ConstantOutOfRange {
        mnemonic: Mnemonic,
        value: u16,
        min: u16,
        max: u16,
    },
    /// A non-zero constant on a line without a `K` operand.
    ConstantWithoutK { value: u16 },
    /// A drive instruction needs more values on the int stack than the section has loaded
    /// before it in the 1 ms cycle.
    StackUnderflow {
        mnemonic: Mnemonic,
        needs: u8,
        loaded: u8,
    },
    /// A drive parameter set a second time in the drive section (safety.md 4 for the
    /// safety settings, docs/program-format.md "Settings once per section" for all of
    /// them): `mnemonic` is the second line's ([`Mnemonic::setting_name`] names the parameter), `first` is the
    /// line that set it first.
    SettingTwice { mnemonic: Mnemonic, first: u16 },
    /// `SFR x` for a function whose needed setting the drive section lacks (the first
    /// missing one in safety.md 4's order).
    SafetyNeeds {
        function: SafetyFunction,
        setting: SafetySetting,
    },
    /// `SFR x` other than `STO` with a drive section in direct mode (`WR PW1/PW3/PW5`):
    /// v means nothing there.
    SafetyNeedsSine { function: SafetyFunction },
}

/// The LCD text of a verifier error (at most 16 characters, for `NNN:text` on a
/// 20-column row): fixed for most, naming the setting or function for the safety rules.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ShortText {
    Fixed(&'static str),
    /// `fss twice`, `PRx twice` (the parameter, [`Mnemonic::setting_name`])
    Twice(Mnemonic),
    /// `SS2 needs ts2`
    Needs(SafetyFunction, SafetySetting),
    /// `SOS needs sine`
    NeedsSine(SafetyFunction),
}

impl core::fmt::Display for ShortText {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            ShortText::Fixed(t) => f.write_str(t),
            ShortText::Twice(m) => write!(f, "{} twice", m.setting_name()),
            ShortText::Needs(func, s) => write!(f, "{} needs {}", func.name(), s.text()),
            ShortText::NeedsSine(func) => write!(f, "{} needs sine", func.name()),
        }
    }
}

struct ClassList(OperandSet);

impl core::fmt::Display for ClassList {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        for (n, c) in self.0.classes().enumerate() {
            if n > 0 {
                f.write_str(", ")?;
            }
            f.write_str(c.name())?;
        }
        Ok(())
    }
}

fn section_text(section: Section) -> &'static str {
    match section {
        Section::Drive => "drive section (lines 000-149)",
        Section::Plc => "PLC section (lines 150-999)",
    }
}

fn other(section: Section) -> Section {
    match section {
        Section::Drive => Section::Plc,
        Section::Plc => Section::Drive,
    }
}

impl VerifyErrorKind {
    /// At most 16 characters, for a 20x4 LCD status line.
    pub fn short(&self) -> ShortText {
        let fixed = match *self {
            VerifyErrorKind::SettingTwice { mnemonic, .. } => return ShortText::Twice(mnemonic),
            VerifyErrorKind::SafetyNeeds { function, setting } => {
                return ShortText::Needs(function, setting)
            }
            VerifyErrorKind::SafetyNeedsSine { function } => return ShortText::NeedsSine(function),
            VerifyErrorKind::LineOutOfRange => "bad line number",
            VerifyErrorKind::WrongSection { .. } => "wrong section",
            VerifyErrorKind::OperandMissing { .. } => "operand missing",
            VerifyErrorKind::OperandNotAllowed { .. } => "no operand here",
            VerifyErrorKind::OperandWrongKind { .. } => "wrong operand",
            VerifyErrorKind::LdcOnInt { .. } => "LDC needs a bit",
            VerifyErrorKind::OperandOutOfRange { .. } => "operand range",
            VerifyErrorKind::ConstantOutOfRange { .. } => "constant range",
            VerifyErrorKind::ConstantWithoutK { .. } => "constant w/o K",
            VerifyErrorKind::StackUnderflow { .. } => "stack underflow",
        };
        ShortText::Fixed(fixed)
    }
}

impl core::fmt::Display for VerifyErrorKind {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            VerifyErrorKind::LineOutOfRange => f.write_str("line number above 999"),
            VerifyErrorKind::WrongSection { mnemonic, section } => write!(
                f,
                "{} is not allowed in the {}, only in the {}",
                mnemonic.text(),
                section_text(section),
                section_text(other(section))
            ),
            VerifyErrorKind::OperandMissing { mnemonic, section } => write!(
                f,
                "{} needs an operand ({})",
                mnemonic.text(),
                ClassList(operand_set(mnemonic, section).unwrap_or_default())
            ),
            VerifyErrorKind::OperandNotAllowed { mnemonic, operand } => {
                write!(f, "{} takes no operand, found {}", mnemonic.text(), operand)
            }
            VerifyErrorKind::OperandWrongKind {
                mnemonic,
                section,
                operand,
            } => write!(
                f,
                "operand {} not allowed with {} here (expected {})",
                operand,
                mnemonic.text(),
                ClassList(operand_set(mnemonic, section).unwrap_or_default())
            ),
            VerifyErrorKind::LdcOnInt { operand } => write!(
                f,
                "LDC needs a bit operand ({}), {} is an int",
                ClassList(PLC_BITS),
                operand
            ),
            VerifyErrorKind::OperandOutOfRange { operand } => {
                let class = operand.class();
                write!(
                    f,
                    "operand {} out of range ({}00-{}{:02})",
                    operand,
                    class.name(),
                    class.name(),
                    class.count().saturating_sub(1)
                )
            }
            VerifyErrorKind::ConstantOutOfRange {
                mnemonic,
                value,
                min,
                max,
            } => write!(
                f,
                "constant {:04} out of range for {} ({:04}-{:04})",
                value,
                mnemonic.text(),
                min,
                max
            ),
            VerifyErrorKind::StackUnderflow {
                mnemonic,
                needs,
                loaded,
            } => write!(
                f,
                "{} needs {} value{} on the stack, only {} loaded before it in this cycle",
                mnemonic.text(),
                needs,
                if needs == 1 { "" } else { "s" },
                loaded
            ),
            VerifyErrorKind::ConstantWithoutK { value } => write!(
                f,
                "constant {value:04} not allowed: only a K operand takes a constant"
            ),
            VerifyErrorKind::SettingTwice { mnemonic, first } => {
                write!(f, "{} set twice ({first:03})", mnemonic.setting_name())
            }
            VerifyErrorKind::SafetyNeeds { function, setting } => {
                write!(f, "{} needs {}", function.name(), setting.text())
            }
            VerifyErrorKind::SafetyNeedsSine { function } => {
                write!(f, "{} needs sine mode", function.name())
            }
        }
    }
}

/// The first line that may not run, and why.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct VerifyError {
    pub line: u16,
    pub kind: VerifyErrorKind,
}

impl core::error::Error for VerifyError {}

impl core::fmt::Display for VerifyError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "line {:03}: {}", self.line, self.kind)
    }
}

/// Check one line as it would stand on program line `line`.
pub fn verify_line(line: u16, i: &Instruction) -> Result<(), VerifyErrorKind> {
    let section = Section::of_line(line).ok_or(VerifyErrorKind::LineOutOfRange)?;
    let mnemonic = i.mnemonic;
    let set = operand_set(mnemonic, section)
        .ok_or(VerifyErrorKind::WrongSection { mnemonic, section })?;
    match i.operand {
        None if !set.is_empty() => Err(VerifyErrorKind::OperandMissing { mnemonic, section }),
        None => {
            if i.constant != 0 {
                return Err(VerifyErrorKind::ConstantWithoutK { value: i.constant });
            }
            Ok(())
        }
        Some(operand) if set.is_empty() => {
            Err(VerifyErrorKind::OperandNotAllowed { mnemonic, operand })
        }
        Some(operand) => {
            let class = operand.class();
            if !set.contains(class) {
                if mnemonic == Mnemonic::Ldc
                    && operand_set(Mnemonic::Ld, section).is_some_and(|s| s.contains(class))
                {
                    return Err(VerifyErrorKind::LdcOnInt { operand });
                }
                return Err(VerifyErrorKind::OperandWrongKind {
                    mnemonic,
                    section,
                    operand,
                });
            }
            if !operand.in_range() {
                return Err(VerifyErrorKind::OperandOutOfRange { operand });
            }
            match constant_range(mnemonic, section, Some(operand)) {
                Some(r) if !r.contains(&i.constant) => Err(VerifyErrorKind::ConstantOutOfRange {
                    mnemonic,
                    value: i.constant,
                    min: *r.start(),
                    max: *r.end(),
                }),
                Some(_) => Ok(()),
                None if i.constant != 0 => {
                    Err(VerifyErrorKind::ConstantWithoutK { value: i.constant })
                }
                None => Ok(()),
            }
        }
    }
}

/// The first bad line. `PLC` = the lines may include the PLC section, whose `SFR` lines
/// are checked against the drive section's settings (the drive's own check,
/// [`verify_drive`], has no PLC lines and leaves that code out of its image).
fn first_error<const PLC: bool>(lines: &[Option<Instruction>]) -> Result<(), VerifyError> {
    let mut v = Verifier::<PLC>::new();
    for (line, slot) in (0u16..).zip(lines) {
        let Some(i) = slot else { continue };
        v.line(line, i).map_err(|mut e| {
            if let VerifyErrorKind::SettingTwice { mnemonic, first } = &mut e.kind {
                *first = first_line_of(lines, *mnemonic, line);
            }
            e
        })?;
    }
    Ok(())
}

/// The whole-program check fed one used line at a time, in ascending line order: for a
/// program that is not in a [`Program`] (the PLC's service port checks a program written
/// into the EEPROM while it streams it back, with no room for a second `Program`).
/// `verify` and `verify_drive` are this over a program's lines. A `SettingTwice` error
/// gives the repeated line as `first` (only the whole-program check finds the first
/// line again).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Verifier<const PLC: bool> {
    depth: u8,
    // The safety settings the drive section has set (bit = signature position), whether
    // SS1 then needs `fss` (early limit or ramp monitoring on), and whether a leg is in
    // direct mode: the PLC section's `SFR` lines are checked against them (the drive
    // section comes first in line order).
    present: u32,
    // The other drive parameters it has set (`Mnemonic::setting_bit`).
    params: u32,
    ss1_needs_fss: bool,
    direct: bool,
}

/// [`Verifier`] of a whole program (both sections), as [`verify`].
pub type ProgramVerifier = Verifier<true>;

impl<const PLC: bool> Verifier<PLC> {
    pub const fn new() -> Self {
        Verifier {
            depth: 0,
            present: 0,
            params: 0,
            ss1_needs_fss: false,
            direct: false,
        }
    }

    /// Checks used line `line` holding `i` (lines must come in ascending order).
    pub fn line(&mut self, line: u16, i: &Instruction) -> Result<(), VerifyError> {
        let fail = |kind| VerifyError { line, kind };
        verify_line(line, i).map_err(fail)?;
        if line < PLC_FIRST_LINE {
            self.depth = drive_stack_step(self.depth, i.mnemonic).map_err(|loaded| {
                fail(VerifyErrorKind::StackUnderflow {
                    mnemonic: i.mnemonic,
                    needs: drive_stack_use(i.mnemonic).needs,
                    loaded,
                })
            })?;
            let (present, bit) = match i.mnemonic.safety_setting() {
                Some(s) => (&mut self.present, 1u32 << s.index()),
                None => (&mut self.params, i.mnemonic.setting_bit()),
            };
            if *present & bit != 0 {
                return Err(fail(VerifyErrorKind::SettingTwice {
                    mnemonic: i.mnemonic,
                    first: line,
                }));
            }
            *present |= bit;
            self.ss1_needs_fss |=
                matches!(i.mnemonic, Mnemonic::Tel | Mnemonic::Ard) && i.constant > 0;
            self.direct |= i.mnemonic == Mnemonic::Wr
                && matches!(i.operand, Some(Operand::Pw1 | Operand::Pw3 | Operand::Pw5));
        } else if PLC {
            if let (Mnemonic::Sfr, Some(Operand::Sf(function))) = (i.mnemonic, i.operand) {
                if self.direct && function != SafetyFunction::Sto {
                    return Err(fail(VerifyErrorKind::SafetyNeedsSine { function }));
                }
                let missing = function
                    .needed(self.ss1_needs_fss)
                    .iter()
                    .find(|s| self.present & (1 << s.index()) == 0);
                if let Some(&setting) = missing {
                    return Err(fail(VerifyErrorKind::SafetyNeeds { function, setting }));
                }
            }
        }
        Ok(())
    }
}

/// The line that first set the parameter `m` sets ([`Mnemonic::same_setting`]), for the error at
/// the second one (`line`): the verifier keeps only a bit per parameter and finds the
/// line again on this error path.
fn first_line_of(lines: &[Option<Instruction>], m: Mnemonic, line: u16) -> u16 {
    lines
        .iter()
        .take(usize::from(line))
        .position(|l| l.is_some_and(|i| i.mnemonic.same_setting() == m.same_setting()))
        .map_or(line, |n| n as u16)
}

/// The safety settings of a drive section (safety.md 4), as a verified section sets them
/// (each at most once); the signature is [`SafetySettings::signature`] of this.
pub fn safety_settings<'a>(
    lines: impl IntoIterator<Item = &'a Option<Instruction>>,
) -> SafetySettings {
    let mut s = SafetySettings::default();
    for i in lines.into_iter().flatten() {
        if let Some(k) = i.mnemonic.safety_setting() {
            s.set(k, Some(i.constant));
        }
    }
    s
}

/// Whether a program uses the safety functions (any `SFR` or safety setting): it then
/// shows its signature (safety.md 8).
pub fn uses_safety(p: &Program) -> bool {
    p.lines
        .iter()
        .flatten()
        .any(|i| i.mnemonic == Mnemonic::Sfr || i.mnemonic.safety_setting().is_some())
}

/// Check a whole program; the error names the first bad line (ascending). Besides each
/// line's own rules this tracks the drive section's stack ([`drive_stack_step`]).
pub fn verify(p: &Program) -> Result<(), VerifyError> {
    first_error::<true>(&p.lines)
}

/// Check a drive section as the drive receives it (every line must be a drive line).
pub fn verify_drive(d: &DriveSection) -> Result<(), VerifyError> {
    first_error::<false>(&d.lines)
}

/// A drive section that passed [`verify_drive`]. The drive's link verifies a download in
/// its own step; the core then loads this without verifying again (the verifier is
/// ~3 800 Cortex-M4 instructions, a large part of a PWM period).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct VerifiedDriveSection(DriveSection);

impl VerifiedDriveSection {
    /// Verifies `s`.
    pub fn new(s: DriveSection) -> Result<Self, VerifyError> {
        verify_drive(&s)?;
        Ok(VerifiedDriveSection(s))
    }

    /// For the link, which ran [`verify_drive`] on exactly this section in an earlier
    /// step and has not changed it since.
    pub(crate) fn verified_earlier(s: DriveSection) -> Self {
        VerifiedDriveSection(s)
    }

    pub fn section(&self) -> &DriveSection {
        &self.0
    }

    /// The section, moved out (the drive core keeps it).
    pub fn into_section(self) -> DriveSection {
        self.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ins(mnemonic: Mnemonic, operand: Option<Operand>, constant: u16) -> Instruction {
        Instruction {
            mnemonic,
            operand,
            constant,
        }
    }

    /// The streaming check finds what the whole-program check finds: the shipped
    /// programs pass both, and each single-line corruption of them fails both at the same
    /// line with the same kind (a repeated setting's `first` aside).
    #[test]
    fn the_streaming_verifier_agrees_with_verify() {
        let stream = |p: &Program| {
            let mut v = ProgramVerifier::new();
            p.lines
                .iter()
                .enumerate()
                .filter_map(|(n, l)| l.map(|i| (n as u16, i)))
                .try_for_each(|(n, i)| v.line(n, &i))
        };
        let texts = [
            include_str!("../../programs/motor.plc"),
            include_str!("../../programs/lift.plc"),
            include_str!("../../programs/safety_lab.plc"),
            include_str!("../../programs/direct_pwm.plc"),
        ];
        let mut failures = 0;
        for text in texts {
            let p = crate::program::assemble(text).unwrap();
            assert_eq!(stream(&p), Ok(()));
            assert_eq!(verify(&p), Ok(()));
            let used: Vec<usize> = (0..crate::program::LINES)
                .filter(|&n| p.lines[n].is_some())
                .collect();
            for &n in &used {
                for m in [Mnemonic::Ld, Mnemonic::Add, Mnemonic::Wr, Mnemonic::Sfr] {
                    let mut q = p.clone();
                    let i = q.lines[n].as_mut().unwrap();
                    i.mnemonic = m;
                    let (a, b) = (verify(&q), stream(&q));
                    match (a, b) {
                        (Ok(()), Ok(())) => {}
                        (Err(a), Err(b)) => {
                            failures += 1;
                            assert_eq!(a.line, b.line);
                            match (a.kind, b.kind) {
                                (
                                    VerifyErrorKind::SettingTwice { mnemonic: x, .. },
                                    VerifyErrorKind::SettingTwice { mnemonic: y, .. },
                                ) => assert_eq!(x, y),
                                (x, y) => assert_eq!(x, y),
                            }
                        }
                        (a, b) => panic!("line {n}: {a:?} vs {b:?}"),
                    }
                }
            }
        }
        assert!(failures > 10, "{failures}");
    }

    #[test]
    fn every_offered_choice_verifies_and_nothing_else_does() {
        for section in [Section::Drive, Section::Plc] {
            let line = match section {
                Section::Drive => 0,
                Section::Plc => 150,
            };
            for m in Mnemonic::ALL {
                let offered: std::vec::Vec<_> = operands_for(m, section).collect();
                let in_section = mnemonics_for(section).any(|x| x == m);
                assert_eq!(in_section, !offered.is_empty(), "{m:?} {section:?}");
                // All possible operands, including out-of-range indices.
                let mut all: std::vec::Vec<Option<Operand>> = std::vec![None];
                for c in OperandClass::ALL {
                    for idx in 0..=c.count() {
                        all.push(Some(c.operand_unchecked_range(idx)));
                    }
                }
                for op in all {
                    let c = constant_range(m, section, op).map_or(0, |r| *r.start());
                    let ok = verify_line(line, &ins(m, op, c)).is_ok();
                    assert_eq!(ok, offered.contains(&op), "{m:?} {op:?} {section:?}");
                }
            }
        }
    }

    #[test]
    fn editor_order_and_counts() {
        let ld: std::vec::Vec<_> = operands_for(Mnemonic::Ld, Section::Plc).collect();
        assert_eq!(ld.first(), Some(&Some(Operand::D(0))));
        assert_eq!(ld.last(), Some(&Some(Operand::Sfp)));
        // 16 D + 8 O + 100 B + 4 A + 100 K + 64 Q + 12 named + 12 functions, SDC, SFT, SFP.
        assert_eq!(ld.len(), 16 + 8 + 100 + 4 + 100 + 64 + 12 + 15);
        // SFR takes the twelve functions, in bit order; LDC the bits among them.
        let sfr: std::vec::Vec<_> = operands_for(Mnemonic::Sfr, Section::Plc).collect();
        let all: std::vec::Vec<_> = SafetyFunction::ALL
            .iter()
            .map(|&f| Some(Operand::Sf(f)))
            .collect();
        assert_eq!(sfr, all);
        assert!(operands_for(Mnemonic::Ldc, Section::Plc).any(|o| o == Some(Operand::Sdc)));
        assert!(!operands_for(Mnemonic::Ldc, Section::Plc)
            .any(|o| o == Some(Operand::Sft) || o == Some(Operand::Sfp)));
        for m in [
            Mnemonic::Wr,
            Mnemonic::Wrc,
            Mnemonic::Set,
            Mnemonic::Res,
            Mnemonic::Io,
        ] {
            assert!(!operands_for(m, Section::Plc).any(|o| matches!(
                o,
                Some(Operand::Sf(_) | Operand::Sdc | Operand::Sft | Operand::Sfp)
            )));
        }
        let not: std::vec::Vec<_> = operands_for(Mnemonic::Not, Section::Plc).collect();
        assert_eq!(not, std::vec![None]);
        assert_eq!(operands_for(Mnemonic::Pwf, Section::Plc).count(), 0);
        assert_eq!(mnemonics_for(Section::Plc).count(), 31);
        assert_eq!(mnemonics_for(Section::Drive).count(), 51);
        // The safety settings: drive section, K only, 0000-9999.
        for setting in crate::safety::SafetySetting::ALL {
            let m = Mnemonic::of_setting(setting);
            assert_eq!(m.safety_setting(), Some(setting));
            assert_eq!(
                operand_set(m, Section::Drive),
                Some(OperandSet::of(&[OperandClass::K]))
            );
            assert_eq!(operand_set(m, Section::Plc), None);
            assert_eq!(
                constant_range(m, Section::Drive, Some(Operand::K(0))),
                Some(0..=9999)
            );
        }
        assert_eq!(
            constant_range(Mnemonic::IMaxHw, Section::Drive, Some(Operand::K(0))),
            Some(1..=999)
        );
        assert_eq!(
            constant_range(Mnemonic::UMaxHw, Section::Drive, Some(Operand::K(0))),
            Some(1..=45)
        );
    }

    #[test]
    fn constant_ranges() {
        let k = Some(Operand::K(0));
        assert_eq!(
            constant_range(Mnemonic::Pwf, Section::Drive, k),
            Some(488..=9999)
        );
        assert_eq!(
            constant_range(Mnemonic::DuSet, Section::Drive, k),
            Some(0..=1023)
        );
        assert_eq!(
            constant_range(Mnemonic::Div, Section::Plc, k),
            Some(1..=9999)
        );
        assert_eq!(
            constant_range(Mnemonic::Ton, Section::Plc, k),
            Some(0..=9999)
        );
        assert_eq!(
            constant_range(Mnemonic::Ton, Section::Plc, Some(Operand::Q(1))),
            None
        );
        assert_eq!(constant_range(Mnemonic::Pwf, Section::Plc, k), None);
        assert_eq!(constant_range(Mnemonic::Wr, Section::Plc, k), None);
    }

    #[test]
    fn error_kinds() {
        use VerifyErrorKind as E;
        let e = |line, m, op, c| verify_line(line, &ins(m, op, c)).unwrap_err();
        assert!(matches!(e(1000, Mnemonic::Ld, None, 0), E::LineOutOfRange));
        assert!(matches!(
            e(150, Mnemonic::Pwf, Some(Operand::K(0)), 600),
            E::WrongSection { .. }
        ));
        assert!(matches!(
            e(149, Mnemonic::Lcd, None, 0),
            E::WrongSection { .. }
        ));
        assert!(matches!(
            e(150, Mnemonic::Wr, None, 0),
            E::OperandMissing { .. }
        ));
        assert!(matches!(
            e(150, Mnemonic::Not, Some(Operand::B(0)), 0),
            E::OperandNotAllowed { .. }
        ));
        assert!(matches!(
            e(150, Mnemonic::Wr, Some(Operand::A(0)), 0),
            E::OperandWrongKind { .. }
        ));
        assert!(matches!(
            e(10, Mnemonic::Ld, Some(Operand::D(0)), 0),
            E::OperandWrongKind { .. }
        ));
        assert!(matches!(
            e(150, Mnemonic::Ldc, Some(Operand::K(0)), 0),
            E::LdcOnInt { .. }
        ));
        assert!(matches!(
            e(150, Mnemonic::Ld, Some(Operand::D(16)), 0),
            E::OperandOutOfRange { .. }
        ));
        assert!(matches!(
            e(5, Mnemonic::Pwf, Some(Operand::K(0)), 487),
            E::ConstantOutOfRange { .. }
        ));
        assert!(matches!(
            e(150, Mnemonic::Ld, Some(Operand::K(0)), 10000),
            E::ConstantOutOfRange { .. }
        ));
        assert!(matches!(
            e(150, Mnemonic::Ld, Some(Operand::D(0)), 1),
            E::ConstantWithoutK { .. }
        ));
        assert!(matches!(
            e(150, Mnemonic::Lcd, None, 1),
            E::ConstantWithoutK { .. }
        ));
    }

    #[test]
    fn messages() {
        let msg = |k: VerifyErrorKind| std::format!("{k}");
        assert_eq!(
            msg(VerifyErrorKind::OperandOutOfRange {
                operand: Operand::D(16)
            }),
            "operand D16 out of range (D00-D15)"
        );
        assert_eq!(
            msg(VerifyErrorKind::OperandWrongKind {
                mnemonic: Mnemonic::Wr,
                section: Section::Plc,
                operand: Operand::A(0)
            }),
            "operand A00 not allowed with WR here (expected O, B, Q)"
        );
        assert_eq!(
            msg(VerifyErrorKind::ConstantOutOfRange {
                mnemonic: Mnemonic::Pwf,
                value: 100,
                min: 488,
                max: 9999
            }),
            "constant 0100 out of range for PWF (0488-9999)"
        );
        let err = VerifyError {
            line: 7,
            kind: VerifyErrorKind::LineOutOfRange,
        };
        assert_eq!(std::format!("{err}"), "line 007: line number above 999");
    }

    #[test]
    fn short_texts_fit_the_lcd() {
        let kinds = [
            VerifyErrorKind::LineOutOfRange,
            VerifyErrorKind::WrongSection {
                mnemonic: Mnemonic::Ld,
                section: Section::Plc,
            },
            VerifyErrorKind::OperandMissing {
                mnemonic: Mnemonic::Ld,
                section: Section::Plc,
            },
            VerifyErrorKind::OperandNotAllowed {
                mnemonic: Mnemonic::Ld,
                operand: Operand::Com,
            },
            VerifyErrorKind::OperandWrongKind {
                mnemonic: Mnemonic::Ld,
                section: Section::Plc,
                operand: Operand::Com,
            },
            VerifyErrorKind::LdcOnInt {
                operand: Operand::Com,
            },
            VerifyErrorKind::OperandOutOfRange {
                operand: Operand::D(16),
            },
            VerifyErrorKind::ConstantOutOfRange {
                mnemonic: Mnemonic::Ld,
                value: 0,
                min: 0,
                max: 0,
            },
            VerifyErrorKind::ConstantWithoutK { value: 1 },
            VerifyErrorKind::StackUnderflow {
                mnemonic: Mnemonic::Sn1,
                needs: 3,
                loaded: 0,
            },
        ];
        for k in kinds {
            assert!(k.short().to_string().len() <= 16, "{}", k.short());
        }
    }

    #[test]
    fn drive_stack_depth_is_tracked_line_by_line() {
        use crate::program::{assemble, assemble_runnable};
        let k = |v| Some(Operand::K(v));
        let mut d = DriveSection::default();
        // SN1 with only two values: the motor would never turn.
        d.lines[0] = Some(ins(Mnemonic::Ld, k(0), 500));
        d.lines[1] = Some(ins(Mnemonic::Ld, k(1), 0));
        d.lines[2] = Some(ins(Mnemonic::Sn1, None, 0));
        let e = verify_drive(&d).unwrap_err();
        assert_eq!(e.line, 2);
        assert_eq!(
            e.kind,
            VerifyErrorKind::StackUnderflow {
                mnemonic: Mnemonic::Sn1,
                needs: 3,
                loaded: 2
            }
        );
        assert_eq!(
            std::format!("{e}"),
            "line 002: SN1 needs 3 values on the stack, only 2 loaded before it in this cycle"
        );
        // A third value before it: fine (the frequency, then the amplitude, the phase).
        d.lines[0] = None;
        d.lines[5] = Some(ins(Mnemonic::Ld, k(0), 500));
        d.lines[6] = Some(ins(Mnemonic::Ld, k(0), 500));
        d.lines[7] = Some(ins(Mnemonic::Ld, k(0), 0));
        d.lines[8] = Some(ins(Mnemonic::Sn1, None, 0));
        d.lines[1] = None;
        d.lines[2] = None;
        assert_eq!(verify_drive(&d), Ok(()));
        // PI needs four; it leaves one (enough for a WR or SN2, not for SN1).
        let ok = "000 LD K00 0000\n001 LD K01 2000\n002 LD Q00\n003 LD K02 0500\n\
                  004 PI K03 1000\n005 WR Q00\n006 WR PW1\n";
        assert!(assemble_runnable(ok).is_ok());
        let p = crate::program::Program::default();
        assert_eq!(verify(&p), Ok(()));
        let bad = "; ramp\n000 LD K01 2000\n001 LD Q00\n002 LD K02 0500\n003  PI K03 1000\n";
        // The text format alone is fine; the program does not run.
        assert!(assemble(bad).is_ok());
        let e = assemble_runnable(bad).unwrap_err();
        assert_eq!(
            std::format!("{e}"),
            "5:6: PI needs 4 values on the stack, only 3 loaded before it in this cycle"
        );
        // Five loads are the most the stack keeps; the count saturates.
        let mut depth = 0;
        for _ in 0..7 {
            depth = drive_stack_step(depth, Mnemonic::Ld).unwrap();
        }
        assert_eq!(depth, DRIVE_STACK_DEPTH);
        assert_eq!(drive_stack_step(depth, Mnemonic::Pi), Ok(2));
        assert_eq!(drive_stack_step(0, Mnemonic::Wr), Err(0));
        // The PLC section has its own bit stack: not counted.
        let plc = "150 LD D00\n151 WR O00\n";
        assert!(assemble_runnable(plc).is_ok());
    }

    #[test]
    fn program_reports_first_bad_line() {
        let mut p = Program::default();
        p.lines[300] = Some(ins(Mnemonic::Wr, None, 0));
        p.lines[200] = Some(ins(Mnemonic::Ld, Some(Operand::D(16)), 0));
        p.lines[150] = Some(ins(Mnemonic::Ld, Some(Operand::D(0)), 0));
        p.lines[0] = Some(ins(Mnemonic::Pwf, Some(Operand::Q(0)), 0));
        assert_eq!(verify(&p).unwrap_err().line, 200);
        p.lines[200] = None;
        assert_eq!(verify(&p).unwrap_err().line, 300);
        p.lines[300] = None;
        assert_eq!(verify(&p), Ok(()));
        let mut d = p.drive_section();
        assert_eq!(verify_drive(&d), Ok(()));
        d.lines[149] = Some(ins(Mnemonic::Lcd, None, 0));
        assert_eq!(verify_drive(&d).unwrap_err().line, 149);
    }
}

/// The safety rules of safety.md 4: duplicates, the needed settings (exhaustively), direct
/// mode, and the texts.
#[cfg(test)]
mod safety_tests {
    use super::*;
    use crate::program::{assemble, assemble_runnable};
    use crate::safety::{SafetySetting as S, SETTINGS};

    const SINE: &str = "000 LD Q01\n001 LD Q01\n002 LD K00 0000\n003 SN1\n";

    fn with_settings(settings: &[(S, u16)], sfr: &[SafetyFunction]) -> Program {
        let mut text = std::string::String::from(SINE);
        for (n, (s, v)) in settings.iter().enumerate() {
            text += &std::format!("{:03} {} K00 {:04}\n", 10 + n, s.text(), v);
        }
        for (n, f) in sfr.iter().enumerate() {
            text += &std::format!("{:03} SFR {}\n", 197 + n, f.name());
        }
        assemble(&text).unwrap()
    }

    #[test]
    fn a_setting_twice_is_an_error_at_the_second_line_also_on_the_drive() {
        let p = assemble("030 fss K00 0040\n031 fss K01 0041\n").unwrap();
        let e = verify(&p).unwrap_err();
        assert_eq!(
            e,
            VerifyError {
                line: 31,
                kind: VerifyErrorKind::SettingTwice {
                    mnemonic: Mnemonic::Fss,
                    first: 30
                }
            }
        );
        assert_eq!(e.kind.to_string(), "fss set twice (030)");
        assert_eq!(
            std::format!("{:03}:{}", e.line, e.kind.short()),
            "031:fss twice"
        );
        assert_eq!(verify_drive(&p.drive_section()), Err(e));
        // Different settings, and the same K label, are fine.
        let p = assemble("030 fss K00 0040\n031 pss K00 0200\n").unwrap();
        assert_eq!(verify(&p), Ok(()));
    }

    /// Every drive parameter once per section (docs/program-format.md "Settings once per
    /// section"): the issue's section, whose second `fmx` made the drive run at 80.0 Hz
    /// while it reported 50.0 Hz, is refused at the second line, naming the first, by
    /// the PLC and by the drive.
    #[test]
    fn every_drive_setting_twice_is_an_error_naming_both_lines() {
        let p = assemble(
            "000 FMX K00 0900\n001 LD K00 0800\n002 LD K00 0800\n003 LD K00 0000\n\
             004 SN1\n005 FMX K00 0500\n",
        )
        .unwrap();
        let e = verify(&p).unwrap_err();
        assert_eq!(e.to_string(), "line 005: fmx set twice (000)");
        assert_eq!(
            std::format!("{:03}:{}", e.line, e.kind.short()),
            "005:fmx twice"
        );
        assert_eq!(verify_drive(&p.drive_section()), Err(e));
        // Each setting, the same constant or not, K or Q.
        for m in mnemonics_for(Section::Drive).filter(|m| m.drive_setting().is_some()) {
            let operand = operands_for(m, Section::Drive).next().unwrap();
            let i = Instruction {
                mnemonic: m,
                operand,
                constant: constant_range(m, Section::Drive, operand).map_or(0, |r| *r.start()),
            };
            let mut d = DriveSection::default();
            d.lines[7] = Some(i);
            assert_eq!(verify_drive(&d), Ok(()), "{m:?}");
            d.lines[120] = Some(i);
            let e = verify_drive(&d).unwrap_err();
            assert_eq!(
                (e.line, e.kind.to_string()),
                (120, std::format!("{} set twice (007)", m.setting_name()))
            );
        }
        // The alternatives of one parameter: `PR0`/`PR1`/`PR2`, `=dU`/`dU=`, `PWF` K/Q.
        for (text, error, short) in [
            (
                "041 PR0\n043 PR2\n",
                "line 043: PRx set twice (041)",
                "PRx twice",
            ),
            (
                "003 =dU\n004 dU= K03 0512\n",
                "line 004: dU set twice (003)",
                "dU twice",
            ),
            (
                "000 PWF K00 1500\n009 PWF Q00\n",
                "line 009: PWF set twice (000)",
                "PWF twice",
            ),
        ] {
            let p = assemble(text).unwrap();
            let e = verify(&p).unwrap_err();
            assert_eq!(e.to_string(), error);
            assert_eq!(e.kind.short().to_string(), short);
            assert_eq!(verify_drive(&p.drive_section()), Err(e));
        }
        // What the source's examples do stays valid: each parameter once, `=dU` from
        // `Rs=`, `Uc=`, `Iz=`.
        let p =
            assemble("007 Rs= K03 0195\n008 Uc= K04 0030\n009 Iz= K05 0060\n010 =dU\n011 PR1\n")
                .unwrap();
        assert_eq!(verify(&p), Ok(()));
    }

    /// Every function against every subset of its needed settings: the error names the
    /// first missing one in safety.md 4's order, at the `SFR` line.
    #[test]
    fn needed_settings_exhaustively() {
        for f in SafetyFunction::ALL {
            for optional in [false, true] {
                // With the early limit on, SS1 needs fss too.
                let base: std::vec::Vec<(S, u16)> = if optional {
                    std::vec![(S::Tel, 50)]
                } else {
                    std::vec![]
                };
                let needed = f.needed(optional);
                for subset in 0u32..(1 << needed.len()) {
                    let mut set = base.clone();
                    for (b, &s) in needed.iter().enumerate() {
                        if subset & (1 << b) != 0 {
                            set.push((s, 100));
                        }
                    }
                    let p = with_settings(&set, &[f]);
                    let missing = needed
                        .iter()
                        .enumerate()
                        .find(|(b, _)| subset & (1 << b) == 0)
                        .map(|(_, &s)| s);
                    let got = verify(&p);
                    match missing {
                        None => assert_eq!(got, Ok(()), "{f:?} {set:?}"),
                        Some(setting) => {
                            let e = got.unwrap_err();
                            assert_eq!(e.line, 197);
                            assert_eq!(
                                e.kind,
                                VerifyErrorKind::SafetyNeeds {
                                    function: f,
                                    setting
                                }
                            );
                            assert_eq!(
                                e.kind.to_string(),
                                std::format!("{} needs {}", f.name(), setting.text())
                            );
                        }
                    }
                }
            }
        }
        // A setting of 0000 is present (only absent counts as missing).
        let p = with_settings(&[(S::Ts1, 0)], &[SafetyFunction::Ss1]);
        assert_eq!(verify(&p), Ok(()));
        // The rule checks each SFR line: the second one fails here.
        let p = with_settings(
            &[(S::Ts1, 100)],
            &[SafetyFunction::Ss1, SafetyFunction::Ss2],
        );
        assert_eq!(verify(&p).unwrap_err().line, 198);
        assert_eq!(
            std::format!("{}", verify(&p).unwrap_err().kind.short()),
            "SS2 needs ts2"
        );
    }

    #[test]
    fn direct_mode_allows_only_sto() {
        let text = "000 LD K00 0500\n001 WR PW3\n010 fss K01 0040\n011 pss K02 0200\n";
        let p = assemble(&(text.to_string() + "197 SFR STO\n")).unwrap();
        assert_eq!(verify(&p), Ok(()));
        let p = assemble(&(text.to_string() + "197 SFR SOS\n")).unwrap();
        let e = verify(&p).unwrap_err();
        assert_eq!(e.line, 197);
        assert_eq!(e.kind.to_string(), "SOS needs sine mode");
        assert_eq!(e.kind.short().to_string(), "SOS needs sine");
    }

    #[test]
    fn asm_reports_the_rule_at_the_sfr_line() {
        let text = "000 LD Q01\n001 LD Q01\n002 LD K00 0000\n003 SN1\n\
                    010 fss K01 0040\n011 pss K02 0200\n197 SFR SS2\n";
        let e = assemble_runnable(text).unwrap_err();
        assert_eq!(e.to_string(), "7:5: SS2 needs ts2");
        assert_eq!(
            assemble_runnable(&(text.to_string() + "012 ts2 K03 0100\n")).map(|_| ()),
            Ok(())
        );
    }

    #[test]
    fn the_signature_ignores_line_numbers_and_k_labels() {
        let a = assemble("010 fss K00 0040\n011 pss K01 0200\n").unwrap();
        let b = assemble("099 pss K07 0200\n120 fss K09 0040\n").unwrap();
        let sa = safety_settings(a.lines.iter());
        assert_eq!(sa, safety_settings(b.lines.iter()));
        let c = assemble("010 fss K00 0041\n011 pss K01 0200\n").unwrap();
        assert_ne!(sa.signature(), safety_settings(c.lines.iter()).signature());
        assert!(uses_safety(&a));
        assert!(!uses_safety(&assemble(SINE).unwrap()));
        assert!(uses_safety(&assemble("197 SFR STO\n").unwrap()));
        assert_eq!(SETTINGS, 24);
    }
}
