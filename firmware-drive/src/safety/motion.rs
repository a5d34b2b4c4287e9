//! The position functions (safety.md 3.4): SOS (standstill held, 001 §3.2), SLI (a
//! position window with a disable delay that a toggled request cannot reset, 001 §3.6),
//! SDP/SDN (a trailing reference in the allowed direction, 001 §3.7).

use shared_protocol::fault::FaultCode;
use shared_protocol::safety::{SafetyFunction, SafetySetting as S};

use super::{Eval, Limits};

/// SOS: x0 = x(k_r − 1); |v| > `fss` or |x − x0| > `pss` is code 12.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Sos {
    x0: i64,
}

impl Sos {
    #[allow(clippy::too_many_arguments)]
    pub(super) fn tick(
        &mut self,
        requested: bool,
        rise: bool,
        lim: &Limits,
        speed: i32,
        x_prev: i64,
        x: i64,
        ev: &mut Eval,
    ) {
        if !requested {
            return;
        }
        if rise {
            self.x0 = x_prev;
        }
        ev.check(
            speed > lim.fss() || (x - self.x0).abs() > lim.pss(),
            FaultCode::Sos,
            SafetyFunction::Sos,
        );
    }
}

/// SLI: active (status 1) from a request at standstill until `tli` after the release.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Sli {
    active: bool,
    x0: i64,
    /// The first tick without the request while active (the disable delay runs).
    released_at: Option<u32>,
}

impl Sli {
    #[allow(clippy::too_many_arguments)]
    pub(super) fn tick(
        &mut self,
        requested: bool,
        rise: bool,
        lim: &Limits,
        k: u32,
        speed: i32,
        x_prev: i64,
        x: i64,
        ev: &mut Eval,
    ) {
        if requested {
            if self.active {
                // A new request inside the disable delay keeps x0, with no new
                // standstill check: toggling cannot reset the window.
                self.released_at = None;
            } else if rise {
                if speed > lim.fss() {
                    ev.trip(FaultCode::Sli);
                    return;
                }
                self.active = true;
                self.x0 = x_prev;
            }
        } else if self.active {
            let at = *self.released_at.get_or_insert(k);
            if k.saturating_sub(at) >= lim.ticks(S::Tli) {
                *self = Sli::default();
            }
        }
        if !self.active {
            return;
        }
        ev.check(
            (x - self.x0).abs() > lim.turns_e4(S::Pli),
            FaultCode::Sli,
            SafetyFunction::Sli,
        );
    }
}

/// SDP / SDN: active from k_a = k_r + `tdi`; the reference trails the furthest point
/// reached in the allowed direction.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Sdi {
    k_a: u32,
    x_ref: Option<i64>,
}

impl Sdi {
    /// Not inlined: one copy for SDP and SDN.
    #[allow(clippy::too_many_arguments)]
    #[inline(never)]
    pub(super) fn tick(
        &mut self,
        func: SafetyFunction,
        requested: bool,
        rise: bool,
        lim: &Limits,
        k: u32,
        x_prev: i64,
        x: i64,
        ev: &mut Eval,
    ) {
        if !requested {
            *self = Sdi::default();
            return;
        }
        if rise {
            self.k_a = k.saturating_add(lim.ticks(S::Tdi));
        }
        if k < self.k_a {
            return;
        }
        let forward = func == SafetyFunction::Sdp;
        let r = self.x_ref.get_or_insert(x_prev);
        let back = if forward {
            *r = (*r).max(x);
            *r - x
        } else {
            *r = (*r).min(x);
            x - *r
        };
        ev.check(back > lim.pss(), FaultCode::Sdi, func);
    }
}
