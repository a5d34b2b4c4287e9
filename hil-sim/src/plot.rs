//! `--plot`: a run's samples drawn by the `trend-plot` crate, which plcctl's
//! `trend --plot` shares (service.md 8), so a simulated and a real run are drawn alike.
//! This module only says which of a [`Sample`]'s fields are which plotted column.

use std::path::Path;

use anyhow::Result;
pub use trend_plot::{check_target, Column, Marks, PlotFormat};

use crate::sim::Sample;

impl trend_plot::Row for Sample {
    fn t_s(&self) -> f64 {
        self.t_ns as f64 * 1e-9
    }

    fn get(&self, c: Column) -> Option<f64> {
        let flag = |b: bool| if b { 1.0 } else { 0.0 };
        Some(match c {
            Column::FCmdHz => self.f_cmd_hz,
            Column::Dir => f64::from(self.dir),
            Column::SpeedRpm => self.speed_rpm,
            Column::IA => self.i_abc_a[0],
            Column::IB => self.i_abc_a[1],
            Column::IC => self.i_abc_a[2],
            // The drive's own figure is not in a simulation's record (its CSV has the
            // phase currents themselves).
            Column::ImxA => return None,
            Column::UAbV => self.u_ab_v,
            Column::UDcV => self.u_dc_v,
            Column::Fault => f64::from(self.fault),
            Column::Brake => flag(self.brake),
            Column::PwmOn => flag(self.pwm_on),
            Column::CarMm => self.lift?.car_mm,
        })
    }
}

/// Writes the plot of `samples` to `path` (PNG or SVG by its extension).
pub fn plot(path: &Path, samples: &[Sample], title: &str, marks: &Marks) -> Result<()> {
    trend_plot::plot(path, samples, title, marks)
}
