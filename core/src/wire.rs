//! Pipeline output to protocol messages (pure; the shell only sends them).

use towernav_geometry::{Datum, Geodetic};
use towernav_protocol::{NodeId, PoseEstimate, PoseMethod, Track, TrackReport};

use crate::filter::Estimate;
use crate::landmarks::LandmarkMap;
use crate::localizer::Method;
use crate::pipeline::FrameOutput;

/// How a published pose was made, for the wire.
pub fn pose_method(method: Method, filtered: bool) -> PoseMethod {
    match (method, filtered) {
        (Method::Paper, false) => PoseMethod::PaperLbl,
        (Method::Paper, true) => PoseMethod::PaperEkf,
        (Method::Rays, false) => PoseMethod::RaysLbl,
        (Method::Rays, true) => PoseMethod::RaysEkf,
    }
}

pub fn pose_estimate(
    uav: &NodeId,
    out: &FrameOutput,
    estimate: &Estimate,
    method: PoseMethod,
    datum: &Datum,
) -> PoseEstimate {
    let p = estimate.position_in_world;
    let Geodetic {
        lat_deg,
        lon_deg,
        height_m,
    } = datum.to_geodetic(&p);
    let c = &estimate.covariance;
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
        yaw_rad: estimate.yaw,
        covariance: std::array::from_fn(|r| std::array::from_fn(|col| c[(r, col)])),
        method,
        towers_used: out
            .fix
            .as_ref()
            .filter(|_| estimate.updated)
            .map(|f| f.towers_used.clone())
            .unwrap_or_default(),
        coast_s: estimate.coast_s.max(0.0),
    }
}

pub fn track_report(
    uav: &NodeId,
    session: u64,
    out: &FrameOutput,
    map: &LandmarkMap,
) -> TrackReport {
    TrackReport {
        uav: uav.clone(),
        session,
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
                confidence: t.confidence,
            })
            .collect(),
    }
}
