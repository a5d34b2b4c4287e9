//! Test rig shared by the `vm_*` scenario tests: assembles `.plc` text, verifies it,
//! and drives a [`PlcVm`] scan by scan with explicit times.
#![allow(dead_code)]

use plc_vm::{PlcVm, ScanInputs, ScanOutputs};
use shared_protocol::program::{assemble, verify, Program};
use shared_protocol::units::Millis;

pub struct Rig {
    pub vm: PlcVm,
    pub prog: Program,
    pub inputs: ScanInputs,
    pub now: u32,
    pub out: ScanOutputs,
}

impl Rig {
    /// Assembles and verifies `text` (panics with the assembler's message otherwise) and
    /// starts RUN at t = 0.
    pub fn new(text: &str) -> Rig {
        let prog = assemble(text).unwrap_or_else(|e| panic!("assemble: {e}"));
        verify(&prog).unwrap_or_else(|e| panic!("verify: {e:?}"));
        let mut vm = PlcVm::new();
        vm.start(Millis(0));
        Rig {
            vm,
            prog,
            inputs: ScanInputs::default(),
            now: 0,
            out: ScanOutputs::default(),
        }
    }

    pub fn scan(&mut self) -> ScanOutputs {
        self.vm
            .scan(&self.prog, &self.inputs, Millis(self.now), &mut self.out);
        self.out
    }

    pub fn scan_at(&mut self, t_ms: u32) -> ScanOutputs {
        self.now = t_ms;
        self.scan()
    }

    /// Advances the clock by `dt_ms` and scans.
    pub fn step(&mut self, dt_ms: u32) -> ScanOutputs {
        self.now = self.now.wrapping_add(dt_ms);
        self.scan()
    }

    pub fn d(&mut self, i: u8, v: bool) {
        if v {
            self.inputs.digital |= 1 << i;
        } else {
            self.inputs.digital &= !(1 << i);
        }
    }

    /// One scan with Dn pressed, then one with it released.
    pub fn press(&mut self, i: u8, dt_ms: u32) -> (ScanOutputs, ScanOutputs) {
        self.d(i, true);
        let down = self.step(dt_ms);
        self.d(i, false);
        let up = self.step(dt_ms);
        (down, up)
    }
}
