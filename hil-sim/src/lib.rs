//! hil-sim: runs the firmware cores against a simulated plant in virtual time.
//!
//! * [`plant`]: DC link, inverter, induction motor, sensors, comparators.
//! * [`mcu`]: the two MCUs (the firmware's cores behind one seam per peripheral).
//! * [`emu`]: the same runs on the real firmware images, in an emulator of both boards.
//! * [`panel`]: the interactive front panel (`hil-sim panel`).
//! * [`sim`]: the virtual-time scheduler joining them with the UART wires.
//! * [`scenario`]: scenario files; [`record`]: the CSV; [`plot`]: the PNG;
//!   [`run`]: one whole run as the CLI does it; [`latency`]: `WR Q` latency end to end;
//!   [`service`]: the PLC's service port on a pty (`--service-pty`);
//!   [`lab`]: the source's lab chapter (ramp times, current ripple), `docs/lab.md`.
//!
//! [`emu`], [`panel`] and [`plot`] are the default features of the same names (what each
//! brings in: `Cargo.toml`); without them the library still parses scenarios and runs the
//! cores on the plant.
//!
//! Decisions and model equations: `hil-sim/docs/`.

pub mod args;
pub mod campaign;
pub mod decimate;
#[cfg(feature = "emu")]
pub mod emu;
pub mod lab;
pub mod latency;
pub mod mcu;
#[cfg(feature = "panel")]
pub mod panel;
pub mod plant;
#[cfg(feature = "plot")]
pub mod plot;
pub mod record;
pub mod run;
pub mod scenario;
pub mod service;
pub mod sim;
pub mod tim1;

#[cfg(feature = "panel")]
use std::path::Path;

/// Size of the EEPROM image `asm -o` writes.
pub const IMAGE_BYTES: usize = firmware_plc::storage::EEPROM_BYTES;

/// The exact EEPROM bytes the PLC would store for `program` (slot 1, RUN at power-up).
pub fn image_bytes(program: &shared_protocol::program::Program) -> anyhow::Result<Vec<u8>> {
    let image = firmware_plc::storage::image::program_image(
        program,
        &firmware_plc::storage::image::ImageOptions::default(),
    )
    .map_err(|e| anyhow::anyhow!("cannot build the EEPROM image: {e:?}"))?;
    Ok(image.to_vec())
}

/// `hil-sim panel`: the interactive front panel.
/// `lift`: the lift plant on the shaft (`--lift`, lift.md 4).
/// `service_version`: with `--service-pty`, the service port on a pty announcing it.
#[cfg(feature = "panel")]
pub fn panel_command(
    program: Option<&Path>,
    eeprom: Option<&Path>,
    lift: bool,
    service_version: Option<u16>,
) -> anyhow::Result<()> {
    use std::io::IsTerminal;
    // Bad files first, with or without a terminal (nothing is created or changed yet).
    if let Some(p) = program {
        panel::read_program(p)?;
    }
    if let Some(e) = eeprom {
        panel::files::read_eeprom_image(e)?;
    }
    // ratatui panics without a terminal (piped stdin, CI, ssh without -t): say so instead.
    if !(std::io::stdin().is_terminal() && std::io::stdout().is_terminal()) {
        anyhow::bail!(
            "panel needs an interactive terminal on stdin and stdout (ssh -t, no pipes); \
             for scripted runs use `hil-sim run`"
        );
    }
    match service_version {
        Some(v) => panel::run_with_service(program, eeprom, lift, v),
        None => panel::run(program, eeprom, lift),
    }
}
