//! Program storage in the I2C EEPROM (24C256): program slots, boot record, fault log.
//!
//! Layout and byte format: `docs/eeprom-image.md`. In short:
//! * 4 slots (numbered 1..=4), each with two copies (A, B) carrying a CRC-32 and a
//!   generation counter; a save writes the stale copy completely first, checks it, and
//!   only then overwrites the other one, so at every instant at least one copy holds
//!   either the old or the new program in full. A load uses the newest copy that checks,
//!   and says when the other one is damaged.
//! * A boot record (two copies) names the slot last run and whether to start RUN at
//!   power-up, and counts power-ups (the fault log's clock).
//! * The fault log keeps the newest 32 faults.
//!
//! Everything is synchronous over the [`Eeprom`] trait; [`MemEeprom`] is the RAM model
//! used by tests and hil-sim.

pub mod boot;
pub mod eeprom;
pub mod fault_log;
pub mod image;
pub mod layout;
pub mod slot;

pub use boot::BootRecord;
pub use eeprom::{Eeprom, EepromError, MemEeprom, EEPROM_BYTES, PAGE_BYTES};
pub use fault_log::FaultEntry;
pub use layout::{FAULT_LOG_ENTRIES, SLOTS};
pub use slot::CopyError;

use shared_protocol::program::Program;

/// Why a storage operation failed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum StorageError {
    /// Slot number outside 1..=[`SLOTS`].
    NoSuchSlot(u8),
    /// The slot was never saved.
    Empty(u8),
    /// Both copies of the slot are damaged.
    Damaged(u8),
    /// The program does not fit a slot (cannot happen with 1000 lines of 4 bytes; kept
    /// for a future wider line format).
    TooBig,
    /// The copy just written did not read back correctly (worn or failing EEPROM).
    VerifyFailed,
    Eeprom(EepromError),
}

impl From<EepromError> for StorageError {
    fn from(e: EepromError) -> Self {
        StorageError::Eeprom(e)
    }
}

/// Copy A or B of a slot.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum SlotCopy {
    A,
    B,
}

impl SlotCopy {
    fn index(self) -> u8 {
        match self {
            SlotCopy::A => 0,
            SlotCopy::B => 1,
        }
    }
    pub fn other(self) -> SlotCopy {
        match self {
            SlotCopy::A => SlotCopy::B,
            SlotCopy::B => SlotCopy::A,
        }
    }
    /// The letter shown on the LCD.
    pub fn letter(self) -> char {
        match self {
            SlotCopy::A => 'A',
            SlotCopy::B => 'B',
        }
    }
}

/// State of the copy that was not used by a load.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum OtherCopy {
    /// Same generation: the normal state after a complete save.
    Same,
    /// Valid but older: a save was cut between the two copies (harmless).
    Older,
    /// Damaged or missing (bit flips, or a save cut while writing it): the LCD says so.
    Bad(CopyError),
}

/// How a load went.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct LoadReport {
    pub slot: u8,
    pub used: SlotCopy,
    pub generation: u32,
    pub other: OtherCopy,
}

/// Summary of one slot for the load/save prompts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct SlotInfo {
    pub slot: u8,
    /// Newest valid generation and its used-line count; `None` when the slot is empty.
    pub program: Option<(u32, u16)>,
}

/// What power-up found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct PowerUp {
    /// This power-up's number (1 for a fresh EEPROM).
    pub power_cycle: u32,
    /// The slot loaded into the program, with how the load went.
    pub loaded: Option<Result<LoadReport, StorageError>>,
    /// Start RUN now without a key (the PLC was running that slot at power-off).
    pub run: bool,
}

/// The storage facade the application calls.
pub struct Storage<E: Eeprom> {
    eeprom: E,
    power_cycle: u32,
}

impl<E: Eeprom> Storage<E> {
    pub fn new(eeprom: E) -> Self {
        Storage {
            eeprom,
            power_cycle: 0,
        }
    }

    /// The EEPROM (tests inject faults through it).
    pub fn eeprom(&mut self) -> &mut E {
        &mut self.eeprom
    }

    /// Give the EEPROM back.
    pub fn into_eeprom(self) -> E {
        self.eeprom
    }

    /// The power-up number found by [`Storage::power_up`] (0 before it ran).
    pub fn power_cycle(&self) -> u32 {
        self.power_cycle
    }

    /// Power-up: count the power cycle and load the slot last run into `program`.
    ///
    /// `run` is true only when the PLC was in RUN at power-off and the slot loaded
    /// cleanly or from its second copy; the caller starts RUN then (after verifying, as
    /// for any RUN).
    pub fn power_up(&mut self, program: &mut Program) -> Result<PowerUp, StorageError> {
        let record = boot::read(&mut self.eeprom)?.map(|(r, _)| r);
        let mut record = record.unwrap_or_default();
        record.power_cycles = record.power_cycles.wrapping_add(1);
        let record = boot::write(&mut self.eeprom, record)?;
        self.power_cycle = record.power_cycles;
        let loaded = record.last_run_slot.map(|s| self.load(s, program));
        let run = record.run_at_power_up && matches!(loaded, Some(Ok(_)));
        Ok(PowerUp {
            power_cycle: record.power_cycles,
            loaded,
            run,
        })
    }

    /// Record that `slot` was started (`running` = true) or that the user stopped
    /// (`running` = false, the slot stays the one loaded at power-up).
    ///
    /// RUN of a program that is in no slot (`slot` = `None`: edited since its last load
    /// or save) clears the run-at-power-up flag: after a power cut the PLC must not start
    /// an older program than the one that was running. The last slot is still loaded.
    pub fn set_run_state(&mut self, slot: Option<u8>, running: bool) -> Result<(), StorageError> {
        let running = running && slot.is_some();
        let mut record = boot::read(&mut self.eeprom)?
            .map(|(r, _)| r)
            .unwrap_or_default();
        if let Some(s) = slot {
            if !(1..=SLOTS).contains(&s) {
                return Err(StorageError::NoSuchSlot(s));
            }
        }
        let want_slot = slot.or(record.last_run_slot);
        if record.last_run_slot == want_slot && record.run_at_power_up == running {
            // Nothing changes: spare the EEPROM a write.
            return Ok(());
        }
        record.last_run_slot = want_slot;
        record.run_at_power_up = running;
        boot::write(&mut self.eeprom, record)?;
        Ok(())
    }

    /// The boot record as stored (None on a fresh EEPROM).
    pub fn boot_record(&mut self) -> Result<Option<BootRecord>, StorageError> {
        Ok(boot::read(&mut self.eeprom)?.map(|(r, _)| r))
    }

    fn addr(slot: u8, copy: SlotCopy) -> Result<u16, StorageError> {
        layout::copy_addr(slot, copy.index()).ok_or(StorageError::NoSuchSlot(slot))
    }

    fn check(
        &mut self,
        slot: u8,
        copy: SlotCopy,
    ) -> Result<Result<slot::CopyHeader, CopyError>, StorageError> {
        let addr = Self::addr(slot, copy)?;
        match slot::check_copy(&mut self.eeprom, addr, slot) {
            Err(CopyError::Eeprom(e)) => Err(StorageError::Eeprom(e)),
            r => Ok(r),
        }
    }

    /// Save `program` into `slot` (power-fail safe; see the module docs).
    pub fn save(&mut self, slot: u8, program: &Program) -> Result<u32, StorageError> {
        let a = self.check(slot, SlotCopy::A)?;
        let b = self.check(slot, SlotCopy::B)?;
        // The first copy written is the damaged one, else the older one (A on a tie).
        let first = match (&a, &b) {
            (Err(_), _) => SlotCopy::A,
            (Ok(_), Err(_)) => SlotCopy::B,
            (Ok(ha), Ok(hb)) if hb.generation < ha.generation => SlotCopy::B,
            _ => SlotCopy::A,
        };
        let newest = [&a, &b]
            .iter()
            .filter_map(|r| r.as_ref().ok().map(|h| h.generation))
            .max()
            .unwrap_or(0);
        let generation = newest.wrapping_add(1);
        for copy in [first, first.other()] {
            let addr = Self::addr(slot, copy)?;
            match slot::write_copy(&mut self.eeprom, addr, slot, generation, program) {
                Ok(_) => {}
                Err(CopyError::Eeprom(e)) => return Err(StorageError::Eeprom(e)),
                Err(_) => return Err(StorageError::TooBig),
            }
            match self.check(slot, copy)? {
                Ok(h) if h.generation == generation => {}
                _ => return Err(StorageError::VerifyFailed),
            }
        }
        Ok(generation)
    }

    /// Load `slot` into `program`. On error `program` is unchanged, except for an EEPROM
    /// read error in the middle of the transfer, which leaves it empty.
    pub fn load(&mut self, slot: u8, program: &mut Program) -> Result<LoadReport, StorageError> {
        let a = self.check(slot, SlotCopy::A)?;
        let b = self.check(slot, SlotCopy::B)?;
        let (used, h, other) = match (a, b) {
            (Ok(ha), Ok(hb)) => {
                let (used, h, other_gen) = if hb.generation > ha.generation {
                    (SlotCopy::B, hb, ha.generation)
                } else {
                    (SlotCopy::A, ha, hb.generation)
                };
                let other = if other_gen == h.generation {
                    OtherCopy::Same
                } else {
                    OtherCopy::Older
                };
                (used, h, other)
            }
            (Ok(ha), Err(e)) => (SlotCopy::A, ha, OtherCopy::Bad(e)),
            (Err(e), Ok(hb)) => (SlotCopy::B, hb, OtherCopy::Bad(e)),
            // A copy never written means no save of this slot ever completed (the first
            // save writes both): whatever the other copy holds is a cut first save.
            (Err(CopyError::NoHeader), Err(_)) | (Err(_), Err(CopyError::NoHeader)) => {
                return Err(StorageError::Empty(slot))
            }
            (Err(_), Err(_)) => return Err(StorageError::Damaged(slot)),
        };
        let addr = Self::addr(slot, used)?;
        slot::read_copy(&mut self.eeprom, addr, &h, program).map_err(|e| match e {
            CopyError::Eeprom(e) => StorageError::Eeprom(e),
            _ => StorageError::Damaged(slot),
        })?;
        Ok(LoadReport {
            slot,
            used,
            generation: h.generation,
            other,
        })
    }

    /// What each slot holds (for the save/load prompts).
    pub fn slot_info(&mut self, slot: u8) -> Result<SlotInfo, StorageError> {
        let a = self.check(slot, SlotCopy::A)?;
        let b = self.check(slot, SlotCopy::B)?;
        let program = [a, b]
            .iter()
            .filter_map(|r| r.as_ref().ok())
            .max_by_key(|h| h.generation)
            .map(|h| (h.generation, h.lines));
        Ok(SlotInfo { slot, program })
    }

    /// Log a fault that happened `uptime_ms` after this power-up.
    pub fn log_fault(&mut self, code: u8, uptime_ms: u64) -> Result<FaultEntry, StorageError> {
        let entry = FaultEntry {
            code,
            power_cycle: self.power_cycle as u16,
            uptime_s: u32::try_from(uptime_ms / 1000).unwrap_or(u32::MAX),
        };
        fault_log::append(&mut self.eeprom, entry)?;
        Ok(entry)
    }

    /// The logged faults, newest first.
    pub fn fault_log(
        &mut self,
        out: &mut heapless::Vec<FaultEntry, FAULT_LOG_ENTRIES>,
    ) -> Result<(), StorageError> {
        fault_log::read_all(&mut self.eeprom, out)?;
        Ok(())
    }

    /// Erase the fault log.
    pub fn clear_fault_log(&mut self) -> Result<(), StorageError> {
        fault_log::clear(&mut self.eeprom)?;
        Ok(())
    }
}
