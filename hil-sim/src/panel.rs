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
pub mod keys;
pub mod sim_backend;
pub mod ui;

use std::path::Path;
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use firmware_plc::storage::image::{is_image, program_from_image};
use ratatui::crossterm::event::{self, Event, KeyEventKind};
use shared_protocol::program::{assemble, Program};

pub use app::PanelApp;
pub use sim_backend::{RigStatus, SimBackend};

/// Read a program from a `.plc` text or an EEPROM image.
pub fn read_program(path: &Path) -> Result<Program> {
    let bytes = std::fs::read(path).with_context(|| format!("cannot read {}", path.display()))?;
    if is_image(&bytes) {
        return program_from_image(&bytes)
            .map_err(|e| anyhow::anyhow!("{}: not a valid EEPROM image: {e:?}", path.display()));
    }
    let text = String::from_utf8(bytes)
        .with_context(|| format!("{}: neither text nor an EEPROM image", path.display()))?;
    assemble(&text).map_err(|e| anyhow::anyhow!("{}:{e}", path.display()))
}

/// Run the panel until Esc / Ctrl-C.
pub fn run(program: Option<&Path>) -> Result<()> {
    let program = program.map(read_program).transpose()?;
    let mut app = PanelApp::new(SimBackend::new(program.as_ref())?);
    let mut terminal = ratatui::init();
    let result = event_loop(&mut terminal, &mut app);
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
                    if let Some(input) = keys::map_key(k) {
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
