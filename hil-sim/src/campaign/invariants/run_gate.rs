//! `run_gate`: no output without RUN. The drive drives its legs only in its RUN state
//! (drive.md "States": PWM off in BOOT, IDLE and FAULT; the core leaves RUN at once and
//! its next PWM period turns the outputs off, drive.md "Trips": within one PWM period),
//! and not for longer than the link timeout after the PLC left RUN (drive.md: STOP or the
//! PLC leaving RUN turns the PWM off; a drive that hears nothing trips `LINK` after the
//! link timeout, 50 ms by default).

use shared_protocol::drive_state::DriveState;

use super::Invariant;
use crate::campaign::observe::Observation;

/// How long the outputs may stay on after the PLC left RUN, ns: the default link timeout
/// (drive.md, code 5: 50 ms) plus the 1 ms tick that notices it and a frame's time.
pub const AFTER_PLC_RUN_NS: u64 = 55_000_000;

/// Beyond one PWM period: the timer's rounding of the period to whole nanoseconds.
pub const PERIOD_SLACK_NS: u64 = 1_000;

#[derive(Default)]
pub struct RunGate {
    /// When the PLC was last seen in RUN.
    plc_run_seen_ns: Option<u64>,
    /// When the drive left RUN, and the PWM period then.
    left_run: Option<(u64, u64)>,
}

impl Invariant for RunGate {
    fn name(&self) -> &'static str {
        "run_gate"
    }

    fn check(&mut self, o: &Observation) -> Option<String> {
        if o.plc_running {
            self.plc_run_seen_ns = Some(o.t_ns);
        }
        if o.drive_state == DriveState::Run {
            self.left_run = None;
        } else {
            let (t0, period) = *self.left_run.get_or_insert((o.t_ns, o.pwm_period_ns));
            let late = o.t_ns - t0;
            if o.outputs_on && late > period + PERIOD_SLACK_NS {
                return Some(format!(
                    "outputs on in drive state {} {:.3} ms after it left RUN (one PWM period: {:.3} ms)",
                    o.drive_state.name(),
                    late as f64 / 1e6,
                    period as f64 / 1e6
                ));
            }
            return None;
        }
        if !o.outputs_on {
            return None;
        }
        match self.plc_run_seen_ns {
            None => Some("outputs on and the PLC was never in RUN".into()),
            Some(t) if o.t_ns - t > AFTER_PLC_RUN_NS => Some(format!(
                "outputs on {:.1} ms after the PLC left RUN (limit {:.1} ms)",
                (o.t_ns - t) as f64 / 1e6,
                AFTER_PLC_RUN_NS as f64 / 1e6
            )),
            Some(_) => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::campaign::invariants::first_firing;

    fn at(t_ns: u64, state: DriveState, plc: bool, on: bool) -> Observation {
        Observation {
            t_ns,
            drive_state: state,
            plc_running: plc,
            outputs_on: on,
            legs_driven: [on; 3],
            ..Observation::default()
        }
    }

    #[test]
    fn fires_on_outputs_outside_the_drives_run_after_one_pwm_period() {
        let (run, idle) = (DriveState::Run, DriveState::Idle);
        let mut inv = RunGate::default();
        // The period of the default observation is 100 us.
        let fine = [
            at(0, run, true, true),
            at(10, idle, true, true),
            at(100_000, idle, true, true),
        ];
        assert_eq!(first_firing(&mut inv, &fine), None);
        let mut inv = RunGate::default();
        let late = [
            at(0, run, true, true),
            at(10, DriveState::Fault, true, true),
            at(102_000, DriveState::Fault, true, true),
        ];
        let m = first_firing(&mut inv, &late).unwrap().1;
        assert!(m.contains("FAULT"), "{m}");
    }

    #[test]
    fn fires_on_outputs_long_after_the_plc_left_run() {
        let run = DriveState::Run;
        let mut inv = RunGate::default();
        let fine = [at(0, run, true, true), at(50_000_000, run, false, true)];
        assert_eq!(first_firing(&mut inv, &fine), None);
        let mut inv = RunGate::default();
        let late = [at(0, run, true, true), at(60_000_000, run, false, true)];
        assert!(first_firing(&mut inv, &late)
            .unwrap()
            .1
            .contains("left RUN"));
        let mut inv = RunGate::default();
        assert!(first_firing(&mut inv, &[at(0, run, false, true)]).is_some());
    }
}
