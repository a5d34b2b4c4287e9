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
//! * The fault log keeps the newest 16 faults (format 1's 32 are still read).
//!
//! The firmware queues every operation as a [`Job`] and moves it on one EEPROM page per
//! pass with [`Storage::step`] (see [`job`]); the synchronous methods ([`Storage::save`],
//! [`Storage::load`], ...) run the same jobs to the end, for power-up (before the
//! watchdog runs), tools and tests. `MemEeprom` is the RAM model used by tests and hil-sim;
//! `image` builds EEPROM images with it (the image links neither: nothing on the board
//! calls them).

pub mod boot;
pub mod counters;
pub mod eeprom;
pub mod fault_log;
pub mod image;
pub mod job;
pub mod layout;
pub mod mem_eeprom;
pub mod reads;
pub mod slot;
pub mod staged;

pub use boot::BootRecord;
pub use eeprom::{Eeprom, EepromError, EEPROM_BYTES, PAGE_BYTES};
pub use fault_log::{FaultEntry, NO_VALUE, WALL_UNSET};
pub use job::{
    BootChange, Job, JobDone, JobKind, JobOutcome, JobStep, JobSummary, ProgramUse,
    WRITE_CYCLE_LIMIT_US,
};
pub use layout::{FAULT_LOG_ENTRIES, SLOTS};
pub use mem_eeprom::MemEeprom;
pub use slot::CopyError;

use job::{Access, Phase, Prog};
use shared_protocol::program::Program;
use shared_protocol::units::Micros;

/// Jobs that can wait in the queue besides the active one.
pub const QUEUE_JOBS: usize = 8;
/// Steps a synchronous operation may take before it gives up (a full save is about 400).
const SYNC_STEP_LIMIT: u32 = 100_000;

/// Why a storage operation failed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
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
    /// Another job holds the EEPROM (the queue is full, or a synchronous operation was
    /// asked for while jobs are queued).
    Busy,
}

impl core::fmt::Display for StorageError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            StorageError::NoSuchSlot(s) => write!(f, "no slot {s}"),
            StorageError::Empty(s) => write!(f, "slot {s} is empty"),
            StorageError::Damaged(s) => write!(f, "both copies of slot {s} are damaged"),
            StorageError::TooBig => f.write_str("the program does not fit a slot"),
            StorageError::VerifyFailed => f.write_str("the written copy did not read back"),
            StorageError::Eeprom(e) => write!(f, "{e}"),
            StorageError::Busy => f.write_str("the EEPROM is busy"),
        }
    }
}

impl core::error::Error for StorageError {}

impl From<EepromError> for StorageError {
    fn from(e: EepromError) -> Self {
        StorageError::Eeprom(e)
    }
}

/// Copy A or B of a slot.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SlotCopy {
    A,
    B,
}

impl SlotCopy {
    pub(crate) fn index(self) -> u8 {
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
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
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
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LoadReport {
    pub slot: u8,
    pub used: SlotCopy,
    pub generation: u32,
    pub other: OtherCopy,
}

/// Summary of one slot for the load/save prompts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SlotInfo {
    pub slot: u8,
    /// Newest valid generation and its used-line count; `None` when the slot is empty.
    pub program: Option<(u32, u16)>,
}

/// What power-up found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PowerUp {
    /// This power-up's number (1 for a fresh EEPROM).
    pub power_cycle: u32,
    /// The slot loaded into the program, with how the load went.
    pub loaded: Option<Result<LoadReport, StorageError>>,
    /// Start RUN now without a key (the PLC was running that slot at power-off).
    pub run: bool,
}

/// Why a job was not queued.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct QueueFull;

impl core::fmt::Display for QueueFull {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str("the storage queue is full")
    }
}

impl core::error::Error for QueueFull {}

/// The storage facade the application calls: the EEPROM, the job queue and the job in
/// progress.
pub struct Storage<E: Eeprom> {
    eeprom: E,
    power_cycle: u32,
    queue: heapless::Deque<Job, QUEUE_JOBS>,
    active: Option<(Job, Phase)>,
    /// A write cycle may be running: since when the chip has been polled busy (`None`
    /// until the first poll). The limit counts from the first poll, not from the step
    /// that made the write: on the board that step's time is taken before the transfer,
    /// which itself takes about 7 ms at 100 kHz, and the write cycle starts at its STOP.
    writing_since: Option<Option<Micros>>,
}

impl<E: Eeprom> Storage<E> {
    pub fn new(eeprom: E) -> Self {
        Storage {
            eeprom,
            power_cycle: 0,
            queue: heapless::Deque::new(),
            active: None,
            writing_since: None,
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

    /// Queue `job` behind the others (first in, first out). A boot-record change replaces
    /// a boot-record change still waiting (the newest state is what must be stored).
    pub fn queue(&mut self, job: Job) -> Result<(), QueueFull> {
        if let Job::Boot(BootChange::Run { .. }) = job {
            if let Some(waiting) = self
                .queue
                .iter_mut()
                .find(|j| matches!(j, Job::Boot(BootChange::Run { .. })))
            {
                *waiting = job;
                return Ok(());
            }
        }
        self.queue.push_back(job).map_err(|_| QueueFull)
    }

    /// Whether any job is queued or running.
    pub fn busy(&self) -> bool {
        self.active.is_some() || !self.queue.is_empty()
    }

    /// Whether the EEPROM is free for an access outside the queue: no job, and no write
    /// cycle that may still be running (the chip does not answer during one).
    pub fn idle(&self) -> bool {
        !self.busy() && self.writing_since.is_none()
    }

    /// Writes `bytes` (within one page) at `addr` outside the job queue: the service
    /// port's staging of a program write into a slot's spare copy
    /// ([`staged`]), which only the [`Job::Commit`] after it makes count. Only while
    /// nothing else uses the EEPROM ([`Storage::idle`], else `Busy`); the write cycle is
    /// waited for like a job's, by the next [`Storage::step`].
    pub fn write_outside_queue(&mut self, addr: u16, bytes: &[u8]) -> Result<(), StorageError> {
        if !self.idle() {
            return Err(StorageError::Busy);
        }
        // Even a failed write may have started a cycle.
        self.writing_since = Some(None);
        self.eeprom.start_write(addr, bytes)?;
        Ok(())
    }

    /// The job in progress.
    pub fn active_job(&self) -> Option<Job> {
        self.active.as_ref().map(|(j, _)| *j)
    }

    /// Jobs in progress or queued, oldest first.
    pub fn jobs(&self) -> impl Iterator<Item = Job> + '_ {
        self.active_job()
            .into_iter()
            .chain(self.queue.iter().copied())
    }

    /// How the queued and running jobs hold the program: `Writes` while a load is
    /// queued or running, else `Reads` while a save is.
    pub fn program_use(&self) -> Option<ProgramUse> {
        self.jobs().filter_map(|j| j.uses_program()).max()
    }

    /// Moves the queue on: at most one EEPROM transfer of at most one page (plus, before
    /// it, one ready poll if a write cycle may still run). Call once per pass; `program`
    /// is the application's (a save reads it, a load rewrites it).
    pub fn step(&mut self, now: Micros, program: &mut Program) -> JobStep {
        self.step_with(now, &mut Prog::Mut(program))
    }

    fn step_with(&mut self, now: Micros, prog: &mut Prog<'_>) -> JobStep {
        if self.active.is_none() && self.queue.is_empty() && self.writing_since.is_some() {
            // Only a write outside the queue to wait for.
            let since = self.writing_since.flatten().unwrap_or(now);
            self.writing_since = match self.eeprom.ready() {
                Ok(false) if now.0.saturating_sub(since.0) <= WRITE_CYCLE_LIMIT_US => {
                    Some(Some(since))
                }
                // Ready, or a chip that never comes back: the next job finds out.
                _ => None,
            };
            return JobStep {
                used_bus: true,
                done: None,
            };
        }
        if self.active.is_none() {
            let Some(job) = self.queue.pop_front() else {
                return JobStep::IDLE;
            };
            match job::start(job) {
                Ok(phase) => self.active = Some((job, phase)),
                Err(e) => {
                    return JobStep {
                        used_bus: false,
                        done: Some(JobDone::failed(job, e)),
                    }
                }
            }
        }
        let Some((job, _)) = self.active else {
            return JobStep::IDLE;
        };
        let mut used_bus = false;
        if let Some(since) = self.writing_since {
            used_bus = true;
            let since = since.unwrap_or(now);
            let failed = match self.eeprom.ready() {
                Ok(true) => {
                    self.writing_since = None;
                    None
                }
                Ok(false) if now.0.saturating_sub(since.0) <= WRITE_CYCLE_LIMIT_US => {
                    self.writing_since = Some(Some(since));
                    return JobStep {
                        used_bus,
                        done: None,
                    };
                }
                Ok(false) => Some(StorageError::Eeprom(EepromError::Bus)),
                Err(e) => Some(StorageError::Eeprom(e)),
            };
            if let Some(e) = failed {
                self.writing_since = None;
                self.active = None;
                return JobStep {
                    used_bus,
                    done: Some(JobDone::failed(job, e)),
                };
            }
        }
        let Some((_, phase)) = self.active.as_mut() else {
            return JobStep::IDLE;
        };
        let (done, access) = job::advance(&mut self.eeprom, job, phase, prog);
        if access == Access::Write {
            // Even a failed write may have started a cycle: wait it out before the next
            // access of any job.
            self.writing_since = Some(None);
        }
        used_bus |= access != Access::None;
        if done.is_some() {
            self.active = None;
        }
        JobStep { used_bus, done }
    }

    /// Runs `job` to the end, steps timed by `clock`. Refused while jobs are queued.
    fn run(
        &mut self,
        job: Job,
        prog: &mut Prog<'_>,
        clock: &mut dyn FnMut() -> Micros,
    ) -> Result<JobDone, StorageError> {
        if self.busy() {
            return Err(StorageError::Busy);
        }
        self.queue.push_back(job).map_err(|_| StorageError::Busy)?;
        for _ in 0..SYNC_STEP_LIMIT {
            let now = clock();
            if let Some(done) = self.step_with(now, prog).done {
                return Ok(done);
            }
        }
        self.active = None;
        self.writing_since = None;
        Err(StorageError::Eeprom(EepromError::Bus))
    }

    /// [`Storage::run`] with a made-up clock that advances 1 ms per step: for the RAM
    /// model, tools and tests.
    fn run_sync(&mut self, job: Job, prog: &mut Prog<'_>) -> Result<JobDone, StorageError> {
        let mut t = 0u64;
        let mut clock = || {
            t += 1000;
            Micros(t)
        };
        self.run(job, prog, &mut clock)
    }

    /// Power-up: count the power cycle and load the slot last run into `program`, with a
    /// fake clock (host use; see [`Storage::power_up_clocked`]).
    pub fn power_up(&mut self, program: &mut Program) -> Result<PowerUp, StorageError> {
        let mut t = 0u64;
        let mut clock = || {
            t += 1000;
            Micros(t)
        };
        self.power_up_clocked(program, &mut clock)
    }

    /// Power-up: count the power cycle and load the slot last run into `program`,
    /// synchronously (the board calls it before the watchdog runs), timing the EEPROM's
    /// write cycles with `clock`. The chip may still be finishing a write cycle started
    /// before a reset, so the first access waits for it.
    ///
    /// `run` is true only when the PLC was in RUN at power-off and the slot loaded
    /// cleanly or from its second copy; the caller starts RUN then (after verifying, as
    /// for any RUN).
    pub fn power_up_clocked(
        &mut self,
        program: &mut Program,
        clock: &mut dyn FnMut() -> Micros,
    ) -> Result<PowerUp, StorageError> {
        self.queue.clear();
        self.active = None;
        self.writing_since = Some(None);
        let mut prog = Prog::Mut(program);
        // The record as stored, read through a job that changes nothing.
        let record = {
            let mut best = None;
            for (i, &addr) in layout::BOOT_ADDR.iter().enumerate() {
                self.wait_idle(clock)?;
                let mut b = [0u8; boot::RECORD_BYTES];
                self.eeprom.read(addr, &mut b)?;
                best = boot::keep_newest(best, i, &b);
            }
            best.map(|(r, _)| r)
        };
        let record = record.unwrap_or_default();
        let count = record.power_cycles.wrapping_add(1);
        self.power_cycle = count;
        let done = self.run(Job::Boot(BootChange::PowerUp { count }), &mut prog, clock)?;
        if let Some(e) = done.error() {
            return Err(e);
        }
        let loaded = match record.last_run_slot {
            Some(slot) => match self.run(Job::Load { slot }, &mut prog, clock)? {
                JobDone::Loaded { result, .. } => Some(result),
                _ => None,
            },
            None => None,
        };
        let run = record.run_at_power_up && matches!(loaded, Some(Ok(_)));
        Ok(PowerUp {
            power_cycle: count,
            loaded,
            run,
        })
    }

    /// Waits (polling) until a write cycle that may be running has ended.
    fn wait_idle(&mut self, clock: &mut dyn FnMut() -> Micros) -> Result<(), StorageError> {
        let since = clock();
        while self.writing_since.is_some() {
            if self.eeprom.ready()? {
                self.writing_since = None;
            } else if clock().0.saturating_sub(since.0) > WRITE_CYCLE_LIMIT_US {
                self.writing_since = None;
                return Err(StorageError::Eeprom(EepromError::Bus));
            }
        }
        Ok(())
    }

    /// Record that `slot` was started (`running` = true) or that the user stopped
    /// (`running` = false, the slot stays the one loaded at power-up).
    ///
    /// RUN of a program that is in no slot (`slot` = `None`: edited since its last load
    /// or save) clears the run-at-power-up flag: after a power cut the PLC must not start
    /// an older program than the one that was running. The last slot is still loaded.
    pub fn set_run_state(&mut self, slot: Option<u8>, running: bool) -> Result<(), StorageError> {
        let empty = Program::default();
        let job = Job::Boot(BootChange::Run { slot, running });
        match self.run_sync(job, &mut Prog::Ref(&empty))? {
            JobDone::BootWritten { result, .. } => result,
            _ => Err(StorageError::Busy),
        }
    }

    /// The boot record as stored (None on a fresh EEPROM).
    pub fn boot_record(&mut self) -> Result<Option<BootRecord>, StorageError> {
        if self.busy() {
            return Err(StorageError::Busy);
        }
        Ok(boot::read(&mut self.eeprom)?.map(|(r, _)| r))
    }

    /// Save `program` into `slot` (power-fail safe; see the module docs).
    pub fn save(&mut self, slot: u8, program: &Program) -> Result<u32, StorageError> {
        match self.run_sync(Job::Save { slot }, &mut Prog::Ref(program))? {
            JobDone::Saved { result, .. } => result,
            _ => Err(StorageError::Busy),
        }
    }

    /// Load `slot` into `program`. On error `program` is unchanged, except for a read
    /// error or a damaged copy found in the middle of the transfer, which leaves it empty.
    pub fn load(&mut self, slot: u8, program: &mut Program) -> Result<LoadReport, StorageError> {
        match self.run_sync(Job::Load { slot }, &mut Prog::Mut(program))? {
            JobDone::Loaded { result, .. } => result,
            _ => Err(StorageError::Busy),
        }
    }

    fn check(
        &mut self,
        slot: u8,
        copy: SlotCopy,
    ) -> Result<Result<slot::CopyHeader, CopyError>, StorageError> {
        let addr = layout::copy_addr(slot, copy.index()).ok_or(StorageError::NoSuchSlot(slot))?;
        match slot::check_copy(&mut self.eeprom, addr, slot) {
            Err(CopyError::Eeprom(e)) => Err(StorageError::Eeprom(e)),
            r => Ok(r),
        }
    }

    /// What each slot holds (for the save/load prompts; synchronous).
    pub fn slot_info(&mut self, slot: u8) -> Result<SlotInfo, StorageError> {
        if self.busy() {
            return Err(StorageError::Busy);
        }
        let a = self.check(slot, SlotCopy::A)?;
        let b = self.check(slot, SlotCopy::B)?;
        let program = [a, b]
            .iter()
            .filter_map(|r| r.as_ref().ok())
            .max_by_key(|h| h.generation)
            .map(|h| (h.generation, h.lines));
        Ok(SlotInfo { slot, program })
    }

    /// The fault-log entry for a fault that happened `uptime_ms` after this power-up,
    /// without time of day and values (the application adds them).
    pub fn fault_entry(&self, code: u8, uptime_ms: u64) -> FaultEntry {
        FaultEntry::new(
            code,
            self.power_cycle as u16,
            u32::try_from(uptime_ms / 1000).unwrap_or(u32::MAX),
        )
    }

    /// Log a fault that happened `uptime_ms` after this power-up (synchronous).
    pub fn log_fault(&mut self, code: u8, uptime_ms: u64) -> Result<FaultEntry, StorageError> {
        let entry = self.fault_entry(code, uptime_ms);
        let empty = Program::default();
        match self.run_sync(Job::LogFault(entry), &mut Prog::Ref(&empty))? {
            JobDone::FaultLogged { result, .. } => result.map(|_| entry),
            _ => Err(StorageError::Busy),
        }
    }

    /// The logged faults, newest first (synchronous: power-up and tools).
    pub fn fault_log(
        &mut self,
        out: &mut heapless::Vec<FaultEntry, FAULT_LOG_ENTRIES>,
    ) -> Result<(), StorageError> {
        if self.busy() {
            return Err(StorageError::Busy);
        }
        fault_log::read_all(&mut self.eeprom, out)?;
        Ok(())
    }

    /// [`Storage::fault_log`], also giving the ring position of the newest entry.
    pub fn fault_log_with_head(
        &mut self,
        out: &mut heapless::Vec<FaultEntry, FAULT_LOG_ENTRIES>,
    ) -> Result<Option<u8>, StorageError> {
        if self.busy() {
            return Err(StorageError::Busy);
        }
        Ok(fault_log::read_all_with_head(&mut self.eeprom, out)?)
    }

    /// Erase the fault log (synchronous).
    pub fn clear_fault_log(&mut self) -> Result<(), StorageError> {
        let empty = Program::default();
        match self.run_sync(Job::ClearFaultLog, &mut Prog::Ref(&empty))? {
            JobDone::FaultLogCleared { result } => result,
            _ => Err(StorageError::Busy),
        }
    }
}
