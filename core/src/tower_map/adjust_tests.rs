//! A synthetic survey: three passes past six towers, the log's positions
//! off by a wandering GNSS error and its heading by a wandering attitude
//! error. Placed together, the towers come out better than one by one, and
//! inside their ellipses.

use nalgebra::{Point3, Rotation3, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

use super::*;
use crate::tower_map::drift::DriftFix;
use crate::tower_map::triangulate::triangulate;

const FRAME_S: f64 = 0.1;
const SPEED: f64 = 10.0;

fn towers() -> Vec<Point3<f64>> {
    [
        (100.0, 50.0),
        (300.0, 50.0),
        (500.0, 50.0),
        (150.0, -50.0),
        (350.0, -50.0),
        (550.0, -50.0),
    ]
    .iter()
    .map(|&(e, n)| Point3::new(e, n, 0.0))
    .collect()
}

/// A first-order Gauss-Markov sequence, one value per frame.
fn markov(rng: &mut ChaCha8Rng, n: usize, sigma: f64, correlation_s: f64) -> Vec<f64> {
    let keep = (-FRAME_S / correlation_s).exp();
    let mut x = sigma * rng.sample::<f64, _>(StandardNormal);
    (0..n)
        .map(|_| {
            x = keep * x
                + sigma * (1.0 - keep * keep).sqrt() * rng.sample::<f64, _>(StandardNormal);
            x
        })
        .collect()
}

/// Each tower's views along three passes (east at north 0, west at north
/// 100, east at north -100), with a forward camera's 35 degree half field,
/// as the log would give them: `errors` scales the pose errors (0: exact).
fn survey(seed: u64, errors: f64) -> Vec<Vec<TowerView>> {
    survey_turned(seed, errors, 0.0)
}

/// As `survey`, with every ray turned by a camera yawed `boresight` (rad)
/// against the attitude.
fn survey_turned(seed: u64, errors: f64, boresight: f64) -> Vec<Vec<TowerView>> {
    survey_logged(seed, errors, boresight).0
}

/// As `survey_turned`, with the log's fixes: its positions, and velocities
/// off by a 0.1 m/s error forgotten within a second; each leg's first 3 s
/// unlogged (the legs are flown one after the other without the turns).
fn survey_logged(seed: u64, errors: f64, boresight: f64) -> (Vec<Vec<TowerView>>, Vec<DriftFix>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let legs = [(0.0, 1.0), (100.0, -1.0), (-100.0, 1.0)];
    let per_leg = (700.0 / SPEED / FRAME_S) as usize;
    let n = per_leg * legs.len();
    let (ge, gn) = (
        markov(&mut rng, n, 1.5, 10.0),
        markov(&mut rng, n, 1.5, 10.0),
    );
    let heading = markov(&mut rng, n, 0.5_f64.to_radians(), 3.0);
    let mut velocity_rng = ChaCha8Rng::seed_from_u64(seed + 1000);
    let (ve, vn) = (
        markov(&mut velocity_rng, n, 0.1, 1.0),
        markov(&mut velocity_rng, n, 0.1, 1.0),
    );
    let mut fixes = Vec::new();
    let mut views = vec![Vec::new(); towers().len()];
    for (leg, &(north, dir)) in legs.iter().enumerate() {
        for i in 0..per_leg {
            let k = leg * per_leg + i;
            let time_s = k as f64 * FRAME_S;
            let east = if dir > 0.0 { -50.0 } else { 650.0 } + dir * SPEED * i as f64 * FRAME_S;
            let camera = Point3::new(east, north, 60.0);
            let logged = camera + errors * Vector3::new(ge[k], gn[k], 0.0);
            if i as f64 * FRAME_S >= 3.0 {
                fixes.push(DriftFix {
                    time_s,
                    position: logged.xy(),
                    velocity: Vector2::new(dir * SPEED + errors * ve[k], errors * vn[k]),
                });
            }
            let turn =
                Rotation3::from_axis_angle(&Vector3::z_axis(), errors * heading[k] + boresight);
            for (t, foot) in towers().iter().enumerate() {
                let to = foot - camera;
                let off_axis = (to.y.atan2(to.x)
                    - if dir > 0.0 { 0.0 } else { std::f64::consts::PI })
                .sin()
                .asin();
                let ahead = to.x * dir > 0.0;
                if !ahead || off_axis.abs() > 35_f64.to_radians() || to.xy().norm() > 600.0 {
                    continue;
                }
                let ray = |z: f64| turn * (Point3::new(foot.x, foot.y, z) - camera);
                views[t].push(TowerView {
                    time_s,
                    camera_in_world: logged,
                    centre_ray: ray(15.0),
                    top_ray: ray(30.0),
                    foot_ray: ray(0.0),
                    cut: false,
                });
            }
        }
    }
    (views, fixes)
}

/// The adjustment with its priors alone: no velocities.
fn adjust_alone(
    views: &[Vec<TowerView>],
    starts: &[Point2<f64>],
    p: &TriangulationParams,
) -> Option<Adjustment> {
    adjust(views, starts, p, &GnssDrift::default())
}

fn placed_alone(views: &[Vec<TowerView>]) -> Vec<Point2<f64>> {
    views
        .iter()
        .map(|v| {
            triangulate(v, &TriangulationParams::default())
                .expect("each tower triangulates")
                .foot_in_world
                .xy()
        })
        .collect()
}

/// RMS distance of `feet` from the first towers, in order.
fn rms(feet: &[Point2<f64>]) -> f64 {
    rms_from(feet, 0)
}

fn rms_from(feet: &[Point2<f64>], first: usize) -> f64 {
    let truth = towers();
    let sq: f64 = feet
        .iter()
        .zip(&truth[first..])
        .map(|(f, t)| (f - t.xy()).norm_squared())
        .sum();
    (sq / feet.len() as f64).sqrt()
}

#[test]
fn exact_views_give_every_tower_back() {
    let views = survey(1, 0.0);
    let starts: Vec<_> = towers()
        .iter()
        .map(|t| t.xy() + Vector2::new(4.0, -3.0))
        .collect();
    let a = adjust_alone(&views, &starts, &TriangulationParams::default()).expect("solvable");
    assert!(rms(&a.feet) < 1e-3, "{:?}", a.feet);
    assert!(a.gnss_error(20.0).norm() < 1e-3);
}

#[test]
fn shared_pose_errors_are_solved_not_inherited() {
    let p = TriangulationParams::default();
    let (mut alone, mut together) = (0.0, 0.0);
    for seed in 0..6 {
        let views = survey(seed, 1.0);
        let starts = placed_alone(&views);
        let a = adjust_alone(&views, &starts, &p).expect("solvable");
        for ((foot, cov), truth) in a.feet.iter().zip(&a.covariances).zip(towers()) {
            let d = foot - truth.xy();
            let m2 = (d.transpose() * cov.try_inverse().expect("invertible") * d)[0];
            // Chi-square, two degrees of freedom: 99.9 % inside 13.8.
            assert!(m2 < 13.8, "seed {seed}: off by {d:?}, Mahalanobis^2 {m2}");
        }
        alone += rms(&starts).powi(2);
        together += rms(&a.feet).powi(2);
    }
    let (alone, together) = ((alone / 6.0).sqrt(), (together / 6.0).sqrt());
    assert!(
        together < 0.7 * alone,
        "together {together:.2} m, alone {alone:.2} m"
    );
}

#[test]
fn the_logs_velocities_tie_each_seconds_gnss_error_to_the_next() {
    let p = TriangulationParams::default();
    let (mut prior, mut tied, mut gnss_prior, mut gnss_tied) = (0.0, 0.0, 0.0, 0.0);
    for seed in 0..6 {
        let (views, fixes) = survey_logged(seed, 1.0, 0.0);
        let starts = placed_alone(&views);
        let drift = GnssDrift::new(&fixes);
        let alone = adjust_alone(&views, &starts, &p).expect("solvable");
        let with = adjust(&views, &starts, &p, &drift).expect("solvable");
        for ((foot, cov), truth) in with.feet.iter().zip(&with.covariances).zip(towers()) {
            let d = foot - truth.xy();
            let m2 = (d.transpose() * cov.try_inverse().expect("invertible") * d)[0];
            assert!(m2 < 13.8, "seed {seed}: off by {d:?}, Mahalanobis^2 {m2}");
        }
        prior += rms(&alone.feet).powi(2);
        tied += rms(&with.feet).powi(2);
        // How well each second's GNSS error is solved, less the flight's
        // shared part, which no view sees.
        let (mut solved_alone, mut solved_with, mut truth) = (vec![], vec![], vec![]);
        for f in fixes.iter().step_by(10) {
            let t = f.time_s;
            let logged = views.iter().flatten().find(|v| v.time_s == t);
            truth.push(logged.map_or(Vector2::zeros(), |v| {
                v.camera_in_world.xy() - true_camera(t)
            }));
            solved_alone.push(alone.gnss_error(t));
            solved_with.push(with.gnss_error(t));
        }
        gnss_prior += spread(&solved_alone, &truth);
        gnss_tied += spread(&solved_with, &truth);
    }
    let (prior, tied) = ((prior / 6.0).sqrt(), (tied / 6.0).sqrt());
    let (gnss_prior, gnss_tied) = (gnss_prior / 6.0, gnss_tied / 6.0);
    eprintln!("feet {tied:.3} against {prior:.3}; seconds {gnss_tied:.3} against {gnss_prior:.3}");
    // Measured: 0.65 against 0.78 m, and 0.75 against 0.99 m.
    assert!(
        tied < 0.9 * prior,
        "with velocities {tied:.2} m, without {prior:.2} m"
    );
    assert!(
        gnss_tied < 0.85 * gnss_prior,
        "each second's GNSS error solved to {gnss_tied:.2} with velocities, {gnss_prior:.2} without"
    );
}

/// Where the survey's camera truly is at `time_s`.
fn true_camera(time_s: f64) -> Point2<f64> {
    let per_leg = (700.0 / SPEED / FRAME_S) as usize;
    let k = (time_s / FRAME_S).round() as usize;
    let (leg, i) = (k / per_leg, k % per_leg);
    let (north, dir) = [(0.0, 1.0), (100.0, -1.0), (-100.0, 1.0)][leg];
    let east = if dir > 0.0 { -50.0 } else { 650.0 } + dir * SPEED * i as f64 * FRAME_S;
    Point2::new(east, north)
}

/// RMS of `solved - truth` about its mean, m.
fn spread(solved: &[Vector2<f64>], truth: &[Vector2<f64>]) -> f64 {
    let d: Vec<Vector2<f64>> = solved.iter().zip(truth).map(|(s, t)| s - t).collect();
    let mean = d.iter().sum::<Vector2<f64>>() / d.len() as f64;
    (d.iter().map(|x| (x - mean).norm_squared()).sum::<f64>() / d.len() as f64).sqrt()
}

#[test]
fn a_view_of_nothing_does_not_move_the_towers() {
    let mut views = survey(3, 0.0);
    // A box on clutter, given to the first tower: its line misses by 40 m.
    let mut stray = views[0][10];
    stray.centre_ray = Rotation3::from_axis_angle(&Vector3::z_axis(), 0.2) * stray.centre_ray;
    views[0].push(stray);
    let starts: Vec<_> = towers().iter().map(|t| t.xy()).collect();
    let a = adjust_alone(&views, &starts, &TriangulationParams::default()).expect("solvable");
    let truth = towers();
    assert!((a.feet[0] - truth[0].xy()).norm() < 0.5, "{:?}", a.feet[0]);
    assert!(rms_from(&a.feet[1..], 1) < 0.05, "{:?}", a.feet);
    assert!(
        a.weights[0].iter().any(|w| *w < 0.1),
        "the stray view is down-weighted"
    );
}

#[test]
fn a_tower_seen_along_a_narrow_fan_is_not_pulled_towards_the_cameras() {
    // One pass towards a tower 50 m to the side, from 600 m to 60 m off:
    // bearings from 5 to 40 degrees, each 2 degrees wrong (white).
    let foot = Point2::new(0.0, 50.0);
    let sigma = 2_f64.to_radians();
    let p = TriangulationParams {
        box_sigma_rad: sigma,
        bearing_sigma_rad: 1e-6,
        position_sigma_m: 1e-3,
        ..TriangulationParams::default()
    };
    let (mut adjusted, mut crossed) = (0.0, 0.0);
    let seeds = 20;
    for seed in 0..seeds {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let views: Vec<TowerView> = (0..540)
            .map(|i| {
                let camera = Point3::new(-600.0 + i as f64, 0.0, 60.0);
                let error: f64 = sigma * rng.sample::<f64, _>(StandardNormal);
                let turn = Rotation3::from_axis_angle(&Vector3::z_axis(), error);
                let ray = |z: f64| turn * (Point3::new(foot.x, foot.y, z) - camera);
                TowerView {
                    time_s: i as f64 / 10.0,
                    camera_in_world: camera,
                    centre_ray: ray(15.0),
                    top_ray: ray(30.0),
                    foot_ray: ray(0.0),
                    cut: false,
                }
            })
            .collect();
        let a = adjust_alone(std::slice::from_ref(&views), &[foot], &p).expect("solvable");
        adjusted += a.feet[0].x - foot.x;
        // The plain crossing of the measured lines, each weighted by its
        // range: the estimator whose normals carry the noise.
        let (mut m, mut b) = (nalgebra::Matrix2::zeros(), Vector2::zeros());
        for v in &views {
            let d = v.centre_ray.xy().normalize();
            let n = Vector2::new(-d.y, d.x);
            let w = 1.0 / (foot - v.camera_in_world.xy()).norm_squared();
            m += w * n * n.transpose();
            b += w * n * n.dot(&v.camera_in_world.xy().coords);
        }
        crossed += (m.try_inverse().expect("invertible") * b).x - foot.x;
    }
    let (adjusted, crossed) = (adjusted / seeds as f64, crossed / seeds as f64);
    assert!(
        crossed < -1.0,
        "the plain crossing is pulled back: {crossed:.2} m"
    );
    assert!(
        adjusted.abs() < 0.3 * crossed.abs(),
        "adjusted {adjusted:.2} m, crossed {crossed:.2} m"
    );
}

/// A camera yawed 0.4 degrees on its mount turns every bearing of the
/// flight: with the yaw free, passes both ways find it and put the towers
/// back; held as calibrated (the default), it moves them by most of a metre.
#[test]
fn a_constant_camera_yaw_is_found_not_spread_over_the_towers() {
    let yaw = 0.4_f64.to_radians();
    let views = survey_turned(4, 0.0, yaw);
    let starts: Vec<_> = towers().iter().map(|t| t.xy()).collect();
    let free = TriangulationParams {
        boresight_sigma_rad: 2_f64.to_radians(),
        ..TriangulationParams::default()
    };
    let a = adjust_alone(&views, &starts, &free).expect("solvable");
    assert!(
        (a.boresight - yaw).abs() < 0.01_f64.to_radians(),
        "{}",
        a.boresight.to_degrees()
    );
    assert!(rms(&a.feet) < 0.05, "{}", rms(&a.feet));
    let held = adjust_alone(&views, &starts, &TriangulationParams::default()).expect("solvable");
    assert!(held.boresight.abs() < 1e-6);
    assert!(rms(&held.feet) > 0.5, "{}", rms(&held.feet));
}
