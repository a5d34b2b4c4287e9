//! One `hil-sim emu` run: check the inputs, co-simulate, report.

use std::path::Path;
use std::time::{Duration, Instant};

use anyhow::{bail, Result};
use g431_emu::cpu::CpuEvent;
use g431_emu::log::LogLine;
use g431_emu::time::cycles_to_ns;
use shared_protocol::program::Program;

use super::sim::EmuSim;
use crate::mcu::SimLcd;
use crate::scenario::Scenario;
use crate::sim::{FaultRecord, RunOptions, Sample};
use shared_protocol::fault::fault_name;

/// What an `emu` run produced.
#[derive(Debug, Clone)]
pub struct EmuReport {
    pub samples: Vec<Sample>,
    pub faults: Vec<FaultRecord>,
    pub lcd: SimLcd,
    pub sim_s: f64,
    pub wall: Duration,
    /// Both images' defmt logs, merged in virtual time: (image, line).
    pub log: Vec<(String, LogLine)>,
    /// Resets, HardFaults, lockups of either image.
    pub cpu_events: Vec<(String, CpuEvent)>,
    /// The HardFaults, lockups, watchdog and self resets the scenario does not expect
    /// (`[emu] expect`): `hil-sim emu` then exits with status 2.
    pub unexpected: Vec<String>,
    /// What the emulator found (unmodelled registers, stuck polls, model reports).
    pub diagnostics: Vec<(String, String)>,
    /// Longest gap between two IWDG feeds, µs, per image (drive, PLC); `None` if the
    /// watchdog was never fed.
    pub longest_feed_gap_us: [Option<u64>; 2],
    /// How deep each image's stack has been (drive, PLC): flip-link puts it below the
    /// statics, so an overflow is a HardFault, and this says how close the run came.
    pub stack: [Option<g431_emu::soc::StackUse>; 2],
    pub final_speed_rpm: f64,
    pub final_f_hz: f64,
}

fn fault_text(code: u8) -> String {
    use super::sim::image_fault;
    match code {
        image_fault::HARD_FAULT => "drive image HardFault".into(),
        image_fault::LOCKUP => "drive core LOCKUP".into(),
        image_fault::WATCHDOG => "drive image watchdog reset".into(),
        image_fault::BOOT_ROM => "drive booted the ROM bootloader (BOOT0 high)".into(),
        c => fault_name(c).to_string(),
    }
}

impl EmuReport {
    /// The summary printed at the end of `emu`.
    pub fn summary(&self) -> String {
        let wall = self.wall.as_secs_f64();
        let mut s = format!(
            "emulated {:.3} s of both images in {:.3} s wall ({:.2}x real time)\n",
            self.sim_s,
            wall,
            if wall > 0.0 { self.sim_s / wall } else { 0.0 }
        );
        s.push_str(&format!(
            "final: f = {:.1} Hz, speed = {:.0} rpm\n",
            self.final_f_hz, self.final_speed_rpm
        ));
        s.push_str(&crate::run::faults_summary(&self.faults, fault_text));
        for (k, name) in ["drive", "PLC"].iter().enumerate() {
            match self.longest_feed_gap_us[k] {
                Some(us) => s.push_str(&format!(
                    "{name} watchdog: longest gap between feeds {:.1} ms\n",
                    us as f64 / 1000.0
                )),
                None => s.push_str(&format!("{name} watchdog: never fed\n")),
            }
        }
        for (k, name) in ["drive", "PLC"].iter().enumerate() {
            if let Some(st) = self.stack[k] {
                s.push_str(&format!(
                    "{name} stack: deepest {} of {} B ({} B never used)\n",
                    st.used_bytes,
                    st.size_bytes,
                    st.size_bytes - st.used_bytes
                ));
            }
        }
        let images: Vec<String> = self
            .cpu_events
            .iter()
            .filter(|(_, e)| !matches!(e, CpuEvent::Reset { at: 0, .. }))
            .map(|(n, e)| format!("  {n}: {}", event_text(e)))
            .collect();
        if images.is_empty() {
            s.push_str("images: no reset, fault or lockup\n");
        } else {
            s.push_str("images:\n");
            for l in images {
                s.push_str(&l);
                s.push('\n');
            }
        }
        if !self.unexpected.is_empty() {
            s.push_str("not expected by the scenario:\n");
            for l in &self.unexpected {
                s.push_str(&format!("  {l}\n"));
            }
        }
        if !self.diagnostics.is_empty() {
            s.push_str("emulator diagnostics:\n");
            for (n, d) in &self.diagnostics {
                s.push_str(&format!("  {n}: {d}\n"));
            }
        }
        s.push_str("LCD:\n");
        s.push_str(&self.lcd.framed());
        s.push('\n');
        s
    }
}

/// One line for a CPU event.
pub fn event_text(e: &CpuEvent) -> String {
    let t = |c: u64| cycles_to_ns(c) as f64 * 1e-9;
    match e {
        CpuEvent::HardFault { at, pc, cfsr, hfsr } => format!(
            "{:.6} s HardFault at {pc:#010x} (CFSR {cfsr:#010x}, HFSR {hfsr:#010x})",
            t(*at)
        ),
        CpuEvent::Lockup { at, pc } => format!("{:.6} s LOCKUP at {pc:#010x}", t(*at)),
        CpuEvent::Reset { at, why } => format!("{:.6} s reset ({why:?})", t(*at)),
        CpuEvent::BootRom { at } => {
            format!(
                "{:.6} s BOOT0 high: ROM bootloader, the image does not run",
                t(*at)
            )
        }
        CpuEvent::Unsupported { at, pc, what } => {
            format!("{:.6} s unsupported at {pc:#010x}: {what}", t(*at))
        }
    }
}

/// Co-simulates `program` on the images under `scenario` for `duration_s`. `on_log` gets
/// each log line as it appears (image name, line).
#[allow(clippy::too_many_arguments)]
pub fn run(
    drive_elf: &Path,
    plc_elf: &Path,
    program: &Program,
    scenario: Scenario,
    duration_s: f64,
    opts: RunOptions,
    keep_samples: crate::decimate::KeepSamples,
    mut on_sample: impl FnMut(&Sample),
    mut on_log: impl FnMut(&str, &LogLine),
) -> Result<EmuReport> {
    if !(duration_s.is_finite() && duration_s > 0.0) {
        bail!("the duration must be a positive number of seconds, got {duration_s}");
    }
    let start = Instant::now();
    let mut sim = EmuSim::new(drive_elf, plc_elf, program, scenario, opts)?;
    let end_ns = (duration_s * 1e9).round() as u64;
    let mut samples = crate::decimate::Kept::new(keep_samples);
    let mut shown = [0usize; 2];
    let mut log: Vec<(String, LogLine)> = Vec::new();
    let chunk_ns = 10_000_000;
    let mut t = 0;
    while t < end_ns {
        t = (t + chunk_ns).min(end_ns);
        sim.run_until(t, |s| {
            on_sample(s);
            samples.push(s);
        });
        let mut fresh: Vec<(String, LogLine)> = Vec::new();
        for (k, m) in [sim.drive(), sim.plc()].into_iter().enumerate() {
            for l in m.log_since(shown[k]) {
                fresh.push((m.name.clone(), l.clone()));
            }
            shown[k] = m.log().len();
        }
        fresh.sort_by_key(|(_, l)| l.at);
        for (n, l) in &fresh {
            on_log(n, l);
        }
        log.extend(fresh);
    }
    let mut diagnostics = Vec::new();
    for m in [sim.drive(), sim.plc()] {
        for d in m.diagnostics() {
            diagnostics.push((m.name.clone(), d.to_string()));
        }
    }
    let unexpected = sim.unexpected_troubles();
    let gap = |m: &g431_emu::mcu::Mcu| {
        let w = m.soc().iwdg();
        (w.feeds > 1).then(|| cycles_to_ns(w.longest_gap) / 1000)
    };
    let o = sim.rig().plant.outputs();
    Ok(EmuReport {
        samples: samples.into_vec(),
        faults: sim.faults().to_vec(),
        lcd: sim.lcd(),
        sim_s: sim.now_ns() as f64 * 1e-9,
        wall: start.elapsed(),
        log,
        cpu_events: sim.cpu_events(),
        unexpected,
        diagnostics,
        longest_feed_gap_us: [gap(sim.drive()), gap(sim.plc())],
        stack: [
            sim.drive().soc().stack_high_water(),
            sim.plc().soc().stack_high_water(),
        ],
        final_speed_rpm: o.speed_rad_s * 60.0 / (2.0 * std::f64::consts::PI),
        final_f_hz: sim.status().map_or(0.0, |s| f64::from(s.freq_dhz) / 10.0),
    })
}
