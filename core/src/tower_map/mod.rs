//! Towers measured from a survey flight (GNSS and attitude still good): each
//! track's views triangulated into a foot and a height (`triangulate`),
//! tracks of one tower merged, and the result held against the database
//! (`matching`). Pure: views in, estimates out.

pub mod adjust;
pub mod anchor;
pub mod bearing_misses;
mod bordered;
pub mod drift;
mod height_trend;
pub mod matching;
pub mod triangulate;
mod view;

use std::collections::BTreeMap;

use towernav_protocol::TowerType;

pub use anchor::Anchor;
pub use drift::{DriftFix, GnssDrift};
pub use matching::{KnownTower, MatchParams, MatchReport, Verdict, match_towers};
pub use triangulate::{TowerEstimate, TowerView, TriangulationParams, triangulate};

/// A tower the flight measured.
#[derive(Debug, Clone, PartialEq)]
pub struct MappedTower {
    pub estimate: TowerEstimate,
    /// The type the detector gave most often.
    pub tower_type: Option<TowerType>,
    /// The tracks whose views made it.
    pub track_ids: Vec<u64>,
    /// The longest stretch of flight it was seen in without a break, s.
    pub followed_s: f64,
    /// A surveyed record (`Anchor`) fits it: a reference for the others, not
    /// a measurement (`map-towers` writes the record's place for it).
    pub anchored: bool,
}

impl MappedTower {
    /// Placed within `max_sigma_m` (one sigma), and seen long enough
    /// without a break to be a tower, not a few stray boxes that cross.
    pub fn is_solid(&self, max_sigma_m: f64) -> bool {
        self.doubt(max_sigma_m).is_none()
    }

    /// Why the tower is not solid, in words for the survey's report and
    /// what to do about it; `None` where it is.
    pub fn doubt(&self, max_sigma_m: f64) -> Option<String> {
        if self.followed_s < FOLLOWED_S {
            return Some(format!(
                "seen for {:.1} s at most without a break: stray boxes, or a tower only glimpsed",
                self.followed_s
            ));
        }
        let sigma = self.estimate.sigma_horizontal_m();
        (sigma > max_sigma_m)
            .then(|| format!("placed to {sigma:.1} m only: fly past it from another side"))
    }
}

/// Pieces of tracks that place one tower: where, how near another piece
/// must land to join, and their views.
struct Cluster {
    at: nalgebra::Point2<f64>,
    gate: f64,
    ids: Vec<u64>,
    views: Vec<TowerView>,
}

/// Views gathered track by track over a flight.
#[derive(Debug, Clone, Default)]
pub struct TowerMapper {
    tracks: BTreeMap<u64, (Vec<TowerView>, BTreeMap<TowerType, usize>)>,
    drift: GnssDrift,
}

/// Two tracks' towers closer than this (or than 3 sigma together) are one.
const MERGE_M: f64 = 5.0;
/// A track whose foot lands this far (or this share of the range) from
/// where its last views put it, for `SWITCH_VIEWS` views running, has
/// jumped to another tower.
const SWITCH_M: f64 = 15.0;
const SWITCH_SHARE: f64 = 0.15;
const SWITCH_VIEWS: usize = 3;

impl TowerView {
    /// Where the foot's ray meets level ground at `ground_z`; `None` for a
    /// cut box or a ray that does not come down.
    pub fn ground_point(&self, ground_z: f64) -> Option<nalgebra::Point2<f64>> {
        let (c, r) = (self.camera_in_world, self.foot_ray);
        let dz = ground_z - c.z;
        if self.cut || r.z >= -1e-6 || dz >= 0.0 {
            return None;
        }
        Some((c + r * (dz / r.z)).xy())
    }
}

/// A track cut where its views' feet jump to another place: a tracker that
/// swapped two towers overlapping in the image.
fn split_at_switches(views: &[TowerView], ground_z: f64) -> Vec<Vec<TowerView>> {
    let mut segments: Vec<Vec<TowerView>> = vec![Vec::new()];
    let mut recent: Vec<nalgebra::Point2<f64>> = Vec::new();
    let mut pending: Vec<TowerView> = Vec::new();
    for v in views {
        let Some(g) = v.ground_point(ground_z) else {
            if pending.is_empty() {
                if let Some(s) = segments.last_mut() {
                    s.push(*v);
                }
            } else {
                pending.push(*v);
            }
            continue;
        };
        let reference = median_point(&recent);
        let range = (g - v.camera_in_world.xy()).norm();
        let jumped = reference.is_some_and(|r| (g - r).norm() > SWITCH_M.max(SWITCH_SHARE * range));
        if !jumped {
            if let Some(s) = segments.last_mut() {
                s.append(&mut pending);
                s.push(*v);
            }
            recent.push(g);
            if recent.len() > 5 {
                recent.remove(0);
            }
            continue;
        }
        pending.push(*v);
        let jumped_views = pending
            .iter()
            .filter(|p| p.ground_point(ground_z).is_some())
            .count();
        if jumped_views >= SWITCH_VIEWS {
            recent = pending
                .iter()
                .filter_map(|p| p.ground_point(ground_z))
                .collect();
            segments.push(std::mem::take(&mut pending));
        }
    }
    if let Some(s) = segments.last_mut() {
        s.append(&mut pending);
    }
    segments.retain(|s| !s.is_empty());
    segments
}

/// The one claiming tower a view can be of: its bearing passes the
/// tower's foot within 3 `sigma` (given the tower and the range) and,
/// where its foot row lands on the ground, near it. A view that fits none,
/// or two (towers one behind the other), is no one's.
fn owner(
    v: &TowerView,
    towers: &[TowerEstimate],
    claiming: &[bool],
    sigma: impl Fn(&TowerEstimate, f64) -> f64,
    ground_z: Option<f64>,
) -> Option<usize> {
    let d = v.centre_ray.xy();
    if d.norm() < 1e-9 {
        return None;
    }
    let normal = nalgebra::Vector2::new(-d.y, d.x) / d.norm();
    let c = v.camera_in_world.xy();
    let ground = ground_z.and_then(|z| v.ground_point(z));
    let mut fits = towers.iter().enumerate().filter(|(k, t)| {
        if !claiming[*k] {
            return false;
        }
        let to = t.foot_in_world.xy() - c;
        let range = to.norm();
        let on_bearing = to.dot(&d) > 0.0 && normal.dot(&to).abs() <= 3.0 * sigma(t, range);
        let at_range = ground.is_none_or(|g| {
            (g - t.foot_in_world.xy()).norm() <= SWITCH_M.max(SWITCH_SHARE * range)
        });
        on_bearing && at_range
    });
    let first = fits.next()?.0;
    fits.next().is_none().then_some(first)
}

/// Whether a tower may take views from other clusters: placed within
/// `MERGE_M` and seen for `FOLLOWED_S` without a break. One that is not (a
/// few views of clutter, leftovers of other towers' tracks) keeps its own
/// views but takes no other's: it would take them from their tower.
fn claims(t: &TowerEstimate, views: &[TowerView]) -> bool {
    t.sigma_horizontal_m() <= MERGE_M && longest_run_s(views) >= FOLLOWED_S
}

/// A tower seen this long without a break, s: a cluster of a few short
/// tracks is clutter or the leftovers of other towers' tracks.
pub const FOLLOWED_S: f64 = 3.0;
/// Views further apart than this break a run.
const RUN_GAP_S: f64 = 0.5;

/// The longest stretch of `views` (in time order) without a gap.
fn longest_run_s(views: &[TowerView]) -> f64 {
    let mut longest: f64 = 0.0;
    let mut start = None;
    for pair in views.windows(2) {
        let (a, b) = (pair[0].time_s, pair[1].time_s);
        let from = *start.get_or_insert(a);
        if b - a > RUN_GAP_S {
            start = Some(b);
        } else {
            longest = longest.max(b - from);
        }
    }
    longest
}

fn median_point(points: &[nalgebra::Point2<f64>]) -> Option<nalgebra::Point2<f64>> {
    let xs: Vec<f64> = points.iter().map(|p| p.x).collect();
    let ys: Vec<f64> = points.iter().map(|p| p.y).collect();
    Some(nalgebra::Point2::new(
        triangulate::median(&xs)?,
        triangulate::median(&ys)?,
    ))
}

impl TowerMapper {
    /// The log's GNSS error changes, from its velocities, for the
    /// adjustment (`adjust`); without them it has its prior alone.
    pub fn with_drift(self, drift: GnssDrift) -> Self {
        Self { drift, ..self }
    }

    pub fn add(&mut self, track_id: u64, tower_type: TowerType, view: TowerView) {
        let (views, types) = self.tracks.entry(track_id).or_default();
        views.push(view);
        *types.entry(tower_type).or_default() += 1;
    }

    pub fn tracks(&self) -> usize {
        self.tracks.len()
    }

    /// Every view added, track by track.
    pub fn views(&self) -> impl Iterator<Item = &TowerView> {
        self.tracks.values().flat_map(|(views, _)| views)
    }

    /// Every track triangulated, cut first where it jumps between towers
    /// (with `ground_z`, the ground's height in the world frame, to place
    /// each view's foot); tracks of one tower (a tower passed twice, a track
    /// lost and found again) merged and triangulated together; then all the
    /// towers adjusted at once with the flight's pose errors (`adjust`),
    /// then moved together onto the surveyed `anchors` they fit.
    pub fn finish(
        &self,
        p: &TriangulationParams,
        ground_z: Option<f64>,
        anchors: &[Anchor],
    ) -> Vec<MappedTower> {
        let mut pieces: Vec<(u64, Vec<TowerView>)> = Vec::new();
        for (id, (views, _)) in &self.tracks {
            match ground_z {
                Some(z) => pieces.extend(split_at_switches(views, z).into_iter().map(|s| (*id, s))),
                None => pieces.push((*id, views.clone())),
            }
        }
        // Each piece's place: its own crossing where its bearings spread
        // enough, else where its feet land (a piece seen from one side).
        let mut anchored: Vec<(u64, Vec<TowerView>, nalgebra::Point2<f64>, f64)> = pieces
            .into_iter()
            .filter_map(|(id, views)| {
                let (at, gate) = match triangulate(&views, p) {
                    Some(e) => (
                        e.foot_in_world.xy(),
                        MERGE_M.max(3.0 * e.sigma_horizontal_m()),
                    ),
                    None => {
                        let z = ground_z?;
                        let feet: Vec<_> = views.iter().filter_map(|v| v.ground_point(z)).collect();
                        let at = median_point(&feet)?;
                        let range = views
                            .iter()
                            .map(|v| (at - v.camera_in_world.xy()).norm())
                            .fold(f64::INFINITY, f64::min);
                        (at, SWITCH_M.max(SWITCH_SHARE * range))
                    }
                };
                Some((id, views, at, gate))
            })
            .collect();
        anchored.sort_by_key(|a| std::cmp::Reverse(a.1.len()));
        let mut clusters: Vec<Cluster> = Vec::new();
        for (id, views, at, gate) in anchored {
            match clusters
                .iter_mut()
                .find(|c| (c.at - at).norm() <= c.gate.max(gate))
            {
                Some(c) => {
                    if !c.ids.contains(&id) {
                        c.ids.push(id);
                    }
                    c.views.extend(views);
                }
                None => clusters.push(Cluster {
                    at,
                    gate,
                    ids: vec![id],
                    views,
                }),
            }
        }
        let groups = merge_duplicates(clusters, p);
        let views: Vec<Vec<TowerView>> = groups.iter().map(|g| g.2.clone()).collect();
        let firsts: Vec<TowerEstimate> = groups.iter().map(|g| g.0.clone()).collect();
        let sigma =
            |_: &TowerEstimate, range: f64| (range * p.bearing_sigma_rad).hypot(p.position_sigma_m);
        let owned = reown(&views, &firsts, |v| *v, sigma, ground_z);
        let towers: Vec<(Vec<u64>, Vec<TowerView>, TowerEstimate)> = groups
            .into_iter()
            .zip(owned)
            .map(|((first, ids, _), views)| {
                let estimate = triangulate(&views, p).unwrap_or(first);
                (ids, views, estimate)
            })
            .collect();
        let adjusted = adjusted(&towers, p, ground_z, anchors, &self.drift);
        towers
            .into_iter()
            .zip(adjusted)
            .map(|((ids, views, estimate), better)| {
                let (views, estimate, anchored) = better.unwrap_or((views, estimate, false));
                let mut types: BTreeMap<TowerType, usize> = BTreeMap::new();
                for id in &ids {
                    for (t, n) in &self.tracks[id].1 {
                        *types.entry(*t).or_default() += n;
                    }
                }
                let tower_type = types.into_iter().max_by_key(|(_, n)| *n).map(|(t, _)| t);
                MappedTower {
                    estimate,
                    tower_type,
                    track_ids: ids,
                    followed_s: longest_run_s(&views),
                    anchored,
                }
            })
            .collect()
    }
}

/// Every view given to the one tower it fits (`owner`, the view as
/// `correct` makes it), in time order; a tower that does not claim keeps
/// its own views that fit no other.
fn reown(
    views: &[Vec<TowerView>],
    towers: &[TowerEstimate],
    correct: impl Fn(&TowerView) -> TowerView,
    sigma: impl Fn(&TowerEstimate, f64) -> f64 + Copy,
    ground_z: Option<f64>,
) -> Vec<Vec<TowerView>> {
    let claiming: Vec<bool> = towers
        .iter()
        .zip(views)
        .map(|(t, v)| claims(t, v))
        .collect();
    let mut owned = vec![Vec::new(); towers.len()];
    for (from, tower_views) in views.iter().enumerate() {
        for v in tower_views {
            match owner(&correct(v), towers, &claiming, sigma, ground_z) {
                Some(k) => owned[k].push(*v),
                None if !claiming[from] => owned[from].push(*v),
                None => {}
            }
        }
    }
    for o in &mut owned {
        o.sort_by(|a, b| a.time_s.total_cmp(&b.time_s));
    }
    owned
}

/// Clusters triangulated, and two whose towers land within `MERGE_M` (or 3
/// sigma together) of each other merged and triangulated again: two pieces
/// of one tower's tracks anchored apart (one seen from one side only) would
/// otherwise both claim its views, and a view two towers claim is no one's.
fn merge_duplicates(
    clusters: Vec<Cluster>,
    p: &TriangulationParams,
) -> Vec<(TowerEstimate, Vec<u64>, Vec<TowerView>)> {
    let mut groups: Vec<(TowerEstimate, Vec<u64>, Vec<TowerView>)> = clusters
        .into_iter()
        .filter_map(|mut c| {
            c.views.sort_by(|a, b| a.time_s.total_cmp(&b.time_s));
            Some((triangulate(&c.views, p)?, c.ids, c.views))
        })
        .collect();
    loop {
        let close = |a: &TowerEstimate, b: &TowerEstimate| {
            let gate = MERGE_M.max(
                3.0 * (a.covariance_en + b.covariance_en)
                    .symmetric_eigenvalues()
                    .max()
                    .max(0.0)
                    .sqrt(),
            );
            (a.foot_in_world.xy() - b.foot_in_world.xy()).norm() <= gate
        };
        let pair = (0..groups.len()).find_map(|i| {
            (i + 1..groups.len())
                .find(|&j| close(&groups[i].0, &groups[j].0))
                .map(|j| (i, j))
        });
        let Some((i, j)) = pair else {
            return groups;
        };
        let (_, ids, views) = groups.remove(j);
        let mut merged = std::mem::take(&mut groups[i].2);
        merged.extend(views);
        merged.sort_by(|a, b| a.time_s.total_cmp(&b.time_s));
        for id in ids {
            if !groups[i].1.contains(&id) {
                groups[i].1.push(id);
            }
        }
        match triangulate(&merged, p) {
            Some(e) => {
                groups[i].0 = e;
                groups[i].2 = merged;
            }
            // Not one tower after all: keep the first as it was.
            None => groups[i].2 = merged,
        }
    }
}

/// The towers placed together with the flight's pose errors (`adjust`);
/// then every view given again to the one tower its corrected line passes
/// (the camera moved by the solved GNSS error, the bearing turned by the
/// solved heading error: far tighter than the pose's own errors), and the
/// towers adjusted again. Each view's camera is corrected before the
/// heights are measured. Last, every tower moved by the one translation
/// that takes those a surveyed record fits onto their records (`anchor`).
/// `None` for a tower left as it was; `true` beside an anchored tower.
fn adjusted(
    towers: &[(Vec<u64>, Vec<TowerView>, TowerEstimate)],
    p: &TriangulationParams,
    ground_z: Option<f64>,
    anchors: &[Anchor],
    drift: &GnssDrift,
) -> Vec<Option<(Vec<TowerView>, TowerEstimate, bool)>> {
    let views: Vec<Vec<TowerView>> = towers.iter().map(|t| t.1.clone()).collect();
    let starts: Vec<_> = towers.iter().map(|t| t.2.foot_in_world.xy()).collect();
    let Some(a) = adjust::adjust(&views, &starts, p, drift) else {
        return vec![None; towers.len()];
    };
    let placed: Vec<TowerEstimate> = towers
        .iter()
        .enumerate()
        .map(|(j, (_, _, first))| TowerEstimate {
            foot_in_world: nalgebra::Point3::new(a.feet[j].x, a.feet[j].y, first.foot_in_world.z),
            covariance_en: a.covariances[j],
            ..first.clone()
        })
        .collect();
    let sigma = |t: &TowerEstimate, range: f64| {
        (range * p.box_sigma_rad)
            .hypot(t.sigma_horizontal_m())
            .hypot(adjust::MIN_LINE_SIGMA_M)
    };
    let regrouped = reown(&views, &placed, |v| a.corrected(v), sigma, ground_z);
    let Some(a) = adjust::adjust(&regrouped, &a.feet, p, drift) else {
        return vec![None; towers.len()];
    };
    let paired = anchor::pair(&a.feet, &a.covariances, anchors);
    let shift = anchor::shift(&a.feet, &a.covariances, &paired, p.position_sigma_m);
    if let Some(s) = &shift {
        tracing::info!(
            anchors = paired.iter().flatten().count(),
            of = anchors.len(),
            east_m = format!("{:.2}", s.by.x),
            north_m = format!("{:.2}", s.by.y),
            "towers moved onto their surveyed anchors"
        );
    }
    if p.boresight_sigma_rad > 0.0 {
        tracing::info!(
            yaw_deg = format!("{:.2}", a.boresight.to_degrees()),
            "the camera's yaw on its mount, solved from the towers"
        );
    }
    regrouped
        .into_iter()
        .enumerate()
        .map(|(j, views)| {
            // A tower left with too few views, or one the adjustment carried
            // off (a handful of views that fit no line), stays as it was.
            let start = towers[j].2.foot_in_world.xy();
            if views.len() < p.min_views || (a.feet[j] - start).norm() > SWITCH_M {
                return None;
            }
            let moved: Vec<TowerView> = views.iter().map(|v| a.corrected(v)).collect();
            let weights = &a.weights[j];
            let inliers = weights.iter().filter(|w| **w >= 1.0).count();
            let inlier_share = inliers as f64 / weights.len().max(1) as f64;
            // The spread of the views as first placed: regiving moves few.
            let spread = towers[j].2.spread_rad;
            let e = triangulate::measured_at(
                &moved,
                a.feet[j],
                a.covariances[j],
                (spread, inlier_share),
                p,
            )?;
            // The towers' ellipses keep the shared error the shift took
            // out: conservative, where they would otherwise claim the
            // anchors' accuracy for towers far from any.
            let e = match &shift {
                Some(s) => TowerEstimate {
                    foot_in_world: e.foot_in_world + s.by.push(0.0),
                    ..e
                },
                None => e,
            };
            Some((views, e, paired[j].is_some()))
        })
        .collect()
}

#[cfg(test)]
#[path = "mapper_tests.rs"]
mod tests;
