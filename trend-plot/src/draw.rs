//! The drawing (feature `draw`): the panels, their traces and captions, the limits and the
//! event markers, through plotters onto a PNG or SVG.

use std::path::Path;
use std::sync::Once;

use anyhow::{anyhow, Result};
use plotters::prelude::*;
use plotters::style::FontStyle;

use crate::{axis_label, temp_path, Column, Marks, PlotFormat, Row};

static FONT: &[u8] = include_bytes!("../assets/DejaVuSansMono.ttf");
static REGISTER: Once = Once::new();

fn register_font() {
    REGISTER.call_once(|| {
        // The font is in the binary, so this cannot fail for a well-formed file.
        let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, FONT);
    });
}

struct Series {
    name: &'static str,
    /// The colour's name in the panel's caption.
    color_name: &'static str,
    color: RGBColor,
    y: fn(&dyn Row) -> Option<f64>,
}

impl Series {
    const fn of(
        name: &'static str,
        color_name: &'static str,
        color: RGBColor,
        y: fn(&dyn Row) -> Option<f64>,
    ) -> Series {
        Series {
            name,
            color_name,
            color,
            y,
        }
    }
}

/// Which panel: the limits and the zoom belong to their panel, not to a position.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    Frequency,
    Speed,
    Currents,
    LineVoltage,
    DcLink,
    Signals,
    Car,
}

struct PanelSpec {
    kind: Kind,
    caption: &'static str,
    min_span: f64,
    series: Vec<Series>,
}

/// Every panel the plot can have, top to bottom; those without data are left out.
fn all_panels() -> Vec<PanelSpec> {
    let green = RGBColor(0, 128, 0);
    vec![
        PanelSpec {
            kind: Kind::Frequency,
            caption: "output frequency [Hz] (signed by direction)",
            min_span: 1.0,
            series: vec![Series::of("f_cmd_hz * dir", "blue", BLUE, |r| {
                Some(r.get(Column::FCmdHz)? * r.get(Column::Dir)?)
            })],
        },
        PanelSpec {
            kind: Kind::Speed,
            caption: "shaft speed [rpm]",
            min_span: 10.0,
            series: vec![Series::of("speed_rpm", "green", green, |r| {
                r.get(Column::SpeedRpm)
            })],
        },
        PanelSpec {
            kind: Kind::Currents,
            caption: "phase currents [A]",
            min_span: 0.1,
            series: vec![
                Series::of("i_a", "red", RED, |r| r.get(Column::IA)),
                Series::of("i_b", "green", RGBColor(0, 150, 0), |r| r.get(Column::IB)),
                Series::of("i_c", "blue", BLUE, |r| r.get(Column::IC)),
                Series::of("imx_a", "orange", RGBColor(230, 120, 0), |r| {
                    r.get(Column::ImxA)
                }),
            ],
        },
        PanelSpec {
            kind: Kind::LineVoltage,
            caption: "line voltage a-b [V] (PWM-period average)",
            min_span: 1.0,
            series: vec![Series::of("u_ab_v", "teal", RGBColor(0, 110, 160), |r| {
                r.get(Column::UAbV)
            })],
        },
        PanelSpec {
            kind: Kind::DcLink,
            caption: "DC-link voltage [V]",
            min_span: 2.0,
            series: vec![Series::of("u_dc_v", "brown", RGBColor(160, 80, 0), |r| {
                r.get(Column::UDcV)
            })],
        },
        PanelSpec {
            kind: Kind::Signals,
            caption: "fault code / brake / PWM on",
            min_span: 1.0,
            series: vec![
                Series::of("fault", "red", RED, |r| r.get(Column::Fault)),
                // Drawn at 1.5 so that it is not hidden under `pwm_on`.
                Series::of("brake", "purple", RGBColor(128, 0, 128), |r| {
                    Some(r.get(Column::Brake)? * 1.5)
                }),
                Series::of("pwm_on", "black", BLACK, |r| r.get(Column::PwmOn)),
            ],
        },
        // The lift (lift.md 4.4): car position with the floor levels, as the last panel.
        PanelSpec {
            kind: Kind::Car,
            caption: "car position [mm] (dashed: floor levels)",
            min_span: 100.0,
            series: vec![Series::of("car_mm", "navy", RGBColor(0, 0, 128), |r| {
                r.get(Column::CarMm)
            })],
        },
    ]
}

/// The panels and, in each, the traces some row has.
fn present_panels<R: Row>(rows: &[R]) -> Vec<PanelSpec> {
    all_panels()
        .into_iter()
        .filter_map(|mut p| {
            p.series
                .retain(|ser| rows.iter().any(|r| (ser.y)(r).is_some()));
            (!p.series.is_empty()).then_some(p)
        })
        .collect()
}

fn range<R: Row>(rows: &[R], series: &[Series], min_span: f64) -> (f64, f64) {
    let mut lo = f64::INFINITY;
    let mut hi = f64::NEG_INFINITY;
    for s in rows {
        for ser in series {
            let v = (ser.y)(s).unwrap_or(f64::NAN);
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

/// Writes the plot of `rows` (in time order) to `path` (PNG or SVG by its extension).
pub fn plot<R: Row>(path: &Path, rows: &[R], title: &str, marks: &Marks) -> Result<()> {
    let format = PlotFormat::of(path)?;
    register_font();
    let tmp = temp_path(path);
    let drawn = match format {
        PlotFormat::Png => draw(
            BitMapBackend::new(&tmp, SIZE).into_drawing_area(),
            rows,
            title,
            marks,
        ),
        PlotFormat::Svg => draw(
            SVGBackend::new(&tmp, SIZE).into_drawing_area(),
            rows,
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

fn draw<DB: DrawingBackend, R: Row>(
    root: DrawingArea<DB, plotters::coord::Shift>,
    rows: &[R],
    title: &str,
    marks: &Marks,
) -> Result<()> {
    let err = |e: &dyn std::fmt::Display| anyhow!("{e}");
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let root = root
        .titled(title, ("sans-serif", 22))
        .map_err(|e| err(&e))?;
    // The time axis spans the rows (a window of a run starts where it starts).
    let t_start = rows.first().map_or(0.0, |s| s.t_s());
    let t_end = rows.last().map_or(1.0, |s| s.t_s()).max(t_start + 1e-6);
    let mut panels = present_panels(rows);
    if panels.is_empty() {
        // Nothing to draw but the time axis: one empty frequency panel says so.
        panels = all_panels().into_iter().take(1).collect();
    }
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
    for (k, (area, spec)) in areas.iter().zip(panels.iter()).enumerate() {
        let names: Vec<String> = spec
            .series
            .iter()
            .map(|s| format!("{} ({})", s.name, s.color_name))
            .collect();
        let (limits, mirrored): (&[(String, f64)], bool) = match spec.kind {
            Kind::Currents => (&marks.current_limits_a, true),
            Kind::DcLink => (&marks.dc_limits_v, false),
            Kind::Car => (&marks.floor_levels_mm, false),
            _ => (&[], false),
        };
        let mut caption = format!("{}: {}", spec.caption, names.join(", "));
        if !limits.is_empty() {
            let l: Vec<String> = limits.iter().map(|(n, v)| format!("{n} {v:.1}")).collect();
            caption.push_str(&format!("; dashed: {}", l.join(", ")));
        }
        let panel = Panel {
            series: &spec.series,
            min_span: spec.min_span,
            limits,
            mirrored,
            events: if k == 0 || k == last { &events } else { &[] },
            labels: k == 0,
            x_label_area: if k == last { 44 } else { 28 },
        };
        let phases = rows.iter().any(|r| r.get(Column::IA).is_some());
        if spec.kind == Kind::Currents && phases {
            // The currents: the envelope of the run, and a zoom of a few periods in
            // which the three phases can be told apart.
            let (wide, zoom) = area.split_horizontally(area.dim_in_pixel().0 * 68 / 100);
            panel.draw(&wide, rows, (t_start, t_end), &caption, &err)?;
            let (z0, z1) = zoom_window(rows, marks.zoom_at_s, (t_start, t_end));
            // The rows are in time order: the window is a slice, not a copy.
            let first = rows.partition_point(|s| s.t_s() < z0);
            let end = rows.partition_point(|s| s.t_s() <= z1);
            let inside = rows.get(first..end).unwrap_or(&[]);
            let zoom_caption = format!("zoom {z0:.3}-{z1:.3} s");
            panel.draw(&zoom, inside, (z0, z1), &zoom_caption, &err)?;
        } else {
            panel.draw(area, rows, (t_start, t_end), &caption, &err)?;
        }
    }
    root.present().map_err(|e| err(&e))?;
    Ok(())
}

/// About three periods of the output frequency (0.1 s when it is below 1 Hz) ending at
/// `at` (default: the end of the run), within the run.
fn zoom_window<R: Row>(rows: &[R], at: Option<f64>, (t0, t1): (f64, f64)) -> (f64, f64) {
    let end = at.unwrap_or(t1).clamp(t0, t1);
    let f = rows
        .iter()
        .rev()
        .find(|s| s.t_s() <= end)
        .and_then(|s| s.get(Column::FCmdHz))
        .map_or(0.0, f64::abs);
    let span = if f >= 1.0 { 3.0 / f } else { 0.1 };
    let start = (end - span).max(t0);
    (start, end.max(start + 1e-6))
}

/// One chart: traces, limits, event markers.
struct Panel<'a> {
    series: &'a [Series],
    min_span: f64,
    limits: &'a [(String, f64)],
    mirrored: bool,
    events: &'a [(f64, String)],
    labels: bool,
    x_label_area: u32,
}

impl Panel<'_> {
    fn draw<DB: DrawingBackend, R: Row>(
        &self,
        area: &DrawingArea<DB, plotters::coord::Shift>,
        rows: &[R],
        (t_start, t_end): (f64, f64),
        caption: &str,
        err: &dyn Fn(&dyn std::fmt::Display) -> anyhow::Error,
    ) -> Result<()> {
        let (lo, hi) = range(rows, self.series, self.min_span);
        let mut chart = ChartBuilder::on(area)
            .caption(caption, ("sans-serif", 16))
            .margin(8)
            .margin_right(24)
            // The bottom panel carries the time axis's name below its labels.
            .x_label_area_size(self.x_label_area)
            .y_label_area_size(60)
            .build_cartesian_2d(t_start..t_end, lo..hi)
            .map_err(|e| err(&e))?;
        let x_fmt = |v: &f64| axis_label(*v, t_end - t_start);
        let y_fmt = |v: &f64| axis_label(*v, hi - lo);
        chart
            .configure_mesh()
            .x_desc("t [s]")
            .x_label_formatter(&x_fmt)
            .y_label_formatter(&y_fmt)
            .label_style(("sans-serif", 12))
            .draw()
            .map_err(|e| err(&e))?;
        for ser in self.series {
            // A row without the value (the link down) breaks the line: a gap, not a
            // straight line across it.
            let mut run: Vec<(f64, f64)> = Vec::new();
            for r in rows {
                match (ser.y)(r) {
                    Some(v) if v.is_finite() => run.push((r.t_s(), v)),
                    _ if !run.is_empty() => {
                        chart
                            .draw_series(LineSeries::new(std::mem::take(&mut run), ser.color))
                            .map_err(|e| err(&e))?;
                    }
                    _ => {}
                }
            }
            if !run.is_empty() {
                chart
                    .draw_series(LineSeries::new(run, ser.color))
                    .map_err(|e| err(&e))?;
            }
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A row with the given columns (all other columns absent).
    struct R {
        t_s: f64,
        cols: Vec<(Column, f64)>,
    }

    impl Row for R {
        fn t_s(&self) -> f64 {
            self.t_s
        }
        fn get(&self, c: Column) -> Option<f64> {
            self.cols.iter().find(|(k, _)| *k == c).map(|(_, v)| *v)
        }
    }

    fn rows(cols: &[Column], n: usize) -> Vec<R> {
        (0..n)
            .map(|i| R {
                t_s: i as f64 * 0.01,
                cols: cols.iter().map(|c| (*c, (i as f64 * 0.3).sin())).collect(),
            })
            .collect()
    }

    fn kinds(rows: &[R]) -> Vec<(Kind, Vec<&'static str>)> {
        present_panels(rows)
            .into_iter()
            .map(|p| (p.kind, p.series.iter().map(|s| s.name).collect()))
            .collect()
    }

    #[test]
    fn a_plc_record_gets_frequency_drive_current_dc_link_and_fault() {
        use Column::*;
        let r = rows(&[FCmdHz, Dir, Fault, UDcV, ImxA], 10);
        assert_eq!(
            kinds(&r),
            vec![
                (Kind::Frequency, vec!["f_cmd_hz * dir"]),
                (Kind::Currents, vec!["imx_a"]),
                (Kind::DcLink, vec!["u_dc_v"]),
                (Kind::Signals, vec!["fault"]),
            ]
        );
    }

    #[test]
    fn a_simulated_record_gets_every_panel_and_the_car_only_with_the_lift() {
        use Column::*;
        let sim = [
            FCmdHz, Dir, SpeedRpm, IA, IB, IC, UAbV, UDcV, Fault, Brake, PwmOn,
        ];
        let all: Vec<Kind> = kinds(&rows(&sim, 10)).into_iter().map(|k| k.0).collect();
        assert_eq!(
            all,
            [
                Kind::Frequency,
                Kind::Speed,
                Kind::Currents,
                Kind::LineVoltage,
                Kind::DcLink,
                Kind::Signals
            ]
        );
        let mut lift = sim.to_vec();
        lift.push(CarMm);
        assert_eq!(kinds(&rows(&lift, 10)).last().map(|k| k.0), Some(Kind::Car));
    }

    #[test]
    fn the_signed_frequency_needs_both_columns() {
        // `f_cmd_hz` without `dir` cannot be signed: no trace rather than a wrong one.
        let r = rows(&[Column::FCmdHz], 5);
        assert!(kinds(&r).is_empty());
    }

    #[test]
    fn a_record_with_gaps_is_drawn_complete_and_no_partial_file_is_left() {
        use Column::*;
        let dir = std::env::temp_dir().join(format!("trend-plot-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let mut r = rows(&[FCmdHz, Dir, Fault, UDcV, ImxA], 200);
        // The link down for a while: the drive's columns are absent.
        for row in r.iter_mut().skip(50).take(30) {
            row.cols.clear();
        }
        for name in ["gap.png", "gap.svg"] {
            let path = dir.join(name);
            plot(&path, &r, "gaps", &Marks::default()).unwrap();
            let bytes = std::fs::read(&path).unwrap();
            if name.ends_with("png") {
                assert_eq!(&bytes[1..4], b"PNG");
                // IHDR: width and height.
                assert_eq!(&bytes[16..24], &[0, 0, 0x05, 0x78, 0, 0, 0x07, 0x08]);
            } else {
                let text = String::from_utf8(bytes).unwrap();
                assert!(text.contains("imx_a (orange)"), "caption names the trace");
                assert!(!text.contains("speed_rpm"), "no panel without data");
            }
            assert!(!dir.join(temp_path(&path)).exists());
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
