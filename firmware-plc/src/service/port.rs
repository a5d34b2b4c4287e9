//! The protocol side of the service endpoint: frames in, requests out to be executed,
//! answers and samples in, frames out. Knows nothing of the PLC application (that is
//! `crate::app`'s service glue); time is an argument.
//!
//! * Receiving ([`ServicePort::receive`]) costs bounded work per byte: the link's frame
//!   reader (a frame is decoded once, at its delimiter). Only the newest request is kept;
//!   a repeat of the request being worked on is ignored (its answer is coming).
//! * [`ServicePort::take`] hands out at most one request per call, after the rules that
//!   need no application: `Hello` and the version, `Refused(Hello)` before it, remote
//!   service for guarded requests (`Refused(Locked)`; the caller says whether it is on:
//!   the keypad's consent belongs to the application), `Subscribe`, the stored answer of
//!   a repeated guarded request. The caller executes what is left and reports with
//!   [`ServicePort::answered`].
//! * Samples: [`ServicePort::sample_due`] at the end of each scan says whether one is due
//!   (the first scan at or after each period boundary); [`ServicePort::offer_sample`]
//!   keeps it for the transmitter, or drops and counts it when the previous one has not
//!   gone yet (transmitter busy): samples never delay answers.

use heapless::Vec;
use shared_protocol::service::{
    Answer, RefuseReason, Request, Sample, ServiceReader, WriteResult, FORGET_CLIENT_MS,
    MAX_SUBSCRIBED_Q, SAMPLE_PERIOD_MAX_MS, SAMPLE_PERIOD_MIN_MS, SERVICE_VERSION,
};
use shared_protocol::units::Micros;

use crate::app::up_to;

/// The answer kept for a repeat of the last guarded request (they are all small).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stored {
    Done,
    Refused(RefuseReason),
    Write(WriteResult),
}

impl Stored {
    fn answer(self) -> Answer {
        match self {
            Stored::Done => Answer::Done,
            Stored::Refused(r) => Answer::Refused(r),
            Stored::Write(w) => Answer::WriteResult(w),
        }
    }

    fn of(a: &Answer) -> Option<Stored> {
        match a {
            Answer::Done => Some(Stored::Done),
            Answer::Refused(r) => Some(Stored::Refused(*r)),
            Answer::WriteResult(w) => Some(Stored::Write(*w)),
            _ => None,
        }
    }
}

/// What [`ServicePort::take`] hands out.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Step {
    /// Answer this at once (the port decided).
    Reply(u8, Answer),
    /// Execute this request (`again`: it was handed out before and is still being worked
    /// on, e.g. an EEPROM read between scans).
    Execute {
        id: u8,
        request: Request,
        again: bool,
    },
}

/// Receive-side figures (diagnostics and tests).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct PortStats {
    pub bytes: u32,
    pub frames_ok: u32,
    pub frames_bad: u32,
    pub samples_sent: u32,
    pub samples_dropped: u32,
}

/// An active subscription.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Subscription {
    pub period_ms: u16,
    pub q: Vec<u8, MAX_SUBSCRIBED_Q>,
    next_due_ms: u64,
}

/// The service endpoint's protocol state.
#[derive(Debug, Clone)]
pub struct ServicePort {
    version: u16,
    reader: ServiceReader,
    pending: Option<(u8, Request)>,
    working: Option<(u8, Request)>,
    client: bool,
    last_rx: Option<Micros>,
    last_guarded: Option<(u8, Stored)>,
    subscription: Option<Subscription>,
    sample: Option<Sample>,
    dropped: u32,
    stats: PortStats,
}

impl Default for ServicePort {
    fn default() -> Self {
        Self::new()
    }
}

impl ServicePort {
    pub const fn new() -> Self {
        ServicePort {
            version: SERVICE_VERSION,
            reader: ServiceReader::new(),
            pending: None,
            working: None,
            client: false,
            last_rx: None,
            last_guarded: None,
            subscription: None,
            sample: None,
            dropped: 0,
            stats: PortStats {
                bytes: 0,
                frames_ok: 0,
                frames_bad: 0,
                samples_sent: 0,
                samples_dropped: 0,
            },
        }
    }

    /// The version this PLC announces (tests make it announce another one).
    pub fn set_version(&mut self, version: u16) {
        self.version = version;
    }

    pub fn version(&self) -> u16 {
        self.version
    }

    pub fn stats(&self) -> PortStats {
        self.stats
    }

    /// A client said `Hello` with our version and has not been forgotten.
    pub fn has_client(&self) -> bool {
        self.client
    }

    /// Bytes from the UART.
    pub fn receive(&mut self, bytes: &[u8], now: Micros) {
        for &b in bytes {
            self.stats.bytes = self.stats.bytes.wrapping_add(1);
            match self.reader.push::<Request>(b) {
                None => {}
                Some(Err(_)) => self.stats.frames_bad = self.stats.frames_bad.wrapping_add(1),
                Some(Ok((id, request))) => {
                    self.stats.frames_ok = self.stats.frames_ok.wrapping_add(1);
                    self.last_rx = Some(now);
                    // Requests carry ids 1-255.
                    if id == 0 || self.working.as_ref().is_some_and(|(w, _)| *w == id) {
                        continue;
                    }
                    self.pending = Some((id, request));
                }
            }
        }
    }

    /// Timers: forget a client silent for [`FORGET_CLIENT_MS`] (a new one must say
    /// `Hello`; its subscription stops).
    pub fn tick(&mut self, now: Micros) {
        if self
            .last_rx
            .is_some_and(|t| now.0.saturating_sub(t.0) >= FORGET_CLIENT_MS * 1000)
        {
            self.last_rx = None;
            self.forget_client();
        }
    }

    /// When [`ServicePort::tick`] next has something to do.
    pub fn timeout(&self) -> Option<Micros> {
        self.last_rx.map(|t| Micros(t.0 + FORGET_CLIENT_MS * 1000))
    }

    fn forget_client(&mut self) {
        self.client = false;
        self.subscription = None;
        self.sample = None;
        self.last_guarded = None;
        self.working = None;
    }

    /// The UART reported a line error: drop the frame being received.
    pub fn line_error(&mut self) {
        self.reader.reset();
        self.stats.frames_bad = self.stats.frames_bad.wrapping_add(1);
    }

    /// A sample waits for the transmitter.
    pub fn sample_waiting(&self) -> bool {
        self.sample.is_some()
    }

    /// The request being worked on over several polls.
    pub fn working(&self) -> Option<&Request> {
        self.working.as_ref().map(|(_, r)| r)
    }

    /// A request is waiting or being worked on.
    pub fn busy(&self) -> bool {
        self.pending.is_some() || self.working.is_some()
    }

    /// The next request, with the port's own rules applied (see the module doc);
    /// `remote`: remote service is on. An executed guarded request renews remote service
    /// (the caller's job: [`Step::Execute`] with a guarded request).
    pub fn take(&mut self, remote: bool, now: Micros) -> Option<Step> {
        let Some((id, request)) = self.pending.take() else {
            let (id, request) = self.working.clone()?;
            return Some(Step::Execute {
                id,
                request,
                again: true,
            });
        };
        // A new request supersedes one still being worked on (its client gave up).
        self.working = None;
        if let Request::Hello { version } = request {
            // A new session: nothing of the previous client's applies.
            self.forget_client();
            self.client = version == self.version;
            return Some(Step::Reply(
                id,
                Answer::HelloReply {
                    version: self.version,
                },
            ));
        }
        if !self.client {
            return Some(Step::Reply(id, Answer::Refused(RefuseReason::Hello)));
        }
        if request.is_guarded() {
            if let Some((last, stored)) = self.last_guarded {
                if last == id {
                    return Some(Step::Reply(id, stored.answer()));
                }
            }
            if !remote {
                let a = Answer::Refused(RefuseReason::Locked);
                self.answered(id, &request, &a);
                return Some(Step::Reply(id, a));
            }
        }
        if let Request::Subscribe { period_ms, ref q } = request {
            let period_ms = self.subscribe(period_ms, q, now);
            return Some(Step::Reply(id, Answer::Subscribed { period_ms }));
        }
        Some(Step::Execute {
            id,
            request,
            again: false,
        })
    }

    /// The request handed out by [`ServicePort::take`] is still being worked on: hand it
    /// out again at the next call (repeats of its id are ignored meanwhile).
    pub fn later(&mut self, id: u8, request: Request) {
        if self.pending.is_none() {
            self.working = Some((id, request));
        }
    }

    /// The answer to a request handed out by [`ServicePort::take`] (kept for a repeat when
    /// the request is guarded).
    pub fn answered(&mut self, id: u8, request: &Request, answer: &Answer) {
        if self.working.as_ref().is_some_and(|(w, _)| *w == id) {
            self.working = None;
        }
        if request.is_guarded() {
            if let Some(s) = Stored::of(answer) {
                self.last_guarded = Some((id, s));
            }
        }
    }

    /// `Subscribe`: returns the period in force (0 = none).
    pub fn subscribe(&mut self, period_ms: u16, q: &[u8], now: Micros) -> u16 {
        if period_ms == 0 {
            self.subscription = None;
            self.sample = None;
            return 0;
        }
        let period_ms = period_ms.clamp(SAMPLE_PERIOD_MIN_MS, SAMPLE_PERIOD_MAX_MS);
        let mut list: Vec<u8, MAX_SUBSCRIBED_Q> = up_to(q.iter().copied());
        if list.is_empty() {
            list = up_to(0..MAX_SUBSCRIBED_Q as u8);
        }
        let p = u64::from(period_ms);
        self.subscription = Some(Subscription {
            period_ms,
            q: list,
            next_due_ms: (now.0 / 1000 / p + 1) * p,
        });
        self.dropped = 0;
        period_ms
    }

    pub fn subscription(&self) -> Option<&Subscription> {
        self.subscription.as_ref()
    }

    /// At the end of a scan at `now`: the subscribed Q numbers when a sample is due.
    pub fn sample_due(&mut self, now: Micros) -> Option<&[u8]> {
        let s = self.subscription.as_mut()?;
        let now_ms = now.0 / 1000;
        if now_ms < s.next_due_ms {
            return None;
        }
        let p = u64::from(s.period_ms.max(1));
        s.next_due_ms = (now_ms / p + 1) * p;
        Some(&s.q)
    }

    /// A sample taken now: kept for the transmitter, or dropped and counted when the
    /// previous one is still waiting (answers go first, so a sample waits behind them).
    pub fn offer_sample(&mut self, mut sample: Sample) {
        if self.sample.is_some() {
            self.dropped = self.dropped.saturating_add(1);
            self.stats.samples_dropped = self.stats.samples_dropped.wrapping_add(1);
            return;
        }
        sample.dropped = self.dropped;
        self.dropped = 0;
        self.sample = Some(sample);
    }

    /// The sample waiting for the transmitter, if any (taken: the caller sends it).
    pub fn take_sample(&mut self) -> Option<Sample> {
        let s = self.sample.take();
        if s.is_some() {
            self.stats.samples_sent = self.stats.samples_sent.wrapping_add(1);
        }
        s
    }
}
