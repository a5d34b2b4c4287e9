//! The PLC's end of the link (sans-IO): handshake, commands, download, supervision.
//!
//! Feed received bytes to [`PlcLink::receive`], call [`PlcLink::poll_transmit`] at least
//! every millisecond (it also runs the timers) and whenever the UART can take a frame, and
//! drain [`PlcLink::poll_event`].

use super::config::LinkConfig;
use super::frame::{Frame, MAX_WIRE_FRAME};
use super::message::{
    AckRefusal, DownloadResult, DriveMsg, DriveStatus, PlcMsg, QValue, CHUNK_BYTES,
    MAX_Q_PER_FRAME, PROTOCOL_VERSION,
};
use super::session::{earliest, Reliable, Session, AT_ONCE};
use super::{LinkStats, Q_COUNT};
use crate::fault::FaultCode;
use crate::program::{encode_slot, DriveSection, DRIVE_LINES, LINE_BYTES};
use crate::shift;
use crate::units::Micros;

/// Wire bytes of a heartbeat frame.
const HEARTBEAT_WIRE_BYTES: u64 = 9;
/// How much earlier than `heartbeat_us` a heartbeat may go inside a quiet window.
const HEARTBEAT_EARLY_US: u64 = 2_000;

/// Unacknowledged reliable messages the PLC keeps in flight.
pub const PLC_WINDOW: usize = 8;
/// Commands waiting for a place in the window (all 64 Q plus the download and a few more).
const PENDING: usize = 96;
/// Of [`PENDING`], what other commands may take: the last place is STOP's, so that STOP is
/// never refused for lack of room.
const PENDING_NOT_STOP: usize = PENDING - 1;
const EVENTS: usize = 16;
const SECTION_BYTES: usize = DRIVE_LINES * LINE_BYTES;
const CHUNK_LINES: usize = CHUNK_BYTES / LINE_BYTES;

/// The PLC's view of the link.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum PlcLinkState {
    /// Sending `Hello`, waiting for the drive's answer.
    Connecting,
    /// Handshake done, frames flowing.
    Up,
    /// The drive answered with another protocol version.
    Incompatible { drive_version: u16 },
}

/// What the PLC application hears from the link.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum PlcEvent {
    /// Handshake completed (also after a reconnection).
    Connected,
    /// No valid frame from the drive for `plc_timeout_us`; reconnecting.
    /// `dropped` commands (RUN/STOP/ACK/download) were not known to be applied and are
    /// not sent again; Q values and the direction are resent after reconnection.
    LinkLost { dropped: u16 },
    /// The drive speaks another protocol version (show it on the LCD).
    VersionMismatch { drive_version: u16 },
    /// The drive's answer to the last download.
    Download(DownloadResult),
    /// The drive tripped.
    DriveFault { code: FaultCode, drive_time_ms: u32 },
    /// The drive refused an ACK (`ack_fault`), and why.
    AckRefused(AckRefusal),
}

/// Why a command was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum CommandError {
    /// The handshake has not completed: the command would be meaningless later.
    NotConnected,
    /// Too many commands waiting (the link is far slower than the caller).
    QueueFull,
    /// Q address above 63.
    BadAddress,
}

impl core::fmt::Display for CommandError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            CommandError::NotConnected => "the link to the drive is not up",
            CommandError::QueueFull => "too many commands waiting for the link",
            CommandError::BadAddress => "Q address above 63",
        })
    }
}

impl core::error::Error for CommandError {}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Pending {
    Q(QValue),
    Run,
    Stop,
    Direction(bool),
    AckFault,
    Safety(u16),
    DownloadBegin,
    /// First line of the chunk.
    DownloadChunk(u8),
    DownloadEnd,
}

impl Pending {
    fn is_q(&self) -> bool {
        matches!(self, Pending::Q(_))
    }
}

/// The PLC endpoint.
pub struct PlcLink {
    s: Session<PlcMsg, PLC_WINDOW>,
    state: PlcLinkState,
    session: u8,
    last_hello: Option<Micros>,
    pending: heapless::Vec<Pending, PENDING>,
    q_shadow: [Option<i16>; Q_COUNT],
    direction: Option<bool>,
    /// The safety request mask last set (resent after each handshake).
    safety: Option<u16>,
    section: [u8; SECTION_BYTES],
    section_crc: u32,
    download_active: bool,
    /// Until then the caller issues no command (see [`PlcLink::quiet_for`]).
    quiet_until: Option<Micros>,
    events: heapless::Deque<PlcEvent, EVENTS>,
    status: Option<(DriveStatus, Micros)>,
}

impl PlcLink {
    pub fn new(cfg: LinkConfig) -> Self {
        PlcLink {
            s: Session::new(cfg),
            state: PlcLinkState::Connecting,
            session: 1,
            last_hello: None,
            pending: heapless::Vec::new(),
            q_shadow: [None; Q_COUNT],
            direction: None,
            safety: None,
            section: [0; SECTION_BYTES],
            section_crc: 0,
            download_active: false,
            quiet_until: None,
            events: heapless::Deque::new(),
            status: None,
        }
    }

    pub fn config(&self) -> &LinkConfig {
        self.s.config()
    }

    /// Start session numbering from `seed` (e.g. the power-cycle count), so that a PLC
    /// that restarts while the drive is still up does not reuse the session the drive
    /// knows. (If it does, the drive still sees a restart once commands have flowed in
    /// that session, and otherwise a sequence disagreement is caught by the stall
    /// detectors within the link timeout.) Only before the first handshake.
    pub fn seed_session(&mut self, seed: u8) {
        if self.state == PlcLinkState::Connecting && self.last_hello.is_none() {
            self.session = seed;
        }
    }

    pub fn state(&self) -> PlcLinkState {
        self.state
    }

    pub fn is_up(&self) -> bool {
        self.state == PlcLinkState::Up
    }

    /// The newest status from the drive in this session, with its arrival time.
    pub fn last_status(&self) -> Option<(DriveStatus, Micros)> {
        self.status
    }

    pub fn stats(&self) -> LinkStats {
        self.s.stats()
    }

    /// The UART reported a line error: the frame being received is dropped, the error
    /// counted ([`LinkStats::line_errors`]).
    pub fn line_error(&mut self) {
        self.s.line_error();
    }

    /// Commands not yet acknowledged (queued or in flight).
    pub fn unacknowledged(&self) -> usize {
        self.pending.len() + self.s.in_flight()
    }

    /// Whether a download was started and its result has not arrived yet.
    pub fn download_in_progress(&self) -> bool {
        self.download_active
    }

    pub fn poll_event(&mut self) -> Option<PlcEvent> {
        self.events.pop_front()
    }

    /// New value of a Q variable for the drive. A value still waiting to be sent is
    /// replaced (newest wins); one already on the wire is followed by the new one.
    /// While the link is down only the PLC's copy is kept; all written Q are resent after
    /// each handshake so the drive's copy equals the PLC's last write.
    pub fn write_q(&mut self, addr: u8, value: i16) -> Result<(), CommandError> {
        let slot = self
            .q_shadow
            .get_mut(usize::from(addr))
            .ok_or(CommandError::BadAddress)?;
        *slot = Some(value);
        if !self.is_up() {
            return Ok(());
        }
        self.queue_q(QValue { addr, value })
    }

    /// Forget the Q values written so far (RUN starts with Q cleared): after a
    /// reconnection only the values written since are resent.
    pub fn forget_q(&mut self) {
        self.q_shadow = [None; Q_COUNT];
    }

    /// Coalesce with a write to the same Q still waiting in the run of Q writes at the end
    /// of the queue: the old entry goes, the new one is appended, so the surviving writes
    /// keep the order in which they were issued.
    fn queue_q(&mut self, q: QValue) -> Result<(), CommandError> {
        let tail = self
            .pending
            .iter()
            .rposition(|p| !p.is_q())
            .map_or(0, |i| i + 1);
        let old = self
            .pending
            .iter()
            .skip(tail)
            .position(|p| matches!(p, Pending::Q(o) if o.addr == q.addr));
        if let Some(i) = old {
            shift::remove_at(&mut self.pending, tail + i);
        }
        self.push_pending(Pending::Q(q))
    }

    /// Room left for commands other than STOP.
    fn room(&self) -> usize {
        PENDING_NOT_STOP.saturating_sub(self.pending.len())
    }

    // Out of line: every command calls it (it was inlined into each of them).
    #[inline(never)]
    fn push_pending(&mut self, p: Pending) -> Result<(), CommandError> {
        if self.room() == 0 {
            return Err(CommandError::QueueFull);
        }
        self.pending.push(p).map_err(|_| CommandError::QueueFull)
    }

    #[inline(never)]
    fn command(&mut self, p: Pending) -> Result<(), CommandError> {
        if !self.is_up() {
            return Err(CommandError::NotConnected);
        }
        self.push_pending(p)
    }

    pub fn run(&mut self) -> Result<(), CommandError> {
        self.command(Pending::Run)
    }

    /// STOP (drive.md: PWM off, coast). Never refused for lack of room: it drops what is
    /// still waiting and would contradict or delay it (Q writes, a RUN, an earlier STOP;
    /// none of them on the wire yet) and goes to the head of the queue, so it is the next
    /// new message sent (a retransmission that is due, or a full window of 8 in flight,
    /// still goes first: those are already on the wire). A dropped RUN is what the caller
    /// asked for; dropped Q writes stay in the PLC's copy and are resent after the next
    /// handshake like all others (RUN starts with Q cleared anyway). Refused only while
    /// the link is down ([`CommandError::NotConnected`]): the drive stops itself then
    /// (`LINK` in RUN, and STOP).
    pub fn stop(&mut self) -> Result<(), CommandError> {
        if !self.is_up() {
            return Err(CommandError::NotConnected);
        }
        self.pending
            .retain(|p| !matches!(p, Pending::Q(_) | Pending::Run | Pending::Stop));
        // Cannot fail: other commands leave the last place free (`PENDING_NOT_STOP`).
        shift::insert_front(&mut self.pending, Pending::Stop).map_err(|_| CommandError::QueueFull)
    }

    pub fn ack_fault(&mut self) -> Result<(), CommandError> {
        self.command(Pending::AckFault)
    }

    /// Requested direction (a level). Remembered while the link is down and resent after
    /// each handshake.
    pub fn set_direction(&mut self, reverse: bool) -> Result<(), CommandError> {
        self.direction = Some(reverse);
        if !self.is_up() {
            return Ok(());
        }
        self.command(Pending::Direction(reverse))
    }

    /// The safety functions requested (bit n = function n, safety.md 9): reliable, in
    /// order with the other commands, and the newest wins: a request still waiting is
    /// removed and this one appended. Remembered while the link is down and resent after
    /// each handshake.
    pub fn set_safety_request(&mut self, requested: u16) -> Result<(), CommandError> {
        self.safety = Some(requested);
        if !self.is_up() {
            return Ok(());
        }
        self.pending.retain(|p| !matches!(p, Pending::Safety(_)));
        self.command(Pending::Safety(requested))
    }

    /// The safety request mask last set ([`Self::set_safety_request`]).
    pub fn safety_request(&self) -> Option<u16> {
        self.safety
    }

    /// Send a drive section: `DownloadBegin`, chunks of 16 lines, `DownloadEnd`; the
    /// drive answers with [`PlcEvent::Download`].
    pub fn start_download(&mut self, section: &DriveSection) -> Result<(), CommandError> {
        if !self.is_up() {
            return Err(CommandError::NotConnected);
        }
        let chunks = DRIVE_LINES.div_ceil(CHUNK_LINES);
        if self.room() < chunks + 2 {
            return Err(CommandError::QueueFull);
        }
        for (dst, line) in self
            .section
            .chunks_exact_mut(LINE_BYTES)
            .zip(&section.lines)
        {
            dst.copy_from_slice(&encode_slot(line.as_ref()));
        }
        self.section_crc = section_crc(&self.section);
        self.command(Pending::DownloadBegin)?;
        for c in 0..chunks {
            self.command(Pending::DownloadChunk((c * CHUNK_LINES) as u8))?;
        }
        self.command(Pending::DownloadEnd)?;
        self.download_active = true;
        Ok(())
    }

    /// Bytes received from the UART, in order.
    pub fn receive(&mut self, bytes: &[u8], now: Micros) {
        for &b in bytes {
            if let Some(frame) = self.s.read_byte::<DriveMsg>(b) {
                self.on_frame(frame, now);
            }
        }
        self.tick(now);
    }

    fn on_frame(&mut self, f: Frame<DriveMsg>, now: Micros) {
        if let DriveMsg::HelloReply { version, session } = f.msg {
            if session != self.session || self.state == PlcLinkState::Up {
                return;
            }
            if version == PROTOCOL_VERSION {
                self.connect(now);
            } else if self.state
                != (PlcLinkState::Incompatible {
                    drive_version: version,
                })
            {
                self.state = PlcLinkState::Incompatible {
                    drive_version: version,
                };
                self.push_event(PlcEvent::VersionMismatch {
                    drive_version: version,
                });
            }
            return;
        }
        if self.state != PlcLinkState::Up {
            return;
        }
        self.s.peer_frame(f.ack, now);
        if f.msg.is_reliable() {
            let timeout = self.s.config().plc_timeout_us;
            match self.s.reliable(f.seq, !self.events.is_full(), now, timeout) {
                Reliable::Apply => {}
                Reliable::Drop => return,
                Reliable::Stalled => return self.lose(),
            }
        }
        match f.msg {
            DriveMsg::Status(s) => self.status = Some((s, now)),
            DriveMsg::Download(r) => {
                self.download_active = false;
                self.push_event(PlcEvent::Download(r));
            }
            DriveMsg::Fault {
                code,
                drive_time_ms,
            } => self.push_event(PlcEvent::DriveFault {
                code,
                drive_time_ms,
            }),
            DriveMsg::AckRefused(r) => self.push_event(PlcEvent::AckRefused(r)),
            DriveMsg::HelloReply { .. } | DriveMsg::Ack => {}
        }
    }

    fn push_event(&mut self, e: PlcEvent) {
        if self.events.is_full() {
            self.events.pop_front();
        }
        // Room was made above: keeps the newest events.
        let _ = self.events.push_back(e);
    }

    fn connect(&mut self, now: Micros) {
        self.state = PlcLinkState::Up;
        // What was in flight belonged to the old session: the Q values and the direction
        // go again below, the rest was reported dropped at the loss.
        for _ in self.s.start(now) {}
        self.pending.clear();
        // At most 64 Q, a direction and a safety mask in an empty queue of 96: the pushes
        // cannot fail.
        for (addr, v) in self.q_shadow.iter().enumerate() {
            if let Some(value) = *v {
                let _ = self.pending.push(Pending::Q(QValue {
                    addr: addr as u8,
                    value,
                }));
            }
        }
        if let Some(d) = self.direction {
            let _ = self.pending.push(Pending::Direction(d));
        }
        if let Some(m) = self.safety {
            let _ = self.pending.push(Pending::Safety(m));
        }
        self.push_event(PlcEvent::Connected);
    }

    fn lose(&mut self) {
        let dropped = self.pending.iter().filter(|p| !p.is_q()).count()
            + self
                .s
                .take_in_flight()
                .filter(|m| !matches!(m, PlcMsg::QWrite(_)))
                .count();
        self.pending.clear();
        self.download_active = false;
        self.state = PlcLinkState::Connecting;
        // A new session for the next handshake (its retries keep this number).
        self.session = self.session.wrapping_add(1);
        self.last_hello = None;
        self.status = None;
        self.s.count_loss();
        self.push_event(PlcEvent::LinkLost {
            dropped: dropped as u16,
        });
    }

    /// Run the timers (also done by `receive` and `poll_transmit`).
    pub fn tick(&mut self, now: Micros) {
        if self.state == PlcLinkState::Up && self.s.timed_out(now, self.s.config().plc_timeout_us) {
            self.lose();
        }
    }

    /// When [`Self::poll_transmit`] must be called next if nothing is received meanwhile
    /// (quinn-proto's `poll_timeout`): the `Hello` retry, the retransmission timeout, the
    /// heartbeat (early inside a quiet window) or the link-loss timer, whichever comes
    /// first. A deadline not after the present ([`AT_ONCE`]) means: now. Always `Some`.
    pub fn poll_timeout(&self) -> Option<Micros> {
        let cfg = self.s.config();
        let retry = match self.state {
            PlcLinkState::Up => return self.up_timeout(),
            PlcLinkState::Connecting => cfg.hello_retry_us,
            PlcLinkState::Incompatible { .. } => cfg.incompatible_retry_us,
        };
        Some(
            self.last_hello
                .map_or(AT_ONCE, |t| Micros(t.0.saturating_add(retry))),
        )
    }

    fn up_timeout(&self) -> Option<Micros> {
        let cfg = self.s.config();
        if self.s.ack_owed() || (!self.pending.is_empty() && !self.s.window_full()) {
            return Some(AT_ONCE);
        }
        let last = self.s.last_tx().0;
        let mut heartbeat = last.saturating_add(cfg.heartbeat_us);
        let early = last.saturating_add(cfg.heartbeat_us.saturating_sub(HEARTBEAT_EARLY_US));
        let heartbeat_us = HEARTBEAT_WIRE_BYTES * cfg.byte_time_ns() / 1000;
        if self
            .quiet_until
            .is_some_and(|q| early.saturating_add(heartbeat_us) <= q.0)
        {
            heartbeat = heartbeat.min(early);
        }
        let timers = earliest(
            Some(self.s.loss_deadline(cfg.plc_timeout_us)),
            Some(Micros(heartbeat)),
        );
        earliest(timers, self.s.window_deadline())
    }

    /// The next frame to send, written to `out`; returns its length, 0 when there is
    /// nothing to send now or `out` is smaller than the frame ([`MAX_WIRE_FRAME`] always
    /// fits). Call it whenever the UART can take more, and at least every millisecond.
    #[must_use = "the frame in `out` must be sent"]
    pub fn poll_transmit(&mut self, now: Micros, out: &mut [u8]) -> usize {
        self.tick(now);
        if out.len() < MAX_WIRE_FRAME {
            return 0;
        }
        match self.state {
            PlcLinkState::Connecting | PlcLinkState::Incompatible { .. } => {
                let period = if self.state == PlcLinkState::Connecting {
                    self.s.config().hello_retry_us
                } else {
                    self.s.config().incompatible_retry_us
                };
                let due = self
                    .last_hello
                    .is_none_or(|t| now.0.saturating_sub(t.0) >= period);
                if !due {
                    return 0;
                }
                self.last_hello = Some(now);
                let msg = PlcMsg::Hello {
                    version: PROTOCOL_VERSION,
                    session: self.session,
                };
                self.s.send(msg, true, now, out)
            }
            PlcLinkState::Up => self.transmit_up(now, out),
        }
    }

    fn transmit_up(&mut self, now: Micros, out: &mut [u8]) -> usize {
        self.fill_window();
        let n = self.s.send_reliable(now, out);
        if n > 0 {
            return n;
        }
        let cfg = *self.s.config();
        let since = now.0.saturating_sub(self.s.last_tx().0);
        let heartbeat_us = HEARTBEAT_WIRE_BYTES * cfg.byte_time_ns() / 1000;
        let fits_quiet = self
            .quiet_until
            .is_some_and(|q| now.0.saturating_add(heartbeat_us) <= q.0);
        let early = cfg.heartbeat_us.saturating_sub(HEARTBEAT_EARLY_US);
        if self.s.ack_owed() || since >= cfg.heartbeat_us || (fits_quiet && since >= early) {
            return self.s.send(PlcMsg::Heartbeat, false, now, out);
        }
        0
    }

    /// The caller promises no command for `quiet_us` from `now` (e.g. until its next
    /// scan). A heartbeat that fits in that time is then sent early, so that it is never
    /// on the wire when the next scan's Q writes want it: their latency stays one frame.
    pub fn quiet_for(&mut self, now: Micros, quiet_us: u64) {
        self.quiet_until = Some(Micros(now.0.saturating_add(quiet_us)));
    }

    /// Move the next waiting command into the window (a run of Q writes becomes one
    /// frame), only when the window has room and everything in it was sent: a message in
    /// the window is numbered and can no longer be dropped or overtaken, so commands wait
    /// in `pending` until their frame goes out. That keeps a STOP (which goes to the head
    /// of `pending`) the next new frame, and lets Q writes coalesce until then.
    fn fill_window(&mut self) {
        if !self.s.window_full() && !self.s.has_unsent() {
            let Some(first) = shift::remove_at(&mut self.pending, 0) else {
                return;
            };
            let msg = match first {
                Pending::Q(q) => {
                    let mut v = heapless::Vec::<QValue, MAX_Q_PER_FRAME>::new();
                    // Cannot fail: the first push into an empty vector, then only while
                    // it is not full.
                    let _ = v.push(q);
                    while !v.is_full() {
                        match self.pending.first() {
                            Some(Pending::Q(next)) => {
                                let _ = v.push(*next);
                                shift::remove_at(&mut self.pending, 0);
                            }
                            _ => break,
                        }
                    }
                    PlcMsg::QWrite(v)
                }
                Pending::Run => PlcMsg::Run,
                Pending::Stop => PlcMsg::Stop,
                Pending::Direction(reverse) => PlcMsg::Direction { reverse },
                Pending::AckFault => PlcMsg::AckFault,
                Pending::Safety(requested) => PlcMsg::SafetyRequest { requested },
                Pending::DownloadBegin => PlcMsg::DownloadBegin {
                    crc: self.section_crc,
                },
                Pending::DownloadChunk(first_line) => {
                    let start = usize::from(first_line) * LINE_BYTES;
                    let end = (start + CHUNK_BYTES).min(SECTION_BYTES);
                    let data =
                        heapless::Vec::from_slice(self.section.get(start..end).unwrap_or(&[]))
                            .unwrap_or_default();
                    PlcMsg::DownloadChunk { first_line, data }
                }
                Pending::DownloadEnd => PlcMsg::DownloadEnd,
            };
            // Cannot fail: the window has room (checked above).
            let _ = self.s.push(msg);
        }
    }
}

/// CRC-32C of the encoded drive section, as carried by `DownloadBegin`.
pub fn section_crc(bytes: &[u8]) -> u32 {
    super::frame::CRC.checksum(bytes)
}
