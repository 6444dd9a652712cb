//! One frame in, one pose and a set of bound tracks out: tracker -> identity -> localizer.
//!
//! A real lens is undone at the door: each detector box is mapped into the
//! ideal camera's image (its top, foot and sides undistorted), so the
//! tracker and identity work in pinhole geometry, and tracks go back out on
//! the real image. Ours localizer gets each bound box in both images: it
//! reads the rows in the real one, through the lens model. Positions inside are the camera's centre;
//! what goes out is the body's, the mount's lever arm taken off.

use nalgebra::{Point3, Vector3};
use towernav_geometry::{Attitude, PinholeCamera, PixelBox, Pose, UndistortedView};
use towernav_protocol::{Detection, DetectionFrame, TowerType};

use crate::filter::{Estimate, FilterParams, FixVerdict, PoseFilter};
use crate::identity::{Identity, IdentityParams, View};
use crate::landmarks::LandmarkMap;
use crate::localizer::{
    Fix, Height, LocalizerParams, Method, Observation, paper_lbl, robust_lbl_with_height,
};
use crate::tracker::{CameraMotion, SortParams, SortTracker, TrackOutput, Tracker, TrackerInput};

/// 1-sigma of a position hint (a consumer GNSS fix), metres.
const HINT_SIGMA_M: f64 = 5.0;

#[derive(Debug, Clone, PartialEq)]
pub struct PipelineConfig {
    pub camera: PinholeCamera,
    /// Roughly known take-off position: it seeds identities before the first fix.
    pub takeoff_in_world: Point3<f64>,
    pub sort: SortParams,
    pub identity: IdentityParams,
    pub localizer: LocalizerParams,
    /// The per-frame estimator: ours by default, the paper's as a baseline.
    pub method: Method,
    /// The EKF over fixes; `None` publishes raw per-frame fixes.
    pub filter: Option<FilterParams>,
    /// Also run the paper's method on the same observations, for side-by-side scoring.
    pub compare_paper: bool,
    /// Only towers within this distance of the pose guess are candidates for a new track.
    pub landmark_radius_m: f64,
    /// 1-sigma of the barometer's height above take-off, metres.
    pub barometer_sigma_m: f64,
}

impl PipelineConfig {
    pub fn new(camera: PinholeCamera, takeoff_in_world: Point3<f64>) -> Self {
        Self {
            camera,
            takeoff_in_world,
            sort: SortParams::default(),
            identity: IdentityParams::default(),
            localizer: LocalizerParams::default(),
            method: Method::default(),
            filter: Some(FilterParams::default()),
            compare_paper: false,
            landmark_radius_m: 1500.0,
            barometer_sigma_m: 2.0,
        }
    }
}

#[derive(Debug, Clone, PartialEq)]
pub struct BoundTrack {
    pub track_id: u64,
    pub bbox: PixelBox,
    pub tower_type: TowerType,
    /// Index into the landmark map: the tower this frame's box is taken for
    /// and handed to the localizer as.
    pub tower: Option<usize>,
    /// The tower the track is bound to, also on a frame whose box is left
    /// out (`tower` is then `None`): what names the track over time.
    pub held: Option<usize>,
    pub pinned: bool,
    /// How sure the binding is (see [`Identity::confidence`]).
    pub confidence: Option<f64>,
}

/// A bound box as the localizer gets it; `process_tampered` may alter these.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoundBox {
    pub bbox: PixelBox,
    /// Index into the landmark map.
    pub tower: usize,
    pub score: f64,
}

#[derive(Debug, Clone, PartialEq)]
pub struct FrameOutput {
    pub seq: u64,
    pub time_s: f64,
    /// This frame's own fix, by the configured method.
    pub fix: Option<Fix>,
    /// What is published: the filter's estimate, or the raw fix with no filter.
    pub estimate: Option<Estimate>,
    pub verdict: FixVerdict,
    /// The paper's fix on the same observations, when `compare_paper` is set.
    pub paper_fix: Option<Fix>,
    pub tracks: Vec<BoundTrack>,
}

pub struct Pipeline {
    config: PipelineConfig,
    /// The configured camera and the ideal one that every stage after the
    /// door sees.
    view: UndistortedView,
    map: LandmarkMap,
    tracker: SortTracker,
    identity: Identity,
    filter: Option<PoseFilter>,
    /// Last frame's IMU attitude, for camera-motion compensation.
    prev_attitude: Option<towernav_geometry::Attitude>,
    /// The newest position estimate: the pose guess when the filter has none
    /// (no filter, or lost after an outage). Better than the take-off point.
    last_known: Option<Point3<f64>>,
    /// Each live track's type as last seen: a correction must agree with it.
    track_types: std::collections::HashMap<u64, TowerType>,
    /// The newest barometric height above take-off: (time, metres).
    barometer: Option<(f64, f64)>,
}

/// A barometer reading older than this, seconds, no longer gives a frame its height.
pub const BAROMETER_MAX_AGE_S: f64 = 1.0;

/// How much of an outside id a refusal repeats: a reason names what it
/// refused, it does not echo a 64 KiB payload back.
pub const ECHO_MAX_CHARS: usize = 40;

/// `id` quoted for a refusal reason, cut to [`ECHO_MAX_CHARS`].
pub fn quoted(id: &str) -> String {
    let mut chars = id.chars();
    let head: String = chars.by_ref().take(ECHO_MAX_CHARS).collect();
    if chars.next().is_none() {
        format!("{head:?}")
    } else {
        format!("{head:?}... ({} bytes)", id.len())
    }
}

impl Pipeline {
    pub fn new(config: PipelineConfig, map: LandmarkMap) -> Self {
        let view = UndistortedView::new(&config.camera);
        Self {
            view,
            tracker: SortTracker::new(config.sort),
            identity: Identity::new(config.identity),
            filter: config.filter.map(PoseFilter::new),
            config,
            map,
            prev_attitude: None,
            last_known: None,
            track_types: std::collections::HashMap::new(),
            barometer: None,
        }
    }

    /// The autopilot's barometric height above the take-off point at
    /// `time_s`: the paper's method takes its height from it (see
    /// [`crate::localizer::Height`]).
    pub fn barometric_height(&mut self, time_s: f64, above_takeoff_m: f64) {
        if above_takeoff_m.is_finite() {
            self.barometer = Some((time_s, above_takeoff_m));
        }
    }

    /// The newest barometric height above take-off: (time, metres).
    pub fn barometer(&self) -> Option<(f64, f64)> {
        self.barometer
    }

    /// A velocity from another source (visual-inertial odometry, optical
    /// flow), east-north-up m/s with its covariance, fused into the filter:
    /// through a gap with no tower in view the position's uncertainty then
    /// grows with that velocity's error, and the coast lasts longer. `false`
    /// when it was not fused (no filter, nothing tracked, or it disagreed).
    pub fn fuse_velocity(
        &mut self,
        time_s: f64,
        velocity_in_world: &Vector3<f64>,
        covariance: &nalgebra::Matrix3<f64>,
    ) -> bool {
        let valid = velocity_in_world.iter().all(|v| v.is_finite())
            && covariance.iter().all(|v| v.is_finite())
            && (0..3).all(|i| covariance[(i, i)] > 0.0);
        valid
            && self
                .filter
                .as_mut()
                .is_some_and(|f| f.update_velocity(time_s, velocity_in_world, covariance))
    }

    pub fn map(&self) -> &LandmarkMap {
        &self.map
    }

    pub fn config(&self) -> &PipelineConfig {
        &self.config
    }

    /// Swaps in a new landmark map (the replica changed); bindings follow their towers by id.
    pub fn replace_map(&mut self, map: LandmarkMap) {
        let old = std::mem::replace(&mut self.map, map);
        let new = &self.map;
        self.identity.remap(|i| new.index_of(&old.towers[i].id));
    }

    /// An operator's correction: bind `track_id` to the tower `tower_id` (or to none).
    pub fn pin(&mut self, track_id: u64, tower_id: Option<&str>) -> Result<(), String> {
        if !self.tracker.live_ids().contains(&track_id) {
            return Err(format!("track {track_id} is not live"));
        }
        let tower = match tower_id {
            Some(id) => Some(
                self.map
                    .index_of(id)
                    .ok_or_else(|| format!("tower {} is not in the landmark map", quoted(id)))?,
            ),
            None => None,
        };
        // The detector's type is evidence too: a B track is not an A tower.
        if let (Some(t), Some(seen)) = (tower, self.track_types.get(&track_id)) {
            let tower = &self.map.towers[t];
            if tower.tower_type != *seen {
                return Err(format!(
                    "track {track_id} is a type {seen} tower, and {} is a type {}",
                    quoted(&tower.id),
                    tower.tower_type
                ));
            }
        }
        self.identity.pin(track_id, tower);
        Ok(())
    }

    /// Hands a live track back to the edge's own identity (see [`Identity::release`]).
    pub fn release(&mut self, track_id: u64) -> Result<(), String> {
        if !self.tracker.live_ids().contains(&track_id) {
            return Err(format!("track {track_id} is not live"));
        }
        self.identity.release(track_id);
        Ok(())
    }

    /// Whether the filter runs at `time_s`: it has a state it fused a fix
    /// into within its coast limit (reporting or not).
    pub fn filter_running(&self, time_s: f64) -> bool {
        self.filter
            .as_ref()
            .is_some_and(|f| f.predicted_position(time_s).is_some())
    }

    /// Where the UAV is expected at `time_s`: the filter's prediction, else
    /// the newest position known (an estimate, or a hint).
    pub fn predicted_position(&self, time_s: f64) -> Option<Point3<f64>> {
        self.filter
            .as_ref()
            .and_then(|f| f.predicted_position(time_s))
            .or(self.last_known)
            .map(|p| p - self.lever_arm_in_world(self.prev_attitude.as_ref()))
    }

    /// The camera's centre from the body's origin, in the world, at `attitude`
    /// (none yet: level, facing east; the lever arm is centimetres).
    fn lever_arm_in_world(&self, attitude: Option<&Attitude>) -> Vector3<f64> {
        let lever = self.config.camera.mount.lever_arm();
        match attitude {
            Some(a) => a.world_from_body() * lever,
            None => lever,
        }
    }

    /// Where another source (the autopilot's GNSS, while it is good) puts
    /// the UAV: the prior for identity, the start of the localizer and a
    /// prior one tower may start the filter against, until the filter tracks
    /// on its own; ignored while it does.
    pub fn hint_position(&mut self, time_s: f64, point_in_world: Point3<f64>) {
        let tracking = self
            .filter
            .as_ref()
            .and_then(|f| f.predicted_position(time_s))
            .is_some();
        if !tracking {
            let camera = point_in_world + self.lever_arm_in_world(self.prev_attitude.as_ref());
            self.last_known = Some(camera);
            if let Some(f) = &mut self.filter {
                f.set_prior(time_s, camera, HINT_SIGMA_M);
            }
        }
    }

    pub fn process(&mut self, frame: &DetectionFrame) -> FrameOutput {
        self.process_tampered(frame, |_| {})
    }

    /// `process`, with a hook between identity and localization that may alter
    /// the bound boxes: evaluations use it to inject wrong towers and false boxes.
    pub fn process_tampered(
        &mut self,
        frame: &DetectionFrame,
        tamper: impl FnOnce(&mut Vec<BoundBox>),
    ) -> FrameOutput {
        let undistorted;
        let frame = if self.config.camera.distortion.is_none() {
            frame
        } else {
            undistorted = self.undistort(frame);
            &undistorted
        };
        let predicted = self
            .filter
            .as_ref()
            .and_then(|f| f.predicted_position(frame.time_s))
            .or(self.last_known);
        let (tracks, bindings) = self.track_and_bind(frame, predicted);
        let mut bound: Vec<BoundBox> = tracks
            .iter()
            .zip(&bindings)
            .filter_map(|(t, b)| {
                b.map(|tower| BoundBox {
                    bbox: t.bbox,
                    tower,
                    score: t.score,
                })
            })
            .collect();
        tamper(&mut bound);
        let (fix, paper_fix) = self.localize(frame, &bound, predicted);
        let (mut estimate, verdict) = self.filter_step(frame, fix.as_ref());
        // The pose guess after a loss: where the filter last stood behind,
        // fusing a fix (even one held back as uncertain) or reporting.
        let fused = matches!(verdict, FixVerdict::Accepted | FixVerdict::Restarted);
        if let Some(e) = &estimate {
            self.last_known = Some(e.position_in_world);
        } else if fused && let Some(p) = self.filter.as_ref().and_then(PoseFilter::position) {
            self.last_known = Some(p);
        }
        let lever = self.lever_arm_in_world(Some(&frame.imu_attitude));
        let (mut fix, mut paper_fix) = (fix, paper_fix);
        for f in fix.iter_mut().chain(paper_fix.iter_mut()) {
            f.position_in_world -= lever;
        }
        if let Some(e) = &mut estimate {
            e.position_in_world -= lever;
        }
        self.track_types = tracks.iter().map(|t| (t.track_id, t.tower_type)).collect();
        let tracks = tracks
            .into_iter()
            .zip(bindings)
            .map(|(t, tower)| BoundTrack {
                pinned: self.identity.is_pinned(t.track_id),
                confidence: tower.and_then(|_| self.identity.confidence(t.track_id)),
                held: self.identity.binding(t.track_id),
                track_id: t.track_id,
                bbox: self.view.to_real(&t.bbox),
                tower_type: t.tower_type,
                tower,
            })
            .collect();
        FrameOutput {
            seq: frame.seq,
            time_s: frame.time_s,
            fix,
            estimate,
            verdict,
            paper_fix,
            tracks,
        }
    }

    /// The frame with its boxes in the ideal camera's image
    /// ([`UndistortedView::to_ideal`]). A box the lens model cannot map is
    /// dropped; the edge refuses a lens it cannot invert over the whole image.
    fn undistort(&self, frame: &DetectionFrame) -> DetectionFrame {
        let detections = frame
            .detections
            .iter()
            .filter_map(|d| {
                let Some(bbox) = self.view.to_ideal(&d.bbox) else {
                    tracing::debug!(bbox = ?d.bbox, "a box outside the lens model's field is dropped");
                    return None;
                };
                Some(Detection { bbox, ..d.clone() })
            })
            .collect();
        DetectionFrame {
            detections,
            ..frame.clone()
        }
    }

    /// The tracker's step, then each track bound to a tower (or not) about
    /// the predicted position, or the take-off before the first fix.
    fn track_and_bind(
        &mut self,
        frame: &DetectionFrame,
        predicted: Option<Point3<f64>>,
    ) -> (Vec<TrackOutput>, Vec<Option<usize>>) {
        let motion = self
            .prev_attitude
            .map(|before| CameraMotion::between(&self.view.ideal, &before, &frame.imu_attitude));
        self.prev_attitude = Some(frame.imu_attitude);
        let tracks = self.tracker.step(&TrackerInput {
            time_s: frame.time_s,
            detections: &frame.detections,
            motion: motion.as_ref(),
            features: None,
        });
        let live = self.tracker.live_ids();
        let guess = Pose {
            position_in_world: predicted.unwrap_or(self.config.takeoff_in_world),
            attitude: frame.imu_attitude,
        };
        let trusted = self
            .filter
            .as_ref()
            .is_some_and(|f| f.tracking(frame.time_s, 0.5));
        let view = View {
            guess: &guess,
            trusted,
            camera: &self.view.ideal,
            map: &self.map,
        };
        let bindings = self.identity.update(&tracks, &live, view, || {
            self.map
                .nearby(&guess.position_in_world, self.config.landmark_radius_m)
        });
        (tracks, bindings)
    }

    /// The configured method's fix from the bound boxes, and the paper's
    /// alongside when it is compared.
    fn localize(
        &self,
        frame: &DetectionFrame,
        bound: &[BoundBox],
        predicted: Option<Point3<f64>>,
    ) -> (Option<Fix>, Option<Fix>) {
        let observations: Vec<Observation<'_>> = bound
            .iter()
            .filter_map(|b| {
                Some(Observation {
                    tower: self.map.towers.get(b.tower)?,
                    bbox: b.bbox,
                    raw: self.view.to_real(&b.bbox),
                    score: b.score,
                })
            })
            .collect();
        let params = &self.config.localizer;
        // The camera's height: the take-off point's, the barometer's climb
        // since, and the mount's lever arm.
        let lever = self.lever_arm_in_world(Some(&frame.imu_attitude));
        let barometric = match self.barometer {
            Some((t, h)) if (frame.time_s - t).abs() <= BAROMETER_MAX_AGE_S => Some(Height {
                up_m: self.config.takeoff_in_world.z + h + lever.z,
                sigma_m: self.config.barometer_sigma_m,
            }),
            _ => None,
        };
        let height = barometric.unwrap_or_else(|| {
            Height::unknown(predicted.unwrap_or(self.config.takeoff_in_world).z)
        });
        let paper = || {
            paper_lbl(
                &observations,
                &self.view.ideal.intrinsics,
                frame.imu_attitude.yaw,
                height,
                params,
            )
        };
        let fix = match self.config.method {
            Method::Paper => paper(),
            Method::Rays => robust_lbl_with_height(
                &observations,
                &self.view.real,
                &frame.imu_attitude,
                predicted,
                barometric,
                params,
            )
            .map(|r| r.fix),
        };
        let paper_fix = if self.config.compare_paper {
            paper()
        } else {
            None
        };
        (fix, paper_fix)
    }

    /// The filter's step on the fix; without a filter, the fix as it is.
    fn filter_step(
        &mut self,
        frame: &DetectionFrame,
        fix: Option<&Fix>,
    ) -> (Option<Estimate>, FixVerdict) {
        let params = &self.config.localizer;
        let imu_yaw_var = params.yaw_sigma * params.yaw_sigma;
        match &mut self.filter {
            Some(filter) => filter.step(frame.time_s, fix, frame.imu_attitude.yaw, imu_yaw_var),
            None => (
                fix.map(|f| Estimate {
                    position_in_world: f.position_in_world,
                    velocity_in_world: nalgebra::Vector3::zeros(),
                    yaw: f.yaw,
                    covariance: f.covariance,
                    velocity_covariance: nalgebra::Matrix3::zeros(),
                    updated: true,
                    coast_s: 0.0,
                }),
                if fix.is_some() {
                    FixVerdict::Accepted
                } else {
                    FixVerdict::NoFix
                },
            ),
        }
    }
}
