//! The safety monitor (safety.md 3): twelve functions named after IEC 61800-5-2,
//! evaluated once per 1 ms tick in RUN, after the drive section and before the modulator
//! takes the frequency. **NOT RATED**: it watches the *command* (v = the applied stator
//! frequency, x = its integral in field turns), not the rotor; see `docs/safety.md`.
//!
//! Sans-IO and integer only: v in 0.1 Hz, x in 10⁻⁴ turn (one tick at v adds exactly v),
//! times in ticks. The drive calls [`Monitor::start_run`] when it enters RUN and
//! [`Monitor::tick`] every RUN tick; the [`Verdict`] says which frequency may be applied
//! (the `asr` cap) and which code to latch. A code is latched by the monitor too: every
//! later tick says the same until the next `start_run` (ACK and a new RUN).
//!
//! | module | job |
//! | --- | --- |
//! | `limits.rs` | the 24 settings converted to ticks, 10⁻⁴ turns and rates, once per download |
//! | `ramp.rs` | SS1, SS2, SL1-SL4: delay, ramp, early limit, envelope, end, safe state |
//! | `motion.rs` | SOS, SLI (with its disable delay), SDP/SDN (trailing reference) |
//! | `accel.rs` | SLA: the 100 ms window of v and the limit table |

mod accel;
mod limits;
mod motion;
mod ramp;

#[cfg(test)]
mod tests;

pub use limits::{ramp_drop, Limits};

use shared_protocol::fault::FaultCode;
use shared_protocol::safety::{SafetyFunction, SafetySettings, FUNCTION_MASK};

use accel::Sla;
use motion::{Sdi, Sli, Sos};
use ramp::{Ramp, RAMPS};

/// What the drive hands the monitor each RUN tick.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Input {
    /// Requested functions (bit n = function n; the PLC's mask plus bit 0 while `STO_IN`
    /// is low).
    pub requested: u16,
    /// The drive section's frequency after `fmx` and the `frv` rule, 0.1 Hz (>= 0; 0 when
    /// no leg is in sine mode: v means nothing for direct `WR PWx` legs).
    pub f_dhz: i16,
    /// `fmn`, 0.1 Hz: below it the outputs are off and v = 0.
    pub fmn_dhz: i16,
    /// The applied direction (true = reverse, v < 0).
    pub reverse: bool,
}

/// What the monitor decided for this tick.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Verdict {
    /// The frequency the modulator may take (the program's, under the `asr` cap); 0 when
    /// `trip` is set. `fmn` still applies after it.
    pub f_dhz: i16,
    /// Outputs off in this tick and this code latched (the first one of the tick, STO
    /// first, then the functions in bit order).
    pub trip: Option<FaultCode>,
}

/// The monitor (module docs).
#[derive(Debug, Clone)]
pub struct Monitor {
    lim: Limits,
    /// Ticks since RUN start: the tick being evaluated.
    k: u32,
    /// Commanded field turns since RUN start, 10⁻⁴ turn.
    x: i64,
    /// x when the drive last had no request: the activation's reference of `SFP`.
    x_act: i64,
    prev_req: u16,
    /// SS1, SS2, SL1..SL4.
    ramps: [Ramp; 6],
    sos: Sos,
    sli: Sli,
    /// SDP, SDN.
    sdi: [Sdi; 2],
    sla: Sla,
    /// The stopwatch (safety.md 3.2), ticks.
    sft_ticks: u32,
    status: u16,
    sdc: bool,
    latched: Option<FaultCode>,
}

/// Ramp-function bits (a new request restarts the stopwatch, none clears it).
const RAMP_MASK: u16 = 0x00F6;
/// The stopwatch's end, 0.1 s (001 §4.2.4: `PT := T#15s`).
const SFT_MAX_DS: u32 = 150;
const STO: u16 = SafetyFunction::Sto.mask();

impl Default for Monitor {
    fn default() -> Self {
        Monitor::fresh(Limits::default())
    }
}

impl Monitor {
    pub fn new(settings: &SafetySettings) -> Self {
        Monitor::fresh(Limits::from_settings(settings))
    }

    fn fresh(lim: Limits) -> Self {
        Monitor {
            lim,
            k: 0,
            x: 0,
            x_act: 0,
            prev_req: 0,
            ramps: [Ramp::default(); 6],
            sos: Sos::default(),
            sli: Sli::default(),
            sdi: [Sdi::default(); 2],
            sla: Sla::default(),
            sft_ticks: 0,
            status: 0,
            sdc: false,
            latched: None,
        }
    }

    /// New settings (a download). Takes effect with the next RUN (a download stops RUN).
    #[inline(never)]
    pub fn load(&mut self, settings: &SafetySettings) {
        self.lim.load(settings);
        self.start_run();
    }

    pub fn limits(&self) -> &Limits {
        &self.lim
    }

    /// Entering RUN: every function state, x, `SFP`, the stopwatch and a latched code are
    /// cleared (safety.md 3.1).
    pub fn start_run(&mut self) {
        self.stop();
        self.x = 0;
        self.x_act = 0;
        self.sft_ticks = 0;
        self.latched = None;
    }

    /// Leaving RUN (STOP, a fault): every function is dropped; the stopwatch and x hold
    /// (x, the turns since RUN start, is what hil-sim records after a trip).
    /// Field by field, in place (a whole new `Monitor` would be built on the stack and
    /// copied: flash and stack the drive does not have).
    #[inline(never)]
    pub fn stop(&mut self) {
        self.k = 0;
        self.prev_req = 0;
        for r in self.ramps.iter_mut() {
            r.release();
        }
        self.sos = Sos::default();
        self.sli = Sli::default();
        for d in self.sdi.iter_mut() {
            *d = Sdi::default();
        }
        self.sla.clear();
        self.status = 0;
        self.sdc = false;
    }

    /// Status bits of the last tick (bit n = function n requested and in its safe state).
    pub fn status(&self) -> u16 {
        self.status
    }

    /// `SDC`: a ramp function is in its delay or ramp phase.
    pub fn sdc(&self) -> bool {
        self.sdc
    }

    /// `SFT`: the stopwatch, 0.1 s, held at 15.0 s (001 §4.2.4: a `TP` timer, PT = 15 s).
    pub fn elapsed_ds(&self) -> u16 {
        (self.sft_ticks / 100).min(SFT_MAX_DS) as u16
    }

    /// Commanded field turns since RUN start, 10⁻⁴ turn.
    pub fn turns_e4(&self) -> i64 {
        self.x
    }

    /// `SFP`: whole commanded field turns since the activation (the drive's request mask
    /// leaving 0), signed, truncated toward 0, saturating at ±32767; 0 while nothing is
    /// requested (001 A.3-A.8, "Pohon - Pozice").
    pub fn turns_since_activation(&self) -> i16 {
        let d = self.x.saturating_sub(self.x_act);
        // In i32 (no 64-bit division in the image): ±32767 turns and a fraction.
        (d.clamp(-327_679_999, 327_679_999) as i32 / 10_000) as i16
    }

    /// Every 1 ms tick in every state, after [`Monitor::tick`], with the drive's request
    /// mask: deselected (no request) the activation's reference follows x, so `SFP` reads
    /// 0 and counts from the next request; with no ramp function requested the stopwatch
    /// reads 0 (001 §4.2.4: `elapsedTime := 0` unless a ramp function is active).
    pub fn follow(&mut self, requested: u16) {
        if requested & FUNCTION_MASK == 0 {
            self.x_act = self.x;
        }
        if requested & RAMP_MASK == 0 {
            self.sft_ticks = 0;
        }
    }

    /// The code latched since the last `start_run`.
    pub fn latched(&self) -> Option<FaultCode> {
        self.latched
    }

    /// One RUN tick (safety.md 3.1 steps 1-4).
    #[inline(never)]
    pub fn tick(&mut self, inp: Input) -> Verdict {
        if let Some(code) = self.latched {
            return Verdict {
                f_dhz: 0,
                trip: Some(code),
            };
        }
        let k = self.k;
        let req = inp.requested & FUNCTION_MASK;
        let rise = req & !self.prev_req;
        let lim = &self.lim;
        let fmn = i32::from(inp.fmn_dhz);
        let on = |f: i32| if f > 0 && f >= fmn { f } else { 0 };

        // Step 1: new ramp requests, then the `asr` cap (SS1, SS2), then v.
        for (r, def) in self.ramps.iter_mut().zip(RAMPS) {
            if rise & def.0.mask() != 0 {
                r.request(k);
            }
        }
        let mut f = i32::from(inp.f_dhz.max(0));
        let asr = lim.get(shared_protocol::safety::SafetySetting::Asr);
        if asr > 0 {
            for (r, def) in self.ramps.iter_mut().zip(RAMPS).take(2) {
                if req & def.0.mask() != 0 {
                    f = f.min(r.cap(k, on(f), asr));
                }
            }
        }
        let speed = on(f);
        let v = if inp.reverse { -speed } else { speed };
        // Step 2.
        let x_prev = self.x;
        self.x = x_prev.saturating_add(i64::from(v));
        let x = self.x;

        // Step 3: STO first, then every function in bit order, each on its own.
        let mut ev = Eval::default();
        if req & STO != 0 {
            ev.trip(FaultCode::Sto);
            ev.safe(SafetyFunction::Sto);
        }
        for (r, def) in self.ramps.iter_mut().zip(RAMPS) {
            if req & def.0.mask() == 0 {
                r.release();
                continue;
            }
            r.tick(def, lim, k, speed, x_prev, x, &mut ev);
        }
        self.sos.tick(
            req & SafetyFunction::Sos.mask() != 0,
            rise & SafetyFunction::Sos.mask() != 0,
            lim,
            speed,
            x_prev,
            x,
            &mut ev,
        );
        self.sli.tick(
            req & SafetyFunction::Sli.mask() != 0,
            rise & SafetyFunction::Sli.mask() != 0,
            lim,
            k,
            speed,
            x_prev,
            x,
            &mut ev,
        );
        for (d, func) in self
            .sdi
            .iter_mut()
            .zip([SafetyFunction::Sdp, SafetyFunction::Sdn])
        {
            d.tick(
                func,
                req & func.mask() != 0,
                rise & func.mask() != 0,
                lim,
                k,
                x_prev,
                x,
                &mut ev,
            );
        }
        let mask = SafetyFunction::Sla.mask();
        self.sla
            .tick(req & mask != 0, rise & mask != 0, lim, k, v, &mut ev);

        // The stopwatch: restarts at a new ramp request, counts while SDC = 1.
        if rise & RAMP_MASK != 0 {
            self.sft_ticks = 0;
        }
        if ev.sdc {
            self.sft_ticks = self.sft_ticks.saturating_add(1);
        }
        self.sdc = ev.sdc;
        self.status = ev.status;
        self.prev_req = req;
        self.k = k.saturating_add(1);
        // Step 4.
        self.latched = ev.trip;
        Verdict {
            f_dhz: if ev.trip.is_some() { 0 } else { f as i16 },
            trip: ev.trip,
        }
    }
}

/// One tick's findings, filled by the functions in bit order.
#[derive(Debug, Default)]
pub(crate) struct Eval {
    trip: Option<FaultCode>,
    status: u16,
    sdc: bool,
}

impl Eval {
    /// The first code of the tick wins.
    fn trip(&mut self, code: FaultCode) {
        if self.trip.is_none() {
            self.trip = Some(code);
        }
    }

    fn safe(&mut self, f: SafetyFunction) {
        self.status |= f.mask();
    }

    /// A monitoring function's verdict this tick: `violated` latches `code`, otherwise
    /// `f` is in its safe state.
    fn check(&mut self, violated: bool, code: FaultCode, f: SafetyFunction) {
        if violated {
            self.trip(code);
        } else {
            self.safe(f);
        }
    }
}

/// The ACK rule's "cause gone" for codes 9-16 (safety.md 7), with `requested` the mask
/// the drive has now (bit 0 set while `STO_IN` is low). `None` for the other codes.
pub fn cause_gone(code: FaultCode, requested: u16) -> Option<bool> {
    match code {
        FaultCode::Sto => Some(requested & STO == 0),
        FaultCode::Ss1 => Some(requested & SafetyFunction::Ss1.mask() == 0),
        FaultCode::Ramp
        | FaultCode::Sos
        | FaultCode::Sls
        | FaultCode::Sli
        | FaultCode::Sdi
        | FaultCode::Sla => Some(true),
        _ => None,
    }
}

/// The status bits outside RUN (safety.md 5): IDLE = requested (outputs off, every
/// requested function is in its safe state); FAULT = STO and SS1 as requested, all others
/// 0; BOOT = 0.
pub fn status_outside_run(state: crate::state::DriveState, requested: u16) -> u16 {
    use crate::state::DriveState;
    match state {
        DriveState::Idle => requested & FUNCTION_MASK,
        DriveState::Fault => requested & (STO | SafetyFunction::Ss1.mask()),
        DriveState::Boot | DriveState::Run => 0,
    }
}
