//! How far the views' bearings miss the true towers of a rendered flight:
//! the measurement behind `TriangulationParams::box_sigma_rad` and
//! `adjust::MIN_LINE_SIGMA_M`. With exact poses it is the detector's own
//! error; with a noisy log it adds the attitude's.

use std::collections::BTreeMap;

use nalgebra::Point2;
use towernav_geometry::wrap_angle;

use super::triangulate::{TowerView, median};

/// A ray is taken for a true tower's when it passes within this of its foot.
const ON_TOWER_M: f64 = 5.0;
/// Views nearer than this see the box's centre leave a wide tower's axis.
pub const NEAR_M: f64 = 150.0;

/// Robust one-sigmas (1.4826 median absolute deviation) of the misses, rad.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BearingMisses {
    /// Views whose ray passed within `ON_TOWER_M` of a true tower.
    pub views: usize,
    pub per_view: f64,
    /// Each tower's views averaged over each second: what persists.
    pub per_tower_second: f64,
    /// The views within `NEAR_M` of their tower.
    pub near: f64,
}

impl BearingMisses {
    /// `None` where no view's ray passes near a true foot.
    pub fn of<'a>(
        views: impl IntoIterator<Item = &'a TowerView>,
        feet: &[Point2<f64>],
    ) -> Option<Self> {
        let mut all = Vec::new();
        let mut near = Vec::new();
        let mut seconds: BTreeMap<(usize, i64), (f64, usize)> = BTreeMap::new();
        for v in views {
            let (camera, ray) = (v.camera_in_world.xy(), v.centre_ray.xy());
            if ray.norm() < 1e-9 {
                continue;
            }
            let ray = ray.normalize();
            let nearest = feet
                .iter()
                .enumerate()
                .map(|(k, f)| (k, f - camera))
                .filter(|(_, to)| to.dot(&ray) > 0.0)
                .map(|(k, to)| (k, to, (to.x * ray.y - to.y * ray.x).abs()))
                .min_by(|a, b| a.2.total_cmp(&b.2));
            let Some((k, to, off)) = nearest else {
                continue;
            };
            if off > ON_TOWER_M {
                continue;
            }
            let miss = wrap_angle(ray.y.atan2(ray.x) - to.y.atan2(to.x));
            all.push(miss);
            if to.norm() < NEAR_M {
                near.push(miss);
            }
            let s = seconds
                .entry((k, v.time_s.floor() as i64))
                .or_insert((0.0, 0));
            s.0 += miss;
            s.1 += 1;
        }
        let means: Vec<f64> = seconds.values().map(|(sum, n)| sum / *n as f64).collect();
        Some(Self {
            views: all.len(),
            per_view: robust_sigma(&all)?,
            per_tower_second: robust_sigma(&means)?,
            near: robust_sigma(&near).unwrap_or(f64::NAN),
        })
    }
}

fn robust_sigma(values: &[f64]) -> Option<f64> {
    let m = median(values)?;
    let deviations: Vec<f64> = values.iter().map(|x| (x - m).abs()).collect();
    Some(1.4826 * median(&deviations)?)
}

#[cfg(test)]
mod tests {
    use nalgebra::{Point3, Vector3};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use rand_distr::StandardNormal;

    use super::*;

    fn view(time_s: f64, camera: Point2<f64>, bearing: f64) -> TowerView {
        let ray = Vector3::new(bearing.cos(), bearing.sin(), -0.1);
        TowerView {
            time_s,
            camera_in_world: Point3::new(camera.x, camera.y, 50.0),
            centre_ray: ray,
            top_ray: ray,
            foot_ray: ray,
            cut: false,
        }
    }

    /// Views 30 a second with a miss that holds for each second plus a
    /// smaller one of their own: the per-view figure sees both, the
    /// per-second one the part that persists.
    #[test]
    fn a_persistent_miss_is_told_from_the_frames_own() {
        let feet = [Point2::new(0.0, 0.0), Point2::new(0.0, 400.0)];
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let (persist, own) = (1e-3, 0.5e-3);
        let mut views = Vec::new();
        for second in 0..400 {
            let tower = second % 2;
            let held: f64 = persist * rng.sample::<f64, _>(StandardNormal);
            for frame in 0..30 {
                let t = second as f64 + frame as f64 / 30.0;
                let camera = Point2::new(300.0 + t, 100.0 + 0.5 * t);
                let to = feet[tower] - camera;
                let noise: f64 = own * rng.sample::<f64, _>(StandardNormal);
                views.push(view(t, camera, to.y.atan2(to.x) + held + noise));
            }
        }
        // A box on no tower is left out.
        views.push(view(0.0, Point2::new(300.0, 100.0), 0.0));
        let m = BearingMisses::of(&views, &feet).expect("misses");
        assert_eq!(m.views, 400 * 30);
        let both = persist.hypot(own);
        assert!((m.per_view - both).abs() < 0.1 * both, "{m:?}");
        assert!(
            (m.per_tower_second - persist).abs() < 0.15 * persist,
            "{m:?}"
        );
        assert!(m.near.is_nan(), "every view is over 150 m away");
    }

    #[test]
    fn no_view_on_a_tower_is_no_figure() {
        let views = [view(0.0, Point2::new(0.0, 0.0), 0.0)];
        assert_eq!(BearingMisses::of(&views, &[Point2::new(0.0, 100.0)]), None);
    }
}
