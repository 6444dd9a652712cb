//! The localization evaluation (pure): fly a scenario through the pipeline with
//! the paper's method computed on the same observations, optionally corrupt a
//! share of the observations, and record everything the paper's figures plot.

use nalgebra::{Point3, Vector2};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use towernav_geometry::{PixelBox, Pose};
use towernav_protocol::TowerType;
use towernav_sim::Scenario;

use crate::mot_metrics::MotAccumulator;
use crate::sim_eval::{ErrorStats, error_stats};
use crate::tracking_eval::{add_frame, pipeline_hypotheses};
use towernav_core::landmarks::LandmarkMap;
use towernav_core::localizer::{Observation, paper_range, single_tower_position};
use towernav_core::pipeline::{BoundBox, FrameOutput, Pipeline, PipelineConfig};

/// Per frame: truth and what each method said.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameRecord {
    pub time_s: f64,
    pub truth: Pose,
    pub paper: Option<Point3<f64>>,
    pub rays: Option<Point3<f64>>,
    pub filtered: Option<Point3<f64>>,
    /// Squared Mahalanobis error of the filtered horizontal position (2 dof).
    pub filtered_nees_h: Option<f64>,
}

/// Per correctly bound tower and frame: true and measured (E, D), the paper's
/// lateral offset and range in the camera's horizontal frame, by both geometries.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TowerRecord {
    pub tower_type: TowerType,
    pub box_height_px: f64,
    pub true_e: f64,
    pub true_d: f64,
    pub paper_e: f64,
    pub paper_d: f64,
    /// Ours: attitude-compensated rays (None where the rays do not bracket the tower).
    pub rays_e: Option<f64>,
    pub rays_d: Option<f64>,
}

#[derive(Debug, Clone, Default)]
pub struct EvalRun {
    pub frames: Vec<FrameRecord>,
    pub towers: Vec<TowerRecord>,
    pub observations: usize,
    pub corrupted: usize,
    /// Of bound track-frames, the share bound to the right tower (`mot_metrics`).
    pub binding_accuracy: f64,
}

/// Horizontal error statistics of each method over the frames where it gave a position.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Summary {
    pub paper: ErrorStats,
    pub rays: ErrorStats,
    pub filtered: ErrorStats,
    /// Mean horizontal NEES of the filter (2 is consistent).
    pub filtered_mean_nees_h: f64,
    pub frames: usize,
    /// Of bound track-frames, the share bound to the right tower.
    pub binding_accuracy: f64,
}

impl EvalRun {
    pub fn summary(&self) -> Summary {
        let errs = |f: &dyn Fn(&FrameRecord) -> Option<Point3<f64>>| -> Vec<f64> {
            self.frames
                .iter()
                .filter_map(|r| f(r).map(|p| (p - r.truth.position_in_world).xy().norm()))
                .collect()
        };
        let nees: Vec<f64> = self
            .frames
            .iter()
            .filter_map(|r| r.filtered_nees_h)
            .collect();
        Summary {
            paper: error_stats(&errs(&|r| r.paper)),
            rays: error_stats(&errs(&|r| r.rays)),
            filtered: error_stats(&errs(&|r| r.filtered)),
            filtered_mean_nees_h: if nees.is_empty() {
                0.0
            } else {
                nees.iter().sum::<f64>() / nees.len() as f64
            },
            frames: self.frames.len(),
            binding_accuracy: self.binding_accuracy,
        }
    }
}

/// Replace `share` of the bound boxes: half get another tower's identity, half
/// become false boxes of tower-like shape somewhere in the image.
fn corrupt(
    bound: &mut [BoundBox],
    share: f64,
    towers: usize,
    rng: &mut ChaCha8Rng,
    k: (f64, f64),
) -> usize {
    let mut n = 0;
    for b in bound.iter_mut() {
        if share <= 0.0 || !rng.random_bool(share.min(1.0)) {
            continue;
        }
        n += 1;
        if rng.random_bool(0.5) && towers > 1 {
            let other = (b.tower + rng.random_range(1..towers)) % towers;
            b.tower = other;
        } else {
            let h = rng.random_range(20.0..200.0);
            let w = h * rng.random_range(0.2..0.5);
            let x = rng.random_range(0.0..(k.0 - w));
            let y = rng.random_range(0.0..(k.1 - h));
            b.bbox = PixelBox::new(x, y, x + w, y + h);
        }
    }
    n
}

/// Fly `scenario` through a pipeline made by `config`; `outlier_share` of the
/// bound observations are corrupted (deterministically in `seed`).
pub fn run(
    scenario: &Scenario,
    map: &LandmarkMap,
    mut config: PipelineConfig,
    outlier_share: f64,
    seed: u64,
) -> EvalRun {
    config.compare_paper = true;
    let camera = config.camera;
    let mut pipeline = Pipeline::new(config, map.clone());
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x0a7_11e5);
    let k = &camera.intrinsics;
    let size = (f64::from(k.width), f64::from(k.height));
    let mut run = EvalRun::default();
    let mut identity = MotAccumulator::default();
    for (truth, frame) in scenario.frames() {
        let mut corrupted = 0;
        let mut observed = 0;
        let out: FrameOutput = pipeline.process_tampered(&frame, |bound| {
            observed = bound.len();
            corrupted = corrupt(bound, outlier_share, map.towers.len(), &mut rng, size);
        });
        add_frame(
            &mut identity,
            scenario,
            &truth,
            &pipeline_hypotheses(&out, map),
        );
        run.observations += observed;
        run.corrupted += corrupted;
        let p = truth.pose.position_in_world;
        let filtered_nees_h = out.estimate.as_ref().and_then(|e| {
            let d = Vector2::new(e.position_in_world.x - p.x, e.position_in_world.y - p.y);
            let c = e.covariance.fixed_view::<2, 2>(0, 0).into_owned();
            c.try_inverse().map(|ci| (d.transpose() * ci * d)[(0, 0)])
        });
        run.frames.push(FrameRecord {
            time_s: truth.time_s,
            truth: truth.pose,
            paper: out.paper_fix.as_ref().map(|f| f.position_in_world),
            rays: out.fix.as_ref().map(|f| f.position_in_world),
            filtered: out.estimate.as_ref().map(|e| e.position_in_world),
            filtered_nees_h,
        });
        // Per-tower geometry, only where the track is bound to its true tower
        // (so E/D errors measure geometry, not identity).
        if outlier_share > 0.0 {
            continue;
        }
        let yaw = truth.pose.attitude.yaw;
        let forward = Vector2::new(yaw.cos(), yaw.sin());
        let right = Vector2::new(yaw.sin(), -yaw.cos());
        for t in &out.tracks {
            let Some(i) = t.tower else { continue };
            let tower = &map.towers[i];
            let Some(tb) = truth.boxes.iter().find(|b| b.tower_id == tower.id) else {
                continue;
            };
            if tb.truncated || tb.bbox.iou(&t.bbox) < 0.5 {
                continue;
            }
            let h = t.bbox.height();
            if h < 8.0 {
                continue;
            }
            let rel = (tower.foot_in_world - p).xy();
            let (true_e, true_d) = (rel.dot(&right), rel.dot(&forward));
            let (paper_d, paper_e) = paper_range(k, tower.height_m, &t.bbox);
            let obs = Observation::new(tower, t.bbox, 1.0);
            let ours = single_tower_position(&obs, &camera, &frame.imu_attitude).map(|q| {
                let rel = (tower.foot_in_world - q).xy();
                (rel.dot(&right), rel.dot(&forward))
            });
            run.towers.push(TowerRecord {
                tower_type: tower.tower_type,
                box_height_px: h,
                true_e,
                true_d,
                paper_e,
                paper_d,
                rays_e: ours.map(|o| o.0),
                rays_d: ours.map(|o| o.1),
            });
        }
    }
    run.binding_accuracy = identity.finish().binding_accuracy;
    run
}

/// Standard deviation of (measured - true) E and D per tower type: the paper's Table 3.
pub fn per_type_std(towers: &[TowerRecord], ours: bool) -> Vec<(TowerType, usize, f64, f64)> {
    TowerType::ALL
        .iter()
        .map(|&t| {
            let (mut de, mut dd) = (Vec::new(), Vec::new());
            for r in towers.iter().filter(|r| r.tower_type == t) {
                let (e, d) = if ours {
                    match (r.rays_e, r.rays_d) {
                        (Some(e), Some(d)) => (e, d),
                        _ => continue,
                    }
                } else {
                    (r.paper_e, r.paper_d)
                };
                de.push(e - r.true_e);
                dd.push(d - r.true_d);
            }
            (t, de.len(), std_dev(&de), std_dev(&dd))
        })
        .collect()
}

fn std_dev(v: &[f64]) -> f64 {
    if v.len() < 2 {
        return 0.0;
    }
    let mean = v.iter().sum::<f64>() / v.len() as f64;
    (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (v.len() - 1) as f64).sqrt()
}
