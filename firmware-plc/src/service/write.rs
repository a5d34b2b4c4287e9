//! Program writes over the service port (service.md 3 "Program transfer"): `WriteBegin`,
//! `WriteChunk`, `WriteCommit`.
//!
//! Staging is in the EEPROM, in the payload area of the slot's spare copy (the copy a
//! load does not use; see [`crate::storage::staged`]): the PLC has no RAM for a second
//! 4 KiB program. Each chunk is written there at once (one or two partial page writes,
//! between scans, only while the storage queue is idle), so the spare copy fails its CRC
//! from the first chunk on and a load keeps using the other copy: the slot's previous
//! program. `WriteCommit` queues a [`Job::Commit`], which checks the staged bytes (the
//! announced CRC-32C, completeness, layout, verification), writes the spare copy's header
//! and then the other copy, as a keypad save does. Until its header is written nothing
//! else of the slot changed: a power cut, a cut cable, a new `WriteBegin`, RUN on the
//! keypad (chunks and the commit are then refused `InRun`) all leave the old program.
//!
//! A keypad save of the slot meanwhile overwrites the spare copy: the transfer is
//! forgotten (the commit answers `Incomplete`).

use shared_protocol::service::{
    Answer, RefuseReason, Request, SlotState, WriteResult, CHUNK_BYTES, PROGRAM_MAX_BYTES,
};

use crate::app::{checked_slot, Outcome, PlcApp, RunState};
use crate::storage::layout::{copy_addr, SLOTS};
use crate::storage::reads::SlotReads;
use crate::storage::staged::payload_addr;
use crate::storage::{Eeprom, Job, SlotCopy, StorageError};

/// Payload bytes of a chunk that go into the page where it starts: a copy's payload
/// begins 16 bytes into its first page, so every chunk straddles two pages.
const FIRST_PART: usize = crate::storage::PAGE_BYTES - crate::storage::layout::COPY_HEADER_BYTES;

/// A transfer between `WriteBegin` and `WriteCommit`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Staging {
    slot: u8,
    /// The spare copy the chunks go to.
    copy: SlotCopy,
    len: u16,
    crc: u32,
    /// Bit k: chunk k (offset 64 k) is written.
    have: u64,
    /// The chunk being written (its offset) and how many of its parts are done.
    writing: Option<(u16, u8)>,
    /// The chunk write failed (answered `Refused(Storage)`).
    failed: bool,
}

impl Staging {
    fn chunks(&self) -> u32 {
        u32::from(self.len).div_ceil(CHUNK_BYTES as u32)
    }

    fn complete(&self) -> bool {
        let n = self.chunks();
        let all = if n >= 64 { u64::MAX } else { (1u64 << n) - 1 };
        self.have & all == all
    }
}

/// The service's program write.
#[derive(Debug, Clone, Default)]
pub struct ProgramWrite {
    staging: Option<Staging>,
    /// A commit is queued for this slot: its outcome is awaited.
    committing: Option<u8>,
    /// The commit's outcome, until the `WriteCommit` waiting for it takes it.
    result: Option<Answer>,
}

fn refused(r: RefuseReason) -> Outcome {
    Outcome::Answer(Answer::Refused(r))
}

impl ProgramWrite {
    pub fn new() -> Self {
        Self::default()
    }

    /// Whether a chunk waits to be written into the EEPROM.
    pub fn writing(&self) -> bool {
        self.staging
            .is_some_and(|s| s.writing.is_some() && !s.failed)
    }

    /// Executes `WriteBegin`, `WriteChunk` or `WriteCommit` (guarded: remote service is on).
    pub fn request<E: Eeprom>(
        &mut self,
        app: &mut PlcApp<E>,
        reads: &mut SlotReads,
        request: &Request,
    ) -> Outcome {
        let stopped = app.run_state() == RunState::Stopped;
        match *request {
            Request::WriteBegin { .. } | Request::WriteChunk { .. }
                if self.committing.is_some() =>
            {
                refused(RefuseReason::Busy)
            }
            Request::WriteBegin { slot, len, crc } => {
                if !stopped {
                    return refused(RefuseReason::InRun);
                }
                if !(1..=SLOTS).contains(&slot) {
                    return refused(RefuseReason::Slot);
                }
                if len > PROGRAM_MAX_BYTES {
                    return refused(RefuseReason::Transfer);
                }
                // Which copy a load uses now; the other one takes the chunks.
                let rec = match checked_slot(reads, slot) {
                    Ok(rec) => rec,
                    Err(meanwhile) => return meanwhile,
                };
                let copy = if rec.summary.state == SlotState::Valid
                    && Some(rec.copy_addr) == copy_addr(slot, 0)
                {
                    SlotCopy::B
                } else {
                    SlotCopy::A
                };
                self.staging = Some(Staging {
                    slot,
                    copy,
                    len,
                    crc,
                    have: 0,
                    writing: None,
                    failed: false,
                });
                Outcome::Answer(Answer::Done)
            }
            Request::WriteChunk { offset, ref data } => {
                let Some(s) = self.staging.as_mut() else {
                    return refused(RefuseReason::Transfer);
                };
                if !stopped {
                    return refused(RefuseReason::InRun);
                }
                let start = usize::from(offset);
                let len = usize::from(s.len);
                if start % CHUNK_BYTES != 0
                    || start >= len
                    || data.len() != (len - start).min(CHUNK_BYTES)
                {
                    return refused(RefuseReason::Transfer);
                }
                if s.failed {
                    s.failed = false;
                    s.writing = None;
                    return refused(RefuseReason::Storage);
                }
                let parts = if data.len() > FIRST_PART { 2 } else { 1 };
                match s.writing {
                    Some((o, done)) if o == offset && done >= parts => {
                        s.writing = None;
                        s.have |= 1u64 << (start / CHUNK_BYTES);
                        Outcome::Answer(Answer::Done)
                    }
                    Some((o, _)) if o == offset => Outcome::Later,
                    _ => {
                        s.writing = Some((offset, 0));
                        Outcome::Later
                    }
                }
            }
            Request::WriteCommit => {
                if let Some(a) = self.result.take() {
                    return Outcome::Answer(a);
                }
                if self.committing.is_some() {
                    return Outcome::Later;
                }
                if !stopped {
                    return refused(RefuseReason::InRun);
                }
                let Some(s) = self.staging else {
                    return refused(RefuseReason::Transfer);
                };
                if !s.complete() {
                    return Outcome::Answer(Answer::WriteResult(WriteResult::Incomplete));
                }
                let job = Job::Commit {
                    slot: s.slot,
                    copy: s.copy,
                    len: s.len,
                    crc: s.crc,
                };
                if app.storage().queue(job).is_err() {
                    return refused(RefuseReason::Busy);
                }
                self.staging = None;
                self.committing = Some(s.slot);
                Outcome::Later
            }
            _ => refused(RefuseReason::Transfer),
        }
    }

    /// Writes the next part of the chunk being staged (`request` is the `WriteChunk`
    /// being worked on), when the EEPROM is free. Returns whether the bus was used.
    pub fn step<E: Eeprom>(&mut self, app: &mut PlcApp<E>, request: Option<&Request>) -> bool {
        let Some(s) = self.staging.as_mut() else {
            return false;
        };
        let (Some((offset, done)), Some(Request::WriteChunk { offset: o, data })) =
            (s.writing, request)
        else {
            return false;
        };
        if *o != offset || s.failed || !app.storage().idle() {
            return false;
        }
        let (from, to) = if done == 0 {
            (0, data.len().min(FIRST_PART))
        } else {
            (FIRST_PART, data.len())
        };
        let Some(bytes) = data.get(from..to) else {
            return false;
        };
        let addr = copy_addr(s.slot, s.copy.index())
            .and_then(|a| payload_addr(a, offset.saturating_add(from as u16)));
        let written = match addr {
            Some(addr) => app.storage().write_outside_queue(addr, bytes),
            None => Err(StorageError::NoSuchSlot(s.slot)),
        };
        match written {
            Ok(()) => s.writing = Some((offset, done + 1)),
            Err(_) => s.failed = true,
        }
        true
    }

    /// A keypad save of `slot` went over the spare copy: every chunk staged in it is
    /// void (a commit now answers `Incomplete`).
    pub fn slot_saved(&mut self, slot: u8) {
        if let Some(s) = self.staging.as_mut().filter(|s| s.slot == slot) {
            s.have = 0;
            s.writing = None;
        }
    }

    /// The commit of `slot` ended: its answer waits for the `WriteCommit`.
    pub fn committed(&mut self, slot: u8, result: Result<WriteResult, StorageError>) {
        if self.committing != Some(slot) {
            return;
        }
        self.committing = None;
        self.result = Some(match result {
            Ok(w) => Answer::WriteResult(w),
            Err(_) => Answer::Refused(RefuseReason::Storage),
        });
    }
}
