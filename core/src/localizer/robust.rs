//! Ours: weighted nonlinear least squares over (east, north, up, yaw) from the
//! rows and columns of every bound tower's box, with the IMU yaw as a prior,
//! a Cauchy loss, chi-square gating of whole towers, and a start chosen among
//! single-tower solutions (RANSAC over towers) so a wrong tower cannot drag it.

use nalgebra::{Matrix4, Point3, Vector4};
use towernav_geometry::{Attitude, PinholeCamera, wrap_angle};

use super::measurement::{Residual, Usable, residuals};
use super::single::single_tower_position;
use super::{Fix, Height, LocalizerParams, Observation};
use towernav_geometry::FrameCamera;

/// Chi-square at 99.9 % for 1, 2 and 3 degrees of freedom: a tower whose
/// residuals exceed this is taken to be the wrong tower or a false box.
const GATE: [f64; 4] = [0.0, 10.83, 13.82, 16.27];
/// At most this many towers seed start hypotheses (the tallest boxes).
const MAX_STARTS: usize = 4;
const MAX_ITERATIONS: usize = 15;
/// Measured numbers needed for the three position unknowns.
const MIN_ROWS: usize = 3;

/// The fix with what the solver decided about each observation.
#[derive(Debug, Clone, PartialEq)]
pub struct RobustFix {
    pub fix: Fix,
    /// Indices into the observations: used in the fix, and gated out.
    pub used: Vec<usize>,
    pub rejected: Vec<usize>,
}

struct Candidate<'a, 'b> {
    index: usize,
    obs: &'b Observation<'a>,
    usable: Usable,
    active: bool,
}

/// Solve one frame. `prior_position` (the filter's prediction) joins the start
/// hypotheses only; it does not enter the fix, so fix and filter stay independent.
pub fn robust_lbl(
    observations: &[Observation<'_>],
    camera: &PinholeCamera,
    imu: &Attitude,
    prior_position: Option<Point3<f64>>,
    params: &LocalizerParams,
) -> Option<RobustFix> {
    robust_lbl_with_height(observations, camera, imu, prior_position, None, params)
}

/// [`robust_lbl`] with the camera's height measured by another sensor (the
/// barometer): one more measured number, so one tower cut by the image edge
/// (its foot row and axis column left) still gives a fix, as banked turns
/// often leave it.
pub fn robust_lbl_with_height(
    observations: &[Observation<'_>],
    camera: &PinholeCamera,
    imu: &Attitude,
    prior_position: Option<Point3<f64>>,
    height: Option<Height>,
    params: &LocalizerParams,
) -> Option<RobustFix> {
    let frame = FrameCamera::new(camera, imu);
    let mut cands = candidates(observations, camera, params);
    if cands.is_empty() {
        return None;
    }
    let height =
        height.filter(|h| h.up_m.is_finite() && h.sigma_m > 0.0 && !Height::is_unknown(h.sigma_m));
    let extra_rows = usize::from(height.is_some());
    let mut scratch = Vec::with_capacity(3);
    let mut position = best_start(
        &cands,
        &frame,
        camera,
        imu,
        prior_position,
        params,
        &mut scratch,
    )?;
    let mut yaw = imu.yaw;

    // Solve, gate the worst tower, re-solve from there, until all pass.
    let mut information;
    loop {
        let state = State {
            position,
            yaw,
            imu_yaw: imu.yaw,
            height,
        };
        let solved = solve(&cands, &frame, state, params, &mut scratch)?;
        (position, yaw, information) = solved;
        let worst = cands
            .iter()
            .enumerate()
            .filter(|(_, c)| c.active)
            .map(|(i, c)| {
                let chi2 = tower_chi2(c, &frame, &position, yaw, params, &mut scratch);
                (i, chi2 / GATE[c.usable.count()])
            })
            .max_by(|a, b| a.1.total_cmp(&b.1));
        match worst {
            Some((i, ratio)) if ratio > 1.0 && rows_without(&cands, i) + extra_rows >= MIN_ROWS => {
                cands[i].active = false
            }
            _ => break,
        }
    }
    // Three position unknowns need three measured numbers (yaw has its prior);
    // fewer, or a geometry that leaves a direction unseen, is no fix.
    if rows_without(&cands, usize::MAX) + extra_rows < MIN_ROWS {
        return None;
    }
    let covariance = covariance_if_observable(&information)?;
    let horizontal_sigma = (covariance[(0, 0)] + covariance[(1, 1)]).sqrt();
    if !horizontal_sigma.is_finite() || horizontal_sigma > params.max_horizontal_sigma_m {
        return None;
    }
    let (used, rejected): (Vec<&Candidate>, Vec<&Candidate>) = cands.iter().partition(|c| c.active);
    Some(RobustFix {
        fix: Fix {
            position_in_world: position,
            yaw,
            covariance,
            towers_used: used.iter().map(|c| c.obs.tower.id.clone()).collect(),
        },
        used: used.iter().map(|c| c.index).collect(),
        rejected: rejected.iter().map(|c| c.index).collect(),
    })
}

/// The observations with a box tall enough and an edge inside the image.
fn candidates<'a, 'b>(
    observations: &'b [Observation<'a>],
    camera: &PinholeCamera,
    params: &LocalizerParams,
) -> Vec<Candidate<'a, 'b>> {
    observations
        .iter()
        .enumerate()
        .filter(|(_, o)| o.raw.is_finite() && o.raw.height() >= params.min_box_height_px)
        .map(|(index, obs)| Candidate {
            index,
            obs,
            usable: Usable::of(obs, &camera.intrinsics, params),
            active: true,
        })
        .filter(|c| c.usable.count() > 0)
        .collect()
}

/// The start that most towers agree with: among the prior and the
/// single-tower solutions of the tallest boxes, the least gated cost.
fn best_start(
    cands: &[Candidate<'_, '_>],
    frame: &FrameCamera,
    camera: &PinholeCamera,
    imu: &Attitude,
    prior_position: Option<Point3<f64>>,
    params: &LocalizerParams,
    scratch: &mut Vec<Residual>,
) -> Option<Point3<f64>> {
    let mut starts: Vec<Point3<f64>> = prior_position.into_iter().collect();
    let mut by_height: Vec<&Candidate> = cands
        .iter()
        .filter(|c| c.usable.top && c.usable.bottom)
        .collect();
    by_height.sort_by(|a, b| b.obs.bbox.height().total_cmp(&a.obs.bbox.height()));
    starts.extend(
        by_height
            .iter()
            .take(MAX_STARTS)
            .filter_map(|c| single_tower_position(c.obs, camera, imu)),
    );
    let mut cost = |p: &Point3<f64>| -> f64 {
        cands
            .iter()
            .map(|c| {
                let chi2 = tower_chi2(c, frame, p, imu.yaw, params, scratch);
                chi2.min(GATE[c.usable.count()])
            })
            .sum()
    };
    starts
        .iter()
        .map(|p| (cost(p), *p))
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .map(|(_, p)| p)
}

/// The covariance, unless the information leaves a direction unseen.
fn covariance_if_observable(information: &Matrix4<f64>) -> Option<Matrix4<f64>> {
    let eigen = information.symmetric_eigen();
    let (min_eig, max_eig) = eigen
        .eigenvalues
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(lo, hi), &e| {
            (lo.min(e), hi.max(e))
        });
    if min_eig.is_nan() || min_eig <= max_eig * 1e-12 {
        return None;
    }
    information.try_inverse()
}

/// Measured numbers of the active towers, leaving out tower `skip`.
fn rows_without(cands: &[Candidate<'_, '_>], skip: usize) -> usize {
    cands
        .iter()
        .enumerate()
        .filter(|(i, c)| c.active && *i != skip)
        .map(|(_, c)| c.usable.count())
        .sum()
}

/// Sum of squared normalised residuals of one tower; infinite when it is behind the camera.
fn tower_chi2(
    c: &Candidate<'_, '_>,
    frame: &FrameCamera,
    position: &Point3<f64>,
    yaw: f64,
    params: &LocalizerParams,
    scratch: &mut Vec<Residual>,
) -> f64 {
    if !residuals(c.obs, c.usable, frame, position, yaw, params, scratch) {
        return f64::INFINITY;
    }
    scratch.iter().map(|r| (r.r / r.sigma).powi(2)).sum()
}

/// Cauchy loss of a normalised residual: quadratic near zero, and a gross
/// outlier's pull fades instead of staying constant (as Huber's does), so a
/// near tower with a wrong box cannot drag the solution by its leverage.
fn cauchy(n: f64, k: f64) -> f64 {
    0.5 * k * k * (1.0 + (n / k).powi(2)).ln()
}

/// The IRLS weight of the Cauchy loss.
fn cauchy_weight(n: f64, k: f64) -> f64 {
    1.0 / (1.0 + (n / k).powi(2))
}

/// The robust cost the solver minimises (Cauchy over every active residual plus
/// the yaw prior) and its IRLS normal equations, in one pass over the towers.
/// The cost is infinite when a tower falls behind the camera at this state.
struct Linearized {
    cost: f64,
    h: Matrix4<f64>,
    g: Vector4<f64>,
}

/// Where the solver stands, and the priors it weighs: the IMU's yaw and the
/// barometer's height.
#[derive(Debug, Clone, Copy)]
struct State {
    position: Point3<f64>,
    yaw: f64,
    imu_yaw: f64,
    height: Option<Height>,
}

fn linearize(
    cands: &[Candidate<'_, '_>],
    frame: &FrameCamera,
    state: &State,
    params: &LocalizerParams,
    scratch: &mut Vec<Residual>,
) -> Linearized {
    let (position, yaw) = (&state.position, state.yaw);
    let prior_info = 1.0 / params.yaw_sigma.max(1e-6).powi(2);
    let yaw_error = wrap_angle(state.imu_yaw - yaw);
    let mut out = Linearized {
        cost: 0.5 * yaw_error * yaw_error * prior_info,
        h: Matrix4::zeros(),
        g: Vector4::zeros(),
    };
    out.h[(3, 3)] = prior_info;
    out.g[3] = yaw_error * prior_info;
    if let Some(h) = state.height {
        let info = 1.0 / (h.sigma_m * h.sigma_m);
        let r = h.up_m - position.z;
        out.cost += 0.5 * r * r * info;
        out.h[(2, 2)] += info;
        out.g[2] += r * info;
    }
    for c in cands.iter().filter(|c| c.active) {
        if !residuals(c.obs, c.usable, frame, position, yaw, params, scratch) {
            out.cost = f64::INFINITY;
            continue;
        }
        for r in scratch.iter() {
            let n = r.r / r.sigma;
            out.cost += cauchy(n, params.robust_k);
            let w = cauchy_weight(n, params.robust_k) / (r.sigma * r.sigma);
            let jt = r.jacobian.transpose();
            out.h += jt * r.jacobian * w;
            out.g += jt * (r.r * w);
        }
    }
    out
}

/// Levenberg-Marquardt on iteratively reweighted normal equations over the
/// active towers: a step is taken only if it lowers the robust cost.
/// Returns the state and the information matrix (inverse covariance).
fn solve(
    cands: &[Candidate<'_, '_>],
    frame: &FrameCamera,
    start: State,
    params: &LocalizerParams,
    scratch: &mut Vec<Residual>,
) -> Option<(Point3<f64>, f64, Matrix4<f64>)> {
    let (mut position, mut yaw) = (start.position, start.yaw);
    let mut lambda = 1e-4;
    let mut here = linearize(cands, frame, &start, params, scratch);
    if !here.cost.is_finite() {
        return None;
    }
    for _ in 0..MAX_ITERATIONS {
        let mut improved = false;
        let mut small_step = false;
        while lambda < 1e8 {
            let mut damped = here.h;
            for i in 0..4 {
                damped[(i, i)] += lambda * here.h[(i, i)].max(1e-9);
            }
            let Some(chol) = damped.cholesky() else {
                lambda *= 10.0;
                continue;
            };
            let step = chol.solve(&here.g);
            if !step.iter().all(|v| v.is_finite()) {
                return None;
            }
            let candidate = position + step.fixed_rows::<3>(0).into_owned();
            let candidate_yaw = wrap_angle(yaw + step[3]);
            let there = linearize(
                cands,
                frame,
                &State {
                    position: candidate,
                    yaw: candidate_yaw,
                    ..start
                },
                params,
                scratch,
            );
            small_step = step.fixed_rows::<3>(0).norm() < 1e-4 && step[3].abs() < 1e-7;
            if there.cost <= here.cost {
                (position, yaw, here) = (candidate, candidate_yaw, there);
                lambda = (lambda * 0.3).max(1e-9);
                improved = true;
                break;
            }
            lambda *= 10.0;
            if small_step {
                break;
            }
        }
        if !improved || small_step {
            break;
        }
    }
    Some((position, yaw, here.h))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fixtures::tower;
    use crate::landmarks::MapTower;
    use proptest::prelude::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use rand_distr::StandardNormal;
    use towernav_geometry::{PixelBox, Pose};

    /// A box by the labeling convention with its centre on the axis, as the
    /// measurement model reads it; `noise` adds this spread to each edge.
    fn label(
        camera: &PinholeCamera,
        pose: &Pose,
        t: &MapTower,
        noise: Option<(&mut ChaCha8Rng, f64)>,
    ) -> Option<PixelBox> {
        let cfw = camera.world_from_camera(pose).inverse();
        let foot = camera.project(&(cfw * t.foot_in_world))?;
        let top = camera.project(&(cfw * t.top_in_world()))?;
        let centre = 0.5 * (foot.x + top.x);
        let mut b = PixelBox::new(centre - 6.0, top.y, centre + 6.0, foot.y);
        if let Some((rng, sigma)) = noise {
            let mut n = || sigma * rng.sample::<f64, _>(StandardNormal);
            let (dl, dt, db) = (n(), n(), n());
            // Left and right move together so the centre's spread is sigma / sqrt(2).
            let dr = n();
            b = PixelBox::new(b.left + dl, b.top + dt, b.right + dr, b.bottom + db);
        }
        let k = &camera.intrinsics;
        (b.left > 1.0
            && b.top > 1.0
            && b.right < f64::from(k.width) - 1.0
            && b.bottom < f64::from(k.height) - 1.0)
            .then_some(b)
    }

    fn field() -> Vec<MapTower> {
        vec![
            tower("A1", 150.0, 60.0, 32.0),
            tower("A2", 300.0, 60.0, 32.0),
            tower("B1", 120.0, -50.0, 38.0),
            tower("B2", 320.0, -50.0, 38.0),
            tower("C1", 250.0, 160.0, 45.0),
            tower("D1", 400.0, -150.0, 52.0),
        ]
    }

    fn observe<'a>(
        towers: &'a [MapTower],
        camera: &PinholeCamera,
        pose: &Pose,
        mut noise: Option<(&mut ChaCha8Rng, f64)>,
    ) -> Vec<Observation<'a>> {
        towers
            .iter()
            .filter_map(|t| {
                let n = noise.as_mut().map(|(rng, s)| (&mut **rng, *s));
                label(camera, pose, t, n).map(|bbox| Observation::new(t, bbox, 1.0))
            })
            .collect()
    }

    fn attitude(roll: f64, pitch: f64, yaw: f64) -> Attitude {
        Attitude { roll, pitch, yaw }
    }

    proptest! {
        /// Noiseless boxes from any reasonable attitude: the pose comes back within 1 cm.
        #[test]
        fn noiseless_inputs_recover_the_pose(
            x in -30.0f64..30.0, y in -30.0f64..30.0, z in 20.0f64..60.0,
            roll in -0.25f64..0.25, pitch in -0.25f64..0.1, yaw in -0.3f64..0.3,
        ) {
            let camera = PinholeCamera::default_hd();
            let pose = Pose { position_in_world: Point3::new(x, y, z), attitude: attitude(roll, pitch, yaw) };
            let towers = field();
            let obs = observe(&towers, &camera, &pose, None);
            prop_assume!(obs.len() >= 2);
            let fix = robust_lbl(&obs, &camera, &pose.attitude, None, &LocalizerParams::default()).expect("fix").fix;
            prop_assert!((fix.position_in_world - pose.position_in_world).norm() < 0.01,
                "{} vs {}", fix.position_in_world, pose.position_in_world);
            prop_assert!(wrap_angle(fix.yaw - yaw).abs() < 1e-5);
        }
    }

    /// A banked turn past a near tower: its top is cut by the image, leaving
    /// its foot row and axis column, two numbers for three unknowns. The
    /// barometer's height is the third.
    #[test]
    fn one_cut_tower_and_the_barometer_give_a_fix() {
        let camera = PinholeCamera::default_hd();
        let pose = Pose {
            position_in_world: Point3::new(0.0, 0.0, 30.0),
            attitude: attitude(0.25, -0.3, 0.0),
        };
        let near = [tower("B1", 70.0, 5.0, 45.0)];
        let cfw = camera.world_from_camera(&pose).inverse();
        let foot = camera
            .project(&(cfw * near[0].foot_in_world))
            .expect("foot");
        let top = camera
            .project(&(cfw * near[0].top_in_world()))
            .expect("top");
        assert!(
            top.y < 0.0 && foot.y < 700.0,
            "the top is out of the image, the foot in: {top} {foot}"
        );
        let centre = 0.5 * (foot.x + top.x);
        let obs = [Observation::new(
            &near[0],
            PixelBox::new(centre - 10.0, 0.0, centre + 10.0, foot.y),
            0.9,
        )];
        let params = LocalizerParams::default();
        let prior = Some(Point3::new(3.0, -2.0, 30.0));
        assert!(robust_lbl(&obs, &camera, &pose.attitude, prior, &params).is_none());
        let height = Height {
            up_m: 30.0,
            sigma_m: 0.5,
        };
        let fix =
            robust_lbl_with_height(&obs, &camera, &pose.attitude, prior, Some(height), &params)
                .expect("a fix")
                .fix;
        assert!(
            (fix.position_in_world - pose.position_in_world).norm() < 0.5,
            "{}",
            fix.position_in_world
        );
        // A height no one measured is no help.
        let unknown = Height::unknown(30.0);
        assert!(
            robust_lbl_with_height(&obs, &camera, &pose.attitude, prior, Some(unknown), &params)
                .is_none()
        );
    }

    #[test]
    fn towers_pull_a_biased_imu_yaw_back() {
        let camera = PinholeCamera::default_hd();
        let pose = Pose {
            position_in_world: Point3::new(0.0, 0.0, 30.0),
            attitude: attitude(0.02, -0.08, 0.1),
        };
        let towers = field();
        let obs = observe(&towers, &camera, &pose, None);
        // Heading two degrees off, trusted to five degrees.
        let imu = attitude(0.02, -0.08, 0.1 + 2f64.to_radians());
        let params = LocalizerParams {
            yaw_sigma: 5f64.to_radians(),
            ..LocalizerParams::default()
        };
        let fix = robust_lbl(&obs, &camera, &imu, None, &params)
            .expect("fix")
            .fix;
        assert!(
            wrap_angle(fix.yaw - 0.1).abs() < 0.05f64.to_radians(),
            "yaw error {}",
            (fix.yaw - 0.1).to_degrees()
        );
        assert!((fix.position_in_world - pose.position_in_world).norm() < 0.2);
    }

    #[test]
    fn a_single_tower_needs_and_uses_the_imu_yaw() {
        let camera = PinholeCamera::default_hd();
        let pose = Pose {
            position_in_world: Point3::new(0.0, 0.0, 30.0),
            attitude: attitude(0.05, -0.1, 0.1),
        };
        let towers = vec![tower("A1", 150.0, 20.0, 32.0)];
        let obs = observe(&towers, &camera, &pose, None);
        let fix = robust_lbl(
            &obs,
            &camera,
            &pose.attitude,
            None,
            &LocalizerParams::default(),
        )
        .expect("fix")
        .fix;
        assert!((fix.position_in_world - pose.position_in_world).norm() < 0.01);
        // Position across the line of sight rests on the yaw prior: its spread says so.
        let cov = fix.covariance;
        assert!(cov[(1, 1)].sqrt() > 150.0 * LocalizerParams::default().yaw_sigma * 0.9);
    }

    #[test]
    fn collinear_towers_still_give_a_fix_with_the_yaw_prior() {
        let camera = PinholeCamera::default_hd();
        let pose = Pose {
            position_in_world: Point3::new(0.0, 0.0, 30.0),
            attitude: attitude(0.0, -0.08, 0.0),
        };
        // All on one line straight ahead: bearing alone cannot fix yaw.
        let towers = vec![
            tower("A1", 120.0, 0.0, 32.0),
            tower("A2", 220.0, 0.0, 38.0),
            tower("A3", 320.0, 0.0, 45.0),
        ];
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let obs = observe(&towers, &camera, &pose, Some((&mut rng, 1.0)));
        assert_eq!(obs.len(), 3);
        let fix = robust_lbl(
            &obs,
            &camera,
            &pose.attitude,
            None,
            &LocalizerParams::default(),
        )
        .expect("fix")
        .fix;
        assert!(
            (fix.position_in_world - pose.position_in_world).xy().norm() < 2.0,
            "{}",
            fix.position_in_world
        );
    }

    #[test]
    fn boxes_cut_by_the_edge_use_only_their_honest_edges() {
        let camera = PinholeCamera::default_hd();
        let pose = Pose {
            position_in_world: Point3::new(0.0, 0.0, 30.0),
            attitude: attitude(0.0, -0.05, 0.0),
        };
        let towers = field();
        let mut obs = observe(&towers, &camera, &pose, None);
        // A near tower whose foot is below the image: its bottom edge is the border.
        let near = tower("N1", 40.0, 5.0, 45.0);
        let cfw = camera.world_from_camera(&pose).inverse();
        let top = camera.project(&(cfw * near.top_in_world())).expect("top");
        let foot = camera
            .project(&(cfw * near.foot_in_world))
            .expect("foot, below the image");
        assert!(foot.y > 720.0);
        let centre = 0.5 * (top.x + foot.x);
        obs.push(Observation::new(
            &near,
            PixelBox::new(centre - 30.0, top.y, centre + 30.0, 720.0),
            0.9,
        ));
        let fix = robust_lbl(
            &obs,
            &camera,
            &pose.attitude,
            None,
            &LocalizerParams::default(),
        )
        .expect("fix");
        assert!((fix.fix.position_in_world - pose.position_in_world).norm() < 0.01);
        assert!(
            fix.fix.towers_used.contains(&"N1".to_string()),
            "its top and centre still count"
        );
    }

    /// A near tower whose foot is below the image, boxed as a learned
    /// detector boxes it: the bottom stops 40 px short of the border. Taken
    /// as the foot, it moves the fix by metres; taken as cut by the margin
    /// share, the top, the axis and the barometer give the pose.
    #[test]
    fn a_box_that_stops_short_of_the_border_is_not_read_as_the_foot() {
        let camera = PinholeCamera::default_hd();
        let pose = Pose {
            position_in_world: Point3::new(0.0, 0.0, 30.0),
            attitude: attitude(0.0, -0.05, 0.0),
        };
        let near = tower("N1", 50.0, 5.0, 38.0);
        let cfw = camera.world_from_camera(&pose).inverse();
        let top = camera.project(&(cfw * near.top_in_world())).expect("top");
        let foot = camera.project(&(cfw * near.foot_in_world)).expect("foot");
        assert!(foot.y > 720.0 && top.y > 100.0, "{top} {foot}");
        let centre = 0.5 * (top.x + foot.x);
        let short = Observation::new(
            &near,
            PixelBox::new(centre - 60.0, top.y, centre + 60.0, 680.0),
            0.4,
        );
        let height = Some(Height {
            up_m: 30.0,
            sigma_m: 0.5,
        });
        // A cut tower seeds no start of its own: the prediction does.
        let prior = Some(Point3::new(4.0, -3.0, 30.0));
        let fix = |params: &LocalizerParams| {
            robust_lbl_with_height(&[short], &camera, &pose.attitude, prior, height, params)
                .expect("a fix")
                .fix
        };
        let error = |params: &LocalizerParams| {
            (fix(params).position_in_world - pose.position_in_world).norm()
        };
        let plain = LocalizerParams::default();
        assert!(error(&plain) > 5.0, "the short bottom read as the foot");
        let margin = LocalizerParams {
            cut_margin_share: 0.15,
            edge_sigma_share: 0.025,
            ..plain
        };
        assert!(error(&margin) < 0.5);
        // A cut box's edges stray more, and the fix says so.
        let sigma = |params: &LocalizerParams| fix(params).covariance[(0, 0)].sqrt();
        let wider = LocalizerParams {
            cut_sigma_scale: 3.0,
            ..margin
        };
        assert!(error(&wider) < 0.5);
        assert!(
            sigma(&wider) > 2.0 * sigma(&margin),
            "{} {}",
            sigma(&wider),
            sigma(&margin)
        );
    }

    #[test]
    fn through_a_barrel_lens_a_tower_the_frame_cuts_at_a_side_keeps_its_rows() {
        let mut camera = PinholeCamera::default_hd();
        camera.distortion = towernav_geometry::Distortion::RadialTangential {
            k1: -0.28,
            k2: 0.08,
            p1: 1e-3,
            p2: -2e-3,
            k3: -0.01,
        };
        let view = towernav_geometry::UndistortedView::new(&camera);
        let pose = Pose {
            position_in_world: Point3::new(0.0, 0.0, 30.0),
            attitude: attitude(0.0, 0.0, 0.0),
        };
        // Boxes as a lens draws them: about the bent axis, from the apex's
        // row to the foot's, cut by the real frame's edge.
        fn seen<'a>(
            view: &towernav_geometry::UndistortedView,
            pose: &Pose,
            t: &'a MapTower,
            half_width: f64,
        ) -> Observation<'a> {
            let cfw = view.real.world_from_camera(pose).inverse();
            let top = view.real.project(&(cfw * t.top_in_world())).expect("top");
            let foot = view.real.project(&(cfw * t.foot_in_world)).expect("foot");
            let c = 0.5 * (top.x + foot.x);
            let k = &view.real.intrinsics;
            let raw = PixelBox::new(c - half_width, top.y, c + half_width, foot.y)
                .clipped(f64::from(k.width), f64::from(k.height));
            let mut o = Observation::new(t, view.to_ideal(&raw).expect("maps"), 1.0);
            o.raw = raw;
            o
        }
        let towers = [
            tower("A1", 150.0, 60.0, 32.0),
            tower("B1", 120.0, -50.0, 38.0),
        ];
        let cut = tower("N1", 100.0, 82.0, 40.0);
        let mut obs: Vec<_> = towers.iter().map(|t| seen(&view, &pose, t, 6.0)).collect();
        obs.push(seen(&view, &pose, &cut, 60.0));
        let edge = obs[2].raw;
        assert!(
            edge.left <= 1.0 && edge.right > 20.0,
            "cut at the left: {edge:?}"
        );
        let params = LocalizerParams::default();
        let fix = robust_lbl(&obs, &camera, &pose.attitude, None, &params).expect("fix");
        assert!(
            (fix.fix.position_in_world - pose.position_in_world).norm() < 0.01,
            "{}",
            fix.fix.position_in_world
        );
        assert!(fix.fix.towers_used.contains(&"N1".to_string()));
    }

    #[test]
    fn towers_too_small_to_trust_are_left_out() {
        let camera = PinholeCamera::default_hd();
        let pose = Pose {
            position_in_world: Point3::new(0.0, 0.0, 30.0),
            attitude: attitude(0.0, 0.0, 0.0),
        };
        let far = tower("F1", 5000.0, 0.0, 32.0);
        let obs = observe(std::slice::from_ref(&far), &camera, &pose, None);
        assert!(obs[0].bbox.height() < LocalizerParams::default().min_box_height_px);
        assert!(
            robust_lbl(
                &obs,
                &camera,
                &pose.attitude,
                None,
                &LocalizerParams::default()
            )
            .is_none()
        );
    }

    #[test]
    fn a_wrong_tower_is_gated_out() {
        let camera = PinholeCamera::default_hd();
        let pose = Pose {
            position_in_world: Point3::new(0.0, 0.0, 30.0),
            attitude: attitude(0.0, -0.08, 0.05),
        };
        let towers = field();
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        let mut obs = observe(&towers, &camera, &pose, Some((&mut rng, 1.0)));
        // The box of A1 is bound to A2 instead.
        let a1 = obs
            .iter()
            .position(|o| o.tower.id == "A1")
            .expect("A1 seen");
        let a2 = towers.iter().find(|t| t.id == "A2").expect("A2");
        obs[a1].tower = a2;
        let fix = robust_lbl(
            &obs,
            &camera,
            &pose.attitude,
            None,
            &LocalizerParams::default(),
        )
        .expect("fix");
        assert_eq!(fix.rejected, vec![a1]);
        assert!(
            (fix.fix.position_in_world - pose.position_in_world)
                .xy()
                .norm()
                < 1.5
        );
    }

    /// Monte Carlo: the mean normalised estimation error squared of fixes
    /// over random poses, boxes drawn with the edge noise `noise` states and
    /// fixed with `model`; and how many runs gave a fix.
    fn mean_nees(model: &LocalizerParams, noise: &LocalizerParams) -> (f64, usize) {
        let camera = PinholeCamera::default_hd();
        let towers = field();
        let mut rng = ChaCha8Rng::seed_from_u64(42);
        let runs = 400;
        let mut total = 0.0;
        let mut count = 0;
        for _ in 0..runs {
            let pose = Pose {
                position_in_world: Point3::new(
                    rng.random_range(-20.0..20.0),
                    rng.random_range(-20.0..20.0),
                    rng.random_range(25.0..45.0),
                ),
                attitude: attitude(
                    rng.random_range(-0.1..0.1),
                    rng.random_range(-0.15..0.0),
                    rng.random_range(-0.2..0.2),
                ),
            };
            let boxes: Vec<(usize, PixelBox)> = towers
                .iter()
                .enumerate()
                .filter_map(|(i, t)| label(&camera, &pose, t, None).map(|b| (i, b)))
                .collect();
            let obs: Vec<Observation> = boxes
                .iter()
                .map(|&(i, b)| {
                    let probe = Observation::new(&towers[i], b, 1.0);
                    let ends = super::super::measurement::edge_sigma(&probe, noise);
                    let sides = super::super::measurement::side_sigma(&probe, noise);
                    let mut n = |s: f64| s * rng.sample::<f64, _>(StandardNormal);
                    let (dl, dt, dr, db) = (n(sides), n(ends), n(sides), n(ends));
                    Observation::new(
                        &towers[i],
                        PixelBox::new(b.left + dl, b.top + dt, b.right + dr, b.bottom + db),
                        1.0,
                    )
                })
                .collect();
            if obs.len() < 2 {
                continue;
            }
            let mut imu = pose.attitude;
            imu.yaw += model.yaw_sigma * rng.sample::<f64, _>(StandardNormal);
            let Some(fix) = robust_lbl(&obs, &camera, &imu, None, model) else {
                continue;
            };
            let f = fix.fix;
            let e = Vector4::new(
                f.position_in_world.x - pose.position_in_world.x,
                f.position_in_world.y - pose.position_in_world.y,
                f.position_in_world.z - pose.position_in_world.z,
                wrap_angle(f.yaw - pose.attitude.yaw),
            );
            let nees =
                (e.transpose() * f.covariance.try_inverse().expect("invertible") * e)[(0, 0)];
            total += nees;
            count += 1;
        }
        (total / count.max(1) as f64, count)
    }

    /// With edge noise as the model states it, the mean NEES is the state
    /// dimension, within the chi-square 95 % band for the number of runs.
    fn assert_consistent(params: &LocalizerParams) {
        let (mean, count) = mean_nees(params, params);
        assert!(count > 300, "{count} runs");
        // Mean of N chi-square(4) draws: 4 +/- 1.96 * sqrt(8 / N).
        let band = 1.96 * (8.0 / count as f64).sqrt();
        assert!(
            (mean - 4.0).abs() < band + 0.1,
            "mean NEES {mean:.3} outside 4 +/- {band:.3}"
        );
    }

    #[test]
    fn covariance_is_consistent_nees_within_chi_square_bounds() {
        assert_consistent(&LocalizerParams {
            centre_width_share: 0.0,
            ..LocalizerParams::default()
        });
    }

    /// A learned detector errs in proportion to the box: with that share in
    /// the model the fix's covariance stays honest; without it the same boxes
    /// give a fix that claims several times its real accuracy.
    #[test]
    fn edge_noise_in_proportion_to_the_box_is_carried_into_the_covariance() {
        let learned = LocalizerParams {
            centre_width_share: 0.0,
            edge_sigma_share: 0.03,
            ..LocalizerParams::default()
        };
        assert_consistent(&learned);
        let unaware = LocalizerParams {
            edge_sigma_share: 0.0,
            ..learned
        };
        let (mean, _) = mean_nees(&unaware, &learned);
        assert!(
            mean > 20.0,
            "mean NEES {mean:.2} when the share is left out"
        );
    }
}
