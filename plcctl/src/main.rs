//! `plcctl`: the PLC's service port from a PC (shared/spec/service.md part A, usage in
//! `shared-protocol/docs/service.md` "plcctl"). Exit codes: [`fail::Fail`].

mod args;
mod client;
mod clock;
mod detect;
mod diff;
mod fail;
mod faults;
mod interrupt;
mod program;
mod push;
mod serve;
mod status;
mod time_of_day;
mod trend;

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};
use shared_protocol::service::{Answer, Request, SERVICE_BAUD};

use client::{unexpected, Client};
use fail::{Fail, Result};

#[derive(Parser)]
#[command(name = "plcctl", version, about = "The PLC's service port from a PC")]
struct Cli {
    /// Serial port (default: the one ST-LINK/V3 virtual COM port).
    #[arg(long, global = true)]
    port: Option<String>,
    /// Line rate; must match the PLC's (115200); 300-4000000.
    #[arg(long, global = true, default_value_t = SERVICE_BAUD, value_parser = args::baud)]
    baud: u32,
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// One-shot status.
    Status {
        #[arg(long)]
        json: bool,
    },
    /// Terminal view at 10 Hz: LCD, values, I/O, newest faults (Ctrl-C ends).
    Watch {
        /// Stop after this many seconds (default: never; at most a year).
        #[arg(long, value_parser = args::duration_s)]
        duration: Option<f64>,
    },
    /// Record samples as CSV with hil-sim's column names (Ctrl-C ends it like --duration).
    Trend {
        #[arg(long)]
        csv: PathBuf,
        /// Also draw them (PNG or SVG by the extension) with hil-sim's plot.
        #[arg(long)]
        plot: Option<PathBuf>,
        /// Sample period, 10-100 ms.
        #[arg(long, default_value_t = 10)]
        period_ms: u16,
        /// Seconds to record (default: until Ctrl-C; at most a year).
        #[arg(long, value_parser = args::duration_s)]
        duration: Option<f64>,
        /// Up to 8 Q variables, e.g. Q04,Q05 (default Q00-Q07).
        #[arg(long, value_delimiter = ',')]
        q: Vec<String>,
    },
    /// The fault log, newest first.
    Faults {
        #[arg(long, conflicts_with = "json")]
        csv: bool,
        #[arg(long)]
        json: bool,
        /// The application profile (TOML, as `serve`'s): the texts of the application's
        /// faults and the names of the log's two values.
        #[arg(long)]
        profile: Option<PathBuf>,
    },
    /// The PLC's counters.
    Counters {
        #[arg(long)]
        json: bool,
    },
    /// A program in canonical text; slot 0 = the program in RAM.
    Pull {
        #[arg(value_parser = args::any_slot)]
        slot: u8,
        /// Output file (default: stdout).
        #[arg(short = 'o', long = "output")]
        output: Option<PathBuf>,
    },
    /// Assemble, verify, show the diff, write into a slot, read back (remote service on,
    /// PLC in STOP).
    Push {
        file: PathBuf,
        /// 1-4.
        #[arg(long, value_parser = args::stored_slot)]
        slot: u8,
        /// Write without asking.
        #[arg(long)]
        yes: bool,
    },
    /// RUN (remote service on): the program in RAM, or slot n loaded first.
    Run {
        #[arg(long, default_value_t = 0, value_parser = args::any_slot)]
        slot: u8,
    },
    /// STOP (always allowed).
    Stop,
    /// Acknowledge the drive's fault (keys * 9; remote service on).
    Ack,
    /// Erase the fault log (remote service on, PLC in STOP).
    ClearFaults,
    /// The PLC's clock (UTC, and this PC's local time) and its offset to this PC; `clock
    /// set` sets it.
    Clock {
        #[command(subcommand)]
        set: Option<ClockCmd>,
    },
    /// The web monitor: one page, a JSON API and an event stream (plcctl/docs/serve.md).
    Serve {
        /// Address and port; port 0 picks a free one. Off loopback a token is required.
        #[arg(long, default_value = "127.0.0.1:8080")]
        bind: String,
        /// The application profile (TOML): names, lift mimic, state texts, counters.
        #[arg(long)]
        profile: Option<PathBuf>,
        /// A file holding the access token (at least 32 characters; default off
        /// loopback: a random one, printed). Also `PLCCTL_TOKEN` in the environment.
        #[arg(long)]
        token_file: Option<PathBuf>,
        /// Refused: a token on the command line is visible to every user in `ps`.
        #[arg(long, hide = true)]
        token: Option<String>,
        /// Another name the server answers to (its `Host`), e.g. the machine's DNS
        /// name off loopback; repeatable. Always: `localhost`, `127.0.0.1`, `[::1]`, the bind
        /// address.
        #[arg(long = "host")]
        hosts: Vec<String>,
        /// Append the access and action log to this file too (always on stderr).
        #[arg(long)]
        log: Option<PathBuf>,
    },
}

#[derive(Subcommand)]
enum ClockCmd {
    /// Set the PLC's clock (never guarded): to this PC's UTC time, or to --time.
    Set {
        /// RFC 3339 (2026-11-29T11:00:00+01:00), or YYYY-MM-DD HH:MM:SS in UTC.
        #[arg(long, value_parser = time_of_day::parse_time)]
        time: Option<chrono::DateTime<chrono::Utc>>,
    },
}

fn main() -> ExitCode {
    // A bad argument is a usage error, exit 1 (clap's own code, 2, means "no device"
    // here); `--help` and `--version` exit 0.
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            let _ = e.print();
            return ExitCode::from(u8::from(e.use_stderr()));
        }
    };
    match real_main(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("plcctl: {e}");
            ExitCode::from(e.exit_code())
        }
    }
}

fn real_main(cli: Cli) -> Result<()> {
    let port = detect::port(cli.port.as_deref())?;
    let baud = cli.baud;
    let connect = || Client::connect(&port, baud);
    match cli.cmd {
        Cmd::Status { json } => status::status(&mut connect()?, json),
        Cmd::Watch { duration } => status::watch(connect, duration),
        Cmd::Trend {
            csv,
            plot,
            period_ms,
            duration,
            q,
        } => trend::trend(
            connect,
            &trend::TrendArgs {
                csv: &csv,
                plot: plot.as_deref(),
                period_ms,
                duration,
                q: &q,
                port: &port,
            },
        ),
        Cmd::Faults { csv, json, profile } => {
            let profile = match profile {
                Some(p) => serve::profile::Profile::load(&p)?,
                None => serve::profile::Profile::default(),
            };
            faults::faults(&mut connect()?, csv, json, &profile)
        }
        Cmd::Counters { json } => status::counters(&mut connect()?, json),
        Cmd::Pull { slot, output } => program::pull(&mut connect()?, slot, output.as_deref()),
        Cmd::Push { file, slot, yes } => push::push(connect, &file, slot, yes),
        Cmd::Run { slot } => done(&mut connect()?, Request::Run { slot }, "RUN requested"),
        Cmd::Stop => done(&mut connect()?, Request::Stop, "STOP"),
        Cmd::Ack => done(&mut connect()?, Request::Ack, "acknowledge sent"),
        Cmd::ClearFaults => done(&mut connect()?, Request::ClearFaultLog, "fault log cleared"),
        Cmd::Clock { set: None } => time_of_day::clock(&mut connect()?),
        Cmd::Clock {
            set: Some(ClockCmd::Set { time }),
        } => time_of_day::clock_set(&mut connect()?, time),
        Cmd::Serve {
            bind,
            profile,
            token_file,
            token,
            hosts,
            log,
        } => {
            let token = serve_token(token_file.as_deref(), token.is_some())?;
            let plc_port = port.clone();
            serve::serve(
                move || Client::connect(&plc_port, baud),
                serve::ServeArgs {
                    bind,
                    profile,
                    token,
                    hosts,
                    log,
                    port,
                },
            )
        }
    }
}

/// `serve`'s token: from `--token-file` (its first line), else `PLCCTL_TOKEN`, never from
/// the command line; checked by [`serve::access::check_token`].
fn serve_token(file: Option<&std::path::Path>, on_command_line: bool) -> Result<Option<String>> {
    if on_command_line {
        return Err(usage(
            "--token is refused: the command line is visible to every user (ps); \
             put the token in a file (--token-file F) or in PLCCTL_TOKEN",
        ));
    }
    let (token, source) = match file {
        Some(f) => {
            let text = std::fs::read_to_string(f)
                .map_err(|e| usage(format!("cannot read the token file {}: {e}", f.display())))?;
            let first = text.lines().next().unwrap_or("").trim().to_string();
            (first, format!("{}", f.display()))
        }
        None => match std::env::var("PLCCTL_TOKEN") {
            Ok(t) => (t, "PLCCTL_TOKEN".to_string()),
            Err(std::env::VarError::NotPresent) => return Ok(None),
            Err(e) => return Err(usage(format!("PLCCTL_TOKEN: {e}"))),
        },
    };
    serve::access::check_token(&token).map_err(|e| usage(format!("{source}: {e}")))?;
    Ok(Some(token))
}

/// A request answered `Done` (refusals: exit 5).
fn done(c: &mut Client, req: Request, text: &str) -> Result<()> {
    match c.ask(req)? {
        Answer::Done => {
            println!("{text}");
            Ok(())
        }
        other => Err(unexpected(text, &other)),
    }
}

/// `Fail::Usage` from a message.
fn usage(msg: impl std::fmt::Display) -> Fail {
    Fail::Usage(anyhow::anyhow!("{msg}"))
}
