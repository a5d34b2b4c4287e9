//! `hil-sim panel`: the virtual front panel in the terminal.
//!
//! The LCD is drawn as the PLC's 20x4 display (cursor and blink included), the keypad is
//! the PC keyboard (same characters; arrows and Enter as `2/4/6/8` and `5`), and the rig
//! beside it shows frequency, speed, faults and the digital/analog I/O, which keys
//! toggle. The panel runs the whole co-simulation ([`SimBackend`]): its keys go to the
//! simulator's PLC board, i.e. the firmware's `PlcApp` with its debouncing and editor, as
//! a scenario's keys do (no key handling of its own).
//!
//! Simulated time follows the wall clock (at most 100 ms per frame).

pub mod app;
pub mod files;
pub mod keys;
pub mod rms;
pub mod sim_backend;
pub mod ui;

use std::path::Path;
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use firmware_plc::storage::image::program_from_image;
use ratatui::crossterm::event::{self, Event, KeyEventKind};
use shared_protocol::program::{assemble, Program};

pub use app::PanelApp;
pub use sim_backend::{RigStatus, SimBackend};

/// Read a program from a `.plc` text or an EEPROM image.
pub fn read_program(path: &Path) -> Result<Program> {
    let bytes = std::fs::read(path).with_context(|| format!("cannot read {}", path.display()))?;
    if crate::run::is_eeprom_image(&bytes) {
        return program_from_image(&bytes).map_err(|e| {
            anyhow::anyhow!(
                "{}: an EEPROM image without a program to load: {}",
                path.display(),
                crate::run::storage_error_text(e)
            )
        });
    }
    let text = String::from_utf8(bytes)
        .with_context(|| format!("{}: neither text nor an EEPROM image", path.display()))?;
    assemble(&text).map_err(|e| anyhow::anyhow!("{}:{e}", path.display()))
}

/// The panel with `program_path` (if any) and the EEPROM in `eeprom` (if any, else in
/// memory), before the terminal is touched: every file error is reported here.
pub fn open(program_path: Option<&Path>, eeprom: Option<&Path>) -> Result<PanelApp> {
    open_with(program_path, eeprom, false, None)
}

/// [`open`], with the lift of lift.md 4 on the shaft when `lift` (`--lift`), and the PLC's service port served through `service`
/// (`--service-pty`, whose path the notice line shows).
pub fn open_with(
    program_path: Option<&Path>,
    eeprom: Option<&Path>,
    lift: bool,
    service: Option<(crate::service::Attached, String)>,
) -> Result<PanelApp> {
    let program = program_path.map(read_program).transpose()?;
    let (mut backend, mut note) = match eeprom {
        Some(path) => SimBackend::with_eeprom_file(program.as_ref(), path, lift)?,
        None if lift => (SimBackend::new_lift(program.as_ref())?, None),
        None => (SimBackend::new(program.as_ref())?, None),
    };
    if let Some((svc, path)) = service {
        backend.attach_service(svc);
        let line = format!("service: {path}");
        note = Some(match note {
            Some(n) => format!("{line}; {n}"),
            None => line,
        });
    }
    let mut app = PanelApp::new(backend);
    app.notice = note;
    let stem = program_path
        .and_then(|p| p.file_stem())
        .map_or("program".into(), |s| s.to_string_lossy().into_owned());
    app.export_default = files::export_name(Path::new("."), &stem);
    if let Some(name) = app
        .export_default
        .strip_prefix(".")
        .ok()
        .map(Path::to_path_buf)
    {
        app.export_default = name;
    }
    Ok(app)
}

/// Run the panel until it is quit (Esc / Ctrl-C, confirmed when the program is unsaved).
pub fn run(program: Option<&Path>, eeprom: Option<&Path>, lift: bool) -> Result<()> {
    let mut app = open_with(program, eeprom, lift, None)?;
    run_app(&mut app)
}

/// [`run`] with the service port on a new pty (service.md 9): its path goes to stderr
/// before the panel takes the terminal, and on the panel's notice line.
pub fn run_with_service(
    program: Option<&Path>,
    eeprom: Option<&Path>,
    lift: bool,
    service_version: u16,
) -> Result<()> {
    use crate::service::{line, pty::Pty, Attached, PtyOptions, ServiceLine};
    let pty = Pty::open()?;
    let path = pty.path().display().to_string();
    eprintln!("service: {path}");
    let line = ServiceLine::new(
        line::build_info(1),
        shared_protocol::service::SERVICE_BAUD,
        service_version,
        None,
    );
    let opts = PtyOptions {
        wait_for_client: false,
        linger: Duration::ZERO,
        pace_virtual_per_wall: None,
    };
    let mut app = open_with(
        program,
        eeprom,
        lift,
        Some((Attached::on_pty(line, pty, opts), path)),
    )?;
    run_app(&mut app)
}

/// Run `app` in the terminal until it is quit.
pub fn run_app(app: &mut PanelApp) -> Result<()> {
    let mut terminal = ratatui::init();
    let result = event_loop(&mut terminal, app);
    ratatui::restore();
    result
}

fn event_loop(terminal: &mut ratatui::DefaultTerminal, app: &mut PanelApp) -> Result<()> {
    let mut last = Instant::now();
    while !app.quit {
        terminal.draw(|f| ui::draw(f, app))?;
        if event::poll(Duration::from_millis(25))? {
            if let Event::Key(k) = event::read()? {
                if k.kind != KeyEventKind::Release {
                    if app.modal.is_some() {
                        if let Some(t) = keys::map_text_key(k) {
                            app.modal_key(t);
                        }
                    } else if let Some(input) = keys::map_key(k) {
                        app.input(input);
                    }
                }
            }
        }
        let now = Instant::now();
        let dt = now.duration_since(last).as_millis().min(100) as u32;
        if dt > 0 {
            app.advance(dt);
            last = now;
        }
    }
    Ok(())
}
