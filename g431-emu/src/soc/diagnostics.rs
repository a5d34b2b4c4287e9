//! What a run found that a test or a user should see: unmodelled and unmapped accesses,
//! accesses to unclocked peripherals, stuck polls, floating inputs, registers only stored,
//! the models' own reports, each once; and the stack's high-water mark.

use super::bus::DBGMCU_BASE;
use super::{Soc, FLASH_BASE, RAM_BASE, RAM_BYTES};
use crate::names;

/// Registers of the RCC and PWR models that are plain storage: their value changes nothing
/// in the emulator, so the first change of each is reported (they were
/// accepted silently). (block, offset, what the silicon would do with it.)
pub const STORED_ONLY: &[(&str, u32, &str)] = &[
    (
        "PWR",
        0x08,
        "CR3: wake-up pins, standby pulls (APC), UCPD dead-battery pulls",
    ),
    ("PWR", 0x0C, "CR4: wake-up polarity, VBAT charging"),
    (
        "PWR",
        0x20,
        "PUCRA..PDCRG: pulls applied in Standby/Shutdown",
    ),
    ("RCC", 0x68, "AHB1SMENR: clocks kept in Sleep mode"),
    ("RCC", 0x6C, "AHB2SMENR"),
    ("RCC", 0x70, "AHB3SMENR"),
    ("RCC", 0x78, "APB1SMENR1"),
    ("RCC", 0x7C, "APB1SMENR2"),
    ("RCC", 0x80, "APB2SMENR"),
    ("RCC", 0x9C, "CCIPR2: I2C4 and QUADSPI kernel clocks"),
];

/// Register `offset` of block `name` is plain storage ([`STORED_ONLY`]; PWR's PUCRx/PDCRx
/// are one entry for 0x20..0x5C).
pub(super) fn is_stored_only(name: &str, offset: u32) -> bool {
    let offset = if name == "PWR" && (0x20..0x60).contains(&offset) {
        0x20
    } else {
        offset
    };
    STORED_ONLY
        .iter()
        .any(|(b, o, _)| *b == name && *o == offset)
}

/// Something a run found that a test or a user should see.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Diagnostic {
    /// A register no model implements, by name (first access only).
    Unmodelled { what: String, write: bool },
    /// An access to a peripheral whose RCC clock is off (reads 0, writes ignored, as on
    /// the chip).
    Unclocked { what: String, write: bool },
    /// An access to an address where nothing is mapped.
    Unmapped { addr: u32, write: bool },
    /// A polling loop on a register that nothing will ever change.
    StuckPoll { what: String, value: u32 },
    /// An input pin read while nothing drives it and no pull is on.
    FloatingInput { pin: String },
    /// A register the model only stores was changed (first change only): the silicon would
    /// act on the new value, the emulator does not ([`STORED_ONLY`]).
    StoredOnly { what: String, value: u32 },
    /// A model saw the software use something it does not model, or use it in a way the
    /// reference manual forbids.
    Model(String),
}

impl std::fmt::Display for Diagnostic {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Diagnostic::Unmodelled { what, write } => {
                let rw = if *write { "write to" } else { "read of" };
                write!(f, "{rw} unmodelled register {what}")
            }
            Diagnostic::Unclocked { what, write } => {
                let rw = if *write { "write to" } else { "read of" };
                write!(f, "{rw} {what} while its clock is off")
            }
            Diagnostic::Unmapped { addr, write } => {
                let rw = if *write { "write to" } else { "read of" };
                write!(f, "{rw} unmapped address {addr:#010x}")
            }
            Diagnostic::StuckPoll { what, value } => write!(
                f,
                "busy-wait on {what} (reads {value:#010x}) that nothing will ever change"
            ),
            Diagnostic::FloatingInput { pin } => write!(f, "input {pin} read while floating"),
            Diagnostic::StoredOnly { what, value } => write!(
                f,
                "{what} set to {value:#010x}: stored only, its effect is not modelled"
            ),
            Diagnostic::Model(m) => write!(f, "{m}"),
        }
    }
}

/// How deep a flip-link stack has been ([`Soc::stack_high_water`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StackUse {
    /// The whole stack: from the bottom of RAM to the initial stack pointer.
    pub size_bytes: u32,
    /// The deepest it has been.
    pub used_bytes: u32,
}

impl Soc {
    /// What the run found so far.
    pub fn diagnostics(&self) -> &[Diagnostic] {
        &self.diagnostics
    }

    pub(super) fn report(&mut self, key: (u32, bool, u8), d: Diagnostic) {
        if self.seen.insert(key, ()).is_none() {
            self.diagnostics.push(d);
        }
    }

    /// An access where no model is mapped: a peripheral of the chip without a model yet is
    /// reported by register name, anything else as an unmapped address.
    pub(super) fn report_missing(&mut self, addr: u32, write: bool) {
        let d = match names::locate(addr) {
            Some(_) => Diagnostic::Unmodelled {
                what: names::describe(addr),
                write,
            },
            None => Diagnostic::Unmapped { addr, write },
        };
        self.report((addr, write, 0), d);
    }

    /// A DBGMCU offset the model does not implement (PPB: the metadata does not name it).
    pub(super) fn report_unmodelled_dbgmcu(&mut self, addr: u32, write: bool) {
        self.report(
            (addr, write, 2),
            Diagnostic::Unmodelled {
                what: format!("DBGMCU+{:#x}", addr - DBGMCU_BASE),
                write,
            },
        );
    }

    /// Collects what the models reported since the last call.
    pub fn collect_reports(&mut self) {
        let mut out: Vec<String> = Vec::new();
        for s in self.slots.iter_mut() {
            out.extend(s.model.take_reports());
        }
        for r in out {
            let key = {
                let mut h: u32 = 0x811C_9DC5;
                for b in r.bytes() {
                    h = (h ^ u32::from(b)).wrapping_mul(0x0100_0193);
                }
                h
            };
            self.report((key, false, 5), Diagnostic::Model(r));
        }
    }

    /// The stack's high-water mark since power-on, for an image linked with flip-link
    /// (its initial stack pointer, word 0 of the vector table, is the top of a stack at
    /// the bottom of RAM, below every static). RAM powers up zeroed here (on silicon it
    /// holds noise), so the lowest non-zero byte below the initial stack pointer is the
    /// deepest the stack has been: an image that writes only zeros to its deepest words
    /// reads a few bytes shallower than it was. `None` when word 0 is not in RAM.
    pub fn stack_high_water(&self) -> Option<StackUse> {
        let top = self.mem_word(FLASH_BASE)?;
        let size = top
            .checked_sub(RAM_BASE)
            .filter(|&n| n as usize <= RAM_BYTES)?;
        let region = self.ram.get(..size as usize)?;
        let untouched = region.iter().take_while(|&&b| b == 0).count() as u32;
        Some(StackUse {
            size_bytes: size,
            used_bytes: size - untouched,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::super::BareBoard;
    use super::*;

    fn soc() -> Soc {
        Soc::new(vec![0xFF; 16], Box::new(BareBoard))
    }

    #[test]
    fn stack_high_water_is_the_lowest_written_byte_below_the_initial_sp() {
        // Vector table word 0: a 0x2800-byte flip-link stack.
        let mut flash = vec![0xFF; 16];
        flash[..4].copy_from_slice(&(RAM_BASE + 0x2800).to_le_bytes());
        let mut s = Soc::new(flash, Box::new(BareBoard));
        let fresh = s.stack_high_water().unwrap();
        assert_eq!((fresh.size_bytes, fresh.used_bytes), (0x2800, 0));
        // A push 0x40 bytes below the top, then a deeper one; a static above the top
        // does not count.
        s.ram[0x2800 - 0x40] = 1;
        s.ram[0x2900] = 7;
        assert_eq!(s.stack_high_water().unwrap().used_bytes, 0x40);
        s.ram[0x1000] = 0xAA;
        s.ram[0x2800 - 0x40] = 0;
        assert_eq!(s.stack_high_water().unwrap().used_bytes, 0x1800);
        // Word 0 outside RAM (no flip-link stack): no figure.
        assert_eq!(soc().stack_high_water(), None);
    }

    #[test]
    fn a_change_of_a_stored_only_register_is_reported_once() {
        let mut s = soc();
        // PWR is clocked by APB1ENR1.PWREN; CR4 (wake-up polarity) is stored, not applied.
        s.bus_write(0x4002_1058, 4, 1 << 28);
        s.bus_write(0x4000_700C, 4, 0); // no change: nothing to report
        assert!(s.diagnostics().is_empty(), "{:?}", s.diagnostics());
        s.bus_write(0x4000_700C, 4, 1);
        s.bus_write(0x4000_700C, 4, 3);
        let what: Vec<String> = s.diagnostics().iter().map(|d| d.to_string()).collect();
        assert_eq!(
            what,
            ["PWR.CR4 set to 0x00000001: stored only, its effect is not modelled"]
        );
        // CR1.VOS is modelled (VOSF): not a stored-only report.
        s.bus_write(0x4000_7000, 4, 0x400);
        let stored: Vec<String> = s
            .diagnostics()
            .iter()
            .map(|d| d.to_string())
            .filter(|d| d.contains("stored only"))
            .collect();
        assert_eq!(stored.len(), 1, "{:?}", s.diagnostics());
    }
}
