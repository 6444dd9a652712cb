//! Tower identity: which database tower each track is.
//!
//! Map-based association: every tower of the track's type is projected into the
//! image from the current pose guess, and unbound tracks are matched to free
//! towers by a Hungarian assignment on bearing and size. A binding holds until its
//! track ends, unless a trusted pose keeps putting the track on another tower
//! (then it moves) or on none; an operator's correction pins it. With a
//! trusted guess, a frame whose box speaks against its track's binding, or
//! fits a neighbour about as well, leaves the track out for that frame only.

use std::collections::HashMap;

use nalgebra::Isometry3;

use towernav_geometry::{Cut, PinholeCamera, PixelBox, Pose};

use crate::assignment::max_score_matching;
use crate::landmarks::{LandmarkMap, MapTower};
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
    /// A bound track this far outside the gate of its own tower (while the
    /// pose guess is trusted) takes a strike, and one frame that agrees takes
    /// one back: at `release_after` strikes it is moved or unbound, so that a
    /// wrong early binding does not last the whole track, nor one whose
    /// tracker box flickers between two towers.
    pub release_gate: f64,
    pub release_after: u32,
    /// Another tower must fit better by this much (normalised distance) to
    /// count as evidence against the current binding.
    pub switch_margin: f64,
    /// An unbound track is bound only when its best tower fits better than
    /// any other nearby one, free or held, by this much: a far box between
    /// two towers of a row waits until it grows or the guess tightens,
    /// rather than take a coin toss that the localizer then trusts. With a
    /// trusted guess, a bound track's box within this much of a neighbour is
    /// left out of the frame.
    pub ambiguity_margin: f64,
    /// With a trusted guess, added to the normalised distance of a tower
    /// whose type is not the one the detector named: the type is evidence,
    /// not a rule. A learned type classifier misnames towers it sees small,
    /// blurred or banked, and a box that sits on a tower's predicted place
    /// to a fraction of the tight spread is that tower whatever it was
    /// called; among towers that fit about as well, the named type decides.
    /// With a rough guess the type stays a rule: geometry alone cannot
    /// outvote it then.
    pub type_mismatch_cost: f64,
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
            switch_margin: 0.5,
            ambiguity_margin: 0.5,
            type_mismatch_cost: 2.0,
        }
    }
}

/// Where a tower should stand in the image from the pose guess, pixels.
#[derive(Debug, Clone, Copy)]
struct Prediction {
    /// The column of its axis, halfway between apex and foot.
    u: f64,
    /// Half the column difference between apex and foot: a rolled camera
    /// sees the axis lean.
    lean: f64,
    top: f64,
    foot: f64,
    height: f64,
}

impl Prediction {
    /// From the camera's pose guess (`camera_from_world`); `None` when the
    /// apex or the foot is behind the camera.
    fn of(
        tower: &MapTower,
        camera: &PinholeCamera,
        camera_from_world: &Isometry3<f64>,
    ) -> Option<Self> {
        let foot = camera.project(&(camera_from_world * tower.foot_in_world))?;
        let top = camera.project(&(camera_from_world * tower.top_in_world()))?;
        Some(Self {
            u: 0.5 * (foot.x + top.x),
            lean: 0.5 * (top.x - foot.x),
            top: top.y,
            foot: foot.y,
            height: foot.y - top.y,
        })
    }
}

/// The score that keeps a binding no evidence speaks against; just above
/// the matcher's resolution.
const KEEP: f64 = 1e-3;

#[derive(Debug, Clone, Default)]
pub struct Identity {
    params: IdentityParams,
    /// track id -> tower index in the map.
    bindings: HashMap<u64, usize>,
    /// track id -> operator's choice (None: keep unbound).
    pinned: HashMap<u64, Option<usize>>,
    /// track id -> frames its binding disagreed with a trusted pose, less
    /// those it agreed since.
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

    /// The tower a track is bound to, whether or not its box was left out
    /// of the last frame.
    pub fn binding(&self, track_id: u64) -> Option<usize> {
        self.bindings.get(&track_id).copied()
    }

    pub fn is_pinned(&self, track_id: u64) -> bool {
        self.pinned.contains_key(&track_id)
    }

    /// How sure the binding of a bound track is, 0..=1: 1 when pinned or in
    /// agreement with the trusted pose, falling with each frame it disagrees
    /// (and rising with each it agrees), to 0 just before it is released.
    /// `None` when unbound.
    pub fn confidence(&self, track_id: u64) -> Option<f64> {
        self.bindings.get(&track_id)?;
        if self.is_pinned(track_id) {
            return Some(1.0);
        }
        let strikes = self.strikes.get(&track_id).copied().unwrap_or(0);
        let limit = self.params.release_after.max(1);
        Some(1.0 - f64::from(strikes.min(limit)) / f64::from(limit))
    }

    /// Normalised distance between a track's box and a tower's predicted one:
    /// bearing, log size and, with a trusted guess, the foot's (or apex's) row.
    fn distance(
        &self,
        track: &TrackOutput,
        predicted: Prediction,
        image: (f64, f64),
        trusted: bool,
    ) -> Option<f64> {
        let p = self.params;
        let (bearing_sigma, size_sigma) = if trusted {
            (p.trusted_bearing_sigma_px, p.trusted_log_size_sigma)
        } else {
            (p.bearing_sigma_px, p.log_size_sigma)
        };
        let b = &track.bbox;
        // An edge at the image border is the border's, not the tower's: a box
        // cut at a side says nothing of the centre, one cut at top or bottom
        // nothing of size but that the tower is at least as tall as what shows.
        let cut = Cut::in_image(b, image.0, image.1);
        let (cut_side, cut_end) = (cut.side(), cut.end());
        if cut_side && cut_end {
            // Neither where it is nor how big: no evidence either way.
            return None;
        }
        // A near tower's box centre strays from its axis (cross-arms seen obliquely).
        let bearing_sigma_here = bearing_sigma + 0.08 * b.width();
        let bearing = if cut_side {
            visible_side_offset(b, cut, predicted) / bearing_sigma_here
        } else {
            (b.center_x() - predicted.u) / bearing_sigma_here
        };
        let size = if predicted.height <= 0.0 {
            0.0
        } else {
            let log_ratio = (b.height() / predicted.height).ln();
            if cut_end {
                log_ratio.max(0.0) / size_sigma
            } else {
                log_ratio / size_sigma
            }
        };
        // The foot's row tells range apart from height: a taller tower farther
        // along the same bearing can have the same box height, never the same
        // foot. With the foot cut off, the apex's row does the same.
        let row_sigma = bearing_sigma + 0.05 * b.height();
        let row = if !trusted || (cut.top && cut.bottom) {
            0.0
        } else if cut.bottom {
            (b.top - predicted.top) / row_sigma
        } else {
            (b.bottom - predicted.foot) / row_sigma
        };
        Some((bearing * bearing + size * size + row * row).sqrt())
    }

    /// [`Self::distance`] to `tower`, plus `type_mismatch_cost` when the
    /// detector named another type and the guess is trusted; none when it
    /// named another type and the guess is rough.
    fn fit(
        &self,
        track: &TrackOutput,
        tower: usize,
        predicted: Prediction,
        map: &LandmarkMap,
        image: (f64, f64),
        trusted: bool,
    ) -> Option<f64> {
        let named = map.towers.get(tower)?.tower_type == track.tower_type;
        if !named && !trusted {
            return None;
        }
        let d = self.distance(track, predicted, image, trusted)?;
        Some(if named {
            d
        } else {
            d + self.params.type_mismatch_cost
        })
    }

    /// Binds this frame's tracks; returns each track's tower index, in order.
    /// `candidates` (towers near the pose guess) is asked at most once, and only when a
    /// track is unbound or the guess is trusted enough to check bindings.
    /// With `guess_trusted` (the filter is tracking), bindings that keep
    /// disagreeing with the guess are moved or released.
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
        let predict = |i: usize| Prediction::of(&map.towers[i], camera, &camera_from_world);
        // Towers near the guess, asked for once, and only when some track needs
        // them: to bind it, or (with a trusted guess) to check its binding.
        let unpinned = |t: &&TrackOutput| !self.pinned.contains_key(&t.track_id);
        let needed = tracks
            .iter()
            .filter(unpinned)
            .any(|t| guess_trusted || !self.bindings.contains_key(&t.track_id));
        // Each nearby tower is projected once, for both steps.
        let near: Vec<(usize, Option<Prediction>)> = if needed {
            candidates().into_iter().map(|i| (i, predict(i))).collect()
        } else {
            Vec::new()
        };
        let doubted = if guess_trusted {
            self.reassign(tracks, &near, &predict, image, map)
        } else {
            Vec::new()
        };
        self.bind_unbound(tracks, &near, image, map, guess_trusted);
        tracks
            .iter()
            .map(|t| {
                if doubted.contains(&t.track_id) {
                    None
                } else {
                    self.bindings.get(&t.track_id).copied()
                }
            })
            .collect()
    }

    /// With a trusted guess, all unpinned tracks are matched afresh to the
    /// nearby towers, each track's own tower favoured by the hysteresis margin.
    /// A bound track the matching puts elsewhere takes a strike, and gives one
    /// back when it is put on its own tower; enough strikes move it to where
    /// the matching puts it (or unbind it).
    /// Matching jointly undoes swaps: two tracks each bound to the other's
    /// tower can only be put right together, never one by one.
    /// Returns the tracks whose binding this frame's box speaks against while
    /// most bindings agree, or whose box fits a neighbour about as well as
    /// its own tower: left out for the frame, bound as before after it.
    fn reassign(
        &mut self,
        tracks: &[TrackOutput],
        near: &[(usize, Option<Prediction>)],
        predict: &dyn Fn(usize) -> Option<Prediction>,
        image: (f64, f64),
        map: &LandmarkMap,
    ) -> Vec<u64> {
        let open: Vec<&TrackOutput> = tracks
            .iter()
            .filter(|t| !self.pinned.contains_key(&t.track_id))
            .collect();
        if !open.iter().any(|t| self.bindings.contains_key(&t.track_id)) {
            return Vec::new();
        }
        let pinned_towers: Vec<usize> = self.pinned.values().flatten().copied().collect();
        // The nearby towers and any bound one that is not among them.
        let mut towers: Vec<(usize, Option<Prediction>)> = near.to_vec();
        for t in &open {
            if let Some(&b) = self.bindings.get(&t.track_id)
                && !towers.iter().any(|&(i, _)| i == b)
            {
                towers.push((b, predict(b)));
            }
        }
        towers.retain(|(i, _)| !pinned_towers.contains(i));
        let p = self.params;
        let matches = max_score_matching(
            open.len(),
            towers.len(),
            |r, c| {
                let track = open[r];
                let (tower, predicted) = towers[c];
                let own = self.bindings.get(&track.track_id) == Some(&tower);
                let Some(pred) = upright(predicted) else {
                    return 0.0;
                };
                match (self.fit(track, tower, pred, map, image, true), own) {
                    // A box with no evidence keeps its tower, unless a track
                    // with evidence claims it.
                    (None, true) => KEEP,
                    (None, false) => 0.0,
                    (Some(d), true) if d < p.release_gate => {
                        (p.gate + p.switch_margin - d).max(KEEP)
                    }
                    (Some(_), true) => 0.0,
                    (Some(d), false) => p.gate - d,
                }
            },
            KEEP,
        );
        let mut proposal: HashMap<u64, usize> = HashMap::new();
        for (r, c) in matches {
            proposal.insert(open[r].track_id, towers[c].0);
        }
        // How far a track's box lies from its own tower, and from the
        // nearest other one.
        let fits = |track: &TrackOutput, own: usize| -> Option<(f64, f64)> {
            let fit = |&(tower, predicted): &(usize, Option<Prediction>)| {
                self.fit(track, tower, upright(predicted)?, map, image, true)
            };
            let mine = towers.iter().find(|(i, _)| *i == own).and_then(fit)?;
            let other = towers
                .iter()
                .filter(|(i, _)| *i != own)
                .filter_map(fit)
                .fold(f64::INFINITY, f64::min);
            Some((mine, other))
        };
        // A box that fits a neighbour about as well as its own tower (two
        // towers of a row merged into one box, or half of each) cannot say
        // which it is: if the matching keeps it on its tower, its binding
        // stands, but the frame is not handed to the localizer.
        let crowded: Vec<u64> = open
            .iter()
            .filter(|t| {
                let Some(&bound) = self.bindings.get(&t.track_id) else {
                    return false;
                };
                proposal.get(&t.track_id) == Some(&bound)
                    && fits(t, bound).is_some_and(|(mine, other)| other - mine < p.ambiguity_margin)
            })
            .map(|t| t.track_id)
            .collect();
        let mut moves = Vec::new();
        let (mut agreeing, mut doubted) = (0usize, Vec::new());
        for t in &open {
            let Some(&bound) = self.bindings.get(&t.track_id) else {
                continue;
            };
            let wanted = proposal.get(&t.track_id).copied();
            let strikes = self.strikes.entry(t.track_id).or_insert(0);
            *strikes = if wanted == Some(bound) {
                agreeing += 1;
                strikes.saturating_sub(1)
            } else {
                *strikes + 1
            };
            if *strikes >= p.release_after {
                moves.push((t.track_id, wanted));
            } else if wanted != Some(bound) {
                doubted.push(t.track_id);
            }
        }
        // A box that flickers onto a neighbour of its tower for a frame would
        // hand the localizer the wrong tower; when no fewer bindings agree with
        // the guess, the guess is the better judge of that frame. When most
        // disagree, the guess itself is in doubt, and the bindings stand.
        if doubted.len() > agreeing {
            doubted.clear();
        }
        doubted.extend(crowded);
        for (track, wanted) in moves {
            self.strikes.remove(&track);
            self.bindings.remove(&track);
            if let Some(tower) = wanted {
                // Whoever holds the tower lets go; it is bound again below.
                self.bindings.retain(|_, b| *b != tower);
                self.bindings.insert(track, tower);
            }
        }
        doubted
    }

    /// Binds the tracks that have no tower to the free nearby towers of their
    /// type, best matches first.
    fn bind_unbound(
        &mut self,
        tracks: &[TrackOutput],
        near: &[(usize, Option<Prediction>)],
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
            let free: Vec<(usize, Option<Prediction>)> = near
                .iter()
                .copied()
                .filter(|(i, _)| !taken.contains(i))
                .collect();
            let fit = |track: &TrackOutput, (tower, predicted): (usize, Option<Prediction>)| {
                self.fit(track, tower, upright(predicted)?, map, image, guess_trusted)
            };
            let distance = |r: usize, c: usize| fit(unbound[r], free[c]);
            let matches = max_score_matching(
                unbound.len(),
                free.len(),
                |r, c| distance(r, c).map_or(0.0, |d| self.params.gate - d),
                f64::MIN_POSITIVE,
            );
            let mut chosen = Vec::with_capacity(matches.len());
            for (r, c) in matches {
                let Some(best) = distance(r, c) else { continue };
                // Held towers count too: a second box on a tower another
                // track holds (a duplicate, or a new track before the old
                // one ends) is not pushed onto that tower's free neighbour.
                let runner_up = near
                    .iter()
                    .filter(|&&(i, _)| i != free[c].0)
                    .filter_map(|&o| fit(unbound[r], o))
                    .fold(f64::INFINITY, f64::min);
                if runner_up - best >= self.params.ambiguity_margin {
                    chosen.push((unbound[r].track_id, free[c].0));
                }
            }
            self.bindings.extend(chosen);
        }
    }
}

/// How far, pixels, a box cut by the image's left or right border sticks out
/// of the farthest the predicted tower reaches: its axis (top to foot,
/// leaning with the roll) and half its height either side (no tower is wider
/// than it is tall). The side still in view must lie within that reach (a box
/// cut at the left border with its right side at 60 px is not a tower whose
/// axis stands 700 px outside the image), and so must the cut side, which is
/// the border: the tower runs on past it, so one predicted wholly on the
/// other side of the image, or wholly inside it, did not leave this box.
/// Within the reach the sides say nothing: the box of a tower seen close and
/// obliquely may end anywhere short of its far side.
fn visible_side_offset(b: &PixelBox, cut: Cut, predicted: Prediction) -> f64 {
    if cut.left == cut.right {
        return 0.0;
    }
    let reach = 0.5 * predicted.height.max(0.0) + predicted.lean.abs();
    ((predicted.u - reach) - b.left).max(0.0) + (b.right - (predicted.u + reach)).max(0.0)
}

/// A tower's prediction when a box could be it: it stands upright in front
/// of the camera.
fn upright(predicted: Option<Prediction>) -> Option<Prediction> {
    predicted.filter(|p| p.height > 0.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Point3;
    use towernav_geometry::{Attitude, PixelBox};
    use towernav_protocol::TowerType;

    fn map() -> LandmarkMap {
        map_of(&[
            ("A1", 100.0, 30.0),
            ("A2", 100.0, -30.0),
            ("A3", 300.0, 30.0),
        ])
    }

    /// Type-A towers 30 m tall at `(id, x, y)`.
    fn map_of(towers: &[(&str, f64, f64)]) -> LandmarkMap {
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
            towers.iter().map(|&(id, x, y)| tower(id, x, y)).collect(),
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
    fn a_misnamed_type_is_evidence_not_a_rule() {
        let camera = PinholeCamera::default_hd();
        let pose = pose_at_20m();
        // A1 (type A) stands alone ahead; the classifier calls its box D.
        let map = map_of(&[("A1", 150.0, 0.0), ("A2", 150.0, 120.0)]);
        let mut misnamed = observe(&pose, &camera, &map, 0, 7);
        misnamed.tower_type = TowerType::D;
        let mut identity = Identity::new(IdentityParams::default());
        let bound = identity.update(
            &[misnamed.clone()],
            &[7],
            view(&pose, &camera, &map, true),
            || vec![0, 1],
        );
        assert_eq!(bound, [Some(0)], "on A1's place, it is A1");
        let mut rough = Identity::new(IdentityParams::default());
        let bound = rough.update(&[misnamed], &[7], view(&pose, &camera, &map, false), || {
            vec![0, 1]
        });
        assert_eq!(bound, [None], "a rough guess does not outvote the type");

        // Two towers about as far from the box, one of the named type: that
        // one. A1 (type A) and B1 (type B) side by side, 3 m apart.
        let mut map = map_of(&[("A1", 150.0, 0.0), ("B1", 150.0, 3.0)]);
        map.towers[1].tower_type = TowerType::B;
        let mut between = observe(&pose, &camera, &map, 0, 8);
        let shift =
            0.5 * (observe(&pose, &camera, &map, 1, 8).bbox.center_x() - between.bbox.center_x());
        between.bbox = PixelBox::new(
            between.bbox.left + shift,
            between.bbox.top,
            between.bbox.right + shift,
            between.bbox.bottom,
        );
        between.tower_type = TowerType::B;
        let mut identity = Identity::new(IdentityParams::default());
        let bound = identity.update(&[between], &[8], view(&pose, &camera, &map, true), || {
            vec![0, 1]
        });
        assert_eq!(bound, [Some(1)], "the named type decides a tie");
    }

    /// The view from 20 m up, level, looking along +x.
    fn pose_at_20m() -> Pose {
        Pose {
            position_in_world: Point3::new(0.0, 0.0, 20.0),
            attitude: Attitude::level(0.0),
        }
    }

    fn view<'a>(
        pose: &'a Pose,
        camera: &'a PinholeCamera,
        map: &'a LandmarkMap,
        trusted: bool,
    ) -> View<'a> {
        View {
            guess: pose,
            trusted,
            camera,
            map,
        }
    }

    #[test]
    fn two_tracks_bound_to_each_others_tower_in_a_row_are_put_right_together() {
        // Two look-alike towers one behind the other on the same bearing: each
        // fits the other's box but a little worse, so neither binding can be
        // put right alone while the other still holds its tower.
        let camera = PinholeCamera::default_hd();
        let pose = pose_at_20m();
        let map = map_of(&[("A1", 200.0, 0.0), ("A2", 220.0, 0.0)]);
        let tracks = [
            observe(&pose, &camera, &map, 0, 7),
            observe(&pose, &camera, &map, 1, 8),
        ];
        let mut identity = Identity::new(IdentityParams::default());
        identity.bindings.insert(7, 1);
        identity.bindings.insert(8, 0);
        let mut bound = Vec::new();
        for _ in 0..=IdentityParams::default().release_after {
            bound = identity.update(&tracks, &[7, 8], view(&pose, &camera, &map, true), || {
                vec![0, 1]
            });
        }
        assert_eq!(bound, [Some(0), Some(1)]);
    }

    #[test]
    fn a_near_tower_cut_at_the_foot_is_not_taken_for_a_far_one_on_its_bearing() {
        // The near tower's foot is below the image: its box says nothing of
        // its height but that the tower is at least as tall as what shows.
        let camera = PinholeCamera::default_hd();
        let pose = pose_at_20m();
        let map = map_of(&[("A1", 400.0, 0.0), ("A2", 40.0, 0.0)]);
        let mut near = observe(&pose, &camera, &map, 1, 7);
        let bottom = f64::from(camera.intrinsics.height);
        assert!(
            near.bbox.bottom > bottom,
            "the near foot is out of the image"
        );
        near.bbox.bottom = bottom;
        let far = observe(&pose, &camera, &map, 0, 7);
        assert!((near.bbox.center_x() - far.bbox.center_x()).abs() < 1.0);
        for trusted in [false, true] {
            let mut identity = Identity::new(IdentityParams::default());
            let bound = identity.update(
                std::slice::from_ref(&near),
                &[7],
                view(&pose, &camera, &map, trusted),
                || vec![0, 1],
            );
            assert_eq!(bound, [Some(1)], "trusted: {trusted}");
            // A near tower the survey missed is left unbound, not given the far one.
            let mut identity = Identity::new(IdentityParams::default());
            let bound = identity.update(
                std::slice::from_ref(&near),
                &[7],
                view(&pose, &camera, &map, trusted),
                || vec![0],
            );
            assert_eq!(bound, [None], "trusted: {trusted}");
        }
    }

    #[test]
    fn a_box_between_two_towers_waits_for_a_guess_that_tells_them_apart() {
        // Two look-alikes 2 m apart, 100 m ahead: a rough guess cannot tell
        // which one the box is on, a trusted one can.
        let camera = PinholeCamera::default_hd();
        let pose = pose_at_20m();
        let map = map_of(&[("A1", 100.0, 1.0), ("A2", 100.0, -1.0)]);
        let track = observe(&pose, &camera, &map, 0, 7);
        let mut identity = Identity::new(IdentityParams::default());
        let bound = identity.update(
            std::slice::from_ref(&track),
            &[7],
            view(&pose, &camera, &map, false),
            || vec![0, 1],
        );
        assert_eq!(bound, [None], "a coin toss is not taken");
        let bound = identity.update(
            std::slice::from_ref(&track),
            &[7],
            view(&pose, &camera, &map, true),
            || vec![0, 1],
        );
        assert_eq!(bound, [Some(0)]);
        // With one of them alone near the guess, the rough guess binds too.
        let mut identity = Identity::new(IdentityParams::default());
        let bound = identity.update(
            std::slice::from_ref(&track),
            &[7],
            view(&pose, &camera, &map, false),
            || vec![0],
        );
        assert_eq!(bound, [Some(0)]);
    }

    #[test]
    fn a_box_that_flickers_onto_a_neighbour_is_left_out_for_that_frame_only() {
        // Two towers beside the path and a row of two ahead; the track on the
        // row's first tower shows the second for one frame, as a tracker does
        // when the detector gives one box for two that overlap, then a box
        // across both.
        let camera = PinholeCamera::default_hd();
        let pose = pose_at_20m();
        let map = row();
        let on = |tower: usize, track: u64| observe(&pose, &camera, &map, tower, track);
        let steady = [on(0, 7), on(1, 8), on(2, 9)];
        let flicker = [on(0, 7), on(1, 8), on(3, 9)];
        let ids = [7, 8, 9];
        let towers = || vec![0, 1, 2, 3];
        let mut identity = Identity::new(IdentityParams::default());
        let trusted = view(&pose, &camera, &map, true);
        let bound = identity.update(&steady, &ids, trusted, towers);
        assert_eq!(bound, [Some(0), Some(1), Some(2)]);
        let bound = identity.update(&flicker, &ids, trusted, towers);
        assert_eq!(bound, [Some(0), Some(1), None], "not handed over as B1");
        let bound = identity.update(&steady, &ids, trusted, towers);
        assert_eq!(bound, [Some(0), Some(1), Some(2)], "still B1's track");
        // A box halfway between B1's and B2's cannot say which it is: the
        // matching keeps it on B1, but it is left out, with no strike.
        let (b1, b2) = (on(2, 9).bbox, on(3, 9).bbox);
        let between = TrackOutput {
            bbox: PixelBox::new(
                0.5 * (b1.left + b2.left),
                0.5 * (b1.top + b2.top),
                0.5 * (b1.right + b2.right),
                0.5 * (b1.bottom + b2.bottom),
            ),
            ..on(2, 9)
        };
        let merged = [on(0, 7), on(1, 8), between];
        let strikes_before = identity.confidence(9);
        let bound = identity.update(&merged, &ids, trusted, towers);
        assert_eq!(bound, [Some(0), Some(1), None], "left out");
        assert_eq!(identity.binding(9), Some(2), "still held");
        assert!(
            identity.confidence(9) >= strikes_before,
            "no strike: it agreed"
        );
        // Alone, the box is not enough to doubt the binding: the guess may be the one that is off.
        let mut identity = Identity::new(IdentityParams::default());
        identity.update(&steady[2..], &[9], trusted, towers);
        assert_eq!(
            identity.update(&flicker[2..], &[9], trusted, towers),
            [Some(2)]
        );
        // With one binding that agrees beside it, a tie, the guess judges.
        let mut identity = Identity::new(IdentityParams::default());
        identity.update(&steady[1..], &[8, 9], trusted, towers);
        assert_eq!(
            identity.update(&flicker[1..], &[8, 9], trusted, towers),
            [Some(1), None]
        );
    }

    /// Two towers beside the path, and B1 and B2 ahead, B2 behind B1.
    fn row() -> LandmarkMap {
        map_of(&[
            ("A1", 100.0, 30.0),
            ("A2", 100.0, -30.0),
            ("B1", 200.0, 0.0),
            ("B2", 260.0, 0.0),
        ])
    }

    #[test]
    fn a_second_box_on_a_held_tower_is_not_pushed_onto_its_free_neighbour() {
        // Track 9 holds B1; a new track 10 shows B1 too (a duplicate box, or
        // a new track before the old one ends). B2, behind B1 and free, is
        // within the rough guess's gate, but B1 fits the box far better.
        let camera = PinholeCamera::default_hd();
        let pose = pose_at_20m();
        let map = row();
        let rough = view(&pose, &camera, &map, false);
        let towers = || vec![0, 1, 2, 3];
        let mut identity = Identity::new(IdentityParams::default());
        let first = [observe(&pose, &camera, &map, 2, 9)];
        assert_eq!(identity.update(&first, &[9], rough, towers), [Some(2)]);
        let both = [first[0].clone(), observe(&pose, &camera, &map, 2, 10)];
        let b2 = upright(Some(predicted(&pose, &camera, &map, 3)))
            .and_then(|p| identity.fit(&both[1], 3, p, &map, (1280.0, 720.0), false))
            .expect("B2 is in view");
        assert!(
            b2 < IdentityParams::default().gate,
            "B2 within the gate: {b2}"
        );
        assert_eq!(
            identity.update(&both, &[9, 10], rough, towers),
            [Some(2), None],
            "not taken for B2"
        );
        // Once the old track ends, the new one takes B1.
        assert_eq!(identity.update(&both[1..], &[10], rough, towers), [Some(2)]);
    }

    /// Where tower `i` should stand in the image from `pose`.
    fn predicted(pose: &Pose, camera: &PinholeCamera, map: &LandmarkMap, i: usize) -> Prediction {
        let cfw = camera.world_from_camera(pose).inverse();
        Prediction::of(&map.towers[i], camera, &cfw).expect("visible")
    }

    #[test]
    fn a_box_cut_at_the_border_is_judged_by_the_side_still_in_view() {
        // Cut at the left border, its right side at 59 px: the tower whose
        // axis stands at 25 px fits; one 700 px outside the image, of the
        // same size, does not.
        let identity = Identity::new(IdentityParams::default());
        let track = TrackOutput {
            track_id: 7,
            bbox: PixelBox::new(0.0, 244.0, 59.0, 367.0),
            tower_type: TowerType::A,
            score: 0.9,
        };
        let image = (1280.0, 720.0);
        let at = |u: f64| Prediction {
            u,
            lean: 0.0,
            top: 250.0,
            foot: 360.0,
            height: 110.0,
        };
        let gate = IdentityParams::default().gate;
        let d = |u: f64| {
            identity
                .distance(&track, at(u), image, true)
                .expect("evidence")
        };
        assert!(d(25.0) < 2.0, "{}", d(25.0));
        assert!(d(-687.0) > gate, "{}", d(-687.0));
        // Nor one wholly inside the image, or off its other side: the tower
        // runs on past the border that cut the box.
        assert!(d(640.0) > gate, "{}", d(640.0));
        assert!(d(1843.0) > gate, "{}", d(1843.0));
        // Cut at the right border, the same holds from its left side.
        let mirrored = TrackOutput {
            bbox: PixelBox::new(1221.0, 244.0, 1280.0, 367.0),
            ..track
        };
        let d = |u: f64| {
            identity
                .distance(&mirrored, at(u), image, true)
                .expect("evidence")
        };
        assert!(d(1255.0) < 2.0, "{}", d(1255.0));
        assert!(d(1967.0) > gate, "{}", d(1967.0));
        assert!(d(640.0) > gate, "{}", d(640.0));
        assert!(d(-563.0) > gate, "{}", d(-563.0));
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
