//! Operand classes: the areas (`D`, `O`, ... with their index ranges) and the named
//! operands, as one flat list so that validity tables can be bit sets over it.

use super::model::{Operand, DIGITAL_INPUTS, DIGITAL_OUTPUTS};
use crate::safety::SafetyFunction;

/// Number of Q variables (Q00-Q63): the drive's copies, the PLC's shadows and the link's
/// addresses all have this size.
pub const Q_COUNT: usize = 64;

/// The class of an operand: a lettered area or one named operand.
///
/// The order of [`OperandClass::ALL`] is the order the keypad editor offers operands in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[repr(u8)]
pub enum OperandClass {
    D,
    O,
    B,
    A,
    K,
    Q,
    Com,
    Vlt,
    Amp,
    Pw1,
    Pw3,
    Pw5,
    Frq,
    Udc,
    Imx,
    Flt,
    Dir,
    Rdy,
    Flb,
    Ihw,
    Uhw,
    /// The twelve safety functions (`STO` .. `SLA`), index = the function's bit.
    Sf,
    Sdc,
    Sft,
    Sfp,
}

impl OperandClass {
    /// Every class, in editor order.
    pub const ALL: [OperandClass; 25] = [
        OperandClass::D,
        OperandClass::O,
        OperandClass::B,
        OperandClass::A,
        OperandClass::K,
        OperandClass::Q,
        OperandClass::Com,
        OperandClass::Vlt,
        OperandClass::Amp,
        OperandClass::Pw1,
        OperandClass::Pw3,
        OperandClass::Pw5,
        OperandClass::Frq,
        OperandClass::Udc,
        OperandClass::Imx,
        OperandClass::Flt,
        OperandClass::Dir,
        OperandClass::Rdy,
        OperandClass::Flb,
        OperandClass::Ihw,
        OperandClass::Uhw,
        OperandClass::Sf,
        OperandClass::Sdc,
        OperandClass::Sft,
        OperandClass::Sfp,
    ];

    /// How many operands the class holds (`D` 16: D00-D15; named operands 1).
    pub const fn count(self) -> u8 {
        match self {
            OperandClass::D => DIGITAL_INPUTS,
            OperandClass::O => DIGITAL_OUTPUTS,
            OperandClass::B => 100,
            OperandClass::A => 4,
            OperandClass::K => 100,
            OperandClass::Q => Q_COUNT as u8,
            OperandClass::Sf => SafetyFunction::ALL.len() as u8,
            _ => 1,
        }
    }

    /// Whether the class is a lettered area with a two-digit index.
    pub const fn is_area(self) -> bool {
        matches!(
            self,
            OperandClass::D
                | OperandClass::O
                | OperandClass::B
                | OperandClass::A
                | OperandClass::K
                | OperandClass::Q
        )
    }

    /// Bit operands (PLC bit stack); everything else is an int (or an output register).
    pub const fn is_bit(self) -> bool {
        matches!(
            self,
            OperandClass::D
                | OperandClass::O
                | OperandClass::B
                | OperandClass::Rdy
                | OperandClass::Flb
                | OperandClass::Sf
                | OperandClass::Sdc
        )
    }

    /// The text of the area letter or the named operand, upper case (`"D"`, `"COM"`);
    /// `"STO..SLA"` for the safety functions (each has its own name, [`SafetyFunction::name`]).
    pub const fn name(self) -> &'static str {
        match self {
            OperandClass::D => "D",
            OperandClass::O => "O",
            OperandClass::B => "B",
            OperandClass::A => "A",
            OperandClass::K => "K",
            OperandClass::Q => "Q",
            OperandClass::Com => "COM",
            OperandClass::Vlt => "VLT",
            OperandClass::Amp => "AMP",
            OperandClass::Pw1 => "PW1",
            OperandClass::Pw3 => "PW3",
            OperandClass::Pw5 => "PW5",
            OperandClass::Frq => "FRQ",
            OperandClass::Udc => "UDC",
            OperandClass::Imx => "IMX",
            OperandClass::Flt => "FLT",
            OperandClass::Dir => "DIR",
            OperandClass::Rdy => "RDY",
            OperandClass::Flb => "FLB",
            OperandClass::Ihw => "IHW",
            OperandClass::Uhw => "UHW",
            OperandClass::Sf => "STO..SLA",
            OperandClass::Sdc => "SDC",
            OperandClass::Sft => "SFT",
            OperandClass::Sfp => "SFP",
        }
    }

    /// The operand of this class with this index; `None` when the index is outside the
    /// class (named operands only have index 0).
    pub const fn operand(self, index: u8) -> Option<Operand> {
        if index >= self.count() {
            return None;
        }
        Some(self.operand_unchecked_range(index))
    }

    /// The operand with this index even when the index is outside the area's range
    /// (`D09`); named operands ignore the index. Used by the assembler and decoder, which
    /// leave range checks to the verifier so that errors name the range.
    pub const fn operand_unchecked_range(self, index: u8) -> Operand {
        match self {
            OperandClass::D => Operand::D(index),
            OperandClass::O => Operand::O(index),
            OperandClass::B => Operand::B(index),
            OperandClass::A => Operand::A(index),
            OperandClass::K => Operand::K(index),
            OperandClass::Q => Operand::Q(index),
            OperandClass::Com => Operand::Com,
            OperandClass::Vlt => Operand::Vlt,
            OperandClass::Amp => Operand::Amp,
            OperandClass::Pw1 => Operand::Pw1,
            OperandClass::Pw3 => Operand::Pw3,
            OperandClass::Pw5 => Operand::Pw5,
            OperandClass::Frq => Operand::Frq,
            OperandClass::Udc => Operand::Udc,
            OperandClass::Imx => Operand::Imx,
            OperandClass::Flt => Operand::Flt,
            OperandClass::Dir => Operand::Dir,
            OperandClass::Rdy => Operand::Rdy,
            OperandClass::Flb => Operand::Flb,
            OperandClass::Ihw => Operand::Ihw,
            OperandClass::Uhw => Operand::Uhw,
            OperandClass::Sf => Operand::Sf(SafetyFunction::from_bit_saturating(index)),
            OperandClass::Sdc => Operand::Sdc,
            OperandClass::Sft => Operand::Sft,
            OperandClass::Sfp => Operand::Sfp,
        }
    }

    /// Bit of this class in an [`OperandSet`].
    pub const fn bit(self) -> u32 {
        1 << (self as u8)
    }
}

impl Operand {
    /// The operand's class.
    pub const fn class(&self) -> OperandClass {
        match self {
            Operand::D(_) => OperandClass::D,
            Operand::O(_) => OperandClass::O,
            Operand::B(_) => OperandClass::B,
            Operand::A(_) => OperandClass::A,
            Operand::K(_) => OperandClass::K,
            Operand::Q(_) => OperandClass::Q,
            Operand::Com => OperandClass::Com,
            Operand::Vlt => OperandClass::Vlt,
            Operand::Amp => OperandClass::Amp,
            Operand::Pw1 => OperandClass::Pw1,
            Operand::Pw3 => OperandClass::Pw3,
            Operand::Pw5 => OperandClass::Pw5,
            Operand::Frq => OperandClass::Frq,
            Operand::Udc => OperandClass::Udc,
            Operand::Imx => OperandClass::Imx,
            Operand::Flt => OperandClass::Flt,
            Operand::Dir => OperandClass::Dir,
            Operand::Rdy => OperandClass::Rdy,
            Operand::Flb => OperandClass::Flb,
            Operand::Ihw => OperandClass::Ihw,
            Operand::Uhw => OperandClass::Uhw,
            Operand::Sf(_) => OperandClass::Sf,
            Operand::Sdc => OperandClass::Sdc,
            Operand::Sft => OperandClass::Sft,
            Operand::Sfp => OperandClass::Sfp,
        }
    }

    /// The two-digit index of an area operand, 0 for named operands.
    pub const fn index(&self) -> u8 {
        match self {
            Operand::D(n)
            | Operand::O(n)
            | Operand::B(n)
            | Operand::A(n)
            | Operand::K(n)
            | Operand::Q(n) => *n,
            Operand::Sf(f) => f.bit(),
            _ => 0,
        }
    }

    /// Whether the index lies inside the area (`D00`-`D15`, ...); named operands always do.
    pub const fn in_range(&self) -> bool {
        self.index() < self.class().count()
    }

    /// Whether this is a `K` constant label.
    pub const fn is_k(&self) -> bool {
        matches!(self, Operand::K(_))
    }
}

/// A set of operand classes (one bit per [`OperandClass`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct OperandSet(pub u32);

impl OperandSet {
    /// No operand classes: the mnemonic takes no operand.
    pub const NONE: OperandSet = OperandSet(0);

    pub const fn of(classes: &[OperandClass]) -> OperandSet {
        let mut bits = 0u32;
        let mut i = 0;
        while i < classes.len() {
            // `i < len` is checked just above; const fn cannot use iterators.
            #[allow(clippy::indexing_slicing)]
            {
                bits |= classes[i].bit();
            }
            i += 1;
        }
        OperandSet(bits)
    }

    pub const fn contains(self, class: OperandClass) -> bool {
        self.0 & class.bit() != 0
    }

    pub const fn is_empty(self) -> bool {
        self.0 == 0
    }

    /// The classes in the set, in editor order.
    pub fn classes(self) -> impl Iterator<Item = OperandClass> + Clone {
        OperandClass::ALL
            .into_iter()
            .filter(move |c| self.contains(*c))
    }
}

/// Canonical text: area letter and two digits (`D09`), or the upper-case name (`COM`).
impl core::fmt::Display for Operand {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let class = self.class();
        if class.is_area() {
            write!(f, "{}{:02}", class.name(), self.index())
        } else if let Operand::Sf(func) = self {
            f.write_str(func.name())
        } else {
            f.write_str(class.name())
        }
    }
}
