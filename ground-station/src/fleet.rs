//! What the ground station knows of each UAV (pure: time is passed in).

use std::collections::{BTreeMap, VecDeque};

use towernav_geometry::{Datum, Geodetic};
use towernav_protocol::{NodeId, PoseEstimate, StatusHeartbeat, TrackReport};

/// Poses kept per UAV for its trail on the map.
pub const TRAIL_LEN: usize = 5000;

/// A message from the network thread.
#[derive(Debug, Clone, PartialEq)]
pub enum NetEvent {
    Pose(PoseEstimate),
    Tracks(TrackReport),
    Status(StatusHeartbeat),
    /// A payload that did not decode: shown to the operator, never silently dropped.
    Rejected {
        key: String,
        error: String,
    },
    /// The network side failed and stopped.
    Failed(String),
}

#[derive(Debug, Clone, Default)]
pub struct UavView {
    pub last_pose: Option<PoseEstimate>,
    /// When the last pose arrived, on the ground station's clock.
    pub last_pose_at_s: Option<f64>,
    /// East/north in the ground station's map frame.
    pub trail: VecDeque<[f64; 2]>,
    pub status: Option<StatusHeartbeat>,
    pub tracks: Option<TrackReport>,
}

#[derive(Debug, Clone)]
pub struct Fleet {
    /// The map frame's origin; UAV positions are placed by their WGS84 fix, not their own ENU.
    pub datum: Datum,
    pub uavs: BTreeMap<NodeId, UavView>,
    pub rejected: Vec<(String, String)>,
    pub network_error: Option<String>,
}

impl Fleet {
    pub fn new(datum: Datum) -> Self {
        Self {
            datum,
            uavs: BTreeMap::new(),
            rejected: Vec::new(),
            network_error: None,
        }
    }

    pub fn apply(&mut self, event: NetEvent, now_s: f64) {
        match event {
            NetEvent::Pose(p) => {
                let en = self.datum.to_enu(&Geodetic {
                    lat_deg: p.lat_deg,
                    lon_deg: p.lon_deg,
                    height_m: p.alt_m,
                });
                let view = self.uavs.entry(p.uav.clone()).or_default();
                if view.trail.len() == TRAIL_LEN {
                    view.trail.pop_front();
                }
                view.trail.push_back([en.x, en.y]);
                view.last_pose = Some(p);
                view.last_pose_at_s = Some(now_s);
            }
            NetEvent::Tracks(t) => {
                let uav = t.uav.clone();
                self.uavs.entry(uav).or_default().tracks = Some(t);
            }
            NetEvent::Status(s) => {
                let uav = s.uav.clone();
                self.uavs.entry(uav).or_default().status = Some(s);
            }
            NetEvent::Rejected { key, error } => self.rejected.push((key, error)),
            NetEvent::Failed(e) => self.network_error = Some(e),
        }
    }

    /// Seconds since the UAV's last pose arrived.
    pub fn pose_age_s(&self, uav: &NodeId, now_s: f64) -> Option<f64> {
        self.uavs
            .get(uav)?
            .last_pose_at_s
            .map(|t| (now_s - t).max(0.0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::pose;

    #[test]
    fn poses_build_a_trail_in_the_map_frame_and_an_age() {
        let datum = Datum::new(Geodetic {
            lat_deg: 30.52,
            lon_deg: 114.36,
            height_m: 25.0,
        });
        let mut fleet = Fleet::new(datum);
        fleet.apply(NetEvent::Pose(pose("uav1", 30.52, 114.36, 1)), 10.0);
        fleet.apply(NetEvent::Pose(pose("uav1", 30.52, 114.361, 2)), 11.0);
        let uav = NodeId::new("uav1").expect("valid");
        let view = &fleet.uavs[&uav];
        assert_eq!(view.trail.len(), 2);
        assert!(
            (view.trail[1][0] - 96.0).abs() < 1.0,
            "0.001 deg of longitude at 30.5 N is ~96 m: {}",
            view.trail[1][0]
        );
        assert_eq!(fleet.pose_age_s(&uav, 13.5), Some(2.5));
    }

    #[test]
    fn rejected_payloads_are_kept_for_the_operator() {
        let mut fleet = Fleet::new(Datum::new(Geodetic {
            lat_deg: 0.0,
            lon_deg: 0.0,
            height_m: 0.0,
        }));
        fleet.apply(
            NetEvent::Rejected {
                key: "not/a/key".into(),
                error: "bad".into(),
            },
            0.0,
        );
        assert_eq!(fleet.rejected.len(), 1);
    }
}
