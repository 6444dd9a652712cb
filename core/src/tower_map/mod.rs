//! Towers measured from a survey flight (GNSS and attitude still good): each
//! track's views triangulated into a foot and a height (`triangulate`),
//! tracks of one tower merged, and the result held against the database
//! (`matching`). Pure: views in, estimates out.

pub mod matching;
pub mod triangulate;

use std::collections::BTreeMap;

use towernav_protocol::TowerType;

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

/// The one tower a view can be of: its bearing passes the tower's foot
/// within 3 sigma and, where its foot row lands on the ground, near it. A
/// view that fits none, or two (towers one behind the other), is no one's.
fn owner(
    v: &TowerView,
    towers: &[TowerEstimate],
    p: &TriangulationParams,
    ground_z: Option<f64>,
) -> Option<usize> {
    let d = v.centre_ray.xy();
    if d.norm() < 1e-9 {
        return None;
    }
    let normal = nalgebra::Vector2::new(-d.y, d.x) / d.norm();
    let c = v.camera_in_world.xy();
    let ground = ground_z.and_then(|z| v.ground_point(z));
    let mut fits = towers.iter().enumerate().filter(|(_, t)| {
        let to = t.foot_in_world.xy() - c;
        let range = to.norm();
        let sigma = (range * p.bearing_sigma_rad).hypot(p.position_sigma_m);
        let on_bearing = to.dot(&d) > 0.0 && normal.dot(&to).abs() <= 3.0 * sigma;
        let at_range = ground.is_none_or(|g| {
            (g - t.foot_in_world.xy()).norm() <= SWITCH_M.max(SWITCH_SHARE * range)
        });
        on_bearing && at_range
    });
    let first = fits.next()?.0;
    fits.next().is_none().then_some(first)
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
    pub fn add(&mut self, track_id: u64, tower_type: TowerType, view: TowerView) {
        let (views, types) = self.tracks.entry(track_id).or_default();
        views.push(view);
        *types.entry(tower_type).or_default() += 1;
    }

    pub fn tracks(&self) -> usize {
        self.tracks.len()
    }

    /// Every track triangulated, cut first where it jumps between towers
    /// (with `ground_z`, the ground's height in the world frame, to place
    /// each view's foot); tracks of one tower (a tower passed twice, a track
    /// lost and found again) merged and triangulated together.
    pub fn finish(&self, p: &TriangulationParams, ground_z: Option<f64>) -> Vec<MappedTower> {
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
        let groups: Vec<(TowerEstimate, Vec<u64>, Vec<TowerView>)> = clusters
            .into_iter()
            .filter_map(|mut c| {
                c.views.sort_by(|a, b| a.time_s.total_cmp(&b.time_s));
                Some((triangulate(&c.views, p)?, c.ids, c.views))
            })
            .collect();
        let firsts: Vec<TowerEstimate> = groups.iter().map(|g| g.0.clone()).collect();
        let all: Vec<&TowerView> = groups.iter().flat_map(|g| g.2.iter()).collect();
        let owners: Vec<Option<usize>> =
            all.iter().map(|v| owner(v, &firsts, p, ground_z)).collect();
        groups
            .iter()
            .enumerate()
            .map(|(k, (first, ids, _))| {
                let mut types: BTreeMap<TowerType, usize> = BTreeMap::new();
                for id in ids {
                    for (t, n) in &self.tracks[id].1 {
                        *types.entry(*t).or_default() += n;
                    }
                }
                let mut views: Vec<TowerView> = all
                    .iter()
                    .zip(&owners)
                    .filter(|(_, o)| **o == Some(k))
                    .map(|(v, _)| **v)
                    .collect();
                views.sort_by(|a, b| a.time_s.total_cmp(&b.time_s));
                let estimate = triangulate(&views, p).unwrap_or_else(|| first.clone());
                let tower_type = types.into_iter().max_by_key(|(_, n)| *n).map(|(t, _)| t);
                MappedTower {
                    estimate,
                    tower_type,
                    track_ids: ids.clone(),
                }
            })
            .collect()
    }
}
