//! `towernav-edge eval-localization`: the paper's analysis, reproduced, with
//! tables printed and plots written as PNG.

use std::path::Path;

use anyhow::Context;
use comfy_table::Table;
use towernav_sim::{Scenario, World};

use crate::loc_eval::{EvalRun, Summary, per_type_std, run};
use crate::sim_eval::ErrorStats;
use towernav_core::landmarks::LandmarkMap;
use towernav_core::pipeline::PipelineConfig;

/// The runs the evaluation makes: name, scenario, outlier share.
pub fn cases(seed: u64) -> anyhow::Result<Vec<(String, Scenario, f64)>> {
    let path = |name: &str| -> anyhow::Result<Scenario> {
        Ok(Scenario::preset(World::paper_field(), name, seed)?)
    };
    Ok(vec![
        ("paper-path-1".into(), path("paper-path-1")?, 0.0),
        ("paper-path-2".into(), path("paper-path-2")?, 0.0),
        (
            "paper-path-1, 20 % outliers".into(),
            path("paper-path-1")?,
            0.2,
        ),
        ("skeleton level flight".into(), Scenario::paper(seed), 0.0),
    ])
}

pub fn evaluate(scenario: &Scenario, outliers: f64, seed: u64) -> EvalRun {
    let map = LandmarkMap::from_records(&scenario.world.landmarks(), &scenario.world.datum);
    let config = PipelineConfig::new(scenario.camera, scenario.start_in_world());
    run(scenario, &map, config, outliers, seed)
}

fn cell(s: &ErrorStats) -> String {
    format!("{:.2} / {:.2} / {:.1} ({})", s.rms, s.p95, s.max, s.count)
}

pub fn summary_table(rows: &[(String, Summary)]) -> Table {
    let mut table = Table::new();
    table.set_header([
        "run",
        "paper: RMS / p95 / max m (fixes)",
        "ours per frame",
        "ours + EKF",
        "EKF mean NEES (2 dof)",
        "binding accuracy",
    ]);
    for (name, s) in rows {
        table.add_row([
            name.clone(),
            cell(&s.paper),
            cell(&s.rays),
            cell(&s.filtered),
            format!("{:.2}", s.filtered_mean_nees_h),
            format!("{:.2} %", 100.0 * s.binding_accuracy),
        ]);
    }
    table
}

pub fn type_table(run: &EvalRun) -> Table {
    let mut table = Table::new();
    table.set_header(["type", "boxes", "paper std E / D (m)", "ours std E / D (m)"]);
    let seed = per_type_std(&run.towers, false);
    let ours = per_type_std(&run.towers, true);
    for (s, o) in seed.iter().zip(&ours) {
        table.add_row([
            s.0.to_string(),
            s.1.to_string(),
            format!("{:.2} / {:.2}", s.2, s.3),
            format!("{:.2} / {:.2}", o.2, o.3),
        ]);
    }
    table
}

pub fn write_all(out: &Path, seed: u64) -> anyhow::Result<()> {
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let mut rows = Vec::new();
    let mut runs = Vec::new();
    for (name, scenario, outliers) in cases(seed)? {
        let r = evaluate(&scenario, outliers, seed);
        rows.push((name.clone(), r.summary()));
        runs.push((name, r, outliers));
    }
    println!(
        "Horizontal error on the paper's field (oracle detector, quadrotor attitude on the paper's paths):"
    );
    println!("{}", summary_table(&rows));
    if let Some((_, r, _)) = runs.first() {
        println!("\nPer tower type on paper-path-1 (the paper's Table 3): std of E and D error");
        println!("{}", type_table(r));
    }
    super::loc_plots::write(out, &runs)?;
    println!("\nplots in {}", out.display());
    Ok(())
}
