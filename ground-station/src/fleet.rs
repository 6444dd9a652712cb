//! What the ground station knows of each UAV (pure: time is passed in).

use std::collections::{BTreeMap, VecDeque};

use towernav_geometry::{Datum, Geodetic};
use towernav_protocol::{EdgeState, NodeId, PoseEstimate, StatusHeartbeat, TrackReport};

use crate::corrections::Corrections;
use crate::events::DecodedPreview;
pub use crate::events::NetEvent;

/// Poses kept per UAV for its trail on the map.
pub const TRAIL_LEN: usize = 5000;
/// A UAV from which nothing at all came for this long is late; a pose this
/// old is no longer a current fix. The edge sends status every second and
/// tracks and previews with every frame, so two seconds of silence is news.
pub const STALE_AFTER_S: f64 = 2.0;
/// A UAV silent for this long, or whose liveliness token went, has lost its
/// link: everything shown of it is history. (QGroundControl calls a link lost
/// after 3.5 s without a heartbeat; the edge's status comes every second.)
pub const LOST_AFTER_S: f64 = 5.0;

/// Whether the ground station hears a UAV: any message counts (pose, status,
/// tracks, camera frame), not only poses. A UAV out of sight of towers is
/// heard, and has no fix: that is [`Nav`], not a lost link.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Link {
    /// Nothing heard yet, and no sign of loss.
    Waiting,
    Live,
    /// Messages are late (seconds since the last of any kind).
    Stale(f64),
    /// The link is gone: the edge left, the network stopped, or it has been
    /// silent past [`LOST_AFTER_S`] (seconds since the last message, if any).
    Lost(Option<f64>),
}

/// Whether the UAV knows where it is, from its poses and its status's state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Nav {
    /// Neither a pose nor a status yet.
    Unknown,
    /// Poses are coming (seconds since the last).
    Fix(f64),
    /// Poses are coming, each the filter's prediction through a gap with no
    /// tower fix (seconds since the last tower fix).
    Predicting { coast_s: f64 },
    /// No tower in the last frames: the filter predicts but publishes
    /// nothing current (seconds since the last pose, if any).
    Coasting(Option<f64>),
    /// No estimate (seconds since the last pose, if any).
    NoFix(Option<f64>),
}

impl Nav {
    pub fn is_fix(self) -> bool {
        matches!(self, Nav::Fix(_))
    }

    /// Whether the last pose is where the UAV is now: a fix, or a current
    /// prediction whose covariance says how far to trust it.
    pub fn is_current(self) -> bool {
        matches!(self, Nav::Fix(_) | Nav::Predicting { .. })
    }
}

impl Link {
    pub fn is_live(self) -> bool {
        matches!(self, Link::Live)
    }

    pub fn is_lost(self) -> bool {
        matches!(self, Link::Lost(_))
    }
}
/// A trail point that ends one stretch: the next pose came after a silence
/// of more than [`STALE_AFTER_S`] or from a restarted edge (its frame count
/// went back), and no line may join the two.
pub const TRAIL_BREAK: [f64; 2] = [f64::NAN, f64::NAN];
/// Track reports kept per UAV (three seconds at 30 Hz), to match a preview's frame.
const RECENT_TRACKS: usize = 90;
/// The window the pose rate is counted over.
const RATE_WINDOW_S: f64 = 2.0;

#[derive(Debug, Clone, Default)]
pub struct UavView {
    pub last_pose: Option<PoseEstimate>,
    /// When the last pose arrived, on the ground station's clock.
    pub last_pose_at_s: Option<f64>,
    /// The edge's own times of its last few seconds of poses, for the rate: a
    /// burst of poses queued across a reconnect arrives at once, but was
    /// sent at the edge's pace.
    pose_times: VecDeque<f64>,
    /// Ground speed over the last second or more of poses, m/s.
    pub speed_mps: Option<f64>,
    /// The pose the speed is measured from: (edge time, east/north).
    speed_from: Option<(f64, [f64; 2])>,
    /// East/north in the ground station's map frame; [`TRAIL_BREAK`] between
    /// stretches.
    pub trail: VecDeque<[f64; 2]>,
    /// The simulator's truth, east/north in the map frame.
    pub truth_trail: VecDeque<[f64; 2]>,
    /// The last truth's frame number: one lower than it is a restarted edge,
    /// whose truth starts a new line.
    pub last_truth_seq: Option<u64>,
    pub status: Option<StatusHeartbeat>,
    /// The last tracks reports, newest last: the preview is drawn with the one of its frame.
    pub recent_tracks: VecDeque<TrackReport>,
    pub preview: Option<DecodedPreview>,
    /// The liveliness token: `None` until one was seen either way.
    pub alive: Option<bool>,
    /// When anything from this UAV last arrived (pose, status, tracks,
    /// camera frame), on the ground station's clock.
    pub last_heard_at_s: Option<f64>,
}

impl UavView {
    pub fn tracks(&self) -> Option<&TrackReport> {
        self.recent_tracks.back()
    }

    /// The tracks of frame `seq`, or the latest when that frame's are gone.
    pub fn tracks_near(&self, seq: u64) -> Option<&TrackReport> {
        self.recent_tracks
            .iter()
            .rev()
            .find(|t| t.seq == seq)
            .or_else(|| self.tracks())
    }

    /// Poses per second over the edge's last two seconds of poses (0 until
    /// they span half a second).
    pub fn pose_rate_hz(&self) -> f64 {
        match (self.pose_times.front(), self.pose_times.back()) {
            (Some(&first), Some(&last)) if last - first >= 0.5 => {
                (self.pose_times.len() - 1) as f64 / (last - first)
            }
            _ => 0.0,
        }
    }
}

#[derive(Debug, Clone)]
pub struct Fleet {
    /// The map frame's origin; UAV positions are placed by their WGS84 fix, not their own ENU.
    pub datum: Datum,
    pub uavs: BTreeMap<NodeId, UavView>,
    pub corrections: Corrections,
    pub rejected: Vec<(String, String)>,
    /// Messages for the operator from the network side (recording, sends).
    pub notices: Vec<String>,
    pub network_error: Option<String>,
    /// The recording running, and since when (the app's clock).
    pub recording: Option<(std::path::PathBuf, f64)>,
}

fn push_bounded(trail: &mut VecDeque<[f64; 2]>, point: [f64; 2]) {
    if trail.len() == TRAIL_LEN {
        trail.pop_front();
    }
    trail.push_back(point);
}

impl Fleet {
    pub fn new(datum: Datum) -> Self {
        Self {
            datum,
            uavs: BTreeMap::new(),
            corrections: Corrections::default(),
            rejected: Vec::new(),
            notices: Vec::new(),
            network_error: None,
            recording: None,
        }
    }

    fn en(&self, lat_deg: f64, lon_deg: f64, height_m: f64) -> [f64; 2] {
        let p = self.datum.to_enu(&Geodetic {
            lat_deg,
            lon_deg,
            height_m,
        });
        [p.x, p.y]
    }

    pub fn apply(&mut self, event: NetEvent, now_s: f64) {
        let heard = match &event {
            NetEvent::Pose(p) => Some(p.uav.clone()),
            NetEvent::Tracks(t) => Some(t.uav.clone()),
            NetEvent::Status(s) => Some(s.uav.clone()),
            NetEvent::Preview(p) => Some(p.meta.uav.clone()),
            _ => None,
        };
        if let Some(uav) = heard {
            self.uavs.entry(uav).or_default().last_heard_at_s = Some(now_s);
        }
        match event {
            NetEvent::Pose(p) => {
                let en = self.en(p.lat_deg, p.lon_deg, p.alt_m);
                let view = self.uavs.entry(p.uav.clone()).or_default();
                let silent = view
                    .last_pose_at_s
                    .is_some_and(|t| now_s - t > STALE_AFTER_S);
                let restarted = view.last_pose.as_ref().is_some_and(|l| p.seq < l.seq);
                if (silent || restarted) && !view.trail.is_empty() {
                    push_bounded(&mut view.trail, TRAIL_BREAK);
                }
                if restarted {
                    view.pose_times.clear();
                    view.speed_from = None;
                    view.speed_mps = None;
                }
                push_bounded(&mut view.trail, en);
                view.pose_times.push_back(p.time_s);
                while view
                    .pose_times
                    .front()
                    .is_some_and(|&t| p.time_s - t >= RATE_WINDOW_S)
                {
                    view.pose_times.pop_front();
                }
                match view.speed_from {
                    Some((t, from)) if p.time_s - t >= 1.0 => {
                        let d = ((en[0] - from[0]).powi(2) + (en[1] - from[1]).powi(2)).sqrt();
                        view.speed_mps = Some(d / (p.time_s - t));
                        view.speed_from = Some((p.time_s, en));
                    }
                    Some(_) => {}
                    None => view.speed_from = Some((p.time_s, en)),
                }
                view.last_pose = Some(p);
                view.last_pose_at_s = Some(now_s);
            }
            NetEvent::Truth(t) => {
                let en = self.en(t.lat_deg, t.lon_deg, t.alt_m);
                let view = self.uavs.entry(t.uav).or_default();
                if view.last_truth_seq.is_some_and(|last| t.seq < last)
                    && !view.truth_trail.is_empty()
                {
                    push_bounded(&mut view.truth_trail, TRAIL_BREAK);
                }
                view.last_truth_seq = Some(t.seq);
                push_bounded(&mut view.truth_trail, en);
            }
            NetEvent::Tracks(t) => {
                let uav = t.uav.clone();
                if t.session != 0 {
                    self.corrections.run_changed(&uav, t.session);
                }
                let recent = &mut self.uavs.entry(uav).or_default().recent_tracks;
                if recent.len() == RECENT_TRACKS {
                    recent.pop_front();
                }
                recent.push_back(t);
            }
            NetEvent::Status(s) => {
                let uav = s.uav.clone();
                self.uavs.entry(uav).or_default().status = Some(s);
            }
            NetEvent::Preview(p) => {
                let uav = p.meta.uav.clone();
                self.uavs.entry(uav).or_default().preview = Some(p);
            }
            NetEvent::Ack(ack) => self.corrections.acknowledged(&ack),
            NetEvent::Alive { uav, alive } => {
                self.uavs.entry(uav).or_default().alive = Some(alive);
            }
            NetEvent::Rejected { key, error } => self.rejected.push((key, error)),
            NetEvent::Notice(text) => self.notices.push(text),
            NetEvent::Recording(path) => {
                // A recording that started answers the earlier failures to
                // record: they no longer stand beside a running REC.
                if path.is_some() {
                    self.notices.retain(|n| {
                        !n.starts_with("cannot record") && !n.starts_with("recording stopped")
                    });
                }
                self.recording = path.map(|p| (p, now_s));
            }
            NetEvent::Failed(e) => self.network_error = Some(e),
        }
    }

    /// Forgets every UAV (a replay sought backwards shows its start again);
    /// corrections and notices stay.
    pub fn forget_uavs(&mut self) {
        self.uavs.clear();
    }

    /// Seconds since the UAV's last pose arrived.
    pub fn pose_age_s(&self, uav: &NodeId, now_s: f64) -> Option<f64> {
        self.uavs
            .get(uav)?
            .last_pose_at_s
            .map(|t| (now_s - t).max(0.0))
    }

    /// Seconds since anything from the UAV arrived.
    pub fn heard_age_s(&self, uav: &NodeId, now_s: f64) -> Option<f64> {
        self.uavs
            .get(uav)?
            .last_heard_at_s
            .map(|t| (now_s - t).max(0.0))
    }

    /// Whether the UAV knows where it is: its status's state when it says it
    /// has none (or is coasting), else whether its poses are current.
    pub fn nav(&self, uav: &NodeId, now_s: f64) -> Nav {
        let Some(view) = self.uavs.get(uav) else {
            return Nav::Unknown;
        };
        let age = self.pose_age_s(uav, now_s);
        match (view.status.as_ref().map(|s| s.state), age) {
            (Some(EdgeState::NoFix | EdgeState::Initializing), a) => Nav::NoFix(a),
            // A fresh pose says more than the status, sent once a second.
            (_, Some(a)) if a <= STALE_AFTER_S => match &view.last_pose {
                Some(p) if p.is_coasting() => Nav::Predicting {
                    coast_s: p.coast_s + a,
                },
                _ => Nav::Fix(a),
            },
            (Some(EdgeState::Coasting), a) => Nav::Coasting(a),
            (_, a @ Some(_)) => Nav::NoFix(a),
            (Some(EdgeState::Localized), None) => Nav::NoFix(None),
            (None, None) => Nav::Unknown,
        }
    }

    /// How current this UAV's data is: a gone liveliness token or a stopped
    /// network is a lost link at once, silence (of every kind of message)
    /// grows from stale to lost.
    pub fn link(&self, uav: &NodeId, now_s: f64) -> Link {
        let age = self.heard_age_s(uav, now_s);
        let gone = self.uavs.get(uav).and_then(|v| v.alive) == Some(false);
        match age {
            _ if gone || self.network_error.is_some() => Link::Lost(age),
            Some(a) if a > LOST_AFTER_S => Link::Lost(Some(a)),
            Some(a) if a > STALE_AFTER_S => Link::Stale(a),
            Some(_) => Link::Live,
            None => Link::Waiting,
        }
    }

    /// Whether the UAV's poses stopped coming (it had some, and the last is old).
    pub fn is_stale(&self, uav: &NodeId, now_s: f64) -> bool {
        self.pose_age_s(uav, now_s)
            .is_some_and(|age| age > STALE_AFTER_S)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::pose;

    fn fleet() -> Fleet {
        Fleet::new(Datum::new(Geodetic {
            lat_deg: 30.52,
            lon_deg: 114.36,
            height_m: 25.0,
        }))
    }

    #[test]
    fn silence_turns_a_link_stale_then_lost_and_a_gone_token_loses_it_at_once() {
        let mut fleet = fleet();
        let uav = NodeId::new("uav1").expect("valid");
        assert_eq!(fleet.link(&uav, 0.0), Link::Waiting);
        fleet.apply(NetEvent::Pose(pose("uav1", 30.52, 114.36, 1)), 10.0);
        assert_eq!(fleet.link(&uav, 11.0), Link::Live);
        assert_eq!(fleet.link(&uav, 13.0), Link::Stale(3.0));
        assert_eq!(fleet.link(&uav, 16.0), Link::Lost(Some(6.0)));
        fleet.apply(NetEvent::Pose(pose("uav1", 30.52, 114.36, 2)), 16.0);
        assert!(fleet.link(&uav, 16.1).is_live());
        fleet.apply(
            NetEvent::Alive {
                uav: uav.clone(),
                alive: false,
            },
            16.2,
        );
        assert!(fleet.link(&uav, 16.2).is_lost(), "the edge left");
    }

    #[test]
    fn a_uav_heard_without_poses_keeps_its_link_and_has_no_fix() {
        use crate::test_support::frame_events;
        let mut fleet = fleet();
        let uav = NodeId::new("uav1").expect("valid");
        assert_eq!(fleet.nav(&uav, 0.0), Nav::Unknown);
        fleet.apply(NetEvent::Pose(pose("uav1", 30.52, 114.36, 1)), 10.0);
        assert_eq!(fleet.nav(&uav, 11.0), Nav::Fix(1.0));
        // Camera frames and tracks, no pose, for 30 s.
        for t in 11..=40 {
            for e in frame_events("uav1", u64::from(t as u32)) {
                fleet.apply(e, f64::from(t));
            }
        }
        assert!(fleet.link(&uav, 40.5).is_live());
        assert_eq!(fleet.nav(&uav, 40.0), Nav::NoFix(Some(30.0)));
        // Silence of every kind loses the link.
        assert_eq!(fleet.link(&uav, 46.0), Link::Lost(Some(6.0)));
    }

    #[test]
    fn a_silence_or_a_restarted_edge_breaks_the_trail() {
        let mut fleet = fleet();
        let uav = NodeId::new("uav1").expect("valid");
        let at = |i: u32| pose("uav1", 30.52, 114.36 + 1e-5 * f64::from(i), u64::from(i));
        for i in 0..5 {
            fleet.apply(NetEvent::Pose(at(i)), f64::from(i) * 0.1);
        }
        // Ten seconds of silence, then the same flight goes on.
        fleet.apply(NetEvent::Pose(at(5)), 10.5);
        // The edge restarts: its frame count starts again.
        fleet.apply(NetEvent::Pose(at(1)), 10.6);
        let trail = &fleet.uavs[&uav].trail;
        let breaks: Vec<usize> = trail
            .iter()
            .enumerate()
            .filter(|(_, p)| p[0].is_nan())
            .map(|(i, _)| i)
            .collect();
        assert_eq!(breaks, vec![5, 7], "{trail:?}");
        assert!(
            !trail.back().expect("points")[0].is_nan(),
            "the newest point is a place"
        );
    }

    #[test]
    fn poses_build_a_trail_in_the_map_frame_an_age_and_a_rate() {
        let mut fleet = fleet();
        // Three seconds of poses at 30 Hz, all arriving at once (queued
        // across a reconnect): the rate is the edge's, not the burst's.
        for i in 0..90u32 {
            fleet.apply(
                NetEvent::Pose(pose(
                    "uav1",
                    30.52,
                    114.36 + 1e-5 * f64::from(i),
                    u64::from(i),
                )),
                10.0,
            );
        }
        fleet.apply(NetEvent::Pose(pose("uav1", 30.52, 114.3609, 90)), 11.0);
        let uav = NodeId::new("uav1").expect("valid");
        let view = &fleet.uavs[&uav];
        assert_eq!(view.trail.len(), 91);
        let last = view.trail.back().expect("trail");
        assert!(
            (last[0] - 86.4).abs() < 1.0,
            "0.0009 deg of longitude at 30.5 N is ~86 m: {}",
            last[0]
        );
        assert!(
            (view.pose_rate_hz() - 30.0).abs() < 1e-6,
            "{}",
            view.pose_rate_hz()
        );
        // 0.0003 deg of longitude (28.8 m) in each second.
        let speed = view.speed_mps.expect("a speed");
        assert!((speed - 28.8).abs() < 0.3, "{speed}");
        assert_eq!(fleet.pose_age_s(&uav, 13.5), Some(2.5));
        assert!(fleet.is_stale(&uav, 13.5));
        assert!(!fleet.is_stale(&uav, 12.0));
    }

    #[test]
    fn liveliness_and_rejections_are_kept_for_the_operator() {
        let mut fleet = fleet();
        let uav = NodeId::new("u7").expect("valid");
        fleet.apply(
            NetEvent::Alive {
                uav: uav.clone(),
                alive: true,
            },
            0.0,
        );
        assert_eq!(fleet.uavs[&uav].alive, Some(true));
        fleet.apply(
            NetEvent::Alive {
                uav: uav.clone(),
                alive: false,
            },
            1.0,
        );
        assert_eq!(fleet.uavs[&uav].alive, Some(false));
        assert!(!fleet.is_stale(&uav, 100.0), "never had a pose: not stale");
        fleet.apply(
            NetEvent::Rejected {
                key: "not/a/key".into(),
                error: "bad".into(),
            },
            0.0,
        );
        assert_eq!(fleet.rejected.len(), 1);
    }

    #[test]
    fn a_recording_that_starts_clears_the_earlier_cannot_record() {
        let mut fleet = fleet();
        fleet.apply(NetEvent::Notice("cannot record: disk full".into()), 1.0);
        fleet.apply(NetEvent::Notice("sent correction".into()), 1.5);
        fleet.apply(NetEvent::Recording(Some("a.mcap".into())), 2.0);
        assert_eq!(fleet.notices, vec!["sent correction".to_owned()]);
    }

    #[test]
    fn a_restarted_edges_truth_starts_a_new_line() {
        let mut fleet = fleet();
        let truth = |seq: u64, lat: f64| {
            NetEvent::Truth(towernav_protocol::TruthPose {
                uav: NodeId::new("u1").expect("valid"),
                time_s: seq as f64 / 30.0,
                seq,
                lat_deg: lat,
                lon_deg: 114.36,
                alt_m: 30.0,
            })
        };
        fleet.apply(truth(100, 30.52), 1.0);
        fleet.apply(truth(101, 30.521), 1.1);
        fleet.apply(truth(0, 30.5), 2.0);
        let trail: Vec<[f64; 2]> = fleet
            .uavs
            .values()
            .next()
            .expect("u1")
            .truth_trail
            .iter()
            .copied()
            .collect();
        assert_eq!(trail.len(), 4, "{trail:?}");
        assert!(
            trail[2][0].is_nan(),
            "no break before the restart: {trail:?}"
        );
    }
}
