//! The two plots of a flight: the estimated track against a reference (the
//! simulator's truth, or a replayed log's GNSS) from the top, and the
//! horizontal error over time with the reported 2-sigma where known.

use std::path::{Path, PathBuf};

use plotters::prelude::*;
use towernav_protocol::PoseEstimate;

use super::loc_plots::register_font;
use crate::truth_scorer::TruthScorer;

fn err<E: std::fmt::Debug>(path: &Path) -> impl FnOnce(E) -> anyhow::Error + '_ {
    move |e| anyhow::anyhow!("drawing {}: {e:?}", path.display())
}

/// One point of the error plot: seconds, horizontal error, and the
/// reported 2-sigma radius (the ellipse's major axis) when there is one.
pub type ErrorPoint = (f64, f64, Option<f64>);

/// Writes the demo's `trajectory.png` and `error_over_time.png` into `out`.
pub fn write(
    out: &Path,
    scorer: &TruthScorer,
    received: &[PoseEstimate],
    fps: f64,
) -> anyhow::Result<(PathBuf, PathBuf)> {
    let truth: Vec<(f64, f64)> = scorer.truth_en.values().copied().collect();
    let estimate: Vec<(f64, f64)> = received.iter().map(|p| (p.east_m, p.north_m)).collect();
    let errors: Vec<ErrorPoint> = received
        .iter()
        .filter_map(|p| {
            let (e, n) = *scorer.truth_en.get(&p.seq)?;
            Some((
                p.seq as f64 / fps,
                ((p.east_m - e).powi(2) + (p.north_m - n).powi(2)).sqrt(),
                None,
            ))
        })
        .collect();
    write_track_and_error(out, "truth", &truth, &estimate, &errors)
}

/// Writes `trajectory.png` (the estimate over the `reference` track, which
/// the legend calls `reference_label`) and `error_over_time.png` into `out`.
pub fn write_track_and_error(
    out: &Path,
    reference_label: &str,
    reference: &[(f64, f64)],
    estimate: &[(f64, f64)],
    errors: &[ErrorPoint],
) -> anyhow::Result<(PathBuf, PathBuf)> {
    register_font()?;
    let truth = reference;
    let trajectory = out.join("trajectory.png");
    {
        let path = trajectory.as_path();
        let all = truth.iter().chain(estimate);
        let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        for (x, y) in all {
            (x0, x1, y0, y1) = (x0.min(*x), x1.max(*x), y0.min(*y), y1.max(*y));
        }
        if x0 > x1 {
            (x0, x1, y0, y1) = (0.0, 1.0, 0.0, 1.0);
        }
        let pad = 0.05 * (x1 - x0).max(y1 - y0).max(10.0);
        let root = BitMapBackend::new(path, (1200, 800)).into_drawing_area();
        root.fill(&WHITE).map_err(err(path))?;
        let mut chart = ChartBuilder::on(&root)
            .caption(
                format!("estimate against {reference_label} (top view)"),
                ("sans-serif", 22),
            )
            .margin(10)
            .x_label_area_size(35)
            .y_label_area_size(55)
            .build_cartesian_2d(x0 - pad..x1 + pad, y0 - pad..y1 + pad)
            .map_err(err(path))?;
        chart
            .configure_mesh()
            .x_desc("east (m)")
            .y_desc("north (m)")
            .draw()
            .map_err(err(path))?;
        chart
            .draw_series(LineSeries::new(
                truth.iter().copied(),
                BLACK.stroke_width(2),
            ))
            .map_err(err(path))?
            .label(reference_label)
            .legend(|(x, y)| PathElement::new(vec![(x - 8, y), (x + 8, y)], BLACK));
        let blue = RGBColor(31, 119, 180);
        chart
            .draw_series(estimate.iter().map(|p| Circle::new(*p, 1, blue.filled())))
            .map_err(err(path))?
            .label("estimate")
            .legend(move |(x, y)| Circle::new((x, y), 3, blue.filled()));
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(err(path))?;
        root.present().map_err(err(path))?;
    }
    let error_plot = out.join("error_over_time.png");
    {
        let path = error_plot.as_path();
        let t_min = errors.first().map_or(0.0, |s| s.0);
        let t_max = errors.last().map_or(1.0, |s| s.0).max(t_min + 1.0);
        let e_max = errors.iter().map(|s| s.1).fold(2.0, f64::max).min(30.0);
        let root = BitMapBackend::new(path, (1200, 450)).into_drawing_area();
        root.fill(&WHITE).map_err(err(path))?;
        let mut chart = ChartBuilder::on(&root)
            .caption("horizontal error over time", ("sans-serif", 22))
            .margin(10)
            .x_label_area_size(35)
            .y_label_area_size(55)
            .build_cartesian_2d(t_min..t_max, 0.0..e_max)
            .map_err(err(path))?;
        chart
            .configure_mesh()
            .x_desc("time (s)")
            .y_desc("error (m)")
            .draw()
            .map_err(err(path))?;
        let green = RGBColor(44, 160, 44);
        chart
            .draw_series(LineSeries::new(
                errors.iter().map(|s| (s.0, s.1)),
                green.stroke_width(1),
            ))
            .map_err(err(path))?
            .label("error")
            .legend(move |(x, y)| PathElement::new(vec![(x - 8, y), (x + 8, y)], green));
        if errors.iter().any(|s| s.2.is_some()) {
            let grey = RGBColor(150, 150, 150);
            chart
                .draw_series(LineSeries::new(
                    errors.iter().filter_map(|s| Some((s.0, s.2?.min(e_max)))),
                    grey.stroke_width(1),
                ))
                .map_err(err(path))?
                .label("reported 2-sigma")
                .legend(move |(x, y)| PathElement::new(vec![(x - 8, y), (x + 8, y)], grey));
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.8))
                .border_style(BLACK)
                .draw()
                .map_err(err(path))?;
        }
        root.present().map_err(err(path))?;
    }
    Ok((trajectory, error_plot))
}
