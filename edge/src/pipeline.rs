//! One frame in, one pose and a set of bound tracks out: tracker -> identity -> localizer.

use nalgebra::{Point3, Vector3};
use towernav_geometry::{PinholeCamera, PixelBox, Pose};
use towernav_protocol::{DetectionFrame, TowerType};

use crate::identity::{Identity, IdentityParams};
use crate::landmarks::LandmarkMap;
use crate::localizer::{Fix, LocalizerParams, Observation, seed_lbl};
use crate::tracker::{SortParams, SortTracker};

#[derive(Debug, Clone, PartialEq)]
pub struct PipelineConfig {
    pub camera: PinholeCamera,
    /// Roughly known take-off position: it seeds identities before the first fix.
    pub takeoff_in_world: Point3<f64>,
    pub sort: SortParams,
    pub identity: IdentityParams,
    pub localizer: LocalizerParams,
    /// Only towers within this distance of the pose guess are candidates for a new track.
    pub landmark_radius_m: f64,
}

impl PipelineConfig {
    pub fn new(camera: PinholeCamera, takeoff_in_world: Point3<f64>) -> Self {
        Self {
            camera,
            takeoff_in_world,
            sort: SortParams::default(),
            identity: IdentityParams::default(),
            localizer: LocalizerParams::default(),
            landmark_radius_m: 1500.0,
        }
    }
}

#[derive(Debug, Clone, PartialEq)]
pub struct BoundTrack {
    pub track_id: u64,
    pub bbox: PixelBox,
    pub tower_type: TowerType,
    /// Index into the landmark map.
    pub tower: Option<usize>,
    pub pinned: bool,
}

#[derive(Debug, Clone, PartialEq)]
pub struct FrameOutput {
    pub seq: u64,
    pub time_s: f64,
    pub fix: Option<Fix>,
    pub tracks: Vec<BoundTrack>,
}

pub struct Pipeline {
    config: PipelineConfig,
    map: LandmarkMap,
    tracker: SortTracker,
    identity: Identity,
    /// Last fix and the velocity between the last two, for the next frame's pose guess.
    last_fix: Option<(f64, Point3<f64>)>,
    velocity: Vector3<f64>,
}

impl Pipeline {
    pub fn new(config: PipelineConfig, map: LandmarkMap) -> Self {
        Self {
            tracker: SortTracker::new(config.sort),
            identity: Identity::new(config.identity),
            config,
            map,
            last_fix: None,
            velocity: Vector3::zeros(),
        }
    }

    pub fn map(&self) -> &LandmarkMap {
        &self.map
    }

    /// Swaps in a new landmark map (the replica changed); bindings follow their towers by id.
    pub fn replace_map(&mut self, map: LandmarkMap) {
        let old = std::mem::replace(&mut self.map, map);
        let new = &self.map;
        self.identity.remap(|i| new.index_of(&old.towers[i].id));
    }

    /// An operator's correction: bind `track_id` to the tower `tower_id` (or to none).
    pub fn pin(&mut self, track_id: u64, tower_id: Option<&str>) -> Result<(), String> {
        if !self.tracker.live_ids().any(|id| id == track_id) {
            return Err(format!("track {track_id} is not live"));
        }
        let tower = match tower_id {
            Some(id) => Some(
                self.map
                    .index_of(id)
                    .ok_or_else(|| format!("tower {id:?} is not in the landmark map"))?,
            ),
            None => None,
        };
        self.identity.pin(track_id, tower);
        Ok(())
    }

    fn pose_guess(&self, frame: &DetectionFrame) -> Pose {
        let position_in_world = match self.last_fix {
            Some((t, p)) => p + self.velocity * (frame.time_s - t).clamp(0.0, 5.0),
            None => self.config.takeoff_in_world,
        };
        Pose {
            position_in_world,
            attitude: frame.imu_attitude,
        }
    }

    pub fn process(&mut self, frame: &DetectionFrame) -> FrameOutput {
        let tracks = self.tracker.update(frame.time_s, &frame.detections);
        let live: Vec<u64> = self.tracker.live_ids().collect();
        let guess = self.pose_guess(frame);
        let bindings = self.identity.update(
            &tracks,
            &live,
            &guess,
            &self.config.camera,
            &self.map,
            || {
                self.map
                    .nearby(&guess.position_in_world, self.config.landmark_radius_m)
            },
        );

        let observations: Vec<Observation<'_>> = tracks
            .iter()
            .zip(&bindings)
            .filter_map(|(t, b)| {
                b.map(|i| Observation {
                    tower: &self.map.towers[i],
                    bbox: t.bbox,
                })
            })
            .collect();
        let fix = seed_lbl(
            &observations,
            &self.config.camera.intrinsics,
            frame.imu_attitude.yaw,
            &self.config.localizer,
        );
        if let Some(fix) = &fix {
            if let Some((t, p)) = self.last_fix {
                let dt = frame.time_s - t;
                if dt > 1e-6 {
                    // Low-passed: single fixes are noisy, the guess only needs to be near.
                    self.velocity = self.velocity * 0.9 + (fix.position_in_world - p) / dt * 0.1;
                }
            }
            self.last_fix = Some((frame.time_s, fix.position_in_world));
        }
        let tracks = tracks
            .into_iter()
            .zip(bindings)
            .map(|(t, tower)| BoundTrack {
                pinned: self.identity.is_pinned(t.track_id),
                track_id: t.track_id,
                bbox: t.bbox,
                tower_type: t.tower_type,
                tower,
            })
            .collect();
        FrameOutput {
            seq: frame.seq,
            time_s: frame.time_s,
            fix,
            tracks,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use towernav_sim::Scenario;

    #[test]
    fn bindings_follow_their_towers_when_the_map_is_replaced() {
        let scenario = Scenario::seed(2);
        let records = scenario.world.landmarks();
        let map = LandmarkMap::from_records(&records, &scenario.world.datum);
        let mut pipeline = Pipeline::new(
            PipelineConfig::new(scenario.camera, scenario.start_in_world()),
            map,
        );
        let frames: Vec<_> = scenario.frames().take(200).map(|(_, f)| f).collect();
        let mut last = None;
        for f in &frames[..150] {
            last = Some(pipeline.process(f));
        }
        let ids = |out: &FrameOutput, map: &LandmarkMap| -> Vec<(u64, Option<String>)> {
            out.tracks
                .iter()
                .map(|t| (t.track_id, t.tower.map(|i| map.towers[i].id.clone())))
                .collect()
        };
        let before = ids(&last.expect("frames"), pipeline.map());
        assert!(
            before.iter().filter(|(_, id)| id.is_some()).count() >= 2,
            "{before:?}"
        );

        // The same towers in reverse order, minus one nobody is tracking.
        let tracked: Vec<&str> = before.iter().filter_map(|(_, id)| id.as_deref()).collect();
        let mut reordered: Vec<_> = records.iter().rev().cloned().collect();
        let dropped = reordered
            .iter()
            .position(|r| !tracked.contains(&r.id.as_str()))
            .expect("an untracked tower");
        reordered.remove(dropped);
        pipeline.replace_map(LandmarkMap::from_records(&reordered, &scenario.world.datum));

        let after = pipeline.process(&frames[150]);
        for (track, id) in ids(&after, pipeline.map()) {
            if let Some((_, was)) = before.iter().find(|(t, _)| *t == track) {
                assert_eq!(&id, was, "track {track} changed tower with the map");
            }
        }
    }
}
