//! What a scan reads and what it reports: plain data, so the board layer, the link endpoint,
//! the LCD and hil-sim can fill and read it without knowing the VM.

use shared_protocol::program::{DIGITAL_INPUTS, DIGITAL_OUTPUTS};
use shared_protocol::units::{CentiAmps, Decihertz, Decivolts, Volts};

/// Number of `LCD` value fields on the run screen (program.md 3.2).
pub const LCD_FIELDS: usize = 4;
/// Number of digital inputs D00-D15 (`shared_protocol::program::DIGITAL_INPUTS`).
pub const INPUTS: u8 = DIGITAL_INPUTS;
/// Number of digital outputs O00-O07 (`shared_protocol::program::DIGITAL_OUTPUTS`).
pub const OUTPUTS: u8 = DIGITAL_OUTPUTS;
/// Mask of the valid bits of [`ScanInputs::digital`].
pub const INPUT_MASK: u16 = (u32::MAX >> (32 - INPUTS as u32)) as u16;
/// Mask of the valid bits of [`ScanOutputs::outputs`].
pub const OUTPUT_MASK: u8 = (u32::MAX >> (32 - OUTPUTS as u32)) as u8;

// The images are `u16` (inputs) and `u8` (outputs): more I/O would need wider types.
const _: () = assert!(INPUTS >= 1 && INPUTS <= 16 && OUTPUTS >= 1 && OUTPUTS <= 8);

/// The drive's status as last reported over the link: the source of `COM` and the
/// extension operands (program.md 3.4).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DriveView {
    /// Aux ADC channel, 10-bit; larger values are clamped to 1023.
    pub com: u16,
    /// `FRQ`: actual commanded output frequency.
    pub frq: Decihertz,
    /// `UDC`: DC-link voltage.
    pub udc: Decivolts,
    /// `IMX`: largest |phase current| in the last 10 ms.
    pub imx: CentiAmps,
    /// `FLT`: latched fault code, 0 = none.
    pub flt: u8,
    /// `DIR`: applied direction (`true` = reverse, read as 1).
    pub dir_reverse: bool,
    /// `RDY`: drive ready, no fault, program running.
    pub ready: bool,
    /// `FLB`: any fault latched.
    pub fault_latched: bool,
    /// `IHW`: hardware overcurrent threshold in effect (`I>>`), 0.01 A.
    pub ihw: CentiAmps,
    /// `UHW`: hardware overvoltage threshold in effect (`U>>`), V.
    pub uhw: Volts,
    /// `LD STO` .. `LD SLA`: the safety functions' status bits (bit n = function n
    /// requested and in its safe state, safety.md 5).
    pub sf_status: u16,
    /// `LD SDC`: a ramp function is in its delay or ramp phase.
    pub sf_sdc: bool,
    /// `LD SFT`: the safety stopwatch, 0.1 s.
    pub sf_elapsed_ds: u16,
    /// `LD SFP`: whole commanded field turns since the safety request.
    pub sf_turns: i16,
}

/// Everything one scan reads from the outside world.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ScanInputs {
    /// D00..D15, bit n = Dn; sampled by the caller once at the start of the scan.
    pub digital: u16,
    /// A00..A03 in ADC counts 0..1023 (larger values are clamped to 1023).
    pub analog: [u16; 4],
    pub drive: DriveView,
}

/// A run-time warning raised by a scan; the scan itself goes on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Warning {
    /// `DIV` by zero on this program line (shown as `DIV0 @ line`); P was set to 0.
    Div0 { line: u16 },
}

impl core::fmt::Display for Warning {
    /// The LCD status-line text, e.g. `DIV0 @ 151`.
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Warning::Div0 { line } => write!(f, "DIV0 @ {line:03}"),
        }
    }
}

/// Everything one scan produces. [`crate::PlcVm::scan`] overwrites all of it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ScanOutputs {
    /// Output image O00..O07 (bit n = On) to write to the pins now.
    pub outputs: u8,
    /// The `LCD` fields filled by this scan, in execution order; `None` = no `LCD` reached it.
    pub lcd: [Option<i16>; LCD_FIELDS],
    /// Bit n set = Qn was written by `WR`/`WRC` in this scan (even with an unchanged
    /// value); the value to send is [`crate::PlcVm::q`]`(n)`, the newest write wins.
    pub q_dirty: u64,
    /// Direction request for the drive (`true` = reverse): on the first scan that executes
    /// a `REV` after RUN starts, then only when it differs from the last one reported.
    pub rev_request: Option<bool>,
    /// An `ACK` saw a rising edge: acknowledge the drive's latched faults.
    pub ack_request: bool,
    /// The safety request mask (bit n set = function n requested, i.e. its `SFR` control
    /// bit is 0) when this scan changed it; 0 at RUN start, so only a change is reported.
    pub sf_request: Option<u16>,
    /// The first run-time warning of this scan.
    pub warning: Option<Warning>,
    /// An `ALM K` saw a rising edge of S0: application fault K (1..=99), for the fault
    /// log. One per scan: an `ALM` whose edge comes after the reported one keeps its edge
    /// for the next scan (reported then if its S0 is still 1).
    pub alarm: Option<u8>,
}

impl ScanOutputs {
    /// The Q addresses written in this scan, ascending.
    pub fn dirty_q(&self) -> impl Iterator<Item = u8> + '_ {
        (0u8..64).filter(move |n| self.q_dirty & (1u64 << n) != 0)
    }

    /// Output On as the scan left it.
    pub fn output(&self, n: u8) -> bool {
        n < OUTPUTS && self.outputs & (1 << n) != 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn warning_text_names_the_line() {
        assert_eq!(Warning::Div0 { line: 151 }.to_string(), "DIV0 @ 151");
    }

    #[test]
    fn dirty_q_lists_written_addresses() {
        let out = ScanOutputs {
            q_dirty: (1 << 0) | (1 << 2) | (1 << 63),
            ..ScanOutputs::default()
        };
        assert_eq!(out.dirty_q().collect::<Vec<_>>(), vec![0, 2, 63]);
    }
}
