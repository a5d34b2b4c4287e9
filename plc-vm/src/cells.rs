//! The data memory of the compiled form: every bit operand the program can read or write
//! is one cell of [`Cells::bits`], every int operand one cell of [`Cells::ints`], so that
//! a compiled op names its operand by a single `u8` cell index whatever its class.
//!
//! The scan copies its inputs (D, RDY, FLB, A, COM and the drive's ints) into their cells
//! once at its start; B, O and Q live in their cells between scans. Both arrays have 256
//! cells, so any `u8` index is in range and the hot loop needs no bounds check.

use shared_protocol::program::Operand;
use shared_protocol::safety::SafetyFunction;

use super::io::{ScanInputs, INPUTS, OUTPUTS};
use super::{B_COUNT, Q_COUNT};

/// Largest value of the 10-bit analog operands (A, COM).
const ADC_MAX: u16 = 1023;

/// Cells per array: every `u8` index.
pub const CELLS: usize = 256;

/// Bit cells: B00-B99, then O00-O07, D00-D15, RDY, FLB, the 12 safety status bits, SDC,
/// and the 12 safety requests (written by `SFR`: 1 = requested, so that the cleared
/// cells of RUN start request nothing; never read by the program).
const B0: u8 = 0;
const O0: u8 = B0 + B_COUNT as u8;
const D0: u8 = O0 + OUTPUTS;
const RDY: u8 = D0 + INPUTS;
const FLB: u8 = RDY + 1;
const SF0: u8 = FLB + 1;
const SF_COUNT: u8 = SafetyFunction::ALL.len() as u8;
const SDC: u8 = SF0 + SF_COUNT;
const SFR0: u8 = SDC + 1;

/// Int cells: Q00-Q63, then A00-A03, COM, FRQ, UDC, IMX, FLT, DIR, IHW, UHW, SFT, SFP.
const Q0: u8 = 0;
const A0: u8 = Q0 + Q_COUNT as u8;
const COM: u8 = A0 + 4;
const FRQ: u8 = COM + 1;
const UDC: u8 = FRQ + 1;
const IMX: u8 = UDC + 1;
const FLT: u8 = IMX + 1;
const DIR: u8 = FLT + 1;
const IHW: u8 = DIR + 1;
const UHW: u8 = IHW + 1;
const SFT: u8 = UHW + 1;
const SFP: u8 = SFT + 1;
/// The safety request mask last reported (a cell, not a field of the VM: the VM's
/// all-zero start state then stays one block the board's builder writes in place).
const SF_REPORTED: u8 = SFP + 1;

/// B, O, Q (what RUN clears and the program keeps between scans) and the scan's inputs.
#[derive(Clone)]
pub struct Cells {
    pub bits: [bool; CELLS],
    pub ints: [i16; CELLS],
}

impl Cells {
    pub const fn new() -> Self {
        Cells {
            bits: [false; CELLS],
            ints: [0; CELLS],
        }
    }

    /// Copies the inputs sampled at the start of a scan into their cells.
    pub fn load_inputs(&mut self, inputs: &ScanInputs) {
        let d = &inputs.drive;
        for (n, cell) in self
            .bits
            .iter_mut()
            .skip(usize::from(D0))
            .take(usize::from(INPUTS))
            .enumerate()
        {
            *cell = inputs.digital & (1 << n) != 0;
        }
        self.set_bit(RDY, d.ready);
        self.set_bit(FLB, d.fault_latched);
        for n in 0..SF_COUNT {
            self.set_bit(SF0 + n, d.sf_status & (1 << n) != 0);
        }
        self.set_bit(SDC, d.sf_sdc);
        for (cell, &a) in self
            .ints
            .iter_mut()
            .skip(usize::from(A0))
            .zip(inputs.analog.iter())
        {
            *cell = a.min(ADC_MAX) as i16;
        }
        self.set_int(COM, d.com.min(ADC_MAX) as i16);
        self.set_int(FRQ, d.frq.0);
        self.set_int(UDC, d.udc.0);
        self.set_int(IMX, d.imx.0);
        self.set_int(FLT, i16::from(d.flt));
        self.set_int(DIR, i16::from(d.dir_reverse));
        self.set_int(IHW, d.ihw.0);
        self.set_int(UHW, d.uhw.0);
        self.set_int(SFT, d.sf_elapsed_ds.min(i16::MAX as u16) as i16);
        self.set_int(SFP, d.sf_turns);
    }

    /// The safety request mask the `SFR` lines have set (bit n = function n requested).
    pub fn sf_requested(&self) -> u16 {
        (0..SF_COUNT).fold(0, |m, n| m | u16::from(self.bit(SFR0 + n)) << n)
    }

    /// The request mask when it differs from the one last reported (0 at RUN start),
    /// which it then becomes.
    pub fn sf_changed(&mut self) -> Option<u16> {
        let now = self.sf_requested();
        let before = self.int(SF_REPORTED) as u16;
        self.set_int(SF_REPORTED, now as i16);
        (now != before).then_some(now)
    }

    fn set_bit(&mut self, cell: u8, v: bool) {
        if let Some(c) = self.bits.get_mut(usize::from(cell)) {
            *c = v;
        }
    }

    fn set_int(&mut self, cell: u8, v: i16) {
        if let Some(c) = self.ints.get_mut(usize::from(cell)) {
            *c = v;
        }
    }

    pub fn bit(&self, cell: u8) -> bool {
        self.bits.get(usize::from(cell)).copied().unwrap_or(false)
    }

    pub fn int(&self, cell: u8) -> i16 {
        self.ints.get(usize::from(cell)).copied().unwrap_or(0)
    }

    /// Bn (false out of range).
    pub fn b(&self, n: u8) -> bool {
        usize::from(n) < B_COUNT && self.bit(B0 + n)
    }

    /// Qn (0 out of range).
    pub fn q(&self, n: u8) -> i16 {
        if usize::from(n) < Q_COUNT {
            self.int(Q0 + n)
        } else {
            0
        }
    }

    /// The output image O00-O07 as a bit mask (bit n = On).
    pub fn outputs(&self) -> u8 {
        (0..OUTPUTS).fold(0, |m, n| m | u8::from(self.bit(O0 + n)) << n)
    }
}

/// The cell of a readable bit operand (D, O, B inside their ranges, RDY, FLB).
pub fn bit_cell(op: Operand) -> Option<u8> {
    match op {
        Operand::D(n) if n < INPUTS => Some(D0 + n),
        Operand::O(n) if n < OUTPUTS => Some(O0 + n),
        Operand::B(n) if usize::from(n) < B_COUNT => Some(B0 + n),
        Operand::Rdy => Some(RDY),
        Operand::Flb => Some(FLB),
        Operand::Sf(f) => Some(SF0 + f.bit()),
        Operand::Sdc => Some(SDC),
        _ => None,
    }
}

/// The cell `SFR x` writes (1 = requested).
pub fn sfr_cell(f: SafetyFunction) -> u8 {
    SFR0 + f.bit()
}

/// The cell of a writable bit operand (O, B inside their ranges).
pub fn writable_bit_cell(op: Operand) -> Option<u8> {
    match op {
        Operand::O(_) | Operand::B(_) => bit_cell(op),
        _ => None,
    }
}

/// The cell of an int operand other than K (A, Q inside their ranges, COM and the
/// drive's ints).
pub fn int_cell(op: Operand) -> Option<u8> {
    match op {
        Operand::A(n) if n < 4 => Some(A0 + n),
        Operand::Q(n) => q_cell(n),
        Operand::Com => Some(COM),
        Operand::Frq => Some(FRQ),
        Operand::Udc => Some(UDC),
        Operand::Imx => Some(IMX),
        Operand::Flt => Some(FLT),
        Operand::Dir => Some(DIR),
        Operand::Ihw => Some(IHW),
        Operand::Uhw => Some(UHW),
        Operand::Sft => Some(SFT),
        Operand::Sfp => Some(SFP),
        _ => None,
    }
}

/// The cell of Qn inside its range: its cell index is n, which `WR Q` also uses as its
/// bit in [`super::ScanOutputs::q_dirty`].
pub fn q_cell(n: u8) -> Option<u8> {
    (usize::from(n) < Q_COUNT).then_some(Q0 + n)
}

#[cfg(test)]
mod tests {
    use super::*;
    use shared_protocol::units::{CentiAmps, Decihertz, Decivolts};

    #[test]
    fn cells_do_not_overlap_and_fit() {
        let mut bits = vec![];
        for op in (0..=255).flat_map(|n| [Operand::D(n), Operand::O(n), Operand::B(n)]) {
            bits.extend(bit_cell(op));
        }
        bits.extend(bit_cell(Operand::Rdy));
        bits.extend(bit_cell(Operand::Flb));
        bits.extend(bit_cell(Operand::Sdc));
        for f in SafetyFunction::ALL {
            bits.extend(bit_cell(Operand::Sf(f)));
            bits.push(sfr_cell(f));
        }
        let n = bits.len();
        bits.sort();
        bits.dedup();
        assert_eq!(bits.len(), n);
        assert_eq!(n, 16 + 8 + 100 + 2 + 1 + 24);
        let mut ints = vec![];
        for op in (0..=255).flat_map(|n| [Operand::A(n), Operand::Q(n), Operand::K(n)]) {
            ints.extend(int_cell(op));
        }
        for op in [
            Operand::Com,
            Operand::Frq,
            Operand::Udc,
            Operand::Imx,
            Operand::Flt,
            Operand::Dir,
            Operand::Ihw,
            Operand::Uhw,
            Operand::Sft,
            Operand::Sfp,
        ] {
            ints.extend(int_cell(op));
        }
        let n = ints.len();
        ints.sort();
        ints.dedup();
        assert_eq!(ints.len(), n);
        assert_eq!(n, 4 + 64 + 10);
        assert_eq!(q_cell(63), Some(63));
        assert_eq!(q_cell(64), None);
    }

    #[test]
    fn inputs_land_in_their_cells_clamped() {
        let mut c = Cells::new();
        let mut inputs = ScanInputs {
            digital: 0b1000_0000_1000_0001,
            analog: [0, 1023, 1024, u16::MAX],
            ..ScanInputs::default()
        };
        inputs.drive.com = 5000;
        inputs.drive.frq = Decihertz(-7);
        inputs.drive.udc = Decivolts(3);
        inputs.drive.imx = CentiAmps(4);
        inputs.drive.flt = 200;
        inputs.drive.dir_reverse = true;
        inputs.drive.ready = true;
        c.load_inputs(&inputs);
        let bit = |op| c.bit(bit_cell(op).unwrap());
        let int = |op| c.int(int_cell(op).unwrap());
        assert!(bit(Operand::D(0)) && bit(Operand::D(7)) && !bit(Operand::D(1)));
        assert!(bit(Operand::D(15)) && !bit(Operand::D(14)));
        assert!(bit(Operand::Rdy) && !bit(Operand::Flb));
        assert_eq!(
            [0, 1, 2, 3].map(|n| int(Operand::A(n))),
            [0, 1023, 1023, 1023]
        );
        assert_eq!(int(Operand::Com), 1023);
        assert_eq!(int(Operand::Frq), -7);
        assert_eq!(int(Operand::Udc), 3);
        assert_eq!(int(Operand::Imx), 4);
        assert_eq!(int(Operand::Flt), 200);
        assert_eq!(int(Operand::Dir), 1);
        // Inputs never touch B, O, Q.
        assert!((0..100).all(|n| !c.b(n)));
        assert_eq!(c.outputs(), 0);
        assert!((0..64).all(|n| c.q(n) == 0));
    }
}
