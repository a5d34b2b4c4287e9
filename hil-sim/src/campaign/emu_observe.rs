//! What the invariants see of the real images (`campaign --emu`): the same
//! [`Observation`] as on the cores, taken from what the emulated boards expose.
//!
//! * The gates: TIM1's gate state (MOE, the channels' pin drives, CCR1-3, ARR, the dead
//!   time from DTG) at every TIM1 event the drive board receives (`Rig::tim_trace`), so
//!   a pulse or an overlap between two slices of the co-simulation is seen at its event.
//! * The break inputs: `STO_IN` as the rig's wire drives it (raw, before TIM1's filter);
//!   a comparator break from TIM1's break state (a `Break` event raises it, MOE set
//!   again clears it: TIM1 refuses MOE while a break is active).
//! * The drive's state and fault: what the drive image logs (`drive: State { from: ..,
//!   to: .. }`, `drive: fault <Name>`); a reset of the drive MCU is BOOT with no fault.
//! * The PLC's RUN: what the PLC image logs (`plc: <from> -> <to>`, RUN is `Running`),
//!   and the drive's `link: Run` (the PLC sends Run only in RUN, and logs its own change
//!   a task later); a reset of the PLC MCU leaves RUN.
//!
//! The emulator reads a log line at the end of the co-simulation slice in which the
//! image wrote it (slices are at most `QUANTUM_NS`, 50 us), and an image logs a change
//! from a task, after the interrupt that acted on it: a logged change is known to two
//! slices. Each is credited at the end that favours the firmware: an entry into RUN (the
//! drive's or the PLC's) at the start of the slice before the one it was read in, every
//! other change (leaving RUN, a fault latched) when it was read. A violation shorter than
//! that at such a change is not seen under `--emu` (docs/campaign.md "On the real
//! images").

use g431_emu::cpu::CpuEvent;
use g431_emu::mcu::Mcu;
use g431_emu::periph::tim_adv::{GateState, OffCause, TimEvent};
use g431_emu::time::cycles_to_ns;
use shared_protocol::drive_state::DriveState;

use super::observe::Observation;
use crate::emu::boards::gate_command;
use crate::emu::sim::logged_fault;
use crate::plant::Leg;

/// One thing that changed what the invariants see, at its time.
#[derive(Debug, Clone, Copy)]
pub enum Change {
    Tim(TimEvent),
    /// The drive image logged a state change.
    State(DriveState),
    /// The drive image logged a fault (code).
    Fault(u8),
    /// The drive MCU was reset (power cut, watchdog, software).
    DriveReset,
    /// The PLC entered (`true`) or left RUN, or its MCU was reset (`false`).
    PlcRun(bool),
    /// The rig's STO wire is low (`true`) or high.
    Sto(bool),
    /// TIM1 has no break input active (read at the end of a slice).
    BreaksInactive,
}

impl Change {
    /// An entry into RUN, credited at the start of the slice it was read in.
    pub fn enters_run(&self) -> bool {
        matches!(self, Change::State(DriveState::Run) | Change::PlcRun(true))
    }
}

/// The PLC's RUN change of a `plc: <from> -> <to>` log line.
pub fn logged_plc_run(message: &str) -> Option<bool> {
    let (from, to) = message.strip_prefix("plc: ")?.split_once(" -> ")?;
    match (from.trim() == "Running", to.trim() == "Running") {
        (false, true) => Some(true),
        (true, false) => Some(false),
        _ => None,
    }
}

/// The drive's state from its `State { from: .., to: .. }` log line.
pub fn logged_state(message: &str) -> Option<DriveState> {
    let rest = message.strip_prefix("drive: State {")?;
    let to = rest
        .split("to:")
        .nth(1)?
        .trim()
        .trim_end_matches('}')
        .trim();
    Some(match to {
        "Boot" => DriveState::Boot,
        "Idle" => DriveState::Idle,
        "Run" => DriveState::Run,
        "Fault" => DriveState::Fault,
        _ => return None,
    })
}

/// Reads the drive image's log and resets since the last call: its changes as (ns, change).
#[derive(Debug, Default)]
pub struct DriveLogReader {
    log_seen: usize,
    events_seen: usize,
}

impl DriveLogReader {
    pub fn read(&mut self, drive: &Mcu, out: &mut Vec<(u64, Change)>) {
        for e in drive.events().get(self.events_seen..).unwrap_or(&[]) {
            if let CpuEvent::Reset { at, .. } = e {
                out.push((cycles_to_ns(*at), Change::DriveReset));
            }
        }
        self.events_seen = drive.events().len();
        for l in drive.log_since(self.log_seen) {
            let t = cycles_to_ns(l.at);
            if let Some(code) = logged_fault(&l.message) {
                out.push((t, Change::Fault(code)));
            } else if let Some(s) = logged_state(&l.message) {
                out.push((t, Change::State(s)));
            } else if l.message == "link: Run" {
                out.push((t, Change::PlcRun(true)));
            }
        }
        self.log_seen = drive.log().len();
    }
}

/// Reads the PLC image's log and resets since the last call.
#[derive(Debug, Default)]
pub struct PlcLogReader {
    log_seen: usize,
    events_seen: usize,
}

impl PlcLogReader {
    pub fn read(&mut self, plc: &Mcu, out: &mut Vec<(u64, Change)>) {
        for e in plc.events().get(self.events_seen..).unwrap_or(&[]) {
            if let CpuEvent::Reset { at, .. } = e {
                out.push((cycles_to_ns(*at), Change::PlcRun(false)));
            }
        }
        self.events_seen = plc.events().len();
        for l in plc.log_since(self.log_seen) {
            if let Some(run) = logged_plc_run(&l.message) {
                out.push((cycles_to_ns(l.at), Change::PlcRun(run)));
            }
        }
        self.log_seen = plc.log().len();
    }
}

/// The observer's state between changes.
#[derive(Debug, Clone, Copy)]
pub struct EmuView {
    pub gate: Option<GateState>,
    /// A break opened the outputs and MOE has not been set again.
    pub hw_break: bool,
    /// A break input of TIM1 is active (a `Break` event, until MOE is set again or the
    /// timer says it is inactive at the end of a slice).
    pub break_active: bool,
    pub sto_in_low: bool,
    pub drive_state: DriveState,
    pub drive_fault: u8,
    pub plc_running: bool,
}

impl Default for EmuView {
    fn default() -> Self {
        EmuView {
            gate: None,
            hw_break: false,
            break_active: false,
            sto_in_low: false,
            drive_state: DriveState::Boot,
            drive_fault: 0,
            plc_running: false,
        }
    }
}

impl EmuView {
    pub fn apply(&mut self, c: &Change) {
        match *c {
            Change::Tim(TimEvent::Update { gate, .. } | TimEvent::GateChanged { gate, .. }) => {
                self.gate = Some(gate)
            }
            Change::Tim(TimEvent::OutputsOff { cause, .. }) => {
                if let Some(g) = self.gate.as_mut() {
                    g.outputs_enabled = false;
                }
                if matches!(
                    cause,
                    OffCause::Break | OffCause::Break2 | OffCause::SystemBreak
                ) {
                    self.hw_break = true;
                }
            }
            Change::Tim(TimEvent::OutputsOn { .. }) => {
                self.hw_break = false;
                self.break_active = false;
                if let Some(g) = self.gate.as_mut() {
                    g.outputs_enabled = true;
                    g.moe = true;
                }
            }
            Change::Tim(TimEvent::Break { .. }) => self.break_active = true,
            Change::Tim(_) => {}
            Change::State(s) => self.drive_state = s,
            Change::Fault(code) => self.drive_fault = code,
            Change::PlcRun(run) => self.plc_running = run,
            Change::Sto(low) => self.sto_in_low = low,
            Change::BreaksInactive => self.break_active = false,
            Change::DriveReset => {
                self.drive_state = DriveState::Boot;
                self.drive_fault = 0;
                self.hw_break = false;
                if let Some(g) = self.gate.as_mut() {
                    g.outputs_enabled = false;
                    g.moe = false;
                }
            }
        }
        if self.drive_state != DriveState::Fault && matches!(c, Change::State(_)) {
            // Leaving FAULT clears the latch (the image logs no "fault cleared").
            self.drive_fault = 0;
        }
    }

    /// The observation at `t_ns`. Fields the cores' observation gains later keep their
    /// quiet defaults here until the images expose them.
    #[allow(clippy::needless_update)]
    pub fn observation(&self, t_ns: u64) -> Observation {
        let (period_ns, cmd, compares, arr) = match self.gate {
            Some(g) => {
                let (p, cmd) = gate_command(&g);
                let c = |i: usize| {
                    g.channels
                        .get(i)
                        .map_or(0, |ch| ch.oc.ccr.min(u32::from(u16::MAX)) as u16)
                };
                (
                    p,
                    Some(cmd),
                    [c(0), c(1), c(2)],
                    g.arr.min(u32::from(u16::MAX)) as u16,
                )
            }
            None => (0, None, [0; 3], 0),
        };
        let legs_driven = cmd.map_or([false; 3], |c| c.legs.map(|l| matches!(l, Leg::Duty(_))));
        let defaults = Observation::default();
        Observation {
            t_ns,
            outputs_on: legs_driven.iter().any(|d| *d),
            legs_driven,
            dead_time_ns: cmd.map_or(0, |c| c.dead_time_ns),
            compares,
            arr,
            pwm_period_ns: if period_ns > 0 {
                period_ns
            } else {
                defaults.pwm_period_ns
            },
            hw_break: self.hw_break,
            comparator_high: self.break_active && !self.sto_in_low,
            sto_in_low: self.sto_in_low,
            drive_state: self.drive_state,
            drive_fault: self.drive_fault,
            plc_running: self.plc_running,
            lift: None,
            ..defaults
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_state_is_read_off_the_drive_log() {
        assert_eq!(
            logged_state("drive: State { from: Idle, to: Run }"),
            Some(DriveState::Run)
        );
        assert_eq!(
            logged_state("drive: State { from: Run, to: Fault }"),
            Some(DriveState::Fault)
        );
        assert_eq!(logged_state("drive: fault Link"), None);
        assert_eq!(logged_state("link: State { from: Idle, to: Run }"), None);
        assert_eq!(logged_plc_run("plc: Downloading -> Running"), Some(true));
        assert_eq!(logged_plc_run("plc: Running -> Stopped"), Some(false));
        assert_eq!(logged_plc_run("plc: Stopped -> WaitLink"), None);
    }

    #[test]
    fn a_reset_is_boot_without_a_fault_and_leaving_fault_clears_it() {
        let mut v = EmuView::default();
        v.apply(&Change::Fault(5));
        v.apply(&Change::State(DriveState::Fault));
        assert_eq!(v.observation(0).drive_fault, 5);
        v.apply(&Change::State(DriveState::Idle));
        assert_eq!(v.observation(0).drive_fault, 0);
        v.apply(&Change::Fault(9));
        v.apply(&Change::DriveReset);
        let o = v.observation(0);
        assert_eq!((o.drive_state, o.drive_fault), (DriveState::Boot, 0));
    }
}
