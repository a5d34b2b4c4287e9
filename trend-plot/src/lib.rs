//! The plot of a run (PNG or SVG, by the file's extension): frequency, speed, phase
//! currents, line voltage a-b (PWM-period average), DC-link voltage, and the fault /
//! brake / PWM signals, on a shared time axis. Each panel names its traces and their
//! colours in its caption, so no legend box covers a trace. The file is written under a
//! temporary name and renamed when complete: a failed plot never leaves a partial or
//! empty file behind.
//!
//! One plot for simulated and real runs (service.md 8): hil-sim's `--plot` and plcctl's
//! `trend --plot` both hand their rows over as [`Row`]s, which answer the [`Column`]s
//! they have. A panel is drawn when some row has one of its traces, so a record of the
//! real PLC (no speed, no phase currents, no PWM duties) gets the frequency, its
//! `imx_a` in the current panel, the DC link and the fault code, and the same axes,
//! colours and captions as a simulation.
//!
//! Text is drawn with a font shipped in the crate (DejaVu Sans Mono, `assets/`), through
//! plotters' `ab_glyph` backend: no fontconfig or FreeType needed on the machine.
//!
//! [`atomic`]: the same rule for the other output files of both tools (CSV, images):
//! a file the user had is replaced only when the new one is complete.
//!
//! The drawing ([`plot`], plotters) is the default feature `draw`; without it the crate is
//! the record's vocabulary ([`Column`], [`Row`], [`Marks`], [`PlotFormat`]), which a
//! library that reports a run's marks needs without drawing them (hil-sim without its
//! `plot` feature, for the fuzz targets).

pub mod atomic;
#[cfg(feature = "draw")]
mod draw;

use std::path::Path;

use anyhow::{anyhow, Result};
#[cfg(feature = "draw")]
pub use draw::plot;

/// The quantities the plot draws, by hil-sim's CSV column names.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Column {
    /// `f_cmd_hz`, Hz.
    FCmdHz,
    /// `dir`: +1 or -1.
    Dir,
    /// `speed_rpm`.
    SpeedRpm,
    /// `i_a_a`, `i_b_a`, `i_c_a`, A.
    IA,
    IB,
    IC,
    /// `imx_a`: the drive's largest phase current amplitude as it reports it, A.
    ImxA,
    /// `u_ab_v`, V.
    UAbV,
    /// `u_dc_v`, V.
    UDcV,
    /// `fault`: the latched code, 0 = none.
    Fault,
    /// `brake`: 0/1.
    Brake,
    /// `pwm_on`: 0/1.
    PwmOn,
    /// `car_mm` (the lift).
    CarMm,
}

/// One row of a record: its time and the columns it has (`None`: not in this record, or
/// unknown at that instant, e.g. the drive's values while the link is down).
pub trait Row {
    fn t_s(&self) -> f64;
    fn get(&self, c: Column) -> Option<f64>;
}

/// What is drawn over the traces: limits as dashed horizontal lines (and named in the
/// panel's caption, also when they are off the scale), events as vertical markers.
#[derive(Debug, Clone, Default)]
pub struct Marks {
    /// `I>`, `OC_HW`, ... in A: dashed at +/- in the phase-current panel.
    pub current_limits_a: Vec<(String, f64)>,
    /// `U>`, `U<`, `OV_HW` in V: dashed in the DC-link panel.
    pub dc_limits_v: Vec<(String, f64)>,
    /// (t in s, label): inputs, keys, plant changes and trips, marked on the frequency and
    /// the fault panels.
    pub events: Vec<(f64, String)>,
    /// The end of the phase-current zoom (s); `None`: the end of the run.
    pub zoom_at_s: Option<f64>,
    /// With `[lift]`: the floor levels in mm, dashed in the car-position panel (drawn only
    /// when the samples have the lift).
    pub floor_levels_mm: Vec<(String, f64)>,
}

/// The image formats `--plot` writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PlotFormat {
    Png,
    Svg,
}

impl PlotFormat {
    /// The format of `path` by its extension (case-insensitive); anything else is refused
    /// with the list of what is supported, before a run starts.
    pub fn of(path: &Path) -> Result<PlotFormat> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        match ext.as_deref() {
            Some("png") => Ok(PlotFormat::Png),
            Some("svg") => Ok(PlotFormat::Svg),
            _ => Err(anyhow!(
                "--plot {}: unsupported image format (use a .png or .svg file name)",
                path.display()
            )),
        }
    }
}

/// Checks before a run that `path` has a supported extension and that its directory is
/// writable (a probe file is created and removed), so a long run does not end in an
/// error; nothing is left behind.
pub fn check_target(path: &Path) -> Result<PlotFormat> {
    let format = PlotFormat::of(path)?;
    let probe = temp_path(path);
    std::fs::File::create(&probe).map_err(|e| anyhow!("cannot create {}: {e}", path.display()))?;
    let _ = std::fs::remove_file(&probe);
    Ok(format)
}

/// The name the plot is drawn under before it is renamed to `path`: `x.partial.png` for
/// `x.png` (the bitmap encoder picks the format by the extension).
pub(crate) fn temp_path(path: &Path) -> std::path::PathBuf {
    let mut name = path
        .file_stem()
        .map(|n| n.to_os_string())
        .unwrap_or_default();
    name.push(".partial");
    if let Some(ext) = path.extension() {
        name.push(".");
        name.push(ext);
    }
    path.with_file_name(name)
}

/// An axis label: as many decimals as a tenth of the axis's `span` needs (the mesh has
/// about ten labels), never `-0.0`, never more than 6 decimals.
pub fn axis_label(v: f64, span: f64) -> String {
    if !v.is_finite() {
        return String::new();
    }
    let step = if span.is_finite() && span > 0.0 {
        span / 10.0
    } else {
        1.0
    };
    let decimals = (-step.log10().floor()).clamp(0.0, 6.0) as usize;
    let text = format!("{v:.decimals$}");
    // A value that rounds to zero is zero, whatever its sign.
    match text.strip_prefix('-') {
        Some(rest) if rest.chars().all(|c| c == '0' || c == '.') => rest.to_string(),
        _ => text,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn axis_labels_have_no_negative_zero_and_decimals_by_the_span() {
        assert_eq!(axis_label(-0.0, 10.0), "0");
        assert_eq!(axis_label(-0.004, 1.0), "0.0");
        assert_eq!(axis_label(-1e-12, 0.5), "0.00");
        assert_eq!(axis_label(24.94, 10.0), "25");
        assert_eq!(axis_label(24.94, 1.0), "24.9");
        assert_eq!(axis_label(24.94, 0.2), "24.94");
        assert_eq!(axis_label(-3.5, 100.0), "-4");
        assert_eq!(axis_label(1500.0, 3000.0), "1500");
        assert!(!axis_label(0.123_456_789, 1e-12).contains(' '));
        assert_eq!(axis_label(f64::NAN, 1.0), "");
    }

    #[test]
    fn an_unknown_extension_is_refused_before_anything_is_written() {
        let e = PlotFormat::of(Path::new("x.jpg")).unwrap_err();
        assert!(e.to_string().contains("use a .png or .svg"), "{e}");
    }
}
