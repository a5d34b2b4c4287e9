//! The PNG plot of a run: frequency, speed, phase currents, line voltage a-b (PWM-period
//! average), DC-link voltage, and the fault / brake / PWM signals, on a shared time axis.
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

struct Series<'a> {
    name: &'a str,
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

/// Writes the plot of `samples` to `path` (PNG).
pub fn plot(path: &Path, samples: &[Sample], title: &str) -> Result<()> {
    register_font();
    let err = |e: &dyn std::fmt::Display| anyhow!("plot {}: {e}", path.display());
    let root = BitMapBackend::new(path, (1400, 1800)).into_drawing_area();
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
    let panels: Vec<(&str, f64, Vec<Series<'_>>)> = vec![
        (
            "output frequency [Hz] (signed by direction)",
            1.0,
            vec![Series {
                name: "f_cmd_hz * dir",
                color: BLUE,
                y: Box::new(|s| s.f_cmd_hz * f64::from(s.dir)),
            }],
        ),
        (
            "shaft speed [rpm]",
            10.0,
            vec![Series {
                name: "speed_rpm",
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
                    color: RED,
                    y: Box::new(|s| s.i_abc_a[0]),
                },
                Series {
                    name: "i_b",
                    color: RGBColor(0, 150, 0),
                    y: Box::new(|s| s.i_abc_a[1]),
                },
                Series {
                    name: "i_c",
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
                color: RGBColor(0, 110, 160),
                y: Box::new(|s| s.u_ab_v),
            }],
        ),
        (
            "DC-link voltage [V]",
            2.0,
            vec![Series {
                name: "u_dc_v",
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
                    color: RED,
                    y: Box::new(|s| f64::from(s.fault)),
                },
                Series {
                    name: "brake",
                    color: RGBColor(128, 0, 128),
                    y: Box::new(|s| if s.brake { 1.5 } else { 0.0 }),
                },
                Series {
                    name: "pwm_on",
                    color: BLACK,
                    y: Box::new(|s| if s.pwm_on { 1.0 } else { 0.0 }),
                },
            ],
        ),
    ];
    let areas = root.split_evenly((panels.len(), 1));
    for (area, (caption, min_span, series)) in areas.iter().zip(panels.iter()) {
        let (lo, hi) = range(samples, series, *min_span);
        let mut chart = ChartBuilder::on(area)
            .caption(*caption, ("sans-serif", 16))
            .margin(8)
            .x_label_area_size(28)
            .y_label_area_size(60)
            .build_cartesian_2d(t_start..t_end, lo..hi)
            .map_err(|e| err(&e))?;
        chart
            .configure_mesh()
            .x_desc("t [s]")
            .label_style(("sans-serif", 12))
            .draw()
            .map_err(|e| err(&e))?;
        for ser in series {
            let color = ser.color;
            chart
                .draw_series(LineSeries::new(
                    samples.iter().map(|s| (s.t_ns as f64 * 1e-9, (ser.y)(s))),
                    color,
                ))
                .map_err(|e| err(&e))?
                .label(ser.name)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], color));
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .label_font(("sans-serif", 12))
            .position(SeriesLabelPosition::UpperRight)
            .draw()
            .map_err(|e| err(&e))?;
    }
    root.present().map_err(|e| err(&e))?;
    Ok(())
}
