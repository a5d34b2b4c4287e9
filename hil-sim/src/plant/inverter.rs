//! Three-phase two-level inverter: what each leg connects its phase to.
//!
//! A leg is either driven (the high or the low switch on, or in the averaged model the
//! period-average `duty · Udc`) or floating (both switches off: during dead time, when the
//! outputs are disabled or after a hardware break). A floating leg carrying current is
//! clamped by its freewheeling diodes: to DC+ when current flows out of the motor, to
//! DC− when it flows in.

use serde::{Deserialize, Serialize};

/// How the inverter is modelled.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PwmMode {
    /// Phase voltage = duty · Udc over each PWM period (dead time neglected).
    #[default]
    Averaged,
    /// Every switching edge of a centre-aligned PWM, with dead time.
    Switching,
}

/// Command of one leg for a PWM period.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Leg {
    /// Both switches open.
    Off,
    /// Fraction of the period the high switch is on, 0..=1.
    Duty(f64),
}

/// What the power stage is told for one PWM period.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GateCommand {
    pub legs: [Leg; 3],
    /// Dead time inserted at every transition (switching model only).
    pub dead_time_ns: u64,
}

impl GateCommand {
    pub const OFF: GateCommand = GateCommand {
        legs: [Leg::Off; 3],
        dead_time_ns: 0,
    };

    pub fn any_driven(&self) -> bool {
        self.legs.iter().any(|l| matches!(l, Leg::Duty(_)))
    }
}

/// Connection of a leg during a stretch of time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Conn {
    /// Leg voltage is this fraction of Udc (1 = high switch, 0 = low switch, else average).
    Frac(f64),
    /// Both switches off: the diodes decide.
    Float,
}

impl Conn {
    /// Fraction of Udc given the phase current (positive into the motor).
    pub fn frac(self, i_phase: f64) -> f64 {
        match self {
            Conn::Frac(d) => d,
            Conn::Float => {
                if i_phase < 0.0 {
                    1.0
                } else {
                    0.0
                }
            }
        }
    }
}

/// Edge times of a centre-aligned leg within a period of `period_ns`: the high switch is on
/// in the middle of the period, low at both ends; dead time delays each turn-on.
/// Returns (low off, high on, high off, low on) in ns from the period start.
pub fn leg_edges_ns(duty: f64, period_ns: u64, dead_ns: u64) -> [u64; 4] {
    let t = period_ns as f64;
    let d = duty.clamp(0.0, 1.0);
    let rise = ((1.0 - d) * t / 2.0).round() as u64;
    let fall = ((1.0 + d) * t / 2.0).round() as u64;
    [rise, rise + dead_ns, fall, fall + dead_ns]
}

/// Connection of a leg at time `tau_ns` into the period (switching model).
pub fn switching_conn(leg: Leg, tau_ns: u64, period_ns: u64, dead_ns: u64) -> Conn {
    match leg {
        Leg::Off => Conn::Float,
        Leg::Duty(d) if d <= 0.0 => Conn::Frac(0.0),
        Leg::Duty(d) if d >= 1.0 => Conn::Frac(1.0),
        Leg::Duty(d) => {
            let [low_off, high_on, high_off, low_on] = leg_edges_ns(d, period_ns, dead_ns);
            if tau_ns < low_off || tau_ns >= low_on {
                Conn::Frac(0.0)
            } else if tau_ns >= high_on && tau_ns < high_off {
                Conn::Frac(1.0)
            } else {
                Conn::Float
            }
        }
    }
}

/// Connection of a leg in the averaged model.
pub fn averaged_conn(leg: Leg) -> Conn {
    match leg {
        Leg::Off => Conn::Float,
        Leg::Duty(d) => Conn::Frac(d.clamp(0.0, 1.0)),
    }
}

/// The next edge of any leg strictly after `tau_ns` within the period, or the period end.
pub fn next_edge_ns(cmd: &GateCommand, tau_ns: u64, period_ns: u64) -> u64 {
    let mut next = period_ns;
    for leg in cmd.legs {
        if let Leg::Duty(d) = leg {
            if d > 0.0 && d < 1.0 {
                for e in leg_edges_ns(d, period_ns, cmd.dead_time_ns) {
                    if e > tau_ns && e < next {
                        next = e;
                    }
                }
            }
        }
    }
    next
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn high_and_low_are_never_on_together_and_dead_time_floats() {
        let period = 62_500;
        let dead = 1_000;
        let leg = Leg::Duty(0.3);
        let mut high_ns = 0;
        let mut float_ns = 0;
        for tau in (0..period).step_by(10) {
            match switching_conn(leg, tau, period, dead) {
                Conn::Frac(1.0) => high_ns += 10,
                Conn::Float => float_ns += 10,
                _ => {}
            }
        }
        // High on for duty·T minus one dead time; two dead times per period.
        assert!((high_ns as i64 - (18_750 - 1_000)).abs() <= 20, "{high_ns}");
        assert!((float_ns as i64 - 2_000).abs() <= 20, "{float_ns}");
    }

    #[test]
    fn floating_leg_follows_the_current_direction() {
        assert_eq!(Conn::Float.frac(-0.5), 1.0);
        assert_eq!(Conn::Float.frac(0.5), 0.0);
    }

    #[test]
    fn edges_are_found_in_order() {
        let cmd = GateCommand {
            legs: [Leg::Duty(0.5), Leg::Off, Leg::Duty(1.0)],
            dead_time_ns: 1000,
        };
        assert_eq!(next_edge_ns(&cmd, 0, 100_000), 25_000);
        assert_eq!(next_edge_ns(&cmd, 25_000, 100_000), 26_000);
        assert_eq!(next_edge_ns(&cmd, 76_000, 100_000), 100_000);
    }
}
