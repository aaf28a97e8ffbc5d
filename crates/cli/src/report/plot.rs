//! The report's SVG plots: a fixture's RMSE against frame time or light-space memory.
use super::{pareto, Row, BASELINES};
use std::path::Path;

/// What a plot's x axis shows.
#[derive(Clone, Copy, PartialEq)]
pub(super) enum PlotX {
    /// `frame_ms`: build + estimate.
    Time,
    /// `light_space_bytes`: the light-space data's memory.
    Memory,
}

impl PlotX {
    fn of(self, r: &Row) -> f64 {
        match self {
            PlotX::Time => r.frame_ms,
            PlotX::Memory => r.light_space_bytes as f64,
        }
    }
    fn desc(self) -> &'static str {
        match self {
            PlotX::Time => "build + estimate, ms (log)",
            PlotX::Memory => "light-space data, bytes (log)",
        }
    }
    fn title(self) -> &'static str {
        match self {
            PlotX::Time => "frame time vs RMSE",
            PlotX::Memory => "light-space memory vs RMSE",
        }
    }
}

/// One fixture's RMSE against `x` (time or memory, log scale) for every run: a colour per
/// algorithm, a marker shape per backend (circle CPU, triangle GPU), filled for the seed methods
/// and hollow for the baselines; the legend draws exactly those markers (the algorithms in
/// their colour as CPU circles, then the two backend shapes in black); the time plot adds the
/// Pareto front over both backends.
pub(super) fn plot(path: &Path, fixture: &str, rows: &[&Row], x: PlotX) -> Result<(), String> {
    use plotters::prelude::*;
    let ok: Vec<&Row> = rows
        .iter()
        .copied()
        .filter(|r| r.rmse.is_finite() && x.of(r).is_finite() && x.of(r) > 0.0)
        .collect();
    let root = SVGBackend::new(path, (760, 480)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let xmin = ok
        .iter()
        .map(|r| x.of(r))
        .fold(f64::INFINITY, f64::min)
        .clamp(1e-3, 1e30);
    let xmax = ok
        .iter()
        .map(|r| x.of(r))
        .fold(0.0, f64::max)
        .max(xmin * 2.0);
    let emax = ok.iter().map(|r| r.rmse).fold(0.0, f64::max).max(1e-3) * 1.1;
    let mut chart = ChartBuilder::on(&root)
        .caption(format!("{fixture}: {}", x.title()), ("sans-serif", 18))
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d((xmin / 1.5..xmax * 1.5).log_scale(), 0.0..emax)
        .map_err(|e| e.to_string())?;
    chart
        .configure_mesh()
        .x_desc(x.desc())
        .y_desc("RMSE vs reference")
        .draw()
        .map_err(|e| e.to_string())?;
    let algos: Vec<String> = {
        let mut a: Vec<String> = ok.iter().map(|r| r.algo.clone()).collect();
        a.sort();
        a.dedup();
        a
    };
    for (k, algo) in algos.iter().enumerate() {
        let colour = Palette99::pick(k).to_rgba();
        let baseline = BASELINES.contains(&algo.as_str());
        let label = if baseline {
            format!("{algo} (baseline)")
        } else {
            algo.clone()
        };
        // Filled for the seed methods, hollow for the baselines.
        let style = if baseline {
            colour.stroke_width(2)
        } else {
            colour.filled()
        };
        let pts = |gpu: bool| -> Vec<(f64, f64)> {
            ok.iter()
                .filter(|r| &r.algo == algo && (r.backend == "gpu") == gpu)
                .map(|r| (x.of(r), r.rmse))
                .collect()
        };
        chart
            .draw_series(
                pts(true)
                    .into_iter()
                    .map(|at| TriangleMarker::new(at, 5, style)),
            )
            .map_err(|e| e.to_string())?;
        chart
            .draw_series(pts(false).into_iter().map(|at| Circle::new(at, 4, style)))
            .map_err(|e| e.to_string())?
            .label(label)
            .legend(move |at| Circle::new(at, 4, style));
    }
    // The backends' shapes, in black.
    if ok.iter().any(|r| r.backend != "gpu") {
        chart
            .draw_series(std::iter::empty::<Circle<(f64, f64), i32>>())
            .map_err(|e| e.to_string())?
            .label("CPU")
            .legend(|at| Circle::new(at, 4, BLACK.filled()));
    }
    if ok.iter().any(|r| r.backend == "gpu") {
        chart
            .draw_series(std::iter::empty::<Circle<(f64, f64), i32>>())
            .map_err(|e| e.to_string())?
            .label("GPU")
            .legend(|at| TriangleMarker::new(at, 5, BLACK.filled()));
    }
    if x == PlotX::Time {
        let front: Vec<(f64, f64)> = pareto(&ok)
            .iter()
            .map(|&i| (ok[i].frame_ms, ok[i].rmse))
            .collect();
        chart
            .draw_series(LineSeries::new(front, BLACK.stroke_width(1)))
            .map_err(|e| e.to_string())?
            .label("Pareto front")
            .legend(|(x, y)| PathElement::new(vec![(x - 8, y), (x + 8, y)], BLACK));
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(|e| e.to_string())?;
    root.present().map_err(|e| e.to_string())?;
    Ok(())
}
