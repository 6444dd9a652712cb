//! PNG plots of the localization evaluation (plotters, fonts embedded, no system fonts).

use std::path::Path;

use anyhow::Context;
use plotters::prelude::*;

use crate::loc_eval::{EvalRun, FrameRecord, TowerRecord};

const SEED: RGBColor = RGBColor(214, 39, 40);
const OURS: RGBColor = RGBColor(31, 119, 180);
const FILTERED: RGBColor = RGBColor(44, 160, 44);

/// Registers the embedded font with plotters, once per process (annotation calls this per frame).
pub(crate) fn register_font() -> anyhow::Result<()> {
    static REGISTERED: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| {
        plotters::style::register_font(
            "sans-serif",
            FontStyle::Normal,
            epaint_default_fonts::UBUNTU_LIGHT,
        )
        .is_ok()
    });
    anyhow::ensure!(ok, "the embedded plot font did not load");
    Ok(())
}

fn plot_err<E: std::fmt::Debug>(what: &Path) -> impl FnOnce(E) -> anyhow::Error + '_ {
    move |e| anyhow::anyhow!("drawing {}: {e:?}", what.display())
}

/// One tower observation to scatter: x, the paper's E and D error, and ours if any.
type ErrorPoint = (f64, f64, f64, Option<(f64, f64)>);

/// Scatter of error against a quantity for the paper and ours, one panel each for E and D.
fn scatter(
    path: &Path,
    title: &str,
    x_label: &str,
    points: &[ErrorPoint],
    x_range: std::ops::Range<f64>,
) -> anyhow::Result<()> {
    let root = BitMapBackend::new(path, (1400, 600)).into_drawing_area();
    root.fill(&WHITE).map_err(plot_err(path))?;
    let root = root
        .titled(title, ("sans-serif", 24))
        .map_err(plot_err(path))?;
    let panels = root.split_evenly((1, 2));
    for (panel, (name, pick)) in panels
        .iter()
        .zip([("E error (m)", 0usize), ("D error (m)", 1usize)])
    {
        let lim = 40.0;
        let mut chart = ChartBuilder::on(panel)
            .margin(15)
            .x_label_area_size(40)
            .y_label_area_size(55)
            .build_cartesian_2d(x_range.clone(), -lim..lim)
            .map_err(plot_err(path))?;
        chart
            .configure_mesh()
            .x_desc(x_label)
            .y_desc(name)
            .draw()
            .map_err(plot_err(path))?;
        let paper_pts = points
            .iter()
            .map(|&(x, se, sd, _)| (x, if pick == 0 { se } else { sd }));
        let ours_pts = points
            .iter()
            .filter_map(|&(x, _, _, o)| o.map(|(e, d)| (x, if pick == 0 { e } else { d })));
        let clamp = |(x, y): (f64, f64)| (x, y.clamp(-lim, lim));
        chart
            .draw_series(
                paper_pts
                    .map(clamp)
                    .map(|p| Circle::new(p, 1, SEED.mix(0.3).filled())),
            )
            .map_err(plot_err(path))?
            .label("paper (level camera)")
            .legend(|(x, y)| Circle::new((x, y), 4, SEED.filled()));
        chart
            .draw_series(
                ours_pts
                    .map(clamp)
                    .map(|p| Circle::new(p, 1, OURS.mix(0.3).filled())),
            )
            .map_err(plot_err(path))?
            .label("ours (attitude-compensated rays)")
            .legend(|(x, y)| Circle::new((x, y), 4, OURS.filled()));
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(plot_err(path))?;
    }
    root.present().map_err(plot_err(path))?;
    Ok(())
}

/// Truth, the paper and ours + EKF along x (east) and y (north) over time: the paper's Figure 13.
fn path_xy(path: &Path, title: &str, frames: &[FrameRecord]) -> anyhow::Result<()> {
    let root = BitMapBackend::new(path, (1400, 700)).into_drawing_area();
    root.fill(&WHITE).map_err(plot_err(path))?;
    let root = root
        .titled(title, ("sans-serif", 24))
        .map_err(plot_err(path))?;
    let panels = root.split_evenly((2, 1));
    let t_max = frames.last().map(|f| f.time_s).unwrap_or(1.0).max(1.0);
    for (panel, axis) in panels.iter().zip([0usize, 1]) {
        let coord = |p: &nalgebra::Point3<f64>| if axis == 0 { p.x } else { p.y };
        let truth: Vec<(f64, f64)> = frames
            .iter()
            .map(|f| (f.time_s, coord(&f.truth.position_in_world)))
            .collect();
        let (lo, hi) = truth
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), (_, v)| {
                (a.min(*v), b.max(*v))
            });
        let pad = ((hi - lo) * 0.1).max(20.0);
        let mut chart = ChartBuilder::on(panel)
            .margin(10)
            .x_label_area_size(35)
            .y_label_area_size(60)
            .build_cartesian_2d(0.0..t_max, (lo - pad)..(hi + pad))
            .map_err(plot_err(path))?;
        chart
            .configure_mesh()
            .x_desc("time (s)")
            .y_desc(if axis == 0 {
                "east x (m)"
            } else {
                "north y (m)"
            })
            .draw()
            .map_err(plot_err(path))?;
        let points = |pick: fn(&FrameRecord) -> Option<nalgebra::Point3<f64>>| -> Vec<(f64, f64)> {
            frames
                .iter()
                .filter_map(|f| pick(f).map(|p| (f.time_s, coord(&p).clamp(lo - pad, hi + pad))))
                .collect()
        };
        chart
            .draw_series(
                points(|f| f.paper)
                    .into_iter()
                    .map(|p| Circle::new(p, 1, SEED.mix(0.5).filled())),
            )
            .map_err(plot_err(path))?
            .label("paper")
            .legend(|(x, y)| Circle::new((x, y), 4, SEED.filled()));
        chart
            .draw_series(LineSeries::new(
                points(|f| f.filtered),
                FILTERED.stroke_width(2),
            ))
            .map_err(plot_err(path))?
            .label("ours + EKF")
            .legend(|(x, y)| {
                PathElement::new(vec![(x - 8, y), (x + 8, y)], FILTERED.stroke_width(2))
            });
        chart
            .draw_series(LineSeries::new(truth, BLACK.stroke_width(1)))
            .map_err(plot_err(path))?
            .label("truth")
            .legend(|(x, y)| PathElement::new(vec![(x - 8, y), (x + 8, y)], BLACK));
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(plot_err(path))?;
    }
    root.present().map_err(plot_err(path))?;
    Ok(())
}

/// Horizontal error over time for each method.
fn error_over_time(path: &Path, title: &str, frames: &[FrameRecord]) -> anyhow::Result<()> {
    let root = BitMapBackend::new(path, (1400, 500)).into_drawing_area();
    root.fill(&WHITE).map_err(plot_err(path))?;
    let t_max = frames.last().map(|f| f.time_s).unwrap_or(1.0).max(1.0);
    let lim = 20.0;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 22))
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(55)
        .build_cartesian_2d(0.0..t_max, 0.0..lim)
        .map_err(plot_err(path))?;
    chart
        .configure_mesh()
        .x_desc("time (s)")
        .y_desc("horizontal error (m)")
        .draw()
        .map_err(plot_err(path))?;
    let err = |pick: fn(&FrameRecord) -> Option<nalgebra::Point3<f64>>| -> Vec<(f64, f64)> {
        frames
            .iter()
            .filter_map(|f| {
                pick(f).map(|p| {
                    (
                        f.time_s,
                        (p - f.truth.position_in_world).xy().norm().min(lim),
                    )
                })
            })
            .collect()
    };
    for (pick, colour, name) in [
        (
            (|f: &FrameRecord| f.paper) as fn(&FrameRecord) -> _,
            SEED,
            "paper",
        ),
        (|f: &FrameRecord| f.rays, OURS, "ours per frame"),
    ] {
        chart
            .draw_series(
                err(pick)
                    .into_iter()
                    .map(|p| Circle::new(p, 1, colour.mix(0.5).filled())),
            )
            .map_err(plot_err(path))?
            .label(name)
            .legend(move |(x, y)| Circle::new((x, y), 4, colour.filled()));
    }
    chart
        .draw_series(LineSeries::new(
            err(|f| f.filtered),
            FILTERED.stroke_width(2),
        ))
        .map_err(plot_err(path))?
        .label("ours + EKF")
        .legend(|(x, y)| PathElement::new(vec![(x - 8, y), (x + 8, y)], FILTERED.stroke_width(2)));
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(plot_err(path))?;
    root.present().map_err(plot_err(path))?;
    Ok(())
}

/// Every plot for the runs of `loc_eval_cmd::cases`.
pub fn write(out: &Path, runs: &[(String, EvalRun, f64)]) -> anyhow::Result<()> {
    register_font()?;
    let first = &runs.first().context("no runs to plot")?.1;
    // The same errors, against box height (Fig. 11) and true distance (Fig. 12).
    let errors_against = |x: fn(&TowerRecord) -> f64| -> Vec<ErrorPoint> {
        first
            .towers
            .iter()
            .map(|t| {
                (
                    x(t),
                    t.paper_e - t.true_e,
                    t.paper_d - t.true_d,
                    t.rays_e
                        .zip(t.rays_d)
                        .map(|(e, d)| (e - t.true_e, d - t.true_d)),
                )
            })
            .collect()
    };
    scatter(
        &out.join("ed_error_vs_box_height.png"),
        "E and D error against box height h (paper-path-1; paper's Fig. 11)",
        "box height h (px)",
        &errors_against(|t| t.box_height_px),
        0.0..720.0,
    )?;
    scatter(
        &out.join("ed_error_vs_distance.png"),
        "E and D error against true distance D (paper-path-1; paper's Fig. 12)",
        "true distance D (m)",
        &errors_against(|t| t.true_d),
        0.0..900.0,
    )?;
    for (name, run, outliers) in runs {
        let slug: String = name
            .chars()
            .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
            .collect();
        let slug = slug.trim_matches('_').replace("__", "_");
        if *outliers == 0.0 {
            path_xy(
                &out.join(format!("path_xy_{slug}.png")),
                &format!("x and y along {name} (paper's Fig. 13)"),
                &run.frames,
            )?;
        }
        error_over_time(
            &out.join(format!("error_over_time_{slug}.png")),
            &format!("Horizontal error over time: {name}"),
            &run.frames,
        )?;
    }
    Ok(())
}
