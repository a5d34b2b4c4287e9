//! `hil-sim` command line (hil-sim.md "Commands"). Everything it does lives in the library.

use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};
use hil_sim::record::CsvWriter;
use hil_sim::run::{load_program, run_with};
use hil_sim::scenario::Scenario;
use hil_sim::sim::RunOptions;
use trend_plot::atomic::AtomicFile;

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
        #[command(flatten)]
        record: RecordArgs,
        #[command(flatten)]
        service: ServiceArgs,
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
        /// Attach the lift of lift.md 4 (default `[lift]` keys) to the shaft: run
        /// `shared-protocol/programs/lift.plc`, call with the digital keys.
        #[arg(long)]
        lift: bool,
        /// Serve the PLC's service port on a new pty (path on stderr and on the panel).
        #[arg(long)]
        service_pty: bool,
        /// The service version the simulated PLC announces.
        #[arg(long, default_value_t = shared_protocol::service::SERVICE_VERSION, requires = "service_pty")]
        service_version: u16,
    },
    /// The same run on the real firmware images, in an emulator of both boards.
    Emu {
        #[command(flatten)]
        record: RecordArgs,
        /// The drive's ELF (default: the release image in the workspace's target directory).
        #[arg(long)]
        drive_elf: Option<PathBuf>,
        /// The PLC's ELF (default: the release image in the workspace's target directory).
        #[arg(long)]
        plc_elf: Option<PathBuf>,
        /// Print both images' defmt logs, in virtual time.
        #[arg(long)]
        log: bool,
    },
    /// A seeded fault campaign on the cores (or, with --emu, on the release images):
    /// generated worlds, injected faults, invariants checked at every step
    /// (docs/campaign.md). Exits 3 when an invariant broke.
    Campaign {
        /// How many seeds (worlds) to run.
        #[arg(long)]
        seeds: u64,
        /// The first seed; seeds `first .. first + seeds` run.
        #[arg(long, default_value_t = 1)]
        first: u64,
        /// Worlds run in parallel (threads).
        #[arg(long, default_value_t = 1)]
        jobs: usize,
        /// Simulated seconds per world.
        #[arg(long, default_value_t = 2.0, value_parser = hil_sim::args::duration_s)]
        duration: f64,
        /// At most this many faults per world.
        #[arg(long, default_value_t = 6)]
        max_faults: u32,
        /// Report failing seeds without shrinking their fault lists.
        #[arg(long)]
        no_shrink: bool,
        /// Run each world on the exact release images in the emulator (as `emu`).
        #[arg(long)]
        emu: bool,
        /// With --emu: the drive's ELF (default: the release image in the target directory).
        #[arg(long, requires = "emu")]
        drive_elf: Option<PathBuf>,
        /// With --emu: the PLC's ELF (default: the release image in the target directory).
        #[arg(long, requires = "emu")]
        plc_elf: Option<PathBuf>,
    },
}

/// What `run` and `emu` share: the program, the scenario and the record.
#[derive(clap::Args)]
struct RecordArgs {
    /// The program (.plc text or an EEPROM image).
    program: PathBuf,
    /// Scenario file (TOML); without it all inputs stay 0.
    #[arg(long)]
    scenario: Option<PathBuf>,
    /// Simulated seconds (default: the scenario's duration_s, else 10; at most 1e6).
    #[arg(long, value_parser = hil_sim::args::duration_s)]
    duration: Option<f64>,
    /// Write the record as CSV.
    #[arg(long)]
    csv: Option<PathBuf>,
    /// Write a plot: PNG or SVG, by the file name's extension.
    #[arg(long)]
    plot: Option<PathBuf>,
    /// End of the plot's phase-current zoom (a few periods), s; default: the end.
    #[arg(long, value_parser = hil_sim::args::time_s)]
    zoom_at: Option<f64>,
    /// CSV sampling period, ms (0.001-60000).
    #[arg(long, default_value_t = 1.0, value_parser = hil_sim::args::sample_ms)]
    sample_ms: f64,
    /// Seed of the link's bit errors.
    #[arg(long, default_value_t = 1)]
    seed: u64,
}

/// The PLC's service port on a pseudo-terminal (service.md 9).
#[derive(clap::Args)]
struct ServiceArgs {
    /// Serve the PLC's service port on a new pty; its path is the first stderr line,
    /// `service: <path>`. The run waits for a first client at t = 0, then follows the wall
    /// clock to the end of the linger; clients may come and go (one at a time).
    #[arg(long)]
    service_pty: bool,
    /// After the duration, keep serving clients (inputs held) this long, s (at most 1e6).
    #[arg(long, default_value_t = 5.0, requires = "service_pty", value_parser = hil_sim::args::time_s)]
    service_linger: f64,
    /// Virtual seconds per wall-clock second while serving (0.1 to 100; 1 = real time).
    /// Above 1 for scripts and tests that wait for simulated events: the PLC's byte timing
    /// stays virtual, only the wait for it shortens.
    #[arg(long, default_value_t = 1.0, requires = "service_pty", value_parser = hil_sim::args::speed_factor)]
    service_speed: f64,
    /// The service version the simulated PLC announces (tests of version mismatch).
    #[arg(long, default_value_t = shared_protocol::service::SERVICE_VERSION)]
    service_version: u16,
}

impl ServiceArgs {
    /// The service line for a run, on a pty when asked; prints `service: <path>`.
    fn attach(&self, scen: &Scenario, seed: u64) -> Result<Option<hil_sim::service::Attached>> {
        use hil_sim::service::{line, Attached, PtyOptions, ServiceLine};
        let flood = scen.service_flood.then_some(seed ^ 0x5E4_71CE);
        if !self.service_pty && flood.is_none() {
            return Ok(None);
        }
        let line = ServiceLine::new(
            line::build_info(seed),
            shared_protocol::service::SERVICE_BAUD,
            self.service_version,
            flood,
        );
        if !self.service_pty {
            return Ok(Some(Attached::detached(line)));
        }
        if cfg!(not(unix)) {
            anyhow::bail!("--service-pty needs Linux or macOS");
        }
        let pty = hil_sim::service::pty::Pty::open()?;
        eprintln!("service: {}", pty.path().display());
        Ok(Some(Attached::on_pty(
            line,
            pty,
            PtyOptions {
                wait_for_client: true,
                linger: std::time::Duration::from_secs_f64(self.service_linger),
                pace_virtual_per_wall: Some(self.service_speed),
            },
        )))
    }
}

/// A run's inputs, checked.
struct Prepared {
    prog: shared_protocol::program::Program,
    scen: Scenario,
    duration_s: f64,
    opts: RunOptions,
}

impl RecordArgs {
    /// Everything is checked before anything is simulated: the program, the scenario,
    /// the duration, the sampling and the plot's file type (fail now, not after a long
    /// run).
    fn prepare(&self) -> Result<Prepared> {
        let prog = load_program(&self.program)?;
        let scen = match &self.scenario {
            Some(p) => Scenario::load(p)?,
            None => Scenario::default(),
        };
        let duration_s = scen.duration_s(self.duration);
        hil_sim::args::check_duration_s(duration_s)?;
        let sample_ns = sample_period_ns(self.sample_ms)?;
        if let Some(p) = &self.plot {
            hil_sim::plot::check_target(p)?;
        }
        Ok(Prepared {
            prog,
            scen,
            duration_s,
            opts: RunOptions {
                seed: self.seed,
                sample_ns,
            },
        })
    }

    /// The CSV file, if asked for, starting with `# board: <drive board>`.
    /// Written under a temporary name and renamed when the run succeeded: a failed run
    /// leaves the user's file as it was.
    fn csv_writer(&self, board: &str) -> Result<Option<CsvWriter<AtomicFile>>> {
        let Some(p) = &self.csv else {
            return Ok(None);
        };
        let file = AtomicFile::create(p)?;
        let comment = format!("board: {board}");
        Ok(Some(CsvWriter::with_comment(file, &comment).with_context(
            || format!("cannot write {}", p.display()),
        )?))
    }

    fn keep_samples(&self) -> hil_sim::decimate::KeepSamples {
        hil_sim::decimate::KeepSamples::for_plot(self.plot.is_some())
    }

    /// After the run: the CSV closed, the summary printed first (a plot that fails still
    /// leaves the run's result on screen), then the plot.
    fn finish(
        &self,
        csv: (Option<CsvWriter<AtomicFile>>, Option<std::io::Error>),
        summary: &str,
        samples: &[hil_sim::sim::Sample],
        title: &str,
        marks: hil_sim::plot::Marks,
    ) -> Result<()> {
        if std::io::stderr().is_terminal() {
            eprintln!();
        }
        let (writer, err) = csv;
        if let Some(e) = err {
            return Err(e).context("writing the CSV");
        }
        if let Some(w) = writer {
            w.finish().context("writing the CSV")?.commit()?;
        }
        print!("{summary}");
        if let Some(p) = &self.plot {
            let marks = hil_sim::plot::Marks {
                zoom_at_s: self.zoom_at,
                ..marks
            };
            hil_sim::plot::plot(p, samples, title, &marks)?;
        }
        Ok(())
    }

    /// The scenario as the plot's title names it.
    fn scenario_name(&self) -> String {
        self.scenario
            .as_deref()
            .map_or_else(|| "default".to_string(), |p| p.display().to_string())
    }
}

/// Exit status of `emu` when an image took a HardFault, locked up, or was reset by its
/// watchdog or by itself and the scenario does not expect it (`[emu] expect`): the run
/// itself completed and its outputs are written. Errors (bad input, I/O) exit with 1.
const EXIT_IMAGE_TROUBLE: u8 = 2;

fn main() -> ExitCode {
    // A bad argument exits 1 like any bad input (clap's own 2 is `emu`'s image trouble);
    // `--help` and `--version` exit 0.
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            let _ = e.print();
            return ExitCode::from(u8::from(e.use_stderr()));
        }
    };
    match real_main(cli) {
        Ok(code) => code,
        Err(e) => {
            eprintln!("hil-sim: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn real_main(cli: Cli) -> Result<ExitCode> {
    let done = |r: Result<()>| r.map(|()| ExitCode::SUCCESS);
    match cli.cmd {
        Cmd::Run { record, service } => done(cmd_run(&record, &service)),
        Cmd::Asm { program, output } => done(cmd_asm(&program, output.as_deref())),
        Cmd::Disasm { program } => done(cmd_disasm(&program)),
        Cmd::Panel {
            program,
            eeprom,
            lift,
            service_pty,
            service_version,
        } => done(hil_sim::panel_command(
            program.as_deref(),
            eeprom.as_deref(),
            lift,
            service_pty.then_some(service_version),
        )),
        Cmd::Emu {
            record,
            drive_elf,
            plc_elf,
            log,
        } => cmd_emu(&record, drive_elf.as_deref(), plc_elf.as_deref(), log),
        Cmd::Campaign {
            seeds,
            first,
            jobs,
            duration,
            max_faults,
            no_shrink,
            emu,
            drive_elf,
            plc_elf,
        } => cmd_campaign(
            hil_sim::campaign::CampaignOptions {
                first,
                seeds,
                jobs,
                world: hil_sim::campaign::world::WorldOptions {
                    duration_ns: (duration * 1e9).round() as u64,
                    max_faults,
                    ..Default::default()
                },
                shrink: !no_shrink,
            },
            emu.then_some((drive_elf, plc_elf)),
        ),
    }
}

/// Exit status of `campaign` when an invariant broke (the campaign itself completed).
const EXIT_VIOLATIONS: u8 = 3;

/// `emu`: on the images, with these ELFs (default: the release images).
type EmuElfs = (Option<PathBuf>, Option<PathBuf>);

fn cmd_campaign(
    opts: hil_sim::campaign::CampaignOptions,
    emu: Option<EmuElfs>,
) -> Result<ExitCode> {
    use hil_sim::campaign::{emu as on_images, render_failure_with, run_campaign_with, run_seed};
    use hil_sim::emu::images::{existing, Firmware};
    let images = match emu {
        Some((d, p)) => Some(on_images::EmuImages {
            drive: d.map_or_else(|| existing(Firmware::Drive), Ok)?,
            plc: p.map_or_else(|| existing(Firmware::Plc), Ok)?,
        }),
        None => None,
    };
    let flags = if images.is_some() { " --emu" } else { "" };
    let started = std::time::Instant::now();
    let run_one = |seed| match &images {
        Some(i) => on_images::run_seed(seed, &opts.world, opts.shrink, i),
        None => run_seed(seed, &opts.world, opts.shrink).map(Some),
    };
    let (summary, _) = run_campaign_with(&opts, run_one, |r| {
        if let Some(f) = &r.failure {
            let mut out = std::io::stdout().lock();
            let _ = write!(
                out,
                "{}",
                render_failure_with(r.seed, f, &opts.world, flags)
            );
            let _ = out.flush();
        }
    })?;
    println!("{}", summary.render());
    let wall = started.elapsed().as_secs_f64();
    println!(
        "wall {wall:.1} s on {} job(s), {:.1}x real time",
        opts.jobs.max(1),
        summary.sim_ns as f64 / 1e9 / wall.max(1e-9)
    );
    Ok(if summary.violations > 0 {
        ExitCode::from(EXIT_VIOLATIONS)
    } else {
        ExitCode::SUCCESS
    })
}

/// `--sample-ms` in ns. The co-simulation's clock is the cores' (`Micros`): nothing in it
/// happens on a finer grid than 1 us, so a finer record only repeats values (at 0.0001 ms
/// one simulated second was a 1.2 GB CSV). Refused below [`hil_sim::args::MIN_SAMPLE_MS`].
fn sample_period_ns(sample_ms: f64) -> Result<u64> {
    hil_sim::args::sample_ms(&sample_ms.to_string()).map_err(anyhow::Error::msg)?;
    Ok((sample_ms * 1e6).round() as u64)
}

fn cmd_run(a: &RecordArgs, svc: &ServiceArgs) -> Result<()> {
    let Prepared {
        prog,
        scen,
        duration_s,
        opts,
    } = a.prepare()?;
    let mut service = svc.attach(&scen, opts.seed)?;
    let mut writer = a.csv_writer(scen.rig.board.name)?;
    let mut csv_err = None;
    let tty = std::io::stderr().is_terminal();
    let report = run_with(
        &prog,
        scen,
        duration_s,
        opts,
        a.keep_samples(),
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
        service.as_mut(),
    )?;
    let title = format!(
        "{}, scenario {} ({duration_s} s)",
        a.program.display(),
        a.scenario_name()
    );
    a.finish(
        (writer, csv_err),
        &report.summary(),
        &report.samples,
        &title,
        report.marks.clone(),
    )?;
    if let Some(s) = service.as_mut() {
        std::io::stdout().flush()?;
        s.linger()?;
        let l = s.line();
        eprintln!(
            "service: {} bytes from the client, {} bytes from the PLC",
            l.host_bytes, l.plc_bytes
        );
    }
    Ok(())
}

/// `emu`: [`EXIT_IMAGE_TROUBLE`] when an image did what the scenario does not expect.
fn cmd_emu(
    a: &RecordArgs,
    drive_elf: Option<&Path>,
    plc_elf: Option<&Path>,
    log: bool,
) -> Result<ExitCode> {
    use hil_sim::emu::images::{existing, Firmware};
    let Prepared {
        prog,
        scen,
        duration_s,
        opts,
    } = a.prepare()?;
    let drive_elf = match drive_elf {
        Some(p) => p.to_path_buf(),
        None => existing(Firmware::Drive)?,
    };
    let plc_elf = match plc_elf {
        Some(p) => p.to_path_buf(),
        None => existing(Firmware::Plc)?,
    };
    for p in [&drive_elf, &plc_elf] {
        g431_emu::elf::Image::load(p)?;
    }
    // The emulated drive board is the one the drive image was built for.
    let board = hil_sim::emu::boards::image_board(&g431_emu::elf::Image::load(&drive_elf)?)
        .map_or("unknown (no DRIVE_BOARD_PROFILE marker)", |b| b.name());
    let mut writer = a.csv_writer(board)?;
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
        a.keep_samples(),
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
            if log {
                if tty {
                    eprint!("\r");
                }
                println!("{image:>5} {line}");
            }
        },
    )?;
    let title = format!(
        "{} on the real images, scenario {} ({duration_s} s)",
        a.program.display(),
        a.scenario_name()
    );
    let marks = hil_sim::plot::Marks {
        events: hil_sim::run::event_marks(&actions, &report.faults),
        ..Default::default()
    };
    a.finish(
        (writer, csv_err),
        &report.summary(),
        &report.samples,
        &title,
        marks,
    )?;
    if report.unexpected.is_empty() {
        return Ok(ExitCode::SUCCESS);
    }
    for l in &report.unexpected {
        eprintln!("hil-sim: {l}");
    }
    Ok(ExitCode::from(EXIT_IMAGE_TROUBLE))
}

fn cmd_asm(program: &Path, output: Option<&Path>) -> Result<()> {
    let p = load_program(program)?;
    match output {
        Some(out) => {
            let image = hil_sim::image_bytes(&p)?;
            trend_plot::atomic::write(out, &image)?;
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
