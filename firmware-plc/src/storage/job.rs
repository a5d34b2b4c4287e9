//! Storage work as jobs, done one EEPROM page per step.
//!
//! A save of a full slot reads and writes about 380 pages; over the board's 100 kHz I2C
//! that is seconds. Done in one call it stalls everything else, so
//! every storage operation is a [`Job`] in a queue, and [`super::Storage::step`] moves the
//! active job on by **at most one transfer of at most one page** (64 bytes) per call: the
//! application calls it once per 1 ms pass, between scans.
//!
//! After each page write the 24C256 runs its write cycle (up to 5 ms) and answers nothing;
//! the next step first asks [`super::Eeprom::ready`] (one short poll) and does nothing
//! else while the chip is still busy, so no access ever meets a busy chip. A write cycle
//! that has not ended [`WRITE_CYCLE_LIMIT_US`] after the write fails the job with a bus
//! error. Every job that writes ends only after its last write cycle has ended, so an idle
//! queue means an idle chip.
//!
//! Power-fail safety is the same as for the synchronous operations (they run these very
//! jobs to the end; see `docs/eeprom-image.md`): the order of the page writes is
//! unchanged, only spread over passes.

use shared_protocol::program::Program;
use shared_protocol::service::WriteResult;

use super::boot::{self, BootRecord, RECORD_BYTES};
use super::eeprom::{PAGE_BYTES, PAGE_WRITE_MS};
use super::fault_log::{self, FaultEntry, RingFinder, LOG_PAGES};
use super::layout::BOOT_ADDR;
use super::slot::{CopyError, CopyHeader, CopyReader, CopyWriter, WriterStep};
use super::staged::{Checked, StagedCheck};
use super::{LoadReport, OtherCopy, SlotCopy, StorageError};

/// How long a write cycle may take before the job fails: twice the datasheet's worst case.
pub const WRITE_CYCLE_LIMIT_US: u64 = 2 * PAGE_WRITE_MS as u64 * 1000;

/// A change of the boot record.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum BootChange {
    /// Count this power-up: the record's power-up count becomes `count`.
    PowerUp { count: u32 },
    /// RUN started from `slot` (`running`), or the user stopped (see
    /// [`super::Storage::set_run_state`]).
    Run { slot: Option<u8>, running: bool },
}

/// One storage operation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Job {
    /// Save the program into slot 1..=4 (power-fail safe). The program must not change
    /// until the job is done (the application refuses edits meanwhile).
    Save { slot: u8 },
    /// Load slot 1..=4 into the program (the program is rewritten while the job runs).
    Load { slot: u8 },
    /// Append an entry to the fault log.
    LogFault(FaultEntry),
    /// Erase the fault log.
    ClearFaultLog,
    /// Write the boot record.
    Boot(BootChange),
    /// Seal a program staged over the service port in `copy` of `slot` (see
    /// [`super::staged`]): `len` payload bytes whose CRC-32C must be `crc`. Checked,
    /// verified, then saved power-fail safe like [`Job::Save`], the staged copy first.
    Commit {
        slot: u8,
        copy: SlotCopy,
        len: u16,
        crc: u32,
    },
}

impl Job {
    /// Whether the job reads (`Save`) or rewrites (`Load`) the program while it runs.
    pub fn uses_program(&self) -> Option<ProgramUse> {
        match self {
            Job::Save { .. } => Some(ProgramUse::Reads),
            Job::Load { .. } => Some(ProgramUse::Writes),
            _ => None,
        }
    }
}

/// How a job holds the program.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ProgramUse {
    /// A save: the program must not change (RUN may start: it does not change it).
    Reads,
    /// A load: the program is being replaced (neither edits nor RUN).
    Writes,
}

/// A finished job and how it went. Dropping it loses the outcome the user must see.
#[must_use]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum JobDone {
    /// The new generation of the slot.
    Saved {
        slot: u8,
        result: Result<u32, StorageError>,
    },
    Loaded {
        slot: u8,
        result: Result<LoadReport, StorageError>,
    },
    FaultLogged {
        entry: FaultEntry,
        result: Result<(), StorageError>,
    },
    FaultLogCleared {
        result: Result<(), StorageError>,
    },
    BootWritten {
        change: BootChange,
        result: Result<(), StorageError>,
    },
    /// A [`Job::Commit`]: `Saved` with the new generation, or why nothing was written.
    Written {
        slot: u8,
        result: Result<WriteResult, StorageError>,
    },
}

impl JobDone {
    /// The outcome of `job` when it failed with `e`.
    pub(crate) fn failed(job: Job, e: StorageError) -> JobDone {
        match job {
            Job::Save { slot } => JobDone::Saved {
                slot,
                result: Err(e),
            },
            Job::Load { slot } => JobDone::Loaded {
                slot,
                result: Err(e),
            },
            Job::LogFault(entry) => JobDone::FaultLogged {
                entry,
                result: Err(e),
            },
            Job::ClearFaultLog => JobDone::FaultLogCleared { result: Err(e) },
            Job::Boot(change) => JobDone::BootWritten {
                change,
                result: Err(e),
            },
            Job::Commit { slot, .. } => JobDone::Written {
                slot,
                result: Err(e),
            },
        }
    }

    /// The error, if the job failed.
    pub fn error(&self) -> Option<StorageError> {
        match *self {
            JobDone::Saved { result, .. } => result.err(),
            JobDone::Loaded { result, .. } => result.err(),
            JobDone::Written { result, .. } => result.err(),
            JobDone::FaultLogged { result, .. }
            | JobDone::FaultLogCleared { result }
            | JobDone::BootWritten { result, .. } => result.err(),
        }
    }

    /// A compact form for the board's log line (`storage: Saved 2: Ok 17`): a derived
    /// `defmt::Format` of the whole tree (load reports, errors, write results) cost about
    /// 1 KB of the image for one log line; two field-less enums are a byte each on the
    /// wire and their names stay in the ELF's defmt table, out of the flash.
    pub fn summary(&self) -> JobSummary {
        use JobKind as K;
        let (kind, slot, result) = match *self {
            JobDone::Saved { slot, result } => (K::Saved, slot, result.map(Some)),
            JobDone::Loaded { slot, result } => {
                (K::Loaded, slot, result.map(|r| Some(r.generation)))
            }
            JobDone::FaultLogged { entry, result } => {
                (K::FaultLogged, entry.code, result.map(|()| None))
            }
            JobDone::FaultLogCleared { result } => (K::FaultLogCleared, 0, result.map(|()| None)),
            JobDone::BootWritten { result, .. } => (K::BootWritten, 0, result.map(|()| None)),
            JobDone::Written { slot, result } => {
                let (outcome, value) = match result {
                    Ok(WriteResult::Saved { generation }) => (JobOutcome::Ok, generation),
                    Ok(WriteResult::Invalid { line, .. }) => (JobOutcome::Invalid, u32::from(line)),
                    Ok(WriteResult::Crc) => (JobOutcome::Crc, 0),
                    Ok(WriteResult::Incomplete) => (JobOutcome::Incomplete, 0),
                    Err(e) => JobOutcome::of(e),
                };
                return JobSummary {
                    kind: K::Written,
                    slot,
                    outcome,
                    value,
                };
            }
        };
        let (outcome, value) = match result {
            Ok(v) => (JobOutcome::Ok, v.unwrap_or(0)),
            Err(e) => JobOutcome::of(e),
        };
        JobSummary {
            kind,
            slot,
            outcome,
            value,
        }
    }
}

/// [`JobDone::summary`]: which job ended, its slot (the fault code for a logged fault, 0
/// when none), how it went, and one number (the generation written or loaded, the first
/// invalid line of a staged program, the slot an error names; else 0).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct JobSummary {
    pub kind: JobKind,
    pub slot: u8,
    pub outcome: JobOutcome,
    pub value: u32,
}

/// Which job ended ([`JobDone`]'s variants).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum JobKind {
    Saved,
    Loaded,
    FaultLogged,
    FaultLogCleared,
    BootWritten,
    Written,
}

/// How a job went, flat: success, a staged program's rejection, or the storage error.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum JobOutcome {
    Ok,
    Invalid,
    Crc,
    Incomplete,
    NoSuchSlot,
    Empty,
    Damaged,
    TooBig,
    VerifyFailed,
    EepromOutOfRange,
    EepromCrossesPage,
    EepromBus,
    EepromPowerLost,
    Busy,
}

impl JobOutcome {
    /// The error's outcome and the slot it names (else 0).
    fn of(e: StorageError) -> (JobOutcome, u32) {
        use super::EepromError as Ee;
        match e {
            StorageError::NoSuchSlot(s) => (JobOutcome::NoSuchSlot, u32::from(s)),
            StorageError::Empty(s) => (JobOutcome::Empty, u32::from(s)),
            StorageError::Damaged(s) => (JobOutcome::Damaged, u32::from(s)),
            StorageError::TooBig => (JobOutcome::TooBig, 0),
            StorageError::VerifyFailed => (JobOutcome::VerifyFailed, 0),
            StorageError::Eeprom(Ee::OutOfRange) => (JobOutcome::EepromOutOfRange, 0),
            StorageError::Eeprom(Ee::CrossesPage) => (JobOutcome::EepromCrossesPage, 0),
            StorageError::Eeprom(Ee::Bus) => (JobOutcome::EepromBus, 0),
            StorageError::Eeprom(Ee::PowerLost) => (JobOutcome::EepromPowerLost, 0),
            StorageError::Busy => (JobOutcome::Busy, 0),
        }
    }
}

/// What one step did.
#[must_use]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct JobStep {
    /// The step talked to the EEPROM (a transfer or a ready poll): the bus was busy.
    pub used_bus: bool,
    /// The job that finished in this step.
    pub done: Option<JobDone>,
}

impl JobStep {
    pub(crate) const IDLE: JobStep = JobStep {
        used_bus: false,
        done: None,
    };
}

/// The program as a step may touch it: a save only reads it.
pub(crate) enum Prog<'a> {
    Ref(&'a Program),
    Mut(&'a mut Program),
}

impl Prog<'_> {
    fn get(&self) -> &Program {
        match self {
            Prog::Ref(p) => p,
            Prog::Mut(p) => p,
        }
    }

    fn get_mut(&mut self) -> Option<&mut Program> {
        match self {
            Prog::Ref(_) => None,
            Prog::Mut(p) => Some(p),
        }
    }
}

/// Where the active job stands.
#[derive(Clone)]
pub(crate) enum Phase {
    /// Save or load: checking copy A.
    CheckA(CopyReader),
    /// Then copy B, with A's result.
    CheckB {
        a: Result<CopyHeader, CopyError>,
        r: CopyReader,
    },
    /// Save: writing `copy` (the first or the second one).
    SaveWrite {
        copy: SlotCopy,
        second: bool,
        w: CopyWriter,
    },
    /// Save: reading back what was just written.
    SaveVerify {
        copy: SlotCopy,
        second: bool,
        generation: u32,
        r: CopyReader,
    },
    /// Commit: reading the staged payload back (two passes).
    StagedRead { generation: u32, check: StagedCheck },
    /// Commit: the staged payload checks; write its header.
    StagedHeader(CopyHeader),
    /// Load: reading the chosen copy into the program.
    LoadRead { report: LoadReport, r: CopyReader },
    /// Boot record: reading copy `next` (0, 1) of it.
    BootRead {
        next: u8,
        best: Option<(BootRecord, usize)>,
    },
    /// Fault log: reading page `next` of the ring to find where the entry goes.
    RingScan { next: u8, finder: RingFinder },
    /// Clearing page `next` of the fault log.
    Clear { next: u8 },
    /// The last write was made: wait for its write cycle, then report `done`.
    Settle(JobDone),
}

/// The EEPROM access a phase step made.
#[derive(Clone, Copy, PartialEq, Eq)]
pub(crate) enum Access {
    None,
    Read,
    Write,
}

fn copy_addr(slot: u8, copy: SlotCopy) -> Result<u16, StorageError> {
    super::layout::copy_addr(slot, copy.index()).ok_or(StorageError::NoSuchSlot(slot))
}

fn eeprom_err(e: CopyError) -> Result<Result<CopyHeader, CopyError>, StorageError> {
    match e {
        CopyError::Eeprom(e) => Err(StorageError::Eeprom(e)),
        other => Ok(Err(other)),
    }
}

/// The first phase of `job`.
pub(crate) fn start(job: Job) -> Result<Phase, StorageError> {
    Ok(match job {
        Job::Save { slot } | Job::Load { slot } | Job::Commit { slot, .. } => {
            Phase::CheckA(CopyReader::check(copy_addr(slot, SlotCopy::A)?, slot))
        }
        Job::LogFault(_) => Phase::RingScan {
            next: 0,
            finder: RingFinder::default(),
        },
        Job::ClearFaultLog => Phase::Clear { next: 0 },
        Job::Boot(BootChange::Run { slot: Some(s), .. }) if !(1..=super::SLOTS).contains(&s) => {
            return Err(StorageError::NoSuchSlot(s));
        }
        Job::Boot(_) => Phase::BootRead {
            next: 0,
            best: None,
        },
    })
}

/// Moves `phase` of `job` on by at most one transfer, in place (a phase holds a page
/// buffer and running CRCs: moving it by value through every step cost flash and stack).
/// Returns the outcome once the job is over, and which access was made.
pub(crate) fn advance<E: super::Eeprom>(
    e: &mut E,
    job: Job,
    phase: &mut Phase,
    prog: &mut Prog<'_>,
) -> (Option<JobDone>, Access) {
    match one(e, job, phase, prog) {
        Ok(went) => went,
        Err((err, access)) => (Some(JobDone::failed(job, err)), access),
    }
}

type OneResult = Result<(Option<JobDone>, Access), (StorageError, Access)>;

/// One phase step: at most one transfer (none only when the job ends here). The phase
/// is updated in place; `Some` when the job is over.
fn one<E: super::Eeprom>(e: &mut E, job: Job, phase: &mut Phase, prog: &mut Prog<'_>) -> OneResult {
    let r = |err: StorageError| (err, Access::Read);
    let w = |err: StorageError| (err, Access::Write);
    let (next, access) = match phase {
        Phase::CheckA(rd) => {
            let slot = job_slot(job);
            let a = match rd.step(e, None) {
                Ok(None) => return Ok((None, Access::Read)),
                Ok(Some(h)) => Ok(h),
                Err(err) => eeprom_err(err).map_err(r)?,
            };
            let rb = CopyReader::check(copy_addr(slot, SlotCopy::B).map_err(r)?, slot);
            (Phase::CheckB { a, r: rb }, Access::Read)
        }
        Phase::CheckB { a, r: rd } => {
            let b = match rd.step(e, None) {
                Ok(None) => return Ok((None, Access::Read)),
                Ok(Some(h)) => Ok(h),
                Err(err) => eeprom_err(err).map_err(r)?,
            };
            let a = *a;
            let next = match job {
                Job::Save { slot } => save_plan(slot, a, b, prog.get()).map_err(r)?,
                Job::Load { slot } => load_plan(slot, a, b).map_err(r)?,
                Job::Commit {
                    slot, copy, len, ..
                } => Phase::StagedRead {
                    generation: newest_generation(&a, &b).wrapping_add(1),
                    check: StagedCheck::new(copy_addr(slot, copy).map_err(r)?, len),
                },
                _ => return Err(r(StorageError::Busy)),
            };
            (next, Access::Read)
        }
        Phase::SaveWrite {
            copy,
            second,
            w: wr,
        } => {
            let slot = job_slot(job);
            let went = wr.step(e, prog.get()).map_err(|err| match err {
                CopyError::Eeprom(x) => w(StorageError::Eeprom(x)),
                _ => w(StorageError::TooBig),
            })?;
            match went {
                WriterStep::Read => return Ok((None, Access::Read)),
                WriterStep::Wrote => return Ok((None, Access::Write)),
                WriterStep::Done => {
                    let addr = copy_addr(slot, *copy).map_err(w)?;
                    let next = Phase::SaveVerify {
                        copy: *copy,
                        second: *second,
                        generation: wr.header().generation,
                        r: CopyReader::check(addr, slot),
                    };
                    (next, Access::Write)
                }
            }
        }
        Phase::SaveVerify {
            copy,
            second,
            generation,
            r: rd,
        } => {
            let slot = job_slot(job);
            let generation = *generation;
            match rd.step(e, None) {
                Ok(None) => return Ok((None, Access::Read)),
                Ok(Some(h)) if h.generation == generation => {
                    if *second {
                        let done = match job {
                            Job::Commit { .. } => JobDone::Written {
                                slot,
                                result: Ok(WriteResult::Saved { generation }),
                            },
                            _ => JobDone::Saved {
                                slot,
                                result: Ok(generation),
                            },
                        };
                        return Ok((Some(done), Access::Read));
                    }
                    let copy = *copy;
                    let other = copy.other();
                    let addr = copy_addr(slot, other).map_err(r)?;
                    // The second copy: from the program in RAM (a keypad save), or as a
                    // duplicate of the copy just checked (a program written over the
                    // service port is in no RAM).
                    let wr = match job {
                        Job::Commit { .. } => {
                            CopyWriter::copy_of(copy_addr(slot, copy).map_err(r)?, addr, h)
                        }
                        _ => CopyWriter::new(addr, slot, generation, prog.get())
                            .map_err(|_| r(StorageError::TooBig))?,
                    };
                    let next = Phase::SaveWrite {
                        copy: other,
                        second: true,
                        w: wr,
                    };
                    (next, Access::Read)
                }
                Err(CopyError::Eeprom(x)) => return Err(r(StorageError::Eeprom(x))),
                _ => return Err(r(StorageError::VerifyFailed)),
            }
        }
        Phase::StagedRead { generation, check } => {
            let Job::Commit { slot, len, crc, .. } = job else {
                return Err(r(StorageError::Busy));
            };
            let access = if len > 0 { Access::Read } else { Access::None };
            match check
                .step(e, slot, *generation, crc)
                .map_err(|x| r(x.into()))?
            {
                Checked::More => return Ok((None, access)),
                Checked::Refused(why) => {
                    let done = JobDone::Written {
                        slot,
                        result: Ok(why),
                    };
                    return Ok((Some(done), access));
                }
                Checked::Header(h) => (Phase::StagedHeader(h), access),
            }
        }
        Phase::StagedHeader(h) => {
            let h = *h;
            let Job::Commit { slot, copy, .. } = job else {
                return Err(w(StorageError::Busy));
            };
            let addr = copy_addr(slot, copy).map_err(w)?;
            // From here on this copy is the slot's newest: the old program is replaced.
            e.start_write(addr, &h.to_bytes())
                .map_err(|x| w(x.into()))?;
            let next = Phase::SaveVerify {
                copy,
                second: false,
                generation: h.generation,
                r: CopyReader::check(addr, slot),
            };
            (next, Access::Write)
        }
        Phase::LoadRead { report, r: rd } => {
            let Some(p) = prog.get_mut() else {
                return Err(r(StorageError::Busy));
            };
            return match rd.step(e, Some(p)) {
                Ok(None) => Ok((None, Access::Read)),
                Ok(Some(_)) => {
                    let done = JobDone::Loaded {
                        slot: report.slot,
                        result: Ok(*report),
                    };
                    Ok((Some(done), Access::Read))
                }
                Err(CopyError::Eeprom(x)) => Err(r(StorageError::Eeprom(x))),
                Err(_) => Err(r(StorageError::Damaged(report.slot))),
            };
        }
        Phase::BootRead { next, best } => {
            let Job::Boot(change) = job else {
                return Err(r(StorageError::Busy));
            };
            if let Some(&addr) = BOOT_ADDR.get(usize::from(*next)) {
                let mut b = [0u8; RECORD_BYTES];
                e.read(addr, &mut b).map_err(|x| r(x.into()))?;
                *best = boot::keep_newest(*best, usize::from(*next), &b);
                *next += 1;
                return Ok((None, Access::Read));
            }
            let best = *best;
            let current = best.map(|(rec, _)| rec);
            let mut record = current.unwrap_or_default();
            match change {
                BootChange::PowerUp { count } => record.power_cycles = count,
                BootChange::Run { slot, running } => {
                    let running = running && slot.is_some();
                    let want_slot = slot.or(record.last_run_slot);
                    if record.last_run_slot == want_slot && record.run_at_power_up == running {
                        // Nothing changes: spare the EEPROM a write.
                        let done = JobDone::BootWritten {
                            change,
                            result: Ok(()),
                        };
                        return Ok((Some(done), Access::None));
                    }
                    record.last_run_slot = want_slot;
                    record.run_at_power_up = running;
                }
            }
            let (addr, record) = boot::next_write(best, record);
            e.start_write(addr, &record.to_bytes())
                .map_err(|x| w(x.into()))?;
            let done = JobDone::BootWritten {
                change,
                result: Ok(()),
            };
            (Phase::Settle(done), Access::Write)
        }
        Phase::RingScan { next, finder } => {
            let Job::LogFault(entry) = job else {
                return Err(r(StorageError::Busy));
            };
            if usize::from(*next) < LOG_PAGES {
                let mut page = [0u8; PAGE_BYTES];
                e.read(fault_log::page_addr(usize::from(*next)), &mut page)
                    .map_err(|x| r(x.into()))?;
                finder.push_bytes(&page);
                *next += 1;
                return Ok((None, Access::Read));
            }
            e.start_write(finder.append_addr(), &entry.to_bytes())
                .map_err(|x| w(x.into()))?;
            let done = JobDone::FaultLogged {
                entry,
                result: Ok(()),
            };
            (Phase::Settle(done), Access::Write)
        }
        Phase::Clear { next } => {
            let blank = [0xFFu8; PAGE_BYTES];
            e.start_write(fault_log::page_addr(usize::from(*next)), &blank)
                .map_err(|x| w(x.into()))?;
            *next += 1;
            if usize::from(*next) < LOG_PAGES {
                return Ok((None, Access::Write));
            }
            let done = JobDone::FaultLogCleared { result: Ok(()) };
            (Phase::Settle(done), Access::Write)
        }
        // Reached only once the write cycle has ended (the caller polls first).
        Phase::Settle(done) => return Ok((Some(*done), Access::None)),
    };
    *phase = next;
    Ok((None, access))
}

fn job_slot(job: Job) -> u8 {
    match job {
        Job::Save { slot } | Job::Load { slot } | Job::Commit { slot, .. } => slot,
        _ => 0,
    }
}

/// After both checks of a save: which copy to write first and with which generation.
/// The first copy written is the damaged one, else the older one (A on a tie).
fn save_plan(
    slot: u8,
    a: Result<CopyHeader, CopyError>,
    b: Result<CopyHeader, CopyError>,
    program: &Program,
) -> Result<Phase, StorageError> {
    let first = match (&a, &b) {
        (Err(_), _) => SlotCopy::A,
        (Ok(_), Err(_)) => SlotCopy::B,
        (Ok(ha), Ok(hb)) if hb.generation < ha.generation => SlotCopy::B,
        _ => SlotCopy::A,
    };
    let generation = newest_generation(&a, &b).wrapping_add(1);
    let w = CopyWriter::new(copy_addr(slot, first)?, slot, generation, program)
        .map_err(|_| StorageError::TooBig)?;
    Ok(Phase::SaveWrite {
        copy: first,
        second: false,
        w,
    })
}

/// The newest valid generation of a slot (0: none): a save gives the next one.
fn newest_generation(a: &Result<CopyHeader, CopyError>, b: &Result<CopyHeader, CopyError>) -> u32 {
    [a, b]
        .iter()
        .filter_map(|r| r.as_ref().ok().map(|h| h.generation))
        .max()
        .unwrap_or(0)
}

/// After both checks of a load: which copy to read, or why none.
fn load_plan(
    slot: u8,
    a: Result<CopyHeader, CopyError>,
    b: Result<CopyHeader, CopyError>,
) -> Result<Phase, StorageError> {
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
        // A copy never written means no save of this slot ever completed (the first save
        // writes both): whatever the other copy holds is a cut first save.
        (Err(CopyError::NoHeader), Err(_)) | (Err(_), Err(CopyError::NoHeader)) => {
            return Err(StorageError::Empty(slot))
        }
        (Err(_), Err(_)) => return Err(StorageError::Damaged(slot)),
    };
    Ok(Phase::LoadRead {
        report: LoadReport {
            slot,
            used,
            generation: h.generation,
            other,
        },
        r: CopyReader::load(copy_addr(slot, used)?, slot),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::storage::EepromError;

    fn s(kind: JobKind, slot: u8, outcome: JobOutcome, value: u32) -> JobSummary {
        JobSummary {
            kind,
            slot,
            outcome,
            value,
        }
    }

    #[test]
    fn summaries_keep_the_kind_the_slot_the_outcome_and_the_number() {
        use JobKind as K;
        use JobOutcome as O;
        let cases = [
            (
                JobDone::Saved {
                    slot: 2,
                    result: Ok(17),
                },
                s(K::Saved, 2, O::Ok, 17),
            ),
            (
                JobDone::Saved {
                    slot: 3,
                    result: Err(StorageError::Eeprom(EepromError::Bus)),
                },
                s(K::Saved, 3, O::EepromBus, 0),
            ),
            (
                JobDone::Loaded {
                    slot: 1,
                    result: Err(StorageError::Damaged(1)),
                },
                s(K::Loaded, 1, O::Damaged, 1),
            ),
            (
                JobDone::FaultLogged {
                    entry: FaultEntry::new(42, 3, 9),
                    result: Ok(()),
                },
                s(K::FaultLogged, 42, O::Ok, 0),
            ),
            (
                JobDone::FaultLogCleared {
                    result: Err(StorageError::Busy),
                },
                s(K::FaultLogCleared, 0, O::Busy, 0),
            ),
            (
                JobDone::BootWritten {
                    change: BootChange::PowerUp { count: 5 },
                    result: Err(StorageError::VerifyFailed),
                },
                s(K::BootWritten, 0, O::VerifyFailed, 0),
            ),
            (
                JobDone::Written {
                    slot: 4,
                    result: Ok(WriteResult::Saved { generation: 8 }),
                },
                s(K::Written, 4, O::Ok, 8),
            ),
            (
                JobDone::Written {
                    slot: 4,
                    result: Ok(WriteResult::Crc),
                },
                s(K::Written, 4, O::Crc, 0),
            ),
            (
                JobDone::Written {
                    slot: 4,
                    result: Err(StorageError::Empty(4)),
                },
                s(K::Written, 4, O::Empty, 4),
            ),
        ];
        for (done, want) in cases {
            assert_eq!(done.summary(), want, "{done:?}");
        }
    }
}
