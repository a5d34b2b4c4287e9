//! The ramp functions SS1, SS2 and SL1-SL4 (safety.md 3.2, 001 §3.3-3.5): DELAY
//! (`trd`), RAMP (`ts1`/`ts2`/`tlk`) with the optional envelope (`ard`), the early limit
//! (`tel`, counted from the request), the end, and the safe state (SS2: STANDSTILL,
//! SLk: LIMITED; SS1 ends in STO with code 10). Also the `asr` cap's reference (3.3).

use shared_protocol::fault::FaultCode;
use shared_protocol::safety::{SafetyFunction, SafetySetting as S};

use super::{ramp_drop, Eval, Limits};

#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
enum Phase {
    /// Not requested.
    #[default]
    Off,
    /// DELAY or RAMP (SDC = 1).
    Stopping,
    /// SS2 STANDSTILL or SLk LIMITED (status 1).
    Safe,
    /// SS1 reached its end: STO, code 10.
    Ended,
}

/// Which ramp function a [`Ramp`] is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum RampKind {
    Ss1,
    Ss2,
    Sls,
}

/// Per ramp function (SS1, SS2, SL1..SL4): its kind, target V* and ramp time T_R.
pub(super) const RAMPS: [(SafetyFunction, RampKind, S, S); 6] = [
    (SafetyFunction::Ss1, RampKind::Ss1, S::Fss, S::Ts1),
    (SafetyFunction::Ss2, RampKind::Ss2, S::Fss, S::Ts2),
    (SafetyFunction::Sl1, RampKind::Sls, S::Fl1, S::Tl1),
    (SafetyFunction::Sl2, RampKind::Sls, S::Fl2, S::Tl2),
    (SafetyFunction::Sl3, RampKind::Sls, S::Fl3, S::Tl3),
    (SafetyFunction::Sl4, RampKind::Sls, S::Fl4, S::Tl4),
];

#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Ramp {
    phase: Phase,
    /// The request tick k_r.
    k_r: u32,
    /// Consecutive ticks since the request with |v| within the target (early limit).
    below: u32,
    /// |v(k_B)|, the envelope's start.
    v_b: i32,
    /// SS2's standstill position.
    x0: i64,
    /// |v(k_r)|, the `asr` cap's start (set by the first `cap` after the request).
    cap_ref: Option<i32>,
}

impl Ramp {
    /// A new request at tick `k` (a release and a new request start afresh).
    pub(super) fn request(&mut self, k: u32) {
        *self = Ramp {
            phase: Phase::Stopping,
            k_r: k,
            ..Ramp::default()
        };
    }

    /// Not requested: dropped with no latch.
    pub(super) fn release(&mut self) {
        *self = Ramp::default();
    }

    /// The `asr` cap at tick `k` (safety.md 3.3): max(0, |v(k_r)| − ⌊asr·(k − k_r)/1000⌋);
    /// `speed` is |v| before this cap, taken as |v(k_r)| on the request tick.
    #[inline(never)]
    pub(super) fn cap(&mut self, k: u32, speed: i32, asr: u16) -> i32 {
        let start = *self.cap_ref.get_or_insert(speed);
        let drop = ramp_drop(asr, k.saturating_sub(self.k_r)).min(i32::MAX as u32) as i32;
        (start - drop).max(0)
    }

    /// One tick while requested, on |v(k)| = `speed` and x(k−1), x(k). Not inlined: one
    /// copy for the six ramp functions keeps the drive image small (64 KiB budget).
    #[allow(clippy::too_many_arguments)]
    #[inline(never)]
    pub(super) fn tick(
        &mut self,
        (func, kind, target, ramp_time): (SafetyFunction, RampKind, S, S),
        lim: &Limits,
        k: u32,
        speed: i32,
        x_prev: i64,
        x: i64,
        ev: &mut Eval,
    ) {
        let (target, ramp_ticks) = (lim.speed(target), lim.ticks(ramp_time));
        if self.phase == Phase::Stopping {
            let k_b = self.k_r.saturating_add(lim.ticks(S::Trd));
            let k_end = k_b.saturating_add(ramp_ticks);
            if k == k_b {
                self.v_b = speed;
            }
            let tel = lim.ticks(S::Tel);
            let early = tel > 0 && self.below >= tel;
            if early || k >= k_end {
                // The end: the new state's check applies to v(k) below.
                match kind {
                    RampKind::Ss1 => self.phase = Phase::Ended,
                    RampKind::Ss2 | RampKind::Sls if speed <= target => {
                        self.phase = Phase::Safe;
                        self.x0 = x_prev;
                    }
                    RampKind::Ss2 | RampKind::Sls => {
                        self.phase = Phase::Off;
                        ev.trip(FaultCode::Ramp);
                    }
                }
            } else {
                ev.sdc = true;
                let ard = lim.get(S::Ard);
                if ard > 0 && k >= k_b {
                    let drop = ramp_drop(ard, k - k_b).min(i32::MAX as u32) as i32;
                    let envelope = (self.v_b - drop).max(target);
                    if speed > envelope {
                        ev.trip(FaultCode::Ramp);
                    }
                }
                self.below = if speed <= target {
                    self.below.saturating_add(1)
                } else {
                    0
                };
            }
        }
        match self.phase {
            Phase::Ended => {
                ev.safe(func);
                ev.trip(FaultCode::Ss1);
            }
            Phase::Safe => {
                let violated = match kind {
                    RampKind::Ss2 => (speed > lim.fss() || (x - self.x0).abs() > lim.pss())
                        .then_some(FaultCode::Sos),
                    _ => (speed > target).then_some(FaultCode::Sls),
                };
                match violated {
                    Some(code) => ev.trip(code),
                    None => ev.safe(func),
                }
            }
            Phase::Off | Phase::Stopping => {}
        }
    }
}
