//! SLA (safety.md 3.4, 001 §3.8): a(k) = 10·(v(k) − v(k−100)) in 0.1 Hz/s over a 100 ms
//! window of the command (v = 0 before RUN), against the limit of the quadrant.

use shared_protocol::fault::FaultCode;
use shared_protocol::safety::{SafetyFunction, SafetySetting as S};

use super::{Eval, Limits};

/// The window's length, ticks.
pub(super) const WINDOW: usize = 100;

#[derive(Debug, Clone, Copy)]
pub(super) struct Sla {
    /// v of the last 100 ticks; `at` is the oldest (v(k−100) when tick k starts).
    window: [i16; WINDOW],
    at: u8,
    /// The first active tick, k_r + `tla`.
    k_a: u32,
}

impl Default for Sla {
    fn default() -> Self {
        Sla {
            window: [0; WINDOW],
            at: 0,
            k_a: 0,
        }
    }
}

/// The limit for acceleration `a` at signed speed `v` (safety.md 3.4's table).
pub(super) fn limit(lim: &Limits, v: i32, a: i32) -> i32 {
    let up = a > 0;
    let fss = lim.fss();
    let (aap, adp, aan, adn) = (
        lim.speed(S::Aap),
        lim.speed(S::Adp),
        lim.speed(S::Aan),
        lim.speed(S::Adn),
    );
    if v > fss {
        if up {
            aap
        } else {
            adp
        }
    } else if v < -fss {
        if up {
            adn
        } else {
            aan
        }
    } else if up {
        aap.min(adn)
    } else {
        adp.min(aan)
    }
}

impl Sla {
    /// RUN starts: v = 0 before RUN.
    pub(super) fn clear(&mut self) {
        self.window.fill(0);
        self.at = 0;
        self.k_a = 0;
    }

    /// Every RUN tick (the window runs whether or not SLA is requested).
    pub(super) fn tick(
        &mut self,
        requested: bool,
        rise: bool,
        lim: &Limits,
        k: u32,
        v: i32,
        ev: &mut Eval,
    ) {
        let i = usize::from(self.at);
        let old = self.window.get(i).copied().unwrap_or(0);
        if let Some(slot) = self.window.get_mut(i) {
            *slot = v.clamp(i32::from(i16::MIN), i32::from(i16::MAX)) as i16;
        }
        self.at = if i + 1 >= WINDOW { 0 } else { self.at + 1 };
        if !requested {
            return;
        }
        if rise {
            self.k_a = k.saturating_add(lim.ticks(S::Tla));
        }
        if k < self.k_a {
            return;
        }
        let a = 10 * (v - i32::from(old));
        ev.check(
            a.abs() > limit(lim, v, a),
            FaultCode::Sla,
            SafetyFunction::Sla,
        );
    }
}
