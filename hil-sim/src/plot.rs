//! The plot of a run (PNG or SVG, by the file's extension): frequency, speed, phase
//! currents, line voltage a-b (PWM-period average), DC-link voltage, and the fault /
//! brake / PWM signals, on a shared time axis. Each panel names its traces and their
//! colours in its caption, so no legend box covers a trace. The file is written under a
//! temporary name and renamed when complete: a failed plot never leaves a partial or
//! empty file behind.
//!
//! Text is drawn with a font shipped in the crate (DejaVu Sans Mono, `assets/`), through
//! plotters' `ab_glyph` backend: no fontconfig or FreeType needed on the machine.

use std::path::Path;
use std::sync::Once;

use anyhow::{anyhow, Result};
use plotters::prelude::*;
use plotters::style::FontStyle;

use crate::sim::Sample;

static FONT: &[u8] = include_bytes!("../assets/DejaVuSansMono.ttf");
static REGISTER: Once = Once::new();

fn register_font() {
    REGISTER.call_once(|| {
        // The font is in the binary, so this cannot fail for a well-formed file.
        let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, FONT);
    });
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
fn temp_path(path: &Path) -> std::path::PathBuf {
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

struct Series<'a> {
    name: &'a str,
    /// The colour's name in the panel's caption.
    color_name: &'a str,
    color: RGBColor,
    y: Box<dyn Fn(&Sample) -> f64 + 'a>,
}

fn range(samples: &[Sample], series: &[Series<'_>], min_span: f64) -> (f64, f64) {
    let mut lo = f64::INFINITY;
    let mut hi = f64::NEG_INFINITY;
    for s in samples {
        for ser in series {
            let v = (ser.y)(s);
            if v.is_finite() {
                lo = lo.min(v);
                hi = hi.max(v);
            }
        }
    }
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    if hi - lo < min_span {
        let mid = 0.5 * (hi + lo);
        lo = mid - min_span / 2.0;
        hi = mid + min_span / 2.0;
    }
    let pad = 0.05 * (hi - lo);
    (lo - pad, hi + pad)
}

/// Writes the plot of `samples` to `path` (PNG or SVG by its extension).
pub fn plot(path: &Path, samples: &[Sample], title: &str, marks: &Marks) -> Result<()> {
    let format = PlotFormat::of(path)?;
    register_font();
    let tmp = temp_path(path);
    let drawn = match format {
        PlotFormat::Png => draw(
            BitMapBackend::new(&tmp, SIZE).into_drawing_area(),
            samples,
            title,
            marks,
        ),
        PlotFormat::Svg => draw(
            SVGBackend::new(&tmp, SIZE).into_drawing_area(),
            samples,
            title,
            marks,
        ),
    };
    let done = drawn.and_then(|()| {
        std::fs::rename(&tmp, path).map_err(|e| anyhow!("cannot write {}: {e}", path.display()))
    });
    if done.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    done.map_err(|e| anyhow!("plot {}: {e}", path.display()))
}

const SIZE: (u32, u32) = (1400, 1800);

fn draw<DB: DrawingBackend>(
    root: DrawingArea<DB, plotters::coord::Shift>,
    samples: &[Sample],
    title: &str,
    marks: &Marks,
) -> Result<()> {
    let err = |e: &dyn std::fmt::Display| anyhow!("{e}");
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let root = root
        .titled(title, ("sans-serif", 22))
        .map_err(|e| err(&e))?;
    // The time axis spans the samples (a window of a run starts where it starts).
    let t_start = samples.first().map_or(0.0, |s| s.t_ns as f64 * 1e-9);
    let t_end = samples
        .last()
        .map_or(1.0, |s| s.t_ns as f64 * 1e-9)
        .max(t_start + 1e-6);
    let mut panels: Vec<(&str, f64, Vec<Series<'_>>)> = vec![
        (
            "output frequency [Hz] (signed by direction)",
            1.0,
            vec![Series {
                name: "f_cmd_hz * dir",
                color_name: "blue",
                color: BLUE,
                y: Box::new(|s| s.f_cmd_hz * f64::from(s.dir)),
            }],
        ),
        (
            "shaft speed [rpm]",
            10.0,
            vec![Series {
                name: "speed_rpm",
                color_name: "green",
                color: RGBColor(0, 128, 0),
                y: Box::new(|s| s.speed_rpm),
            }],
        ),
        (
            "phase currents [A]",
            0.1,
            vec![
                Series {
                    name: "i_a",
                    color_name: "red",
                    color: RED,
                    y: Box::new(|s| s.i_abc_a[0]),
                },
                Series {
                    name: "i_b",
                    color_name: "green",
                    color: RGBColor(0, 150, 0),
                    y: Box::new(|s| s.i_abc_a[1]),
                },
                Series {
                    name: "i_c",
                    color_name: "blue",
                    color: BLUE,
                    y: Box::new(|s| s.i_abc_a[2]),
                },
            ],
        ),
        (
            "line voltage a-b [V] (PWM-period average)",
            1.0,
            vec![Series {
                name: "u_ab_v",
                color_name: "teal",
                color: RGBColor(0, 110, 160),
                y: Box::new(|s| s.u_ab_v),
            }],
        ),
        (
            "DC-link voltage [V]",
            2.0,
            vec![Series {
                name: "u_dc_v",
                color_name: "brown",
                color: RGBColor(160, 80, 0),
                y: Box::new(|s| s.u_dc_v),
            }],
        ),
        (
            "fault code / brake / PWM on",
            1.0,
            vec![
                Series {
                    name: "fault",
                    color_name: "red",
                    color: RED,
                    y: Box::new(|s| f64::from(s.fault)),
                },
                Series {
                    name: "brake",
                    color_name: "purple",
                    color: RGBColor(128, 0, 128),
                    y: Box::new(|s| if s.brake { 1.5 } else { 0.0 }),
                },
                Series {
                    name: "pwm_on",
                    color_name: "black",
                    color: BLACK,
                    y: Box::new(|s| if s.pwm_on { 1.0 } else { 0.0 }),
                },
            ],
        ),
    ];
    // The lift (lift.md 4.4): car position with the floor levels, as the last panel.
    let lift_panel = samples.iter().any(|s| s.lift.is_some()).then(|| {
        panels.push((
            "car position [mm] (dashed: floor levels)",
            100.0,
            vec![Series {
                name: "car_mm",
                color_name: "navy",
                color: RGBColor(0, 0, 128),
                y: Box::new(|s| s.lift.map_or(f64::NAN, |l| l.car_mm)),
            }],
        ));
        panels.len() - 1
    });
    let areas = root.split_evenly((panels.len(), 1));
    let last = areas.len().saturating_sub(1);
    // Events at the same instant share one marker and one label.
    let mut events: Vec<(f64, String)> = Vec::new();
    for (t, label) in &marks.events {
        match events.last_mut() {
            Some((t0, l)) if (*t - *t0).abs() < 1e-9 => {
                l.push_str(", ");
                l.push_str(label);
            }
            _ => events.push((*t, label.clone())),
        }
    }
    for (k, (area, (caption, min_span, series))) in areas.iter().zip(panels.iter()).enumerate() {
        let names: Vec<String> = series
            .iter()
            .map(|s| format!("{} ({})", s.name, s.color_name))
            .collect();
        // Panel 2 holds the currents, panel 4 the DC link: their limits.
        let (limits, mirrored): (&[(String, f64)], bool) = match k {
            2 => (&marks.current_limits_a, true),
            4 => (&marks.dc_limits_v, false),
            k if Some(k) == lift_panel => (&marks.floor_levels_mm, false),
            _ => (&[], false),
        };
        let mut caption = format!("{caption}: {}", names.join(", "));
        if !limits.is_empty() {
            let l: Vec<String> = limits.iter().map(|(n, v)| format!("{n} {v:.1}")).collect();
            caption.push_str(&format!("; dashed: {}", l.join(", ")));
        }
        let panel = Panel {
            series,
            min_span: *min_span,
            limits,
            mirrored,
            events: if k == 0 || k == last { &events } else { &[] },
            labels: k == 0,
            x_label_area: if k == last { 44 } else { 28 },
        };
        if k == 2 {
            // The currents: the envelope of the run, and a zoom of a few periods in
            // which the three phases can be told apart.
            let (wide, zoom) = area.split_horizontally(area.dim_in_pixel().0 * 68 / 100);
            panel.draw(&wide, samples, (t_start, t_end), &caption, &err)?;
            let (z0, z1) = zoom_window(samples, marks.zoom_at_s, (t_start, t_end));
            // The samples are in time order: the window is a slice, not a copy.
            let first = samples.partition_point(|s| (s.t_ns as f64) * 1e-9 < z0);
            let end = samples.partition_point(|s| (s.t_ns as f64) * 1e-9 <= z1);
            let inside = samples.get(first..end).unwrap_or(&[]);
            let zoom_caption = format!("zoom {z0:.3}-{z1:.3} s");
            panel.draw(&zoom, inside, (z0, z1), &zoom_caption, &err)?;
        } else {
            panel.draw(area, samples, (t_start, t_end), &caption, &err)?;
        }
    }
    root.present().map_err(|e| err(&e))?;
    Ok(())
}

/// About three periods of the output frequency (0.1 s when it is below 1 Hz) ending at
/// `at` (default: the end of the run), within the run.
fn zoom_window(samples: &[Sample], at: Option<f64>, (t0, t1): (f64, f64)) -> (f64, f64) {
    let end = at.unwrap_or(t1).clamp(t0, t1);
    let f = samples
        .iter()
        .rev()
        .find(|s| s.t_ns as f64 * 1e-9 <= end)
        .map_or(0.0, |s| s.f_cmd_hz.abs());
    let span = if f >= 1.0 { 3.0 / f } else { 0.1 };
    let start = (end - span).max(t0);
    (start, end.max(start + 1e-6))
}

/// One chart: traces, limits, event markers.
struct Panel<'a, 'b> {
    series: &'a [Series<'b>],
    min_span: f64,
    limits: &'a [(String, f64)],
    mirrored: bool,
    events: &'a [(f64, String)],
    labels: bool,
    x_label_area: u32,
}

impl Panel<'_, '_> {
    fn draw<DB: DrawingBackend>(
        &self,
        area: &DrawingArea<DB, plotters::coord::Shift>,
        samples: &[Sample],
        (t_start, t_end): (f64, f64),
        caption: &str,
        err: &dyn Fn(&dyn std::fmt::Display) -> anyhow::Error,
    ) -> Result<()> {
        let (lo, hi) = range(samples, self.series, self.min_span);
        let mut chart = ChartBuilder::on(area)
            .caption(caption, ("sans-serif", 16))
            .margin(8)
            .margin_right(24)
            // The bottom panel carries the time axis's name below its labels.
            .x_label_area_size(self.x_label_area)
            .y_label_area_size(60)
            .build_cartesian_2d(t_start..t_end, lo..hi)
            .map_err(|e| err(&e))?;
        chart
            .configure_mesh()
            .x_desc("t [s]")
            .label_style(("sans-serif", 12))
            .draw()
            .map_err(|e| err(&e))?;
        for ser in self.series {
            chart
                .draw_series(LineSeries::new(
                    samples.iter().map(|s| (s.t_ns as f64 * 1e-9, (ser.y)(s))),
                    ser.color,
                ))
                .map_err(|e| err(&e))?;
        }
        for (_, v) in self.limits {
            let levels: &[f64] = if self.mirrored { &[*v, -*v] } else { &[*v] };
            for &y in levels {
                // Only what is on the scale (the caption names every limit).
                if y > lo && y < hi {
                    chart
                        .draw_series(DashedLineSeries::new(
                            [(t_start, y), (t_end, y)],
                            8,
                            6,
                            RGBColor(200, 0, 0).stroke_width(1),
                        ))
                        .map_err(|e| err(&e))?;
                }
            }
        }
        let visible = self
            .events
            .iter()
            .filter(|(t, _)| *t >= t_start && *t <= t_end);
        for (i, (t, label)) in visible.enumerate() {
            chart
                .draw_series(DashedLineSeries::new(
                    [(*t, lo), (*t, hi)],
                    4,
                    4,
                    RGBColor(90, 90, 90).stroke_width(1),
                ))
                .map_err(|e| err(&e))?;
            if self.labels {
                chart
                    .draw_series(std::iter::once(Text::new(
                        format!(" {label}"),
                        // Alternate rows, so that close events' labels do not overlap.
                        (*t, hi - (i % 2) as f64 * 0.08 * (hi - lo)),
                        ("sans-serif", 11).into_font().color(&RGBColor(60, 60, 60)),
                    )))
                    .map_err(|e| err(&e))?;
            }
        }
        Ok(())
    }
}
