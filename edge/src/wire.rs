//! Pipeline output to protocol messages (pure; the shell only sends them).

use towernav_geometry::{Datum, Geodetic};
use towernav_protocol::{NodeId, PoseEstimate, PoseMethod, Track, TrackReport};

use crate::landmarks::LandmarkMap;
use crate::localizer::Fix;
use crate::pipeline::FrameOutput;

pub fn pose_estimate(uav: &NodeId, out: &FrameOutput, fix: &Fix, datum: &Datum) -> PoseEstimate {
    let p = fix.position_in_world;
    let Geodetic {
        lat_deg,
        lon_deg,
        height_m,
    } = datum.to_geodetic(&p);
    let c = &fix.covariance;
    PoseEstimate {
        uav: uav.clone(),
        time_s: out.time_s,
        seq: out.seq,
        east_m: p.x,
        north_m: p.y,
        up_m: p.z,
        lat_deg,
        lon_deg,
        alt_m: height_m,
        yaw_rad: fix.yaw,
        covariance: std::array::from_fn(|r| std::array::from_fn(|col| c[(r, col)])),
        method: PoseMethod::SeedLbl,
        towers_used: fix.towers_used.clone(),
    }
}

pub fn track_report(uav: &NodeId, out: &FrameOutput, map: &LandmarkMap) -> TrackReport {
    TrackReport {
        uav: uav.clone(),
        time_s: out.time_s,
        seq: out.seq,
        tracks: out
            .tracks
            .iter()
            .map(|t| Track {
                track_id: t.track_id,
                bbox: t.bbox,
                tower_type: t.tower_type,
                tower_id: t.tower.map(|i| map.towers[i].id.clone()),
                pinned: t.pinned,
            })
            .collect(),
    }
}
