//! The PLC's service endpoint (service.md part A), sans-IO like the link's [`PlcLink`]:
//! bytes in ([`Service::on_rx`], bounded work per byte), at most one frame out per
//! [`Service::poll_tx`], the next deadline from [`Service::poll_timeout`], EEPROM reads a
//! page or less per [`Service::eeprom_step`] between scans. The wire and the messages are
//! `shared_protocol::service` (the link's frame codec).
//!
//! * [`port`]: the protocol: frames, ids, repeats, `Hello`, remote-service refusals,
//!   subscriptions and samples.
//! * [`SlotReads`] (in [`crate::storage::reads`]): the paced EEPROM reads behind
//!   `ListSlots`, `ReadProgram` and `Run` of slots 1-4.
//! * [`endpoint`]: the service on the application as the board's byte pump sees it, and
//!   the application task's share (one EEPROM step after each scan).
//! * [`write`](mod@write): program writes (`WriteBegin`, `WriteChunk`, `WriteCommit`),
//!   staged in the slot's spare copy in the EEPROM.
//! * [`counters`]: the counters of service.md 7 and their EEPROM record.
//! * The requests themselves are answered by the application (`app/service.rs`), which
//!   holds everything they read and change.
//!
//! Dependencies point one way: this module drives the application ([`PlcApp`], whose
//! `app/service.rs` answers the requests) and the storage; neither names anything here
//! (`docs/board.md`, "Crate structure").
//!
//! [`Service`] is kept apart from [`PlcApp`]: the board keeps it in its own static (the
//! application builder's stack frame grows with `PlcApp`), and it borrows the
//! application only for the duration of a call.
//!
//! Full description: `shared-protocol/docs/service.md`; the costs per byte and per frame
//! are in `docs/service-cost.md`.
//!
//! [`PlcLink`]: shared_protocol::link::PlcLink

pub mod counters;
pub mod endpoint;
pub mod port;
pub mod write;

pub use crate::storage::reads::{SlotReads, SlotRecord};
pub use counters::Tally;
pub use port::{PortStats, ServicePort, Step, Stored};
pub use write::ProgramWrite;

use shared_protocol::drive_state::DriveState;
use shared_protocol::service::{encode, Answer, Request, WriteResult};
use shared_protocol::units::Micros;

use crate::app::{BuildInfo, Outcome, PlcApp, RunState, Tick};
use crate::storage::{Eeprom, JobDone};
use counters::{Observation, TallyStep, APP_FIRST_Q};

/// EEPROM bytes read per [`Service::eeprom_step`]: one page, the storage jobs' unit.
pub const STEP_BYTES: usize = 64;

/// The service endpoint: protocol state, the EEPROM reads under way, and the build's
/// identity.
#[derive(Clone)]
pub struct Service {
    port: ServicePort,
    reads: SlotReads,
    write: ProgramWrite,
    counters: Tally,
    build: BuildInfo,
}

impl Service {
    pub fn new(build: BuildInfo) -> Self {
        Service {
            port: ServicePort::new(),
            reads: SlotReads::new(),
            write: ProgramWrite::new(),
            counters: Tally::new(),
            build,
        }
    }

    /// Another build and chip for `Identify` (hil-sim's service line brings the
    /// simulated board's when it is plugged in; the board's is fixed at [`Service::new`]).
    pub fn set_build(&mut self, build: BuildInfo) {
        self.build = build;
    }

    /// The port (tests make it announce another version, and read its figures).
    pub fn port(&mut self) -> &mut ServicePort {
        &mut self.port
    }

    /// Bytes from the UART: the frame reader's bounded work per byte; a frame is decoded
    /// at its delimiter and only the newest request is kept (one outstanding).
    pub fn on_rx(&mut self, bytes: &[u8], now: Micros) {
        self.port.receive(bytes, now);
    }

    /// The UART reported a line error: the frame being received is dropped.
    pub fn on_line_error(&mut self) {
        self.port.line_error();
    }

    /// The next frame for the UART into `out` (at least
    /// [`shared_protocol::link::MAX_WIRE_FRAME`] bytes; 0 = nothing now): the answer to
    /// the waiting request, else a waiting sample. At most one request is executed per
    /// call.
    #[must_use = "the frame in `out` must be sent"]
    #[allow(
        clippy::needless_borrows_for_generic_args,
        reason = "`encode` of `&Answer` serialises the answer in place; by value it is moved \
                  into the frame first (44 B more code, docs/size.md)"
    )]
    pub fn poll_tx<E: Eeprom>(
        &mut self,
        app: &mut PlcApp<E>,
        now: Micros,
        out: &mut [u8],
    ) -> usize {
        self.port.tick(now);
        if let Some(step) = self.port.take(app.remote_service(now), now) {
            let (id, answer) = match step {
                Step::Reply(id, a) => (id, a),
                Step::Execute { id, request, .. } => {
                    if request.is_guarded() {
                        app.renew_remote(now);
                    }
                    let outcome = match request {
                        Request::WriteBegin { .. }
                        | Request::WriteChunk { .. }
                        | Request::WriteCommit => {
                            self.write.request(app, &mut self.reads, &request)
                        }
                        Request::GetCounters => Outcome::Answer(Answer::Counters(
                            self.counters.answer(app.storage().power_cycle(), now),
                        )),
                        _ => app.service_request(&mut self.reads, &self.build, &request, now),
                    };
                    match outcome {
                        Outcome::Answer(a) => {
                            self.port.answered(id, &request, &a);
                            (id, a)
                        }
                        Outcome::Later => {
                            self.port.later(id, request);
                            return 0;
                        }
                    }
                }
            };
            // By reference: the answer (up to ~120 B) is serialised where it is, not
            // moved into the frame.
            return encode(id, &answer, out).unwrap_or(0);
        }
        match self.port.take_sample() {
            Some(s) => encode(0, &Answer::Sample(s), out).unwrap_or(0),
            None => 0,
        }
    }

    /// When [`Service::poll_tx`] must be called next even without received bytes: at
    /// once while a request or a sample waits, else when the client is to be forgotten.
    pub fn poll_timeout(&self, now: Micros) -> Option<Micros> {
        if self.port.busy() || self.port.sample_waiting() {
            return Some(now);
        }
        self.port.timeout()
    }

    /// After [`PlcApp::tick_1ms`]: takes a trend sample when the tick ran a scan at or
    /// after the subscription's period boundary (service.md 3 `Sample`).
    /// A keypad save also lands here: what the reads found in that slot is forgotten.
    pub fn after_tick<E: Eeprom>(&mut self, app: &PlcApp<E>, tick: &Tick, now: Micros) {
        self.counters.observe(&observation(app, tick), now);
        match tick.storage {
            Some(JobDone::Saved { slot, .. }) => {
                self.reads.invalidate(slot);
                self.write.slot_saved(slot);
            }
            Some(JobDone::Written { slot, result }) => {
                self.reads.invalidate(slot);
                self.write.committed(slot, result);
            }
            _ => {}
        }
        if !tick.scanned {
            return;
        }
        if let Some(q) = self.port.sample_due(now) {
            let sample = app.service_sample(q, now);
            self.port.offer_sample(sample);
        }
    }

    /// Moves the chunk of a program write being staged, or else the EEPROM reads a
    /// `ListSlots`, `ReadProgram` or `Run` of a slot wait for, on by at most
    /// [`STEP_BYTES`] (one transfer), and only while the storage queue is idle: the board
    /// calls it between scans when the I2C bus is free. Returns whether the bus was used.
    pub fn eeprom_step<E: Eeprom>(&mut self, app: &mut PlcApp<E>) -> bool {
        if !app.storage().idle() {
            return false;
        }
        // A chunk being staged goes first; one whose request was given up (the client
        // moved on) must not hold up the reads and the counters.
        if self.write.writing() && self.write.step(app, self.port.working()) {
            return true;
        }
        match self.counters.eeprom_step(app.storage()) {
            TallyStep::Idle => {}
            TallyStep::UsedBus => return true,
            TallyStep::Reset => {
                app.notify_text("COUNTERS RESET");
                return true;
            }
        }
        if self.reads.idle() {
            return false;
        }
        // A read error is kept in `reads` and answered `Refused(Storage)`.
        self.reads
            .step(app.storage().eeprom(), STEP_BYTES)
            .unwrap_or(true)
    }

    /// A slot was written other than by a keypad save (which [`Service::after_tick`]
    /// sees): forget what the reads found in it.
    pub fn slot_written(&mut self, slot: u8) {
        self.reads.invalidate(slot);
    }

    /// Whether a request is waiting for EEPROM reads.
    pub fn reading(&self) -> bool {
        !self.reads.idle()
    }

    /// The counters (tests read them).
    pub fn counters(&self) -> &Tally {
        &self.counters
    }

    /// The request being worked on, if any (diagnostics).
    pub fn working(&self) -> Option<&Request> {
        self.port.working()
    }
}

/// What a tick showed the counters (service.md 7).
fn observation<E: Eeprom>(app: &PlcApp<E>, tick: &Tick) -> Observation {
    let stats = app.link().stats();
    let to = tick.run_change.map(|(_, to)| to);
    Observation {
        run_started: to == Some(RunState::Running),
        stopped: to == Some(RunState::Stopped),
        running: app.run_state() == RunState::Running,
        pwm_on: app.link().is_up()
            && app
                .link()
                .last_status()
                .is_some_and(|(d, _)| d.state == DriveState::Run && d.freq_dhz != 0),
        link_errors_total: stats.frames_bad.wrapping_add(stats.link_losses),
        saved: matches!(
            tick.storage,
            Some(JobDone::Saved { result: Ok(_), .. })
                | Some(JobDone::Written {
                    result: Ok(WriteResult::Saved { .. }),
                    ..
                })
        ),
        fault: match tick.storage {
            Some(JobDone::FaultLogged { entry, .. }) => Some(entry.code),
            _ => None,
        },
        q: tick
            .scanned
            .then(|| core::array::from_fn(|i| app.q(APP_FIRST_Q + i as u8))),
    }
}
