//! The drive's end of the link (sans-IO): answers the handshake, applies commands exactly
//! once and in order, receives and verifies the drive section, reports status and faults,
//! and supervises the link.
//!
//! Feed received bytes to [`DriveLink::receive`], call [`DriveLink::poll_transmit`] at
//! least every millisecond (it also runs the timers) and drain [`DriveLink::poll_event`]
//! after each `receive`.

use super::config::LinkConfig;
use super::frame::CRC;
use super::frame::{Frame, MAX_WIRE_FRAME};
use super::message::{
    verify_kind_code, AckRefusal, DownloadResult, DriveMsg, DriveStatus, PlcMsg, RejectReason,
    MAX_Q_PER_FRAME, PROTOCOL_VERSION,
};
use super::plc_decode::plc_frame;
use super::session::{earliest, Reliable, Session, AT_ONCE};
use super::LinkStats;
use crate::crc32::CastagnoliDigest;
use crate::fault::FaultCode;
use crate::program::{
    decode_slot, DriveSection, VerifiedDriveSection, Verifier, VerifyError, DRIVE_LINES, LINE_BYTES,
};
use crate::units::Micros;

/// Unacknowledged reliable messages the drive keeps in flight.
pub const DRIVE_WINDOW: usize = 4;
const PENDING: usize = 16;
const EVENTS: usize = 32;
const SECTION_BYTES: usize = DRIVE_LINES * LINE_BYTES;

/// The drive's view of the link.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DriveLinkState {
    /// No handshake yet, or lost: only `Hello` is listened to.
    Down,
    Up,
    /// The PLC speaks another protocol version: the drive keeps its outputs off.
    Incompatible {
        plc_version: u16,
    },
}

/// What the drive application hears from the link. Commands come exactly once, in the
/// order the PLC issued them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DriveEvent {
    Connected,
    /// No valid frame for `drive_timeout_us` (the core trips `LINK` when in RUN).
    LinkLost,
    VersionMismatch {
        plc_version: u16,
    },
    QWrite {
        addr: u8,
        value: i16,
    },
    Run,
    Stop,
    Direction {
        reverse: bool,
    },
    AckFault,
    /// The PLC's safety request mask (bit n = function n requested).
    SafetyRequest {
        requested: u16,
    },
    /// A downloaded section passed the CRC and the verifier: take it with
    /// [`DriveLink::take_program`].
    ProgramAccepted,
    /// A download was refused (the PLC has been told; the core trips `PROG`).
    ProgramRejected {
        line: u16,
        reason: RejectReason,
    },
}

struct DownloadRx {
    buf: [u8; SECTION_BYTES],
    crc: u32,
    /// The CRC of the chunks received so far, in order: a complete download's is the
    /// section's (`section_crc` of `buf`), computed one chunk per receive call instead
    /// of ~4 200 instructions in one check step.
    running: CastagnoliDigest,
    next_line: usize,
    /// Set when a chunk was out of place: the download will be refused at its end.
    broken: bool,
    active: bool,
    check: Check,
}

/// The check of a complete download, one step per [`DriveLink::poll_transmit`] (review
/// D13). On the drive every call into the link runs in a critical section against the
/// PWM interrupt; the whole check (CRC ~3 900, slot decoding ~4 300, verifier ~3 800
/// Cortex-M4 instructions, plus the core's load) in one call held that interrupt off for
/// about 2.8 periods at 20 kHz. One step stays under half a period.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Check {
    Idle,
    Crc,
    /// Decode the lines from this one on, [`DECODE_LINES_PER_STEP`] per step.
    Decode {
        from: u16,
    },
    /// Verify the lines from this one on, [`VERIFY_USED_LINES_PER_STEP`] used lines per
    /// step, with the verifier's state so far.
    Verify {
        from: u16,
        v: Verifier<false>,
    },
    /// The result goes out (and the event to the application) in the next step, so the
    /// application's load of the section never shares a call with the verifier.
    Done(DownloadResult),
}

/// Used lines verified per check step: `verify_drive` of the motor example took ~4 900
/// instructions in one step (m4bench), ~190 per used line.
pub const VERIFY_USED_LINES_PER_STEP: u16 = 10;

/// Lines decoded per check step: the 150 lines in one step took ~7 600 instructions with
/// the safety settings' mnemonics (m4bench), and the link's critical section around it
/// ~9 900 in the emulator, over the 8 500-cycle budget. In steps of 50, the
/// first step of the motor example (its 26 used lines are 000-025) still took 6 771
/// instructions, 9 187 cycles in the emulator's cycle model: a used line costs
/// ~250 instructions, an empty one ~20. Fifteen steps of 10 (~2 600 at most each).
pub const DECODE_LINES_PER_STEP: u16 = 10;

/// The drive endpoint.
pub struct DriveLink {
    s: Session<DriveMsg, DRIVE_WINDOW>,
    state: DriveLinkState,
    session: Option<u8>,
    hello_reply: Option<u8>,
    /// A reliable message was applied in this session.
    session_used: bool,
    pending: heapless::Deque<DriveMsg, PENDING>,
    events: heapless::Deque<DriveEvent, EVENTS>,
    status: DriveStatus,
    last_status: Option<(DriveStatus, Micros)>,
    download: DownloadRx,
    /// The section being checked (decoded in the [`Check::Decode`] steps), then the
    /// accepted one.
    program: Option<DriveSection>,
    /// `program` passed the CRC and the verifier and has not been taken yet.
    accepted: bool,
}

impl DriveLink {
    pub fn new(cfg: LinkConfig) -> Self {
        DriveLink {
            s: Session::new(cfg),
            state: DriveLinkState::Down,
            session: None,
            hello_reply: None,
            session_used: false,
            pending: heapless::Deque::new(),
            events: heapless::Deque::new(),
            status: DriveStatus::default(),
            last_status: None,
            download: DownloadRx {
                buf: [0; SECTION_BYTES],
                crc: 0,
                running: CRC.digest(),
                next_line: 0,
                broken: false,
                active: false,
                check: Check::Idle,
            },
            program: None,
            accepted: false,
        }
    }

    pub fn config(&self) -> &LinkConfig {
        self.s.config()
    }

    pub fn state(&self) -> DriveLinkState {
        self.state
    }

    pub fn is_up(&self) -> bool {
        self.state == DriveLinkState::Up
    }

    pub fn stats(&self) -> LinkStats {
        self.s.stats()
    }

    /// The UART reported a line error: the frame being received is dropped, the error
    /// counted ([`LinkStats::line_errors`]).
    pub fn line_error(&mut self) {
        self.s.line_error();
    }

    pub fn poll_event(&mut self) -> Option<DriveEvent> {
        self.events.pop_front()
    }

    /// The section accepted by the last successful download (once), verified.
    pub fn take_program(&mut self) -> Option<VerifiedDriveSection> {
        if !core::mem::take(&mut self.accepted) {
            return None;
        }
        self.program
            .take()
            .map(VerifiedDriveSection::verified_earlier)
    }

    /// The drive's current state and measurements; sent every `status_us`, and at once
    /// when the state or the fault code changes.
    pub fn set_status(&mut self, status: DriveStatus) {
        self.status = status;
    }

    /// Report a trip to the PLC (reliable; kept across a reconnection). Returns `false`
    /// when 16 reports are already waiting.
    #[must_use = "a report that did not fit must be kept and offered again"]
    pub fn report_fault(&mut self, code: FaultCode, drive_time_ms: u32) -> bool {
        self.pending
            .push_back(DriveMsg::Fault {
                code,
                drive_time_ms,
            })
            .is_ok()
    }

    /// Tell the PLC why an ACK was refused (reliable). Returns `false` when 16 messages
    /// are already waiting (the PLC then shows no reason; the fault stays latched).
    #[must_use = "a refusal that did not fit is not reported"]
    pub fn report_ack_refused(&mut self, why: AckRefusal) -> bool {
        self.pending.push_back(DriveMsg::AckRefused(why)).is_ok()
    }

    /// Bytes received from the UART, in order.
    pub fn receive(&mut self, bytes: &[u8], now: Micros) {
        for &b in bytes {
            // The written-out decoder (`plc_decode`): ~2 KiB less on the drive than serde's.
            if let Some(frame) = self.s.read_byte_with(b, plc_frame) {
                self.on_frame(frame, now);
            }
        }
        self.tick(now);
    }

    /// Out of line: inlined, the deque's wrap-around code was copied at each of its callers
    /// (drive image −0.6 KiB, docs/size.md).
    #[inline(never)]
    fn push_event(&mut self, e: DriveEvent) {
        if self.events.is_full() {
            self.events.pop_front();
        }
        // Cannot fail: room was made above (the newest events are kept).
        let _ = self.events.push_back(e);
    }

    fn on_frame(&mut self, f: Frame<PlcMsg>, now: Micros) {
        if let PlcMsg::Hello { version, session } = f.msg {
            self.on_hello(version, session, now);
            return;
        }
        if self.state != DriveLinkState::Up {
            return;
        }
        self.s.peer_frame(f.ack, now);
        if !f.msg.is_reliable() {
            return;
        }
        // Room for the largest message's events, so nothing applied is ever lost.
        let room = self.events.capacity() - self.events.len() > MAX_Q_PER_FRAME;
        let timeout = self.s.config().drive_timeout_us;
        match self.s.reliable(f.seq, room, now, timeout) {
            Reliable::Apply => self.session_used = true,
            Reliable::Drop => return,
            Reliable::Stalled => return self.lose(),
        }
        match f.msg {
            PlcMsg::QWrite(writes) => {
                for q in writes {
                    self.push_event(DriveEvent::QWrite {
                        addr: q.addr,
                        value: q.value,
                    });
                }
            }
            PlcMsg::Run => self.push_event(DriveEvent::Run),
            PlcMsg::Stop => self.push_event(DriveEvent::Stop),
            PlcMsg::Direction { reverse } => self.push_event(DriveEvent::Direction { reverse }),
            PlcMsg::AckFault => self.push_event(DriveEvent::AckFault),
            PlcMsg::SafetyRequest { requested } => {
                self.push_event(DriveEvent::SafetyRequest { requested })
            }
            PlcMsg::DownloadBegin { crc } => {
                self.download.crc = crc;
                self.download.running = CRC.digest();
                self.download.next_line = 0;
                self.download.broken = false;
                self.download.active = true;
                self.download.check = Check::Idle;
                self.program = None;
                self.accepted = false;
            }
            PlcMsg::DownloadChunk { first_line, data } => self.on_chunk(first_line, &data),
            PlcMsg::DownloadEnd => self.finish_download(),
            PlcMsg::Hello { .. } | PlcMsg::Heartbeat => {}
        }
    }

    fn on_hello(&mut self, version: u16, session: u8, now: Micros) {
        self.hello_reply = Some(session);
        if version != PROTOCOL_VERSION {
            if self.state == DriveLinkState::Up {
                // A reflashed PLC: the old session is over (the core stops).
                self.lose();
            }
            let st = DriveLinkState::Incompatible {
                plc_version: version,
            };
            if self.state != st {
                self.state = st;
                self.push_event(DriveEvent::VersionMismatch {
                    plc_version: version,
                });
            }
            return;
        }
        if self.state == DriveLinkState::Up && self.session == Some(session) && !self.session_used {
            // The PLC did not get our reply yet: answer again, keep the session. (Once a
            // command has arrived in this session, the PLC has had its reply, and a UART
            // keeps order: the same session's Hello now means a PLC that restarted.)
            return;
        }
        if self.state == DriveLinkState::Up {
            // The PLC started over: it has dropped what it had not seen acknowledged
            // (possibly a STOP), so for the drive this is a lost link too.
            self.lose();
        }
        self.session = Some(session);
        self.session_used = false;
        self.state = DriveLinkState::Up;
        self.last_status = None;
        self.download.active = false;
        self.download.check = Check::Idle;
        // Reports not yet acknowledged go out again in the new session, oldest first.
        let mut carried: heapless::Vec<DriveMsg, DRIVE_WINDOW> = heapless::Vec::new();
        for m in self.s.start(now) {
            // Cannot fail: the session holds at most DRIVE_WINDOW unacknowledged messages.
            let _ = carried.push(m);
        }
        for m in carried.into_iter().rev() {
            if self.pending.push_front(m).is_err() {
                break;
            }
        }
        self.push_event(DriveEvent::Connected);
    }

    fn on_chunk(&mut self, first_line: u8, data: &[u8]) {
        let d = &mut self.download;
        let start = usize::from(first_line) * LINE_BYTES;
        let end = start + data.len();
        if !d.active
            || usize::from(first_line) != d.next_line
            || !data.len().is_multiple_of(LINE_BYTES)
            || end > SECTION_BYTES
        {
            d.broken = true;
            return;
        }
        if let Some(dst) = d.buf.get_mut(start..end) {
            dst.copy_from_slice(data);
            d.running.update(data);
            d.next_line += data.len() / LINE_BYTES;
        } else {
            d.broken = true;
        }
    }

    /// `DownloadEnd`: an incomplete download is refused at once; a complete one is
    /// checked in steps ([`Check`]). Chunks arriving meanwhile are refused (`active` is
    /// off), so the buffer does not change under the check.
    fn finish_download(&mut self) {
        let d = &mut self.download;
        let complete = d.active && !d.broken && d.next_line == DRIVE_LINES;
        d.active = false;
        if complete {
            d.check = Check::Crc;
        } else {
            let line = d.next_line.min(DRIVE_LINES) as u16;
            self.report_download(DownloadResult::Rejected {
                line,
                reason: RejectReason::Incomplete,
            });
        }
    }

    /// One step of the check of a complete download (none when there is nothing to do).
    fn check_step(&mut self) {
        self.download.check = match self.download.check {
            Check::Idle => Check::Idle,
            Check::Crc if self.download.running.clone().finalize() != self.download.crc => {
                Check::Done(DownloadResult::Rejected {
                    line: 0,
                    reason: RejectReason::Crc,
                })
            }
            Check::Crc => {
                self.program = Some(DriveSection::default());
                Check::Decode { from: 0 }
            }
            Check::Decode { from } => match self.decode_download(from) {
                Ok(next) if usize::from(next) >= DRIVE_LINES => Check::Verify {
                    from: 0,
                    v: Verifier::new(),
                },
                Ok(next) => Check::Decode { from: next },
                Err(line) => Check::Done(DownloadResult::Rejected {
                    line,
                    reason: RejectReason::Decode,
                }),
            },
            Check::Verify { .. } if self.program.is_none() => {
                Check::Done(DownloadResult::Rejected {
                    line: 0,
                    reason: RejectReason::Incomplete,
                })
            }
            Check::Verify { from, mut v } => match self.verify_download(from, &mut v) {
                Ok(next) if usize::from(next) >= DRIVE_LINES => {
                    Check::Done(DownloadResult::Accepted)
                }
                Ok(next) => Check::Verify { from: next, v },
                Err(e) => Check::Done(DownloadResult::Rejected {
                    line: e.line,
                    reason: RejectReason::Verify(verify_kind_code(&e.kind)),
                }),
            },
            Check::Done(result) => {
                self.accepted = result == DownloadResult::Accepted;
                if !self.accepted {
                    self.program = None;
                }
                self.report_download(result);
                Check::Idle
            }
        };
    }

    /// Decodes the received bytes into `program`; the first bad line on failure.
    /// Decodes up to [`DECODE_LINES_PER_STEP`] received lines from line `from` into
    /// `program`; the next line to decode, or the first bad line.
    fn decode_download(&mut self, from: u16) -> Result<u16, u16> {
        let section = self.program.get_or_insert_with(DriveSection::default);
        let lines = section
            .lines
            .iter_mut()
            .zip(self.download.buf.chunks_exact(LINE_BYTES))
            .enumerate()
            .skip(usize::from(from))
            .take(usize::from(DECODE_LINES_PER_STEP));
        let mut next = from;
        for (n, (slot, bytes)) in lines {
            *slot = decode_slot(bytes).map_err(|_| n as u16)?;
            next = n as u16 + 1;
        }
        Ok(next)
    }

    /// Runs the verifier `v` over the decoded lines from line `from` on, up to
    /// [`VERIFY_USED_LINES_PER_STEP`] used lines; the next line to verify. The verifier in
    /// steps is `verify_drive` (its loop over the lines, `Verifier`), minus the first
    /// line of a `SettingTwice`, which the drive does not report.
    fn verify_download(&self, from: u16, v: &mut Verifier<false>) -> Result<u16, VerifyError> {
        let Some(section) = self.program.as_ref() else {
            return Ok(DRIVE_LINES as u16);
        };
        let mut used = 0;
        let mut next = from;
        for (line, slot) in (0u16..).zip(section.lines.iter()).skip(usize::from(from)) {
            if used == VERIFY_USED_LINES_PER_STEP {
                break;
            }
            next = line + 1;
            if let Some(i) = slot {
                v.line(line, i)?;
                used += 1;
            }
        }
        if next == from {
            // Nothing left: the end.
            next = DRIVE_LINES as u16;
        }
        Ok(next)
    }

    /// The result to the PLC (reliable) and to the application.
    fn report_download(&mut self, result: DownloadResult) {
        if self.pending.push_back(DriveMsg::Download(result)).is_err() {
            // Keep the answer even if fault reports fill the queue: drop the oldest report.
            // The dropped report's fault stays latched and is in every status frame, so
            // the PLC still shows it; only its fault-log entry is lost. This needs 16
            // reports unacknowledged during a download, i.e. a PLC that is not reading.
            self.pending.pop_front();
            let _ = self.pending.push_back(DriveMsg::Download(result));
        }
        match result {
            DownloadResult::Accepted => self.push_event(DriveEvent::ProgramAccepted),
            DownloadResult::Rejected { line, reason } => {
                self.push_event(DriveEvent::ProgramRejected { line, reason })
            }
        }
    }

    /// Run the timers (also done by `receive` and `poll_transmit`).
    pub fn tick(&mut self, now: Micros) {
        if self.state == DriveLinkState::Up
            && self.s.timed_out(now, self.s.config().drive_timeout_us)
        {
            self.lose();
        }
    }

    /// When [`Self::poll_transmit`] must be called next if nothing is received meanwhile
    /// (quinn-proto's `poll_timeout`): a handshake reply, a status change, an ack or a
    /// queued report at once ([`AT_ONCE`]); otherwise the status period, the
    /// retransmission timeout or the link-loss timer, whichever comes first. `None` while
    /// the link is down with nothing to answer: only a received `Hello` changes that.
    pub fn poll_timeout(&self) -> Option<Micros> {
        if self.hello_reply.is_some() {
            return Some(AT_ONCE);
        }
        if self.state != DriveLinkState::Up {
            return None;
        }
        if self.download.check != Check::Idle {
            // The next step of a download's check.
            return Some(AT_ONCE);
        }
        let now_due = self.s.ack_owed() || (!self.pending.is_empty() && !self.s.window_full());
        let status = match self.last_status {
            _ if now_due => AT_ONCE,
            None => AT_ONCE,
            Some((s, _)) if s.urgent_key() != self.status.urgent_key() => AT_ONCE,
            Some((_, t)) => Micros(t.0.saturating_add(self.s.config().status_us)),
        };
        let loss = self.s.loss_deadline(self.s.config().drive_timeout_us);
        earliest(Some(status.min(loss)), self.s.window_deadline())
    }

    fn lose(&mut self) {
        self.state = DriveLinkState::Down;
        self.session = None;
        self.download.active = false;
        self.download.check = Check::Idle;
        self.s.count_loss();
        self.push_event(DriveEvent::LinkLost);
    }

    /// The next frame to send, written to `out`; returns its length, 0 when there is
    /// nothing to send now or `out` is smaller than [`MAX_WIRE_FRAME`].
    #[must_use = "the frame in `out` must be sent"]
    pub fn poll_transmit(&mut self, now: Micros, out: &mut [u8]) -> usize {
        self.tick(now);
        if self.state == DriveLinkState::Up && self.download.check != Check::Idle {
            self.check_step();
            // A step is a call of its own, without a frame: a step (CRC ~4 800
            // instructions at opt-level "s") plus a frame (~1 900) in one critical section
            // held the drive's PWM interrupt off for ~6 700. The next call is
            // due at once (`poll_timeout`).
            return 0;
        }
        if out.len() < MAX_WIRE_FRAME {
            return 0;
        }
        if let Some(session) = self.hello_reply.take() {
            let msg = DriveMsg::HelloReply {
                version: PROTOCOL_VERSION,
                session,
            };
            return self.s.send(msg, true, now, out);
        }
        if self.state != DriveLinkState::Up {
            return 0;
        }
        while !self.s.window_full() {
            let Some(m) = self.pending.pop_front() else {
                break;
            };
            if let Err(m) = self.s.push(m) {
                // Cannot fail: `m` was popped from this queue just above.
                let _ = self.pending.push_front(m);
                break;
            }
        }
        let n = self.s.send_reliable(now, out);
        if n > 0 {
            return n;
        }
        let status_due = match self.last_status {
            None => true,
            Some((s, t)) => {
                s.urgent_key() != self.status.urgent_key()
                    || now.0.saturating_sub(t.0) >= self.s.config().status_us
            }
        };
        if status_due {
            self.last_status = Some((self.status, now));
            return self.s.send(DriveMsg::Status(self.status), false, now, out);
        }
        if self.s.ack_owed() {
            return self.s.send(DriveMsg::Ack, false, now, out);
        }
        0
    }
}
