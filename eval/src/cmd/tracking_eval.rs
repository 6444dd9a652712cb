//! `towernav-edge eval-tracking`: the paper's Table 2 for every tracker and for
//! ours, on the paper's paths and seeded random fields, with MOT-challenge files.

use std::io::Write;
use std::path::Path;

use anyhow::Context;
use comfy_table::Table;
use towernav_sim::world::WorldParams;
use towernav_sim::{Scenario, World};

use crate::tracking_eval::{Method, TrackingRun, describe_all, render_features, run};
use towernav_core::landmarks::LandmarkMap;
use towernav_onnx::runtime::{OnnxError, ReidModel};

/// Scenarios: the paper's two paths over its field, and two random fields.
pub fn cases(seed: u64) -> anyhow::Result<Vec<(String, Scenario)>> {
    let mut out = Vec::new();
    for path in ["paper-path-1", "paper-path-2"] {
        out.push((
            path.to_string(),
            Scenario::preset(World::paper_field(), path, seed)?,
        ));
    }
    for w in 0..2u64 {
        let world_seed = seed.wrapping_mul(7919).wrapping_add(w);
        let world = World::random(world_seed, &WorldParams::default());
        let extent = WorldParams::default().extent_m;
        let towers: Vec<(f64, f64, f64)> = world
            .towers
            .iter()
            .map(|t| (t.foot_in_world.x, t.foot_in_world.y, t.height_m))
            .collect();
        use rand::SeedableRng;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(world_seed);
        let plan = towernav_sim::waypoints::random_crossing(extent, &towers, &mut rng);
        out.push((
            format!("random field {world_seed}"),
            Scenario::flying(world, &plan, seed),
        ));
    }
    Ok(out)
}

/// The benchmark's name in TrackEval's layout (`gt/mot_challenge/TOWERS-train/`).
pub const BENCHMARK: &str = "TOWERS";

/// One MOT-challenge results file: `frame,id,left,top,width,height,conf,-1,-1,-1`.
/// Identities that are not numbers (tower ids) are numbered in order of appearance.
pub fn write_mot(path: &Path, r: &TrackingRun) -> anyhow::Result<()> {
    let mut file = std::io::BufWriter::new(
        std::fs::File::create(path).with_context(|| format!("creating {}", path.display()))?,
    );
    let mut numbers: std::collections::HashMap<&str, usize> = std::collections::HashMap::new();
    for (seq, hyps) in &r.frames {
        for h in hyps {
            let next = numbers.len() + 1;
            let id = *numbers.entry(h.id.as_str()).or_insert(next);
            writeln!(
                file,
                "{},{},{:.2},{:.2},{:.2},{:.2},1,-1,-1,-1",
                seq + 1,
                id,
                h.bbox.left,
                h.bbox.top,
                h.bbox.width(),
                h.bbox.height()
            )?;
        }
    }
    file.flush()
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}

/// `reid`: an ONNX re-identification model for DeepSORT's appearance instead
/// of the Rust crop descriptor.
pub fn write_all(out: &Path, seed: u64, reid: Option<&Path>) -> anyhow::Result<()> {
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let split = format!("{BENCHMARK}-train");
    let gt_root = out.join("gt").join("mot_challenge");
    let trackers_root = out.join("trackers").join("mot_challenge").join(&split);
    let mut seqmap = String::from("name\n");
    let mut model = reid.map(|p| ReidModel::load(p, 2)).transpose()?;
    let mut failure: Option<OnnxError> = None;
    for (name, scenario) in cases(seed)? {
        let map = LandmarkMap::from_records(&scenario.world.landmarks(), &scenario.world.datum);
        let mut table = Table::new();
        table.set_header([
            "method",
            "IDs / true towers",
            "repetitive",
            "hop",
            "ID switches",
            "frag",
            "MOTA",
            "IDF1",
            "HOTA",
            "DetA",
            "AssA",
            "binding accuracy",
            "bound share",
        ]);
        let bar = indicatif::ProgressBar::new(scenario.frame_count());
        bar.set_message(format!("rendering {name} for appearance"));
        let mut describe =
            |image: &image::RgbImage, boxes: &[towernav_geometry::PixelBox]| match &mut model {
                Some(m) => m.embed(image, boxes).unwrap_or_else(|e| {
                    failure.get_or_insert(e);
                    describe_all(image, boxes)
                }),
                None => describe_all(image, boxes),
            };
        let features = render_features(&scenario, &mut describe, |seq| bar.set_position(seq + 1));
        bar.finish_and_clear();
        if let Some(e) = failure.take() {
            return Err(e.into());
        }
        let slug: String = name
            .chars()
            .map(|c| if c.is_ascii_alphanumeric() { c } else { '-' })
            .collect();
        write_gt(&gt_root.join(&split).join(&slug), &slug, &scenario)?;
        seqmap.push_str(&slug);
        seqmap.push('\n');
        for method in Method::ALL {
            let r = run(&scenario, &map, method, Some(&features));
            let m = r.metrics;
            let binds = method == Method::Ours;
            table.add_row([
                method.name().to_string(),
                format!("{} / {}", m.distinct_ids, m.true_towers),
                m.repetitive_errors.to_string(),
                m.hop_errors.to_string(),
                m.id_switches.to_string(),
                m.fragmentations.to_string(),
                format!("{:.3}", m.mota),
                format!("{:.3}", m.idf1),
                format!("{:.3}", m.hota.hota),
                format!("{:.3}", m.hota.det_a),
                format!("{:.3}", m.hota.ass_a),
                if binds {
                    format!("{:.2} %", 100.0 * m.binding_accuracy)
                } else {
                    "-".into()
                },
                if binds {
                    format!("{:.1} %", 100.0 * m.binding_coverage)
                } else {
                    "-".into()
                },
            ]);
            let data = trackers_root.join(method.slug()).join("data");
            std::fs::create_dir_all(&data)
                .with_context(|| format!("creating {}", data.display()))?;
            write_mot(&data.join(format!("{slug}.txt")), &r)?;
        }
        println!(
            "{name} ({} towers, {} frames, oracle detector; DeepSORT appearance: {}):\n{table}\n",
            scenario.world.towers.len(),
            scenario.frame_count(),
            reid.map_or("Rust crop descriptor".to_string(), |p| p
                .display()
                .to_string())
        );
    }
    let seqmaps = gt_root.join("seqmaps");
    std::fs::create_dir_all(&seqmaps).with_context(|| format!("creating {}", seqmaps.display()))?;
    let seqmap_path = seqmaps.join(format!("{split}.txt"));
    std::fs::write(&seqmap_path, seqmap)
        .with_context(|| format!("writing {}", seqmap_path.display()))?;
    println!(
        "MOT-challenge ground truth and results in {} (TrackEval's layout: --GT_FOLDER {} \
         --TRACKERS_FOLDER {} --BENCHMARK {BENCHMARK} --SPLIT_TO_EVAL train)",
        out.display(),
        gt_root.display(),
        out.join("trackers").join("mot_challenge").display()
    );
    Ok(())
}

/// One scenario's ground truth: `gt/gt.txt`, `gt/towers.csv`, `seqinfo.ini`.
fn write_gt(dir: &Path, name: &str, scenario: &Scenario) -> anyhow::Result<()> {
    let frames: Vec<_> = (0..scenario.frame_count())
        .map(|s| scenario.truth(s))
        .collect();
    for (file, text) in towernav_sim::mot::sequence_files(name, scenario, &frames)? {
        let path = dir.join(file);
        if let Some(parent) = path.parent() {
            std::fs::create_dir_all(parent)
                .with_context(|| format!("creating {}", parent.display()))?;
        }
        std::fs::write(&path, text).with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}
