//! `hil-sim` command line (hil-sim.md "Commands"). Everything it does lives in the library.

use std::fs::File;
use std::io::{BufWriter, IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};
use hil_sim::record::CsvWriter;
use hil_sim::run::{load_program, run};
use hil_sim::scenario::Scenario;
use hil_sim::sim::RunOptions;

#[derive(Parser)]
#[command(
    name = "hil-sim",
    version,
    about = "Co-simulates the PLC and drive firmware cores with an induction-motor rig"
)]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// Run a program on the simulated rig.
    Run {
        /// The program (.plc text or an EEPROM image).
        program: PathBuf,
        /// Scenario file (TOML); without it all inputs stay 0.
        #[arg(long)]
        scenario: Option<PathBuf>,
        /// Simulated seconds (default: the scenario's duration_s, else 10).
        #[arg(long)]
        duration: Option<f64>,
        /// Write the record as CSV.
        #[arg(long)]
        csv: Option<PathBuf>,
        /// Write a plot: PNG or SVG, by the file name's extension.
        #[arg(long)]
        plot: Option<PathBuf>,
        /// End of the plot's phase-current zoom (a few periods), s; default: the end.
        #[arg(long)]
        zoom_at: Option<f64>,
        /// CSV sampling period, ms.
        #[arg(long, default_value_t = 1.0)]
        sample_ms: f64,
        /// Seed of the link's bit errors.
        #[arg(long, default_value_t = 1)]
        seed: u64,
    },
    /// Assemble a program: print errors, or write the EEPROM image with -o.
    Asm {
        program: PathBuf,
        #[arg(short = 'o', long = "output")]
        output: Option<PathBuf>,
    },
    /// Print a program (.plc or EEPROM image) in canonical text.
    Disasm { program: PathBuf },
    /// Interactive virtual front panel (LCD + keypad) in the terminal.
    Panel {
        program: Option<PathBuf>,
        /// The 24C256 image that keeps the saved slots between sessions (created if
        /// absent; 32 KiB, as `asm -o` writes). Without it the EEPROM lives in memory.
        #[arg(long)]
        eeprom: Option<PathBuf>,
    },
    /// The same run on the real firmware images, in an emulator of both boards.
    Emu {
        /// The program (.plc text or an EEPROM image).
        program: PathBuf,
        /// Scenario file (TOML); without it all inputs stay 0.
        #[arg(long)]
        scenario: Option<PathBuf>,
        /// Simulated seconds (default: the scenario's duration_s, else 10).
        #[arg(long)]
        duration: Option<f64>,
        /// Write the record as CSV (the columns of `run`).
        #[arg(long)]
        csv: Option<PathBuf>,
        /// Write a plot: PNG or SVG, by the file name's extension.
        #[arg(long)]
        plot: Option<PathBuf>,
        /// End of the plot's phase-current zoom (a few periods), s; default: the end.
        #[arg(long)]
        zoom_at: Option<f64>,
        /// The drive's ELF (default: the release image in the workspace's target directory).
        #[arg(long)]
        drive_elf: Option<PathBuf>,
        /// The PLC's ELF (default: the release image in the workspace's target directory).
        #[arg(long)]
        plc_elf: Option<PathBuf>,
        /// Print both images' defmt logs, in virtual time.
        #[arg(long)]
        log: bool,
        /// CSV sampling period, ms.
        #[arg(long, default_value_t = 1.0)]
        sample_ms: f64,
        /// Seed of the link's bit errors.
        #[arg(long, default_value_t = 1)]
        seed: u64,
    },
}

fn main() -> ExitCode {
    match real_main() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("hil-sim: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn real_main() -> Result<()> {
    match Cli::parse().cmd {
        Cmd::Run {
            program,
            scenario,
            duration,
            csv,
            plot,
            zoom_at,
            sample_ms,
            seed,
        } => cmd_run(
            &program,
            scenario.as_deref(),
            duration,
            csv.as_deref(),
            (plot.as_deref(), zoom_at),
            sample_ms,
            seed,
        ),
        Cmd::Asm { program, output } => cmd_asm(&program, output.as_deref()),
        Cmd::Disasm { program } => cmd_disasm(&program),
        Cmd::Panel { program, eeprom } => {
            hil_sim::panel_command(program.as_deref(), eeprom.as_deref())
        }
        Cmd::Emu {
            program,
            scenario,
            duration,
            csv,
            plot,
            zoom_at,
            drive_elf,
            plc_elf,
            log,
            sample_ms,
            seed,
        } => cmd_emu(EmuArgs {
            program: &program,
            scenario: scenario.as_deref(),
            duration,
            csv: csv.as_deref(),
            plot: plot.as_deref(),
            zoom_at,
            drive_elf: drive_elf.as_deref(),
            plc_elf: plc_elf.as_deref(),
            log,
            sample_ms,
            seed,
        }),
    }
}

/// `--sample-ms` in ns. The co-simulation's clock is the cores' (`Micros`): nothing in it
/// happens on a finer grid than 1 us, so a finer record only repeats values (at 0.0001 ms
/// one simulated second was a 1.2 GB CSV). Refused below [`MIN_SAMPLE_MS`].
fn sample_period_ns(sample_ms: f64) -> Result<u64> {
    if !(sample_ms.is_finite() && sample_ms >= MIN_SAMPLE_MS) {
        anyhow::bail!(
            "--sample-ms must be at least {MIN_SAMPLE_MS} (1 us, the simulation's time step), got {sample_ms}"
        );
    }
    Ok((sample_ms * 1e6).round() as u64)
}

const MIN_SAMPLE_MS: f64 = 0.001;

/// The scenario as the plot's title names it.
fn scenario_name(path: Option<&Path>) -> String {
    path.map_or_else(|| "default".to_string(), |p| p.display().to_string())
}

fn cmd_run(
    program: &Path,
    scenario: Option<&Path>,
    duration: Option<f64>,
    csv: Option<&Path>,
    (plot, zoom_at): (Option<&Path>, Option<f64>),
    sample_ms: f64,
    seed: u64,
) -> Result<()> {
    // Everything is checked before anything is simulated.
    let prog = load_program(program)?;
    let scen = match scenario {
        Some(p) => Scenario::load(p)?,
        None => Scenario::default(),
    };
    let duration_s = scen.duration_s(duration);
    if !(duration_s.is_finite() && duration_s > 0.0) {
        anyhow::bail!("--duration must be a positive number of seconds, got {duration_s}");
    }
    let sample_ns = sample_period_ns(sample_ms)?;
    let opts = RunOptions { seed, sample_ns };
    if let Some(p) = plot {
        // Fail now, not after a long run.
        hil_sim::plot::check_target(p)?;
    }
    let mut writer = match csv {
        Some(p) => Some(
            CsvWriter::new(BufWriter::new(
                File::create(p).with_context(|| format!("cannot create {}", p.display()))?,
            ))
            .with_context(|| format!("cannot write {}", p.display()))?,
        ),
        None => None,
    };
    let mut csv_err = None;
    let tty = std::io::stderr().is_terminal();
    let report = run(
        &prog,
        scen,
        duration_s,
        opts,
        hil_sim::decimate::KeepSamples::for_plot(plot.is_some()),
        |s| {
            if let Some(w) = writer.as_mut() {
                if let Err(e) = w.write(s) {
                    csv_err.get_or_insert(e);
                }
            }
        },
        |t| {
            if tty {
                eprint!("\r{t:8.1} / {duration_s:.1} s simulated");
                let _ = std::io::stderr().flush();
            }
        },
    )?;
    if tty {
        eprintln!();
    }
    if let Some(e) = csv_err {
        return Err(e).context("writing the CSV");
    }
    if let Some(w) = writer {
        w.finish().context("writing the CSV")?;
    }
    // The summary first: a plot that fails still leaves the run's result on screen.
    print!("{}", report.summary());
    if let Some(p) = plot {
        let title = format!(
            "{}, scenario {} ({duration_s} s)",
            program.display(),
            scenario_name(scenario)
        );
        let marks = hil_sim::plot::Marks {
            zoom_at_s: zoom_at,
            ..report.marks.clone()
        };
        hil_sim::plot::plot(p, &report.samples, &title, &marks)?;
    }
    Ok(())
}

struct EmuArgs<'a> {
    program: &'a Path,
    scenario: Option<&'a Path>,
    duration: Option<f64>,
    csv: Option<&'a Path>,
    plot: Option<&'a Path>,
    zoom_at: Option<f64>,
    drive_elf: Option<&'a Path>,
    plc_elf: Option<&'a Path>,
    log: bool,
    sample_ms: f64,
    seed: u64,
}

fn cmd_emu(a: EmuArgs<'_>) -> Result<()> {
    use hil_sim::emu::images::{existing, Firmware};
    // Everything is checked before anything is emulated.
    let prog = load_program(a.program)?;
    let scen = match a.scenario {
        Some(p) => Scenario::load(p)?,
        None => Scenario::default(),
    };
    let duration_s = scen.duration_s(a.duration);
    if !(duration_s.is_finite() && duration_s > 0.0) {
        anyhow::bail!("--duration must be a positive number of seconds, got {duration_s}");
    }
    let sample_ns = sample_period_ns(a.sample_ms)?;
    let drive_elf = match a.drive_elf {
        Some(p) => p.to_path_buf(),
        None => existing(Firmware::Drive)?,
    };
    let plc_elf = match a.plc_elf {
        Some(p) => p.to_path_buf(),
        None => existing(Firmware::Plc)?,
    };
    for p in [&drive_elf, &plc_elf] {
        g431_emu::elf::Image::load(p)?;
    }
    let opts = RunOptions {
        seed: a.seed,
        sample_ns,
    };
    if let Some(p) = a.plot {
        hil_sim::plot::check_target(p)?;
    }
    let mut writer = match a.csv {
        Some(p) => Some(
            CsvWriter::new(BufWriter::new(
                File::create(p).with_context(|| format!("cannot create {}", p.display()))?,
            ))
            .with_context(|| format!("cannot write {}", p.display()))?,
        ),
        None => None,
    };
    let mut csv_err = None;
    let tty = std::io::stderr().is_terminal();
    let mut last_progress = 0.0;
    let actions = scen.actions.clone();
    let report = hil_sim::emu::run::run(
        &drive_elf,
        &plc_elf,
        &prog,
        scen,
        duration_s,
        opts,
        hil_sim::decimate::KeepSamples::for_plot(a.plot.is_some()),
        |s| {
            if let Some(w) = writer.as_mut() {
                if let Err(e) = w.write(s) {
                    csv_err.get_or_insert(e);
                }
            }
            let t = s.t_ns as f64 * 1e-9;
            if tty && t - last_progress >= 0.1 {
                last_progress = t;
                eprint!("\r{t:8.1} / {duration_s:.1} s emulated");
                let _ = std::io::stderr().flush();
            }
        },
        |image, line| {
            if a.log {
                if tty {
                    eprint!("\r");
                }
                println!("{image:>5} {line}");
            }
        },
    )?;
    if tty {
        eprintln!();
    }
    if let Some(e) = csv_err {
        return Err(e).context("writing the CSV");
    }
    if let Some(w) = writer {
        w.finish().context("writing the CSV")?;
    }
    print!("{}", report.summary());
    if let Some(p) = a.plot {
        let title = format!(
            "{} on the real images, scenario {} ({duration_s} s)",
            a.program.display(),
            scenario_name(a.scenario)
        );
        let marks = hil_sim::plot::Marks {
            events: hil_sim::run::event_marks(&actions, &report.faults),
            zoom_at_s: a.zoom_at,
            ..Default::default()
        };
        hil_sim::plot::plot(p, &report.samples, &title, &marks)?;
    }
    Ok(())
}

fn cmd_asm(program: &Path, output: Option<&Path>) -> Result<()> {
    let p = load_program(program)?;
    match output {
        Some(out) => {
            let image = hil_sim::image_bytes(&p)?;
            std::fs::write(out, image)
                .with_context(|| format!("cannot write {}", out.display()))?;
            println!(
                "{}: {} lines, EEPROM image ({} bytes) written to {}",
                program.display(),
                p.lines.iter().flatten().count(),
                hil_sim::IMAGE_BYTES,
                out.display()
            );
        }
        None => println!(
            "{}: ok, {} lines",
            program.display(),
            p.lines.iter().flatten().count()
        ),
    }
    Ok(())
}

fn cmd_disasm(program: &Path) -> Result<()> {
    let p = hil_sim::run::load_any(program)?;
    let mut text = String::new();
    shared_protocol::program::disassemble(&p, &mut text)
        .map_err(|_| anyhow::anyhow!("cannot format the program"))?;
    print!("{text}");
    // Shown so that it can be fixed, but a program the PLC would refuse is an error.
    shared_protocol::program::verify(&p).map_err(|e| {
        anyhow::anyhow!(
            "{}: the PLC would refuse this program: {e}",
            program.display()
        )
    })?;
    Ok(())
}
