//! Tower identity: which database tower each track is.
//!
//! Map-based association: every tower of the track's type is projected into the
//! image from the current pose guess, and unbound tracks are matched to free
//! towers by a Hungarian assignment on bearing and size. A binding holds until its
//! track ends, unless it keeps disagreeing with a trusted pose; an operator's
//! correction pins it.

use std::collections::HashMap;

use towernav_geometry::{Cut, PinholeCamera, Pose};

use crate::assignment::max_score_matching;
use crate::landmarks::LandmarkMap;
use crate::tracker::TrackOutput;

/// What a frame's bindings are judged against: where the pipeline thinks the
/// camera is, the camera, and the towers.
#[derive(Clone, Copy)]
pub struct View<'a> {
    pub guess: &'a Pose,
    /// The filter is tracking: its guess is good enough to release bindings
    /// that keep disagreeing with it.
    pub trusted: bool,
    pub camera: &'a PinholeCamera,
    pub map: &'a LandmarkMap,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IdentityParams {
    /// Expected spread of the predicted box centre, pixels, from a rough pose guess.
    pub bearing_sigma_px: f64,
    /// Expected spread of log(observed height / predicted height), rough guess.
    pub log_size_sigma: f64,
    /// The same spreads when the guess is trusted (the filter is tracking to
    /// about a metre): tight enough to tell apart towers that stand in a row.
    pub trusted_bearing_sigma_px: f64,
    pub trusted_log_size_sigma: f64,
    /// Gate on the normalised distance; farther candidates are never bound.
    pub gate: f64,
    /// A bound track that stays this far outside the gate of its own tower for
    /// `release_after` frames in a row (while the pose guess is trusted) is unbound,
    /// so that a wrong early binding does not last the whole track.
    pub release_gate: f64,
    pub release_after: u32,
    /// Another tower must fit better by this much (normalised distance) to
    /// count as evidence against the current binding.
    pub switch_margin: f64,
}

impl Default for IdentityParams {
    fn default() -> Self {
        Self {
            bearing_sigma_px: 60.0,
            log_size_sigma: 0.3,
            trusted_bearing_sigma_px: 12.0,
            trusted_log_size_sigma: 0.12,
            gate: 3.0,
            release_gate: 4.5,
            release_after: 10,
            switch_margin: 1.0,
        }
    }
}

#[derive(Debug, Clone, Default)]
pub struct Identity {
    params: IdentityParams,
    /// track id -> tower index in the map.
    bindings: HashMap<u64, usize>,
    /// track id -> operator's choice (None: keep unbound).
    pinned: HashMap<u64, Option<usize>>,
    /// track id -> frames in a row its binding disagreed with a trusted pose.
    strikes: HashMap<u64, u32>,
}

impl Identity {
    pub fn new(params: IdentityParams) -> Self {
        Self {
            params,
            ..Self::default()
        }
    }

    /// Pins a track to a tower (or to none) until the track ends.
    pub fn pin(&mut self, track_id: u64, tower: Option<usize>) {
        self.pinned.insert(track_id, tower);
        match tower {
            Some(t) => {
                self.bindings.retain(|_, bound| *bound != t);
                self.bindings.insert(track_id, t);
            }
            None => {
                self.bindings.remove(&track_id);
            }
        }
    }

    /// Ends an operator's pin: the track is unbound and the edge binds it
    /// again by its own evidence from the next frame.
    pub fn release(&mut self, track_id: u64) {
        self.pinned.remove(&track_id);
        self.bindings.remove(&track_id);
    }

    /// Carries bindings over to a new landmark map: `new_index(old)` is a tower's index in it,
    /// `None` if the tower is gone (its tracks become unbound; their pins end).
    pub fn remap(&mut self, new_index: impl Fn(usize) -> Option<usize>) {
        self.bindings = self
            .bindings
            .iter()
            .filter_map(|(&track, &t)| Some((track, new_index(t)?)))
            .collect();
        self.pinned = self
            .pinned
            .iter()
            .filter_map(|(&track, &pin)| match pin {
                None => Some((track, None)),
                Some(t) => new_index(t).map(|n| (track, Some(n))),
            })
            .collect();
    }

    pub fn is_pinned(&self, track_id: u64) -> bool {
        self.pinned.contains_key(&track_id)
    }

    /// How sure the binding of a bound track is, 0..=1: 1 when pinned or in
    /// agreement with the trusted pose, falling with each frame in a row it
    /// disagrees, to 0 just before it is released. `None` when unbound.
    pub fn confidence(&self, track_id: u64) -> Option<f64> {
        self.bindings.get(&track_id)?;
        if self.is_pinned(track_id) {
            return Some(1.0);
        }
        let strikes = self.strikes.get(&track_id).copied().unwrap_or(0);
        let limit = self.params.release_after.max(1);
        Some(1.0 - f64::from(strikes.min(limit)) / f64::from(limit))
    }

    /// Normalised distance between a track's box and a tower's predicted one
    /// (bearing and log size; size is skipped for a box cut by the image edge).
    fn distance(
        &self,
        track: &TrackOutput,
        predicted: (f64, f64, f64),
        image: (f64, f64),
        trusted: bool,
    ) -> Option<f64> {
        let p = self.params;
        let (bearing_sigma, size_sigma) = if trusted {
            (p.trusted_bearing_sigma_px, p.trusted_log_size_sigma)
        } else {
            (p.bearing_sigma_px, p.log_size_sigma)
        };
        let (u, h, foot_v) = predicted;
        let b = &track.bbox;
        // An edge at the image border is the border's, not the tower's: a box
        // cut at a side says nothing of the centre, one cut at top or bottom nothing of size.
        let cut = Cut::in_image(b, image.0, image.1);
        let (cut_side, cut_end) = (cut.side(), cut.end());
        if cut_side && cut_end {
            // Neither where it is nor how big: no evidence either way.
            return None;
        }
        // A near tower's box centre strays from its axis (cross-arms seen obliquely).
        let bearing = if cut_side {
            0.0
        } else {
            (b.center_x() - u) / (bearing_sigma + 0.08 * b.width())
        };
        let size = if cut_end || h <= 0.0 {
            0.0
        } else {
            (b.height() / h).ln() / size_sigma
        };
        // The foot's row tells range apart from height: a taller tower farther
        // along the same bearing can have the same box height, never the same foot.
        let foot = if trusted && !cut.bottom {
            (b.bottom - foot_v) / (bearing_sigma + 0.05 * b.height())
        } else {
            0.0
        };
        Some((bearing * bearing + size * size + foot * foot).sqrt())
    }

    /// Binds this frame's tracks; returns each track's tower index, in order.
    /// `candidates` (towers near the pose guess) is asked at most once, and only when a
    /// track is unbound or the guess is trusted enough to check bindings.
    /// With `guess_trusted` (the filter is tracking), bindings that keep
    /// disagreeing with the guess are released.
    pub fn update(
        &mut self,
        tracks: &[TrackOutput],
        live_track_ids: &[u64],
        view: View<'_>,
        candidates: impl FnOnce() -> Vec<usize>,
    ) -> Vec<Option<usize>> {
        let View {
            guess,
            trusted: guess_trusted,
            camera,
            map,
        } = view;
        self.bindings.retain(|id, _| live_track_ids.contains(id));
        self.pinned.retain(|id, _| live_track_ids.contains(id));
        self.strikes.retain(|id, _| live_track_ids.contains(id));
        let camera_from_world = camera.world_from_camera(guess).inverse();
        let image = (
            f64::from(camera.intrinsics.width),
            f64::from(camera.intrinsics.height),
        );
        let predict = |i: usize| -> Option<(f64, f64, f64)> {
            let tower = &map.towers[i];
            let foot = camera.project(&(camera_from_world * tower.foot_in_world))?;
            let top = camera.project(&(camera_from_world * tower.top_in_world()))?;
            Some((0.5 * (foot.x + top.x), foot.y - top.y, foot.y))
        };
        // Towers near the guess, asked for once, and only when some track needs
        // them: to bind it, or (with a trusted guess) to check its binding.
        let unpinned = |t: &&TrackOutput| !self.pinned.contains_key(&t.track_id);
        let needed = tracks
            .iter()
            .filter(unpinned)
            .any(|t| guess_trusted || !self.bindings.contains_key(&t.track_id));
        let near: Vec<usize> = if needed { candidates() } else { Vec::new() };
        if guess_trusted {
            self.release_disagreeing(tracks, &near, &predict, image, map);
        }
        self.bind_unbound(tracks, &near, &predict, image, map, guess_trusted);
        tracks
            .iter()
            .map(|t| self.bindings.get(&t.track_id).copied())
            .collect()
    }

    /// With a trusted guess: a binding far from its own tower, or beaten by a
    /// tower of its type by the hysteresis margin, takes a strike; enough
    /// strikes in a row release it.
    fn release_disagreeing(
        &mut self,
        tracks: &[TrackOutput],
        near: &[usize],
        predict: &dyn Fn(usize) -> Option<(f64, f64, f64)>,
        image: (f64, f64),
        map: &LandmarkMap,
    ) {
        let bound_here: Vec<(&TrackOutput, usize)> = tracks
            .iter()
            .filter(|t| !self.pinned.contains_key(&t.track_id))
            .filter_map(|t| self.bindings.get(&t.track_id).map(|&b| (t, b)))
            .collect();
        // Predict each nearby tower once, not once per track.
        let near_pred: Vec<(usize, (f64, f64, f64))> = near
            .iter()
            .filter_map(|&i| predict(i).map(|p| (i, p)))
            .collect();
        for (t, tower) in bound_here {
            let own = near_pred
                .iter()
                .find(|(i, _)| *i == tower)
                .map(|(_, p)| *p)
                .or_else(|| predict(tower));
            let current = own.map(|pred| self.distance(t, pred, image, true));
            // Evidence against the binding: far from its own tower, or a
            // tower of the same type fits clearly better (hysteresis margin).
            let off = match current {
                None => true,
                Some(None) => false,
                Some(Some(d)) => {
                    d > self.params.release_gate
                        || near_pred.iter().any(|&(other, p)| {
                            other != tower
                                && map.towers[other].tower_type == t.tower_type
                                && self
                                    .distance(t, p, image, true)
                                    .is_some_and(|alt| alt + self.params.switch_margin < d)
                        })
                }
            };
            let strikes = self.strikes.entry(t.track_id).or_insert(0);
            *strikes = if off { *strikes + 1 } else { 0 };
            if *strikes >= self.params.release_after {
                self.bindings.remove(&t.track_id);
                self.strikes.remove(&t.track_id);
            }
        }
    }

    /// Binds the tracks that have no tower to the free nearby towers of their
    /// type, best matches first.
    fn bind_unbound(
        &mut self,
        tracks: &[TrackOutput],
        near: &[usize],
        predict: &dyn Fn(usize) -> Option<(f64, f64, f64)>,
        image: (f64, f64),
        map: &LandmarkMap,
        guess_trusted: bool,
    ) {
        let unbound: Vec<&TrackOutput> = tracks
            .iter()
            .filter(|t| {
                !self.bindings.contains_key(&t.track_id) && !self.pinned.contains_key(&t.track_id)
            })
            .collect();
        if !unbound.is_empty() {
            let taken: Vec<usize> = self.bindings.values().copied().collect();
            let free: Vec<usize> = near
                .iter()
                .copied()
                .filter(|i| !taken.contains(i))
                .collect();
            let predicted: Vec<Option<(f64, f64, f64)>> =
                free.iter().map(|&i| predict(i)).collect();
            let matches = max_score_matching(
                unbound.len(),
                free.len(),
                |r, c| {
                    let track = unbound[r];
                    let Some(pred) = predicted[c] else {
                        return 0.0;
                    };
                    if map.towers[free[c]].tower_type != track.tower_type || pred.1 <= 0.0 {
                        return 0.0;
                    }
                    self.distance(track, pred, image, guess_trusted)
                        .map_or(0.0, |d| self.params.gate - d)
                },
                f64::MIN_POSITIVE,
            );
            for (r, c) in matches {
                self.bindings.insert(unbound[r].track_id, free[c]);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::landmarks::MapTower;
    use nalgebra::Point3;
    use towernav_geometry::{Attitude, PixelBox};
    use towernav_protocol::TowerType;

    fn map() -> LandmarkMap {
        let tower = |id: &str, x: f64, y: f64| MapTower {
            id: id.into(),
            tower_type: TowerType::A,
            foot_in_world: Point3::new(x, y, 0.0),
            height_m: 30.0,
            sigma_horizontal_m: 0.0,
            sigma_vertical_m: 0.0,
        };
        let datum = towernav_geometry::Datum::new(towernav_geometry::Geodetic {
            lat_deg: 30.5,
            lon_deg: 114.3,
            height_m: 0.0,
        });
        LandmarkMap::new(
            vec![
                tower("A1", 100.0, 30.0),
                tower("A2", 100.0, -30.0),
                tower("A3", 300.0, 30.0),
            ],
            datum,
        )
    }

    fn observe(
        pose: &Pose,
        camera: &PinholeCamera,
        map: &LandmarkMap,
        i: usize,
        id: u64,
    ) -> TrackOutput {
        let cfw = camera.world_from_camera(pose).inverse();
        let t = &map.towers[i];
        let foot = camera.project(&(cfw * t.foot_in_world)).expect("visible");
        let top = camera.project(&(cfw * t.top_in_world())).expect("visible");
        TrackOutput {
            track_id: id,
            bbox: PixelBox::new(foot.x - 5.0, top.y, foot.x + 5.0, foot.y),
            tower_type: TowerType::A,
            score: 0.9,
        }
    }

    #[test]
    fn look_alike_towers_are_told_apart_by_where_they_stand() {
        let camera = PinholeCamera::default_hd();
        let truth = Pose {
            position_in_world: Point3::new(0.0, 0.0, 30.0),
            attitude: Attitude::level(0.0),
        };
        let map = map();
        let tracks = [
            observe(&truth, &camera, &map, 1, 7),
            observe(&truth, &camera, &map, 0, 8),
            observe(&truth, &camera, &map, 2, 9),
        ];
        // The guess is 8 m off: still the right towers.
        let guess = Pose {
            position_in_world: Point3::new(-5.0, 6.0, 30.0),
            ..truth
        };
        let mut identity = Identity::new(IdentityParams::default());
        let bound = identity.update(
            &tracks,
            &[7, 8, 9],
            View {
                guess: &guess,
                trusted: false,
                camera: &camera,
                map: &map,
            },
            || vec![0, 1, 2],
        );
        assert_eq!(bound, [Some(1), Some(0), Some(2)]);
    }

    #[test]
    fn a_pin_overrides_and_ends_with_its_track() {
        let camera = PinholeCamera::default_hd();
        let pose = Pose {
            position_in_world: Point3::new(0.0, 0.0, 30.0),
            attitude: Attitude::level(0.0),
        };
        let map = map();
        let tracks = [observe(&pose, &camera, &map, 0, 7)];
        let mut identity = Identity::new(IdentityParams::default());
        identity.pin(7, Some(2));
        assert_eq!(
            identity.update(
                &tracks,
                &[7],
                View {
                    guess: &pose,
                    trusted: false,
                    camera: &camera,
                    map: &map
                },
                || vec![0, 1, 2]
            ),
            [Some(2)]
        );
        assert!(identity.is_pinned(7));
        identity.update(
            &[],
            &[],
            View {
                guess: &pose,
                trusted: false,
                camera: &camera,
                map: &map,
            },
            || vec![0, 1, 2],
        );
        assert!(!identity.is_pinned(7));
    }

    #[test]
    fn a_released_pin_goes_back_to_the_edges_own_binding() {
        let camera = PinholeCamera::default_hd();
        let pose = Pose {
            position_in_world: Point3::new(0.0, 0.0, 30.0),
            attitude: Attitude::level(0.0),
        };
        let map = map();
        let tracks = [observe(&pose, &camera, &map, 0, 7)];
        let view = || View {
            guess: &pose,
            trusted: false,
            camera: &camera,
            map: &map,
        };
        let mut identity = Identity::new(IdentityParams::default());
        identity.pin(7, Some(2));
        assert_eq!(
            identity.update(&tracks, &[7], view(), || vec![0, 1, 2]),
            [Some(2)]
        );
        identity.release(7);
        assert!(!identity.is_pinned(7));
        assert_eq!(
            identity.update(&tracks, &[7], view(), || vec![0, 1, 2]),
            [Some(0)],
            "the tower it shows, by the edge's own evidence"
        );
    }

    #[test]
    fn a_wrong_binding_is_released_once_a_trusted_pose_disagrees() {
        let camera = PinholeCamera::default_hd();
        let pose = Pose {
            position_in_world: Point3::new(0.0, 0.0, 30.0),
            attitude: Attitude::level(0.0),
        };
        let map = map();
        // The track sees tower 0, but was bound to tower 1 while the pose was unknown.
        let tracks = [observe(&pose, &camera, &map, 0, 7)];
        let mut identity = Identity::new(IdentityParams::default());
        identity.bindings.insert(7, 1);
        for _ in 1..IdentityParams::default().release_after {
            let b = identity.update(
                &tracks,
                &[7],
                View {
                    guess: &pose,
                    trusted: true,
                    camera: &camera,
                    map: &map,
                },
                || vec![0, 1, 2],
            );
            assert_eq!(b, [Some(1)], "hysteresis: one bad frame is not enough");
        }
        // Released on the tenth frame, and rebound to the right tower in the same call.
        let b = identity.update(
            &tracks,
            &[7],
            View {
                guess: &pose,
                trusted: true,
                camera: &camera,
                map: &map,
            },
            || vec![0, 1, 2],
        );
        assert_eq!(b, [Some(0)]);
        // An untrusted guess never releases.
        identity.bindings.insert(7, 1);
        for _ in 0..30 {
            identity.update(
                &tracks,
                &[7],
                View {
                    guess: &pose,
                    trusted: false,
                    camera: &camera,
                    map: &map,
                },
                || vec![0, 1, 2],
            );
        }
        assert_eq!(identity.bindings.get(&7), Some(&1));
    }
}
