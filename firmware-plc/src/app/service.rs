//! The application's side of the service port (service.md part A): what the PLC shows a
//! PC and what a PC may ask of it. The protocol (frames, ids, `Hello`, remote-service
//! refusals, repeats, samples) is `crate::service`, which depends on this module, never
//! the other way; this module answers the requests it hands over, from the application's
//! RAM (status, log, program in RAM) or through the paced EEPROM reads ([`SlotReads`],
//! part of the storage).
//!
//! The few things the service needs that the rest of the application does not keep are
//! in [`Observed`], one small field of [`PlcApp`] (the board's application builder is
//! sensitive to the size of `PlcApp`).

use heapless::Vec;
use shared_protocol::link::plc::PlcLinkState;
use shared_protocol::link::FaultCode;
use shared_protocol::service::{
    Answer, DriveInfo, DriveSample, FaultLog, Identity, LinkView, LogEntry, PlcState, ProgramChunk,
    RefuseReason, Request, RunWarning, Sample, Screen as ScreenRows, SlotState, SlotSummary, Slots,
    Status, WriteResult, CHUNK_BYTES, EVENT_PROGRAM_WRITTEN, LOG_ENTRIES_PER_ANSWER,
    LOG_FROM_NEWEST, LOG_POSITIONS, REMOTE_TIMEOUT_MS,
};
use shared_protocol::units::Micros;

use super::{PlcApp, RunState};
use crate::editor::Notice;
use crate::storage::layout::SLOTS;
use crate::storage::reads::{SlotReads, SlotRecord};
use crate::storage::{Eeprom, Job, StorageError};
use crate::vm;
use shared_protocol::program::payload::for_each_payload_byte;

/// What the service reports that the rest of the application does not keep.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(crate) struct Observed {
    /// Remote service is on until this uptime (ms); `None`: off (service.md 4).
    remote_until_ms: Option<u64>,
    /// The debounced inputs the last scan was given (bit n = Dn) and A00-A03.
    d: u16,
    a: [u16; 4],
    /// Scan timing since RUN started: the previous scan's time, the last and the longest
    /// period.
    scan_prev_us: Option<u64>,
    scan_last_us: u32,
    scan_max_us: u32,
    /// Ring position of the newest fault-log entry (`None`: empty log).
    pub(crate) log_head: Option<u8>,
    /// `Run { slot }` queued this slot's load: RUN starts when it succeeds.
    pub(crate) run_after_load: Option<u8>,
    /// A program written over the service port is being loaded into RAM: the status row
    /// keeps saying `SLOT n WRITTEN (SVC)` after the load.
    pub(crate) written_load: Option<u8>,
}

impl Observed {
    /// A scan ran at `now` with these inputs.
    pub(crate) fn scanned(&mut self, digital: u16, analog: [u16; 4], now: Micros, running: bool) {
        self.d = digital;
        self.a = analog;
        if !running {
            self.scan_prev_us = None;
            return;
        }
        if let Some(prev) = self.scan_prev_us {
            let us = u32::try_from(now.0.saturating_sub(prev)).unwrap_or(u32::MAX);
            self.scan_last_us = us;
            self.scan_max_us = self.scan_max_us.max(us);
        }
        self.scan_prev_us = Some(now.0);
    }

    /// RUN starts: the scan figures count from here.
    pub(crate) fn run_started(&mut self) {
        self.scan_prev_us = None;
        self.scan_last_us = 0;
        self.scan_max_us = 0;
    }

    /// A fault-log entry was appended after the newest one.
    pub(crate) fn logged(&mut self) {
        let next = self.log_head.map_or(0, |h| (h + 1) % LOG_POSITIONS);
        self.log_head = Some(next);
    }
}

/// The result of handing a request to the application.
#[derive(Debug, Clone, PartialEq)]
pub enum Outcome {
    /// Send this answer.
    Answer(Answer),
    /// The EEPROM reads it needs are under way (see [`SlotReads`]): ask again after the
    /// next step of the reads (the service endpoint's EEPROM step).
    Later,
}

/// Slot 1-4's checked record, or what to answer meanwhile: refused `Storage` when the
/// last read failed, [`Outcome::Later`] while the slot is read (the read is started).
/// Every request that needs a slot's record asks through this, so all answer alike.
#[allow(
    clippy::result_large_err,
    reason = "the error is the caller's own return value, passed straight on"
)]
pub(crate) fn checked_slot(reads: &mut SlotReads, slot: u8) -> Result<SlotRecord, Outcome> {
    if reads.take_failure() {
        return Err(Outcome::Answer(Answer::Refused(RefuseReason::Storage)));
    }
    reads.summary(slot).ok_or_else(|| {
        reads.want(slot);
        Outcome::Later
    })
}

/// What an [`Identity`] needs that the application does not know: the board's (or
/// hil-sim's) build and chip.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BuildInfo {
    pub firmware: &'static str,
    pub git: &'static str,
    /// The MCU's 96-bit unique ID.
    pub uid: [u8; 12],
}

fn plc_state(run: RunState) -> PlcState {
    match run {
        RunState::Stopped => PlcState::Stop,
        RunState::WaitLink | RunState::Downloading => PlcState::Starting,
        RunState::Running => PlcState::Run,
    }
}

/// What `.collect()` into a `heapless::Vec` does, cut at the capacity instead of
/// panicking past it (heapless's `FromIterator` has an `expect`; every use here fits, and
/// the panic path was code in the image for each of them).
pub(crate) fn up_to<T, const N: usize>(items: impl Iterator<Item = T>) -> Vec<T, N> {
    let mut v = Vec::new();
    for x in items {
        if v.push(x).is_err() {
            break;
        }
    }
    v
}

/// `s` cut to at most `N` bytes at a character boundary (one copy, no per-character
/// decoding and encoding).
fn short<const N: usize>(s: &str) -> heapless::String<N> {
    let mut n = s.len().min(N);
    while !s.is_char_boundary(n) {
        n -= 1;
    }
    let mut out = heapless::String::new();
    let _ = out.push_str(s.get(..n).unwrap_or(""));
    out
}

impl<E: Eeprom> PlcApp<E> {
    /// Whether remote service is on at `now` (keys `*` `7`; service.md 4).
    pub fn remote_service(&self, now: Micros) -> bool {
        self.observed
            .remote_until_ms
            .is_some_and(|t| now.0 / 1000 < t)
    }

    /// Keys `*` `7`: switch remote service on (for 30 min) or off.
    pub(crate) fn toggle_remote(&mut self, now: Micros) {
        let on = !self.remote_service(now);
        self.observed.remote_until_ms = on.then(|| now.0 / 1000 + REMOTE_TIMEOUT_MS);
        self.editor.notify(Notice::Text(if on {
            "REMOTE SVC ON"
        } else {
            "REMOTE SVC OFF"
        }));
    }

    /// A guarded request was accepted: remote service stays on 30 min from now, or until
    /// its current end if that is later.
    pub fn renew_remote(&mut self, now: Micros) {
        if let Some(t) = self.observed.remote_until_ms.as_mut() {
            *t = (*t).max(now.0 / 1000 + REMOTE_TIMEOUT_MS);
        }
    }

    /// Remote service switches itself off at its end (called every tick).
    pub(crate) fn expire_remote(&mut self, now: Micros) {
        if self
            .observed
            .remote_until_ms
            .is_some_and(|t| now.0 / 1000 >= t)
        {
            self.observed.remote_until_ms = None;
            self.editor.notify(Notice::Text("REMOTE SVC OFF"));
        }
    }

    fn link_view(&self) -> LinkView {
        match self.link.state() {
            PlcLinkState::Up => LinkView::Up,
            PlcLinkState::Connecting => LinkView::Lost,
            PlcLinkState::Incompatible { drive_version } => {
                LinkView::VersionMismatch { drive_version }
            }
        }
    }

    fn drive_info(&self) -> Option<DriveInfo> {
        self.drive_status().map(|s| DriveInfo {
            state: s.state,
            fault: s.fault.map_or(0, FaultCode::code),
            freq_dhz: s.freq_dhz,
            reverse: s.reverse,
            udc_dv: s.udc_dv,
            imax_ca: s.imax_ca,
            com: s.com,
        })
    }

    /// The ring position and code of the newest fault-log entry.
    fn newest_log(&self) -> Option<(u8, u8)> {
        let pos = self.observed.log_head?;
        Some((pos, self.fault_log.first()?.code))
    }

    /// `GetStatus`'s answer.
    pub fn service_status(&self, now: Micros) -> Status {
        Status {
            plc: plc_state(self.run),
            remote: self.remote_service(now),
            link: self.link_view(),
            drive: self.drive_info(),
            d: self.observed.d,
            o: self.out.outputs,
            a: self.observed.a,
            lcd: self.out.lcd,
            warning: self.warning.map(|w| match w {
                vm::Warning::Div0 { line } => RunWarning::Div0 { line },
            }),
            newest_log: self.newest_log(),
            scan_last_us: self.observed.scan_last_us,
            scan_max_us: self.observed.scan_max_us,
            uptime_ms: now.0 / 1000,
            slot: self.editor.loaded_slot(),
            unsaved: self.editor.modified(),
        }
    }

    /// A trend sample of the scan that just ran, with the subscribed Q values.
    pub fn service_sample(&self, q: &[u8], now: Micros) -> Sample {
        let drive = self.drive_status().map(|s| DriveSample {
            freq_dhz: s.freq_dhz,
            reverse: s.reverse,
            udc_dv: s.udc_dv,
            imax_ca: s.imax_ca,
            fault: s.fault.map_or(0, FaultCode::code),
        });
        Sample {
            uptime_ms: now.0 / 1000,
            plc: plc_state(self.run),
            drive,
            d: self.observed.d,
            o: self.out.outputs,
            a: self.observed.a,
            lcd: self.out.lcd,
            q: up_to(q.iter().map(|&n| self.vm.q(n))),
            dropped: 0,
        }
    }

    /// `ReadFaultLog`: up to `count` entries newest first, from ring position `from`.
    fn service_fault_log(&self, from: u8, count: u8) -> FaultLog {
        let head = self.observed.log_head;
        let ring = LOG_POSITIONS;
        // Entry k of the RAM log (newest first) sits k positions before the head.
        let skip = match (head, from) {
            (_, LOG_FROM_NEWEST) | (None, _) => 0,
            (Some(h), f) => usize::from((h + ring - f % ring) % ring),
        };
        let entries = up_to(
            self.fault_log
                .iter()
                .enumerate()
                .skip(skip)
                .take(usize::from(count).min(LOG_ENTRIES_PER_ANSWER))
                .map(|(k, e)| LogEntry {
                    pos: head.map_or(0, |h| (h + ring - (k as u8 % ring)) % ring),
                    code: e.code,
                    power_up: e.power_cycle,
                    uptime_s: e.uptime_s,
                    wall_s: e.wall(),
                    values: [e.value(0), e.value(1)],
                }),
        );
        FaultLog {
            total: self.fault_log.len() as u8,
            newest: head,
            entries,
        }
    }

    /// `Identify`'s answer.
    pub fn service_identity(&self, build: &BuildInfo, now: Micros) -> Identity {
        Identity {
            firmware: short(build.firmware),
            git: short(build.git),
            uid: build.uid,
            power_ups: self.storage.power_cycle(),
            uptime_ms: now.0 / 1000,
        }
    }

    /// `GetScreen`: the rows as the LCD shows them now.
    fn service_screen(&self, now: Micros) -> ScreenRows {
        let mut screen = self.editor.screen();
        self.draw(now, &mut screen);
        // Blank cells are spaces (`Screen::clear`): trimming them alone spares the image
        // `trim_end`'s Unicode white-space table.
        ScreenRows {
            rows: up_to((0..screen.rows()).map(|r| short(screen.row(r).trim_end_matches(' ')))),
        }
    }

    /// `ReadProgram` of slot 0: the program in RAM in the stored payload form.
    fn ram_chunk(&self, offset: u16) -> Outcome {
        let mut digest = shared_protocol::link::frame::CRC.digest();
        let mut len = 0usize;
        let mut data: Vec<u8, CHUNK_BYTES> = Vec::new();
        let start = usize::from(offset);
        for_each_payload_byte(&self.program, |b| {
            digest.update(&[b]);
            if len >= start {
                let _ = data.push(b);
            }
            len += 1;
        });
        if start > len || (start == len && len > 0) {
            return Outcome::Answer(Answer::Refused(RefuseReason::Transfer));
        }
        Outcome::Answer(Answer::ProgramChunk(ProgramChunk {
            slot: 0,
            generation: 0,
            len: len as u16,
            crc: digest.finalize(),
            offset,
            data,
        }))
    }

    /// `ReadProgram` of slot 1-4 through the service's paced reads.
    fn slot_chunk(&self, reads: &mut SlotReads, slot: u8, offset: u16) -> Outcome {
        let s = match checked_slot(reads, slot) {
            Ok(rec) => rec.summary,
            Err(meanwhile) => return meanwhile,
        };
        if s.state != SlotState::Valid {
            return Outcome::Answer(Answer::Refused(RefuseReason::Slot));
        }
        let start = usize::from(offset);
        let len = usize::from(s.len);
        if start > len || (start == len && len > 0) {
            return Outcome::Answer(Answer::Refused(RefuseReason::Transfer));
        }
        let n = (len - start).min(CHUNK_BYTES);
        reads.drop_stale_chunk(slot, offset);
        if n > 0 {
            match reads.take_chunk(slot, offset) {
                Some(data) => {
                    return Outcome::Answer(Answer::ProgramChunk(ProgramChunk {
                        slot,
                        generation: s.generation,
                        len: s.len,
                        crc: s.crc,
                        offset,
                        data,
                    }))
                }
                None => {
                    reads.start_chunk(slot, offset, n);
                    return Outcome::Later;
                }
            }
        }
        Outcome::Answer(Answer::ProgramChunk(ProgramChunk {
            slot,
            generation: s.generation,
            len: s.len,
            crc: s.crc,
            offset,
            data: Vec::new(),
        }))
    }

    /// `ListSlots` through the service's paced reads.
    fn service_slots(&self, reads: &mut SlotReads) -> Outcome {
        if reads.take_failure() {
            return Outcome::Answer(Answer::Refused(RefuseReason::Storage));
        }
        let mut slots = [SlotSummary {
            state: SlotState::Empty,
            generation: 0,
            lines: 0,
            len: 0,
            crc: 0,
        }; SLOTS as usize];
        for (slot, out) in (1..=SLOTS).zip(slots.iter_mut()) {
            match reads.summary(slot) {
                Some(r) => *out = r.summary,
                None => {
                    reads.want(slot);
                    return Outcome::Later;
                }
            }
        }
        Outcome::Answer(Answer::Slots(Slots {
            slots,
            ram_slot: self.editor.loaded_slot(),
            unsaved: self.editor.modified(),
            last_run: self.run_slot,
        }))
    }

    /// Answers a request the service port handed over (its own rules already applied:
    /// `Hello`, remote service, repeats). Guarded requests arrive only with remote
    /// service on.
    pub fn service_request(
        &mut self,
        reads: &mut SlotReads,
        build: &BuildInfo,
        request: &Request,
        now: Micros,
    ) -> Outcome {
        let refused = |r| Outcome::Answer(Answer::Refused(r));
        let stopped = self.run == RunState::Stopped;
        match *request {
            // The port answers these itself.
            Request::Hello { .. } | Request::Subscribe { .. } => refused(RefuseReason::Transfer),
            Request::Identify => {
                Outcome::Answer(Answer::Identity(self.service_identity(build, now)))
            }
            Request::GetStatus => Outcome::Answer(Answer::Status(self.service_status(now))),
            Request::GetScreen => Outcome::Answer(Answer::Screen(self.service_screen(now))),
            Request::ReadFaultLog { from, count } => {
                Outcome::Answer(Answer::FaultLog(self.service_fault_log(from, count)))
            }
            // Answered by the service's tally (`service::counters`), never handed here.
            Request::GetCounters => refused(RefuseReason::Storage),
            Request::ListSlots => self.service_slots(reads),
            Request::ReadProgram { slot: 0, offset } => self.ram_chunk(offset),
            Request::ReadProgram { slot, offset } if (1..=SLOTS).contains(&slot) => {
                self.slot_chunk(reads, slot, offset)
            }
            Request::ReadProgram { .. } => refused(RefuseReason::Slot),
            // Executed by the service's staging (`service::write`), never handed here.
            Request::WriteBegin { .. } | Request::WriteChunk { .. } | Request::WriteCommit => {
                refused(RefuseReason::Transfer)
            }
            Request::Run { slot } => self.service_run(reads, slot, now),
            Request::Stop => {
                // Already stopped: nothing to do (and no boot-record write per request).
                if !stopped {
                    self.stop();
                }
                Outcome::Answer(Answer::Done)
            }
            Request::Ack => match self.ack_fault() {
                Ok(()) => {
                    self.editor.notify(Notice::Text("FAULT ACK SENT (SVC)"));
                    Outcome::Answer(Answer::Done)
                }
                // No link: nothing to acknowledge now.
                Err(_) => refused(RefuseReason::Busy),
            },
            Request::ClearFaultLog if !stopped => refused(RefuseReason::InRun),
            Request::ClearFaultLog => match self.queue_clear_fault_log(now) {
                Ok(()) => Outcome::Answer(Answer::Done),
                Err(crate::storage::QueueFull) => refused(RefuseReason::Busy),
            },
            Request::SetClock { seconds } if !self.set_wall_clock(seconds, now) => {
                refused(RefuseReason::Transfer)
            }
            Request::GetClock | Request::SetClock { .. } => Outcome::Answer(Answer::Clock {
                seconds: self.wall_seconds(now),
            }),
        }
    }

    /// Shows `text` on the status row (the service's messages, e.g. `COUNTERS RESET`).
    pub(crate) fn notify_text(&mut self, text: &'static str) {
        self.editor.notify(Notice::Text(text));
    }

    /// A program write over the service port ended (its [`Job::Commit`]). After `Saved`
    /// (service.md 3): the status row says `SLOT n WRITTEN (SVC)`, the log gets the event
    /// `PGMSVC` (241), and when RAM held that slot without unsaved edits the new program
    /// is loaded (while stopped; in RUN the running program stays and counts as edited,
    /// so nothing discards it unasked).
    pub(crate) fn program_written(
        &mut self,
        slot: u8,
        result: Result<WriteResult, StorageError>,
        now: Micros,
    ) {
        match result {
            Ok(WriteResult::Saved { .. }) => {
                let held = self.editor.loaded_slot() == Some(slot) && !self.editor.modified();
                self.log_fault(EVENT_PROGRAM_WRITTEN, now);
                if held && self.run == RunState::Stopped {
                    match self.storage.queue(Job::Load { slot }) {
                        Ok(()) => self.observed.written_load = Some(slot),
                        Err(_) => self.editor.mark_modified(),
                    }
                } else if held {
                    self.editor.mark_modified();
                }
                self.editor.notify(Notice::Written { slot });
            }
            Ok(_) => {}
            Err(error) => self.editor.notify(Notice::SaveFailed { slot, error }),
        }
    }

    /// `Run { slot }`: 0 runs the program in RAM as key `A` does, 1-4 loads that slot
    /// first (refused with unsaved edits in RAM). `Done` means RUN was requested: for a
    /// slot, the load is queued like the keypad's (one EEPROM page per pass, the lock is
    /// never held across it) and RUN starts when it succeeds.
    fn service_run(&mut self, reads: &mut SlotReads, slot: u8, now: Micros) -> Outcome {
        let refused = |r| Outcome::Answer(Answer::Refused(r));
        if slot == 0 {
            let from = self.editor.slot();
            self.run(from, now);
            return Outcome::Answer(Answer::Done);
        }
        if !(1..=SLOTS).contains(&slot) {
            return refused(RefuseReason::Slot);
        }
        if self.editor.modified() {
            return refused(RefuseReason::Unsaved);
        }
        let rec = match checked_slot(reads, slot) {
            Ok(rec) => rec,
            Err(meanwhile) => return meanwhile,
        };
        if rec.summary.state != SlotState::Valid {
            return refused(RefuseReason::Slot);
        }
        if self.run != RunState::Stopped {
            self.stop();
        }
        if self.storage.queue(Job::Load { slot }).is_err() {
            return refused(RefuseReason::Busy);
        }
        self.observed.run_after_load = Some(slot);
        self.editor.notify(Notice::Text("LOADING..."));
        Outcome::Answer(Answer::Done)
    }
}
