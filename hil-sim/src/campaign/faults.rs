//! The faults a world injects, by class, and how each is applied to a [`Simulation`].
//!
//! A fault starts at its time; a fault with a duration is undone at its end (the link
//! reconnected, the supply and the rotor restored). The classes are the ones the core
//! simulation injects cheaply (docs/campaign.md "A world").

use firmware_drive::ResetCause;
use firmware_plc::storage::Job;

use crate::plant::{SenseSpike, UdcSenseSpike};
use crate::scenario::{KEY_HOLD_S, RUN_KEY};
use crate::sim::Simulation;

/// What is injected.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FaultKind {
    /// Both wires flip each bit with `rate` for `for_ns`.
    LinkBitErrors { rate: f64, for_ns: u64 },
    /// The next `bytes` bytes on one wire each get a bit flipped.
    LinkBurst { to_drive: bool, bytes: u32 },
    /// Both wires cut for `for_ns`, then restored.
    LinkCut { for_ns: u64 },
    /// A spike on one sensed phase current (what the comparators see), `width_ns` wide
    /// from `from_ns` into the next PWM period; one wider than the period goes on for
    /// whole periods ([`sustain`]).
    CurrentSpike {
        phase: usize,
        amps: f64,
        from_ns: u64,
        width_ns: u64,
    },
    /// A spike on the sensed DC-link voltage, as [`FaultKind::CurrentSpike`].
    UdcSpike {
        volts: f64,
        from_ns: u64,
        width_ns: u64,
    },
    /// `STO_IN` low for `width_ns` (safety.md 6: a pulse of any width).
    StoPulse { width_ns: u64 },
    /// The supply's open-circuit voltage changed by `delta_v` for `for_ns` (a dip when
    /// negative, a surge when positive).
    Supply { delta_v: f64, for_ns: u64 },
    /// The load torque set to `nm` from now on.
    LoadStep { nm: f64 },
    /// The rotor held for `for_ns`.
    LockedRotor { for_ns: u64 },
    /// The drive MCU's supply cycled (a restart with reset cause power-on).
    DrivePowerCut,
    /// The PLC MCU's supply cycled (it powers up from its EEPROM).
    PlcPowerCut,
    /// The world typed `C` `slot` (a keypad save), the digit now; the PLC's supply fails
    /// `at_byte` bytes into the save's writes, between or inside its page writes
    /// (`MemEeprom::cut_power_after`); the PLC restarts when the write fails.
    CutInSave { slot: u8, at_byte: u32 },
    /// `STO_IN` low for `sto_width_ns` (a trip the PLC learns of and logs) and the
    /// PLC's supply failing `at_byte` bytes into the log entry's page write.
    CutInLog { sto_width_ns: u64, at_byte: u32 },
    /// The RUN/STOP key typed (a stop writes the boot record and the counters record)
    /// and the PLC's supply failing `at_byte` bytes into the writes from now.
    CutInCounters { at_byte: u32 },
    /// The drive's task stalls and its watchdog restarts it (reset cause watchdog: the
    /// drive latches `WDG` after boot, drive.md). The core simulation has no task
    /// timing: the stall is seen by its end, the watchdog reset.
    DriveWatchdog,
    /// The EEPROM's write cycles last `polls` ready polls (the chip NACKs its address
    /// meanwhile, 24xx datasheet: up to 5 ms) for `for_ns`.
    EepromBusy { polls: u32, for_ns: u64 },
}

/// The classes, for the per-class counts (in this order).
pub const CLASSES: [&str; 17] = [
    "link_bit_errors",
    "link_burst",
    "link_cut",
    "current_spike",
    "udc_spike",
    "sto_pulse",
    "supply_dip",
    "supply_surge",
    "load_step",
    "locked_rotor",
    "drive_power_cut",
    "plc_power_cut",
    "cut_in_save",
    "cut_in_log",
    "cut_in_counters",
    "drive_watchdog",
    "eeprom_busy",
];

impl FaultKind {
    /// The class name (one of [`CLASSES`]).
    pub fn class(&self) -> &'static str {
        match self {
            FaultKind::LinkBitErrors { .. } => "link_bit_errors",
            FaultKind::LinkBurst { .. } => "link_burst",
            FaultKind::LinkCut { .. } => "link_cut",
            FaultKind::CurrentSpike { .. } => "current_spike",
            FaultKind::UdcSpike { .. } => "udc_spike",
            FaultKind::StoPulse { .. } => "sto_pulse",
            FaultKind::Supply { delta_v, .. } if *delta_v < 0.0 => "supply_dip",
            FaultKind::Supply { .. } => "supply_surge",
            FaultKind::LoadStep { .. } => "load_step",
            FaultKind::LockedRotor { .. } => "locked_rotor",
            FaultKind::DrivePowerCut => "drive_power_cut",
            FaultKind::PlcPowerCut => "plc_power_cut",
            FaultKind::CutInSave { .. } => "cut_in_save",
            FaultKind::CutInLog { .. } => "cut_in_log",
            FaultKind::CutInCounters { .. } => "cut_in_counters",
            FaultKind::DriveWatchdog => "drive_watchdog",
            FaultKind::EepromBusy { .. } => "eeprom_busy",
        }
    }

    /// How long the fault lasts before it is undone (0: a step or an instant).
    pub fn duration_ns(&self) -> u64 {
        match *self {
            FaultKind::LinkBitErrors { for_ns, .. }
            | FaultKind::LinkCut { for_ns }
            | FaultKind::Supply { for_ns, .. }
            | FaultKind::LockedRotor { for_ns }
            | FaultKind::EepromBusy { for_ns, .. } => for_ns,
            FaultKind::StoPulse { width_ns }
            | FaultKind::CurrentSpike { width_ns, .. }
            | FaultKind::UdcSpike { width_ns, .. } => width_ns,
            FaultKind::CutInLog { sto_width_ns, .. } => sto_width_ns,
            FaultKind::CutInCounters { .. } => KEY_HOLD_NS,
            _ => 0,
        }
    }
}

/// How long a key is held, ns.
pub const KEY_HOLD_NS: u64 = (KEY_HOLD_S * 1e9) as u64;

/// One injected fault.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fault {
    pub at_ns: u64,
    pub kind: FaultKind,
}

impl std::fmt::Display for Fault {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let us = |ns: u64| ns as f64 / 1e3;
        write!(f, "{:.6} s {}", self.at_ns as f64 / 1e9, self.kind.class())?;
        match self.kind {
            FaultKind::LinkBitErrors { rate, for_ns } => {
                write!(f, " rate {rate:.1e} for {:.0} us", us(for_ns))
            }
            FaultKind::LinkBurst { to_drive, bytes } => write!(
                f,
                " {bytes} bytes to the {}",
                if to_drive { "drive" } else { "PLC" }
            ),
            FaultKind::LinkCut { for_ns } | FaultKind::LockedRotor { for_ns } => {
                write!(f, " for {:.0} us", us(for_ns))
            }
            FaultKind::CurrentSpike {
                phase,
                amps,
                from_ns,
                width_ns,
            } => write!(
                f,
                " phase {} {amps:+.2} A at {:.1} us into the period, {:.1} us wide",
                phase + 1,
                us(from_ns),
                us(width_ns)
            ),
            FaultKind::UdcSpike {
                volts,
                from_ns,
                width_ns,
            } => write!(
                f,
                " {volts:+.2} V at {:.1} us into the period, {:.1} us wide",
                us(from_ns),
                us(width_ns)
            ),
            FaultKind::StoPulse { width_ns } => write!(f, " {:.1} us wide", us(width_ns)),
            FaultKind::Supply { delta_v, for_ns } => {
                write!(f, " {delta_v:+.2} V for {:.0} us", us(for_ns))
            }
            FaultKind::LoadStep { nm } => write!(f, " to {nm:.3} N m"),
            FaultKind::DrivePowerCut | FaultKind::PlcPowerCut => Ok(()),
            FaultKind::CutInSave { slot, at_byte } => {
                write!(f, " slot {slot} at byte {at_byte}")
            }
            FaultKind::CutInLog {
                sto_width_ns,
                at_byte,
            } => write!(f, " STO {:.0} us wide, at byte {at_byte}", us(sto_width_ns)),
            FaultKind::CutInCounters { at_byte } => write!(f, " at byte {at_byte}"),
            FaultKind::DriveWatchdog => Ok(()),
            FaultKind::EepromBusy { polls, for_ns } => {
                write!(f, " {polls} polls a write cycle for {:.0} us", us(for_ns))
            }
        }
    }
}

/// What the world's plant and link are without faults (what an undo restores).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Baseline {
    pub supply_v: f64,
    pub bit_error_rate: f64,
}

/// An instant of a fault: its start, or its end (undo).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FaultEdge {
    pub at_ns: u64,
    pub kind: FaultKind,
    pub end: bool,
}

/// Every start and end of `faults`, in time order (a start before an end at the same
/// time; otherwise the list's order).
pub fn edges(faults: &[Fault]) -> Vec<FaultEdge> {
    let mut e = Vec::with_capacity(faults.len() * 2);
    for f in faults {
        e.push(FaultEdge {
            at_ns: f.at_ns,
            kind: f.kind,
            end: false,
        });
        let d = f.kind.duration_ns();
        if d > 0 {
            e.push(FaultEdge {
                at_ns: f.at_ns.saturating_add(d),
                kind: f.kind,
                end: true,
            });
        }
    }
    e.sort_by_key(|x| (x.at_ns, x.end));
    e
}

/// Applies one edge now.
pub fn apply(sim: &mut Simulation, edge: &FaultEdge, base: &Baseline) {
    match (edge.kind, edge.end) {
        (FaultKind::LinkBitErrors { rate, .. }, false) => sim.set_link_bit_error_rate(rate),
        (FaultKind::LinkBitErrors { .. }, true) => sim.set_link_bit_error_rate(base.bit_error_rate),
        (FaultKind::LinkBurst { to_drive, bytes }, _) => sim.link_burst(to_drive, bytes),
        (FaultKind::LinkCut { .. }, end) => sim.set_link_cut(!end),
        (
            FaultKind::CurrentSpike {
                phase,
                amps,
                from_ns,
                width_ns,
            },
            false,
        ) => sim.plant_mut().inject_sense_spike(SenseSpike {
            phase,
            amps,
            from_ns,
            to_ns: from_ns.saturating_add(width_ns),
        }),
        (
            FaultKind::UdcSpike {
                volts,
                from_ns,
                width_ns,
            },
            false,
        ) => sim.plant_mut().inject_udc_sense_spike(UdcSenseSpike {
            volts,
            from_ns,
            to_ns: from_ns.saturating_add(width_ns),
        }),
        (FaultKind::StoPulse { .. }, end) => sim.plant_mut().set_sto_input(!end),
        (FaultKind::Supply { delta_v, .. }, false) => {
            sim.plant_mut().params_mut().supply_v = (base.supply_v + delta_v).max(0.0)
        }
        (FaultKind::Supply { .. }, true) => sim.plant_mut().params_mut().supply_v = base.supply_v,
        (FaultKind::LoadStep { nm }, _) => sim.plant_mut().params_mut().motor.load_torque_nm = nm,
        (FaultKind::LockedRotor { .. }, end) => {
            sim.plant_mut().params_mut().motor.locked_rotor = !end
        }
        (FaultKind::DrivePowerCut, false) => sim.restart_drive(ResetCause::PowerOn),
        (FaultKind::PlcPowerCut, false) => sim.restart_plc(),
        // The runner arms these cuts as the save or the log entry starts (`aim`).
        (FaultKind::CutInSave { .. }, false) => {}
        (FaultKind::CutInLog { .. }, false) => sim.plant_mut().set_sto_input(false),
        (FaultKind::CutInLog { .. }, true) => sim.plant_mut().set_sto_input(true),
        (FaultKind::CutInCounters { at_byte }, false) => {
            sim.key(RUN_KEY, true);
            arm_cut(sim, at_byte)
        }
        (FaultKind::CutInCounters { .. }, true) => sim.key(RUN_KEY, false),
        (FaultKind::DriveWatchdog, false) => sim.restart_drive(ResetCause::Watchdog),
        (FaultKind::EepromBusy { polls, .. }, end) => sim
            .plc_mut()
            .app_mut()
            .storage()
            .eeprom()
            .set_busy_polls(if end { 0 } else { polls }),
        (FaultKind::CurrentSpike { .. } | FaultKind::UdcSpike { .. }, true)
        | (FaultKind::DrivePowerCut | FaultKind::PlcPowerCut, true)
        | (FaultKind::CutInSave { .. } | FaultKind::DriveWatchdog, true) => {}
    }
}

/// Which storage job an aimed cut waits for.
pub type JobFilter = fn(&Job) -> bool;

/// The storage job a cut waits for, and where in it the supply fails: a cut in a save
/// or in a log entry is armed as that job comes first in the PLC's storage queue, at
/// most [`AIM_WINDOW_NS`] after the fault.
pub fn aim(kind: &FaultKind) -> Option<(JobFilter, u32)> {
    match *kind {
        FaultKind::CutInSave { at_byte, .. } => Some((|j| matches!(j, Job::Save { .. }), at_byte)),
        FaultKind::CutInLog { at_byte, .. } => Some((|j| matches!(j, Job::LogFault(_)), at_byte)),
        _ => None,
    }
}

/// How long an aimed cut waits for its job (a save the editor refused, a pulse that
/// tripped nothing, never comes).
pub const AIM_WINDOW_NS: u64 = 200_000_000;

/// The PLC's supply fails `at_byte` bytes into its next EEPROM writes (the runner
/// restarts the PLC when a write has failed: [`plc_cut_happened`]).
pub fn arm_cut(sim: &mut Simulation, at_byte: u32) {
    sim.plc_mut()
        .app_mut()
        .storage()
        .eeprom()
        .cut_power_after(at_byte);
}

/// An armed cut has stopped an EEPROM write: the PLC has lost its supply.
pub fn plc_cut_happened(sim: &mut Simulation) -> bool {
    sim.plc_mut().app_mut().storage().eeprom().power_lost()
}

/// A spike wider than the PWM period running when it starts goes on past that period.
pub fn outlasts_the_period(kind: &FaultKind, period_ns: u64) -> bool {
    match *kind {
        FaultKind::CurrentSpike {
            from_ns, width_ns, ..
        }
        | FaultKind::UdcSpike {
            from_ns, width_ns, ..
        } => from_ns.saturating_add(width_ns) > period_ns,
        _ => false,
    }
}

/// Arms `kind`'s spike for the whole of the next PWM period (the plant takes a spike for
/// one period at a time): a spike wider than a period is rounded up to whole periods.
pub fn sustain(sim: &mut Simulation, kind: &FaultKind) {
    match *kind {
        FaultKind::CurrentSpike { phase, amps, .. } => {
            sim.plant_mut().inject_sense_spike(SenseSpike {
                phase,
                amps,
                from_ns: 0,
                to_ns: u64::MAX,
            })
        }
        FaultKind::UdcSpike { volts, .. } => {
            sim.plant_mut().inject_udc_sense_spike(UdcSenseSpike {
                volts,
                from_ns: 0,
                to_ns: u64::MAX,
            })
        }
        _ => {}
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn edges_are_in_time_order_with_their_undo() {
        let f = [
            Fault {
                at_ns: 500,
                kind: FaultKind::LinkCut { for_ns: 1000 },
            },
            Fault {
                at_ns: 100,
                kind: FaultKind::DrivePowerCut,
            },
        ];
        let e = edges(&f);
        let t: Vec<(u64, bool)> = e.iter().map(|x| (x.at_ns, x.end)).collect();
        assert_eq!(t, [(100, false), (500, false), (1500, true)]);
    }

    #[test]
    fn a_dip_and_a_surge_are_two_classes() {
        let d = FaultKind::Supply {
            delta_v: -3.0,
            for_ns: 1,
        };
        let s = FaultKind::Supply {
            delta_v: 3.0,
            for_ns: 1,
        };
        assert_eq!((d.class(), s.class()), ("supply_dip", "supply_surge"));
        assert!(CLASSES.contains(&d.class()) && CLASSES.contains(&s.class()));
    }
}
