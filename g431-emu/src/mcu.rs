//! One emulated MCU running one image: the CPU with its SoC, the image's symbols and its
//! defmt log.

use std::path::Path;

use anyhow::Result;

use crate::cpu::{Cpu, CpuEvent, CpuState};
use crate::elf::Image;
use crate::log::{DefmtLog, LogLine};
use crate::soc::{Board, Diagnostic, Soc};
use crate::time::Cycles;

/// An MCU with its image.
pub struct Mcu {
    pub name: String,
    cpu: Cpu,
    image: Image,
    log: DefmtLog,
}

impl Mcu {
    /// Loads the ELF at `path` into a G431 on `board` (power-on).
    pub fn load(name: &str, path: &Path, board: Box<dyn Board>) -> Result<Mcu> {
        Mcu::new(name, Image::load(path)?, board)
    }

    /// `image` on a G431 on `board` (power-on).
    pub fn new(name: &str, image: Image, board: Box<dyn Board>) -> Result<Mcu> {
        let cpu = Cpu::new(image.flash.clone(), board)?;
        let log = DefmtLog::new(&image.elf, image.rtt);
        Ok(Mcu {
            name: name.to_string(),
            cpu,
            image,
            log,
        })
    }

    /// Runs to cycle `until` and drains the log.
    pub fn run_until(&mut self, until: Cycles) {
        self.cpu.run_until(until);
        self.log.drain(self.cpu.soc_mut());
    }

    pub fn cpu(&self) -> &Cpu {
        &self.cpu
    }

    pub fn cpu_mut(&mut self) -> &mut Cpu {
        &mut self.cpu
    }

    pub fn soc(&self) -> &Soc {
        self.cpu.soc()
    }

    pub fn soc_mut(&mut self) -> &mut Soc {
        self.cpu.soc_mut()
    }

    pub fn now(&self) -> Cycles {
        self.cpu.now()
    }

    pub fn state(&self) -> CpuState {
        self.cpu.state()
    }

    pub fn image(&self) -> &Image {
        &self.image
    }

    pub fn log(&self) -> &[LogLine] {
        self.log.lines()
    }

    pub fn log_since(&self, from: usize) -> &[LogLine] {
        self.log.since(from)
    }

    pub fn events(&self) -> &[CpuEvent] {
        self.cpu.events()
    }

    pub fn diagnostics(&self) -> &[Diagnostic] {
        self.cpu.soc().diagnostics()
    }

    /// The function the core is in now.
    pub fn where_(&self) -> String {
        self.image.symbolize(self.cpu.pc())
    }
}
