//! Fixed-point quantities shared by both MCUs, the link and hil-sim. The unit is in the
//! name so that a value can never be read in the wrong scale.

/// A monotonic millisecond clock reading. Wraps after ~49 days: compare with
/// [`Millis::since`], never with `<`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Millis(pub u32);

impl Millis {
    /// Milliseconds elapsed from `earlier` to `self`, correct across one wrap.
    pub const fn since(self, earlier: Millis) -> u32 {
        self.0.wrapping_sub(earlier.0)
    }
    pub const fn add(self, ms: u32) -> Millis {
        Millis(self.0.wrapping_add(ms))
    }
}

/// A monotonic microsecond clock reading (64-bit: never wraps in practice).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, PartialOrd, Ord)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Micros(pub u64);

impl Micros {
    pub const fn millis(self) -> Millis {
        Millis((self.0 / 1000) as u32)
    }
}

/// Frequency in 0.1 Hz (the program's unit for f, fmn, fjm, fmx, frv).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, PartialOrd, Ord)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Decihertz(pub i16);

/// Voltage in 0.1 V (the PLC's `UDC`/`VLT` unit).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, PartialOrd, Ord)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Decivolts(pub i16);

/// Voltage in whole volts (the program's `U>`/`U<`/`U>>`/`Uc=` unit and the PLC's `UHW`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, PartialOrd, Ord)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Volts(pub i16);

/// Current in 0.01 A (the program's `I>`/`Iz=` unit and the PLC's `IMX`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, PartialOrd, Ord)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CentiAmps(pub i16);
