//! One whole run as `hil-sim run` does it: load and check the inputs, simulate, report.

use std::path::Path;
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use firmware_plc::storage::image::{is_image, program_from_image};
use firmware_plc::storage::StorageError;
use shared_protocol::fault::fault_name;
use shared_protocol::program::{assemble, assemble_runnable, verify, Program};

use crate::mcu::SimLcd;
use crate::plant::lift::LiftEvent;
use crate::scenario::{Action, Input, PlantChange, Scenario, TimedAction};
use crate::sim::{FaultRecord, RunOptions, Sample, Simulation};
use trend_plot::Marks;

/// Reads a program that the PLC would start: `.plc` text, or a whole-EEPROM image
/// (32 KiB, as `asm -o` writes), checked by the whole-program verifier (e.g. the drive
/// section's stack depth). Errors name the file, text line and column (or the program
/// line for an image).
pub fn load_program(path: &Path) -> Result<Program> {
    let bytes = std::fs::read(path).with_context(|| format!("cannot read {}", path.display()))?;
    if is_eeprom_image(&bytes) {
        let p = load_any(path)?;
        verify(&p).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
        return Ok(p);
    }
    let Ok(text) = String::from_utf8(bytes) else {
        return load_any(path);
    };
    parse_program(&text, &path.display().to_string())
}

/// Reads any program the text format or an image holds, runnable or not (for `disasm`).
pub fn load_any(path: &Path) -> Result<Program> {
    let bytes = std::fs::read(path).with_context(|| format!("cannot read {}", path.display()))?;
    if is_eeprom_image(&bytes) {
        return program_from_image(&bytes).map_err(|e| {
            anyhow::anyhow!(
                "{}: an EEPROM image without a program to load: {}",
                path.display(),
                storage_error_text(e)
            )
        });
    }
    let Ok(text) = String::from_utf8(bytes) else {
        bail!(
            "{}: neither .plc text (not UTF-8) nor a 32768-byte EEPROM image",
            path.display()
        );
    };
    assemble(&text).map_err(|e| anyhow::anyhow!("{}:{e}", path.display()))
}

/// Whether `bytes` are a whole-EEPROM image (32 KiB) rather than `.plc` text of the
/// same length: text is UTF-8 without NUL, while an image has erased (0xFF) or zero
/// bytes.
pub fn is_eeprom_image(bytes: &[u8]) -> bool {
    is_image(bytes) && (bytes.contains(&0) || std::str::from_utf8(bytes).is_err())
}

/// A storage error in words (for messages; `{:?}` printed `Empty(1)`).
pub fn storage_error_text(e: StorageError) -> String {
    match e {
        StorageError::NoSuchSlot(n) => format!("there is no slot {n}"),
        StorageError::Empty(n) => format!("slot {n} was never saved (no slot holds a program)"),
        StorageError::Damaged(n) => format!("both copies of slot {n} are damaged"),
        StorageError::TooBig => "the program does not fit a slot".into(),
        StorageError::VerifyFailed => "a copy did not read back as written".into(),
        StorageError::Eeprom(e) => format!("EEPROM error {e:?}"),
        StorageError::Busy => "the EEPROM is busy".into(),
    }
}

/// Assembles `.plc` text into a program the PLC would start (line rules and the
/// whole-program verifier); `name` prefixes the error (`name:line:col: message`).
pub fn parse_program(text: &str, name: &str) -> Result<Program> {
    assemble_runnable(text).map_err(|e| anyhow::anyhow!("{name}:{e}"))
}

/// What a run produced.
#[derive(Debug, Clone)]
pub struct RunReport {
    pub samples: Vec<Sample>,
    pub faults: Vec<FaultRecord>,
    pub lcd: SimLcd,
    pub sim_s: f64,
    pub wall: Duration,
    pub drive_state: &'static str,
    pub plc_running: bool,
    pub final_speed_rpm: f64,
    pub final_f_hz: f64,
    /// The lift at the end of the run (`[lift]`).
    pub final_lift: Option<crate::plant::lift::LiftSample>,
    /// Each run-time warning seen (one per status-line text: the long text of its first
    /// appearance), with the time it first appeared.
    pub warnings: Vec<(f64, String)>,
    /// Limits and events for the plot.
    pub marks: Marks,
    /// The drive's state changes (s, state): RUN, trips, accepted ACKs.
    pub drive_states: Vec<(f64, &'static str)>,
    /// Largest |phase current| (A) and DC-link voltage (V) of the run.
    pub peak_current_a: f64,
    pub peak_dc_v: f64,
    /// The parameter signature (safety.md 8) of a program that uses the safety
    /// functions, as the drive reports it at the end of the run.
    pub signature: Option<u16>,
    /// The drive board the run simulates (`[plant] board`).
    pub board: &'static str,
}

/// The summary's fault lines (`faults: none`, or one line per trip with its time),
/// naming each code with `name` (`emu` adds the images' own events).
pub fn faults_summary<T: std::fmt::Display>(
    faults: &[FaultRecord],
    name: impl Fn(u8) -> T,
) -> String {
    if faults.is_empty() {
        return "faults: none\n".into();
    }
    let mut s = String::from("faults:\n");
    for f in faults {
        s.push_str(&format!(
            "  {:.3} s  {} {}\n",
            f.t_ns as f64 * 1e-9,
            f.code,
            name(f.code)
        ));
    }
    s
}

/// A scenario action as a plot marker label.
pub fn action_label(a: &Action) -> String {
    let input = |i: &Input| match *i {
        Input::Digital(n) => format!("D{n:02}"),
        Input::Analog(n) => format!("A{n:02}"),
        Input::Aux => "AUX".to_string(),
        Input::StoIn => "STO_IN".to_string(),
    };
    match a {
        Action::Set(i, v) => format!("{}={v}", input(i)),
        Action::KeyDown(k) => format!("key {k}"),
        Action::KeyUp(_) => String::new(),
        Action::Plant(p) => match p {
            PlantChange::DcLinkV(v) => format!("Udc {v} V"),
            PlantChange::LoadTorqueNm(v) => format!("load {v} Nm"),
            PlantChange::InertiaKgm2(v) => format!("J {v}"),
            PlantChange::BrakeResistorOhm(v) => format!("Rb {v}"),
            PlantChange::LockedRotor(v) => format!("locked {v}"),
        },
        Action::Lift(e) => match e {
            LiftEvent::LoadKg(kg) => format!("load {kg} kg"),
            LiftEvent::DoorBlock(b) => format!("door block {b}"),
            LiftEvent::VaneFail(v) => format!("vane fail {v:?}"),
        },
        Action::Silicon(side, ev) => format!("{side:?} {ev:?}"),
    }
}

/// The plot's event markers: the scenario's actions (a digital input going off and a key
/// release are not marked, so a button press is one marker) and the trips.
pub fn event_marks(actions: &[TimedAction], faults: &[FaultRecord]) -> Vec<(f64, String)> {
    let mut ev: Vec<(f64, String)> = actions
        .iter()
        .filter(|a| !matches!(a.action, Action::Set(Input::Digital(_), 0)))
        .map(|a| (a.at_ns as f64 * 1e-9, action_label(&a.action)))
        .filter(|(_, l)| !l.is_empty())
        .collect();
    ev.extend(faults.iter().map(|f| {
        (
            f.t_ns as f64 * 1e-9,
            format!("F{} {}", f.code, fault_name(f.code)),
        )
    }));
    ev.sort_by(|a, b| a.0.total_cmp(&b.0));
    ev
}

impl RunReport {
    /// The summary printed at the end of `run`.
    pub fn summary(&self) -> String {
        let wall = self.wall.as_secs_f64();
        let mut s = String::new();
        s.push_str(&format!(
            "simulated {:.3} s in {:.3} s wall ({:.1}x real time)\n",
            self.sim_s,
            wall,
            if wall > 0.0 { self.sim_s / wall } else { 0.0 }
        ));
        s.push_str(&format!("drive board: {}\n", self.board));
        s.push_str(&format!(
            "final state: PLC {}, drive {}, f = {:.1} Hz, speed = {:.0} rpm\n",
            if self.plc_running { "RUN" } else { "STOP" },
            self.drive_state,
            self.final_f_hz,
            self.final_speed_rpm
        ));
        if let Some(sig) = self.signature {
            // safety.md 8 and 11: the parameter signature, for the commissioning record.
            s.push_str(&format!(
                "safety functions NOT RATED, parameter signature {sig:04X}\n"
            ));
        }
        if let Some(l) = self.final_lift {
            s.push_str(&format!(
                "lift: car at {:.1} mm, at_floor {}\n",
                l.car_mm, l.at_floor
            ));
        }
        s.push_str(&faults_summary(&self.faults, fault_name));
        if self.warnings.is_empty() {
            s.push_str("warnings: none\n");
        } else {
            s.push_str("warnings:\n");
            for (t, w) in &self.warnings {
                s.push_str(&format!("  {t:.3} s  {w}\n"));
            }
        }
        if !self.drive_states.is_empty() {
            let h: Vec<String> = self
                .drive_states
                .iter()
                .map(|(t, st)| format!("{t:.3} s {st}"))
                .collect();
            s.push_str(&format!("drive states: {}\n", h.join(", ")));
        }
        s.push_str(&format!(
            "peaks: phase current {:.2} A, DC link {:.1} V\n",
            self.peak_current_a, self.peak_dc_v
        ));
        s.push_str("LCD:\n");
        s.push_str(&self.lcd.framed());
        s.push('\n');
        s
    }
}

/// Simulates `program` under `scenario` for `duration_s`. `keep_samples` says which
/// samples the report keeps (all, none, or decimated for a plot; `on_sample` sees every
/// one, for the CSV); `progress` is called every simulated 0.1 s.
pub fn run(
    program: &Program,
    scenario: Scenario,
    duration_s: f64,
    opts: RunOptions,
    keep_samples: crate::decimate::KeepSamples,
    on_sample: impl FnMut(&Sample),
    progress: impl FnMut(f64),
) -> Result<RunReport> {
    run_with(
        program,
        scenario,
        duration_s,
        opts,
        keep_samples,
        on_sample,
        progress,
        None,
    )
}

/// [`run`] with the PLC's service port attached (service.md 9): stepped after each PLC
/// tick; with a pty, the run waits for its client at t = 0. The simulation is left in
/// `service` afterwards, for [`crate::service::Attached::linger`] once the report is out
/// (service.md 9: the summary covers the duration only).
#[allow(clippy::too_many_arguments)]
pub fn run_with(
    program: &Program,
    scenario: Scenario,
    duration_s: f64,
    opts: RunOptions,
    keep_samples: crate::decimate::KeepSamples,
    mut on_sample: impl FnMut(&Sample),
    mut progress: impl FnMut(f64),
    mut service: Option<&mut crate::service::Attached>,
) -> Result<RunReport> {
    if !(duration_s.is_finite() && duration_s > 0.0) {
        bail!("the duration must be a positive number of seconds, got {duration_s}");
    }
    let start = Instant::now();
    let actions = scenario.actions.clone();
    let mut sim = Simulation::new(program, scenario, opts)?;
    let mut peak_current_a: f64 = 0.0;
    let mut peak_dc_v: f64 = 0.0;
    let end_ns = (duration_s * 1e9).round() as u64;
    let mut samples = crate::decimate::Kept::new(keep_samples);
    let mut warnings: Vec<(f64, String)> = Vec::new();
    let mut seen: Vec<String> = Vec::new();
    let chunk_ns = 100_000_000;
    let mut t = 0;
    if let Some(svc) = service.as_deref() {
        svc.wait_for_client();
    }
    while t < end_ns {
        t = (t + chunk_ns).min(end_ns);
        let mut each = |s: &Sample| {
            if !s.warn.is_empty() {
                for (short, long) in s.warn.texts() {
                    if !seen.contains(&short) {
                        seen.push(short);
                        warnings.push((s.t_ns as f64 * 1e-9, long));
                    }
                }
            }
            peak_current_a = s.i_abc_a.iter().fold(peak_current_a, |m, i| m.max(i.abs()));
            peak_dc_v = peak_dc_v.max(s.u_dc_v);
            on_sample(s);
            samples.push(s);
        };
        match service.as_deref_mut() {
            Some(svc) => svc.run_until(&mut sim, t, &mut each),
            None => sim.run_until(t, each),
        }
        if let Some(at) = sim.unstable_at_ns() {
            bail!(
                "model unstable at t = {:.3} s: the plant's state left physics (NaN or beyond \
                 10 kA / 10^5 rad/s / 100 kV); check the scenario's plant values",
                at as f64 * 1e-9
            );
        }
        progress(t as f64 * 1e-9);
    }
    let st = firmware_drive_status(&sim);
    let o = sim.plant().outputs();
    let marks = Marks {
        current_limits_a: current_limits(&sim),
        dc_limits_v: dc_limits(&sim),
        events: event_marks(&actions, sim.faults()),
        zoom_at_s: None,
        floor_levels_mm: sim
            .lift()
            .map(|l| {
                let p = l.params();
                (1..=p.floors)
                    .map(|k| (format!("floor {k}"), p.level_mm(k)))
                    .collect()
            })
            .unwrap_or_default(),
    };
    let signature =
        shared_protocol::program::uses_safety(program).then(|| sim.drive().status().sf_signature);
    let report = RunReport {
        board: sim.plant().params().board.name,
        signature,
        marks,
        drive_states: sim
            .drive_states()
            .iter()
            .map(|(t, s)| (*t as f64 * 1e-9, *s))
            .collect(),
        peak_current_a,
        peak_dc_v,
        samples: samples.into_vec(),
        faults: sim.faults().to_vec(),
        lcd: sim.plc().lcd().clone(),
        sim_s: sim.now_ns() as f64 * 1e-9,
        wall: start.elapsed(),
        drive_state: st.0,
        plc_running: sim.plc().running(),
        final_speed_rpm: o.speed_rad_s * 60.0 / (2.0 * std::f64::consts::PI),
        final_f_hz: st.1,
        final_lift: sim.lift().map(|l| l.sample()),
        warnings,
    };
    if let Some(svc) = service {
        svc.park(sim);
    }
    Ok(report)
}

/// `I>` (if the program sets one) and `OC_HW` as in effect at the end of the run, A.
fn current_limits(sim: &Simulation) -> Vec<(String, f64)> {
    let core = sim.drive().core();
    let st = core.status();
    let mut l = Vec::new();
    let i_max = core.vm().settings().i_max_centiamps;
    if i_max > 0 {
        l.push(("I>".to_string(), f64::from(i_max) / 100.0));
    }
    l.push(("OC_HW".to_string(), f64::from(st.hw.oc_hw.0) / 100.0));
    l
}

/// `U>`, `U<` (if set) and `OV_HW` at the end of the run, V.
fn dc_limits(sim: &Simulation) -> Vec<(String, f64)> {
    let core = sim.drive().core();
    let s = core.vm().settings();
    let mut l = Vec::new();
    if s.u_max_volts > 0 {
        l.push(("U>".to_string(), f64::from(s.u_max_volts)));
    }
    if s.u_min_volts > 0 {
        l.push(("U<".to_string(), f64::from(s.u_min_volts)));
    }
    l.push(("OV_HW".to_string(), f64::from(core.status().hw.ov_hw.0)));
    l
}

fn firmware_drive_status(sim: &Simulation) -> (&'static str, f64) {
    let s = sim.drive().status();
    (s.state.name(), f64::from(s.f_applied.0) / 10.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    const LIFT_PLC: &str = include_str!("../../shared-protocol/programs/lift.plc");

    /// A valid `.plc` text padded with a comment line to exactly `IMAGE_BYTES` bytes (the
    /// EEPROM image's size): such a text was once taken for an image.
    fn text_of_image_size() -> String {
        let mut text = LIFT_PLC.to_string();
        if !text.ends_with('\n') {
            text.push('\n');
        }
        let pad = crate::IMAGE_BYTES - text.len() - 2;
        text.push(';');
        text.push_str(&"x".repeat(pad));
        text.push('\n');
        assert_eq!(text.len(), crate::IMAGE_BYTES);
        text
    }

    #[test]
    fn a_valid_plc_text_of_the_image_size_is_read_as_text() {
        let text = text_of_image_size();
        assert!(!is_eeprom_image(text.as_bytes()));
        let path =
            std::env::temp_dir().join(format!("hil-sim-run-{}-image-size.plc", std::process::id()));
        std::fs::write(&path, &text).unwrap();
        let read = load_program(&path);
        let any = load_any(&path);
        std::fs::remove_file(&path).unwrap();
        let want = assemble(&text).unwrap();
        assert!(
            read.unwrap() == want,
            "load_program: not the text's program"
        );
        assert!(any.unwrap() == want, "load_any: not the text's program");
    }

    #[test]
    fn an_image_is_still_read_as_an_image() {
        let program = assemble(LIFT_PLC).unwrap();
        let image = crate::image_bytes(&program).unwrap();
        assert_eq!(image.len(), crate::IMAGE_BYTES);
        assert!(is_eeprom_image(&image));
        assert!(program_from_image(&image).unwrap() == program);
    }
}
