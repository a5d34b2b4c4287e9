//! The PLC logic VM: executes lines 150-999 of a verified [`Program`] scan after scan
//! (program.md section 3). See `docs/vm.md` for the decisions the spec leaves open.
//!
//! Sans-IO: one [`PlcVm::scan`] call per scan takes the sampled inputs and the monotonic
//! time and fills [`ScanOutputs`]. It never panics and never allocates, on any
//! [`Program`] (lines the verifier would reject execute as no-ops), any inputs and any
//! time (wrapping-safe).
//!
//! At RUN the PLC section is compiled once into a pre-decoded form (`compile.rs`: one
//! 4-byte op per line that does something, operands resolved to memory cells, constants
//! inline) and every scan runs that (`exec.rs`), about four times faster than
//! interpreting the stored lines (docs/vm.md, "Speed"). The direct interpreter is kept,
//! in test builds only, as the oracle of a differential test (`reference.rs`,
//! `differential.rs`).
//!
//! A crate of its own (re-exported as `firmware_plc::vm`) because the image builds it for
//! speed and the rest of the PLC core for size: with one opt-level for both, the scan's
//! loop stops inlining its operations at the size setting (`docs/size.md` of the
//! workspace, "PLC image: VM crate and screen text").
#![cfg_attr(not(test), no_std)]
// The VM touches no registers.
#![forbid(unsafe_code)]
#![cfg_attr(
    not(test),
    deny(
        clippy::unwrap_used,
        clippy::expect_used,
        clippy::indexing_slicing,
        clippy::panic
    )
)]

/// The drive-section mnemonics, as a pattern. The PLC VM's matches (`compile.rs`, and the
/// test interpreter `reference.rs`) list every mnemonic, so that a new one is a compile
/// error until it is given its op or added here (docs/contributing/add-a-plc-instruction.md).
macro_rules! drive_mnemonics {
    () => {
        shared_protocol::program::Mnemonic::Pwf
            | shared_protocol::program::Mnemonic::Pr0
            | shared_protocol::program::Mnemonic::Pr1
            | shared_protocol::program::Mnemonic::Pr2
            | shared_protocol::program::Mnemonic::Pi
            | shared_protocol::program::Mnemonic::Sn1
            | shared_protocol::program::Mnemonic::Sn2
            | shared_protocol::program::Mnemonic::Sn3
            | shared_protocol::program::Mnemonic::RsSet
            | shared_protocol::program::Mnemonic::UcSet
            | shared_protocol::program::Mnemonic::IzSet
            | shared_protocol::program::Mnemonic::CalcDu
            | shared_protocol::program::Mnemonic::DuSet
            | shared_protocol::program::Mnemonic::UMax
            | shared_protocol::program::Mnemonic::UMin
            | shared_protocol::program::Mnemonic::IMax
            | shared_protocol::program::Mnemonic::IMaxHw
            | shared_protocol::program::Mnemonic::UMaxHw
            | shared_protocol::program::Mnemonic::Fmn
            | shared_protocol::program::Mnemonic::Fjm
            | shared_protocol::program::Mnemonic::Fmx
            | shared_protocol::program::Mnemonic::Frv
            | shared_protocol::program::Mnemonic::Fss
            | shared_protocol::program::Mnemonic::Pss
            | shared_protocol::program::Mnemonic::Trd
            | shared_protocol::program::Mnemonic::Ard
            | shared_protocol::program::Mnemonic::Tel
            | shared_protocol::program::Mnemonic::Ts1
            | shared_protocol::program::Mnemonic::Ts2
            | shared_protocol::program::Mnemonic::Fl1
            | shared_protocol::program::Mnemonic::Fl2
            | shared_protocol::program::Mnemonic::Fl3
            | shared_protocol::program::Mnemonic::Fl4
            | shared_protocol::program::Mnemonic::Tl1
            | shared_protocol::program::Mnemonic::Tl2
            | shared_protocol::program::Mnemonic::Tl3
            | shared_protocol::program::Mnemonic::Tl4
            | shared_protocol::program::Mnemonic::Pli
            | shared_protocol::program::Mnemonic::Tli
            | shared_protocol::program::Mnemonic::Tdi
            | shared_protocol::program::Mnemonic::Aap
            | shared_protocol::program::Mnemonic::Adp
            | shared_protocol::program::Mnemonic::Aan
            | shared_protocol::program::Mnemonic::Adn
            | shared_protocol::program::Mnemonic::Tla
            | shared_protocol::program::Mnemonic::Asr
            | shared_protocol::program::Mnemonic::Arc
            | shared_protocol::program::Mnemonic::Art
            | shared_protocol::program::Mnemonic::Arn
    };
}

mod arith;
mod cells;
mod compile;
mod exec;
mod io;
pub mod sample;
mod timer;

#[cfg(test)]
mod differential;
/// The reference interpreter, the oracle of the compiled form: for this crate's tests and,
/// with feature `reference`, for the differential fuzz target (`fuzz/`). The image never
/// enables the feature.
#[cfg(any(test, feature = "reference"))]
pub mod reference;

pub use io::{
    DriveView, ScanInputs, ScanOutputs, Warning, INPUTS, INPUT_MASK, LCD_FIELDS, OUTPUTS,
    OUTPUT_MASK,
};

use cells::Cells;
use compile::Code;
#[cfg(test)]
use shared_protocol::program::{Instruction, Mnemonic, Operand};
use shared_protocol::program::{Program, LINES, PLC_FIRST_LINE};
use shared_protocol::units::Millis;

/// Number of PLC-section lines (150-999), each with its own timer/edge state.
pub const PLC_LINES: usize = LINES - PLC_FIRST_LINE as usize;
/// Bit memory B00-B99.
pub const B_COUNT: usize = 100;
/// Integer variables Q00-Q63 (the count is shared with the drive and the link).
pub use shared_protocol::program::Q_COUNT;

/// The PLC VM: the compiled program with its timer/edge state, the data memory, the
/// first-scan flag and the last direction request. About 7.4 KiB, all inline (no
/// allocation). `Clone` gives a snapshot (e.g. for hil-sim).
#[derive(Clone)]
pub struct PlcVm {
    /// B, O, Q and the inputs of the current scan.
    cells: Cells,
    /// The PLC section compiled at RUN, with its timer/edge state.
    code: Code,
    /// `code` holds the program of this RUN (set by [`PlcVm::start_program`] or by the
    /// first scan after [`PlcVm::start`]).
    compiled: bool,
    /// A scan has run since RUN started (the first-scan rules are off).
    scanned: bool,
    /// Direction set by the last `REV` executed in this RUN.
    rev_state: Direction,
    /// Direction last reported in [`ScanOutputs::rev_request`]; `Unset` at RUN start, so
    /// the first `REV` always reports (the drive may hold an earlier RUN's direction).
    rev_reported: Direction,
}

/// The direction set by a `REV`; `Unset` (none in this RUN yet) is 0.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Direction {
    Unset,
    Forward,
    Reverse,
}

impl Direction {
    fn from_reverse(reverse: bool) -> Self {
        if reverse {
            Direction::Reverse
        } else {
            Direction::Forward
        }
    }
}

impl Default for PlcVm {
    fn default() -> Self {
        Self::new()
    }
}

impl PlcVm {
    /// A VM in the state RUN starts from (as after [`PlcVm::start`]).
    pub const fn new() -> Self {
        Self::EMPTY
    }

    /// The VM as RUN starts it. All zero bytes (see `Direction`, `scanned`, `Code::new`):
    /// the board builds the application in its static slot, and a zero constant is
    /// written there directly, not first on the stack (CI's stack step) or as a copy of
    /// a 7.6 KiB constant in flash.
    const EMPTY: PlcVm = PlcVm {
        cells: Cells::new(),
        code: Code::new(),
        compiled: false,
        scanned: false,
        rev_state: Direction::Unset,
        rev_reported: Direction::Unset,
    };

    /// RUN starts: clears B, Q, the output image and every line's timer/edge state, and
    /// arms the first-scan rule. The first `REV` executed after it reports its direction.
    /// The program is compiled by the first [`PlcVm::scan`] (use
    /// [`PlcVm::start_program`] to compile it now). `now` is not needed: a timer starts
    /// at the first scan that sees its input.
    pub fn start(&mut self, _now: Millis) {
        self.cells = Cells::new();
        self.code.clear();
        self.compiled = false;
        self.scanned = false;
        self.rev_state = Direction::Unset;
        self.rev_reported = Direction::Unset;
    }

    /// RUN starts with `program` (verified by the caller): [`PlcVm::start`], then the PLC
    /// section is compiled at once, so the first scan takes no longer than the others.
    /// Every scan of this RUN executes this program, whatever [`PlcVm::scan`] is given.
    pub fn start_program(&mut self, program: &Program, now: Millis) {
        self.start(now);
        self.code.compile(program, now);
        self.compiled = true;
    }

    /// The PLC's copy of Qn (0 for n out of range).
    pub fn q(&self, addr: u8) -> i16 {
        self.cells.q(addr)
    }

    /// Bit memory Bn (false for n out of range).
    pub fn b(&self, addr: u8) -> bool {
        self.cells.b(addr)
    }

    /// Output image On as the last scan left it.
    pub fn output(&self, n: u8) -> bool {
        n < OUTPUTS && self.cells.outputs() & (1 << n) != 0
    }

    /// `true` until the first scan after [`PlcVm::start`] has run.
    pub fn is_first_scan(&self) -> bool {
        !self.scanned
    }

    /// One scan: executes lines 150-999 in order with the inputs sampled by the caller at
    /// the start of the scan and `now` from the monotonic ms clock; overwrites `out`.
    ///
    /// The first scan after [`PlcVm::start`] compiles `program`; the later scans of the
    /// RUN execute that compiled form and do not read `program` (pass the same one; the
    /// PLC application cannot change its program while running). S and P start every scan
    /// at 0.
    pub fn scan(
        &mut self,
        program: &Program,
        inputs: &ScanInputs,
        now: Millis,
        out: &mut ScanOutputs,
    ) {
        if !self.compiled {
            self.code.compile(program, now);
            self.compiled = true;
        }
        *out = ScanOutputs::default();
        self.cells.load_inputs(inputs);
        let env = exec::Env {
            now,
            first_scan: !self.scanned,
        };
        if let Some(rev) = exec::run(self.code.slots(), &mut self.cells, &env, out) {
            self.rev_state = Direction::from_reverse(rev);
        }
        if self.rev_state != Direction::Unset && self.rev_state != self.rev_reported {
            self.rev_reported = self.rev_state;
            out.rev_request = Some(self.rev_state == Direction::Reverse);
        }
        if let Some(sf) = self.cells.sf_changed() {
            out.sf_request = Some(sf);
        }
        out.outputs = self.cells.outputs() & OUTPUT_MASK;
        self.scanned = true;
    }
}

#[cfg(test)]
mod tests;
