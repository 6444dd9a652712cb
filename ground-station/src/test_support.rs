//! Fixtures shared by the ground station's tests.

use std::sync::mpsc::{Sender, channel};

use towernav_protocol::{LandmarkRecord, NodeId, PoseEstimate, PoseMethod, TowerType};

use crate::app::{GsApp, map_datum};
use crate::fleet::NetEvent;

pub fn pose(uav: &str, lat_deg: f64, lon_deg: f64, seq: u64) -> PoseEstimate {
    PoseEstimate {
        uav: NodeId::new(uav).expect("valid"),
        time_s: seq as f64 / 30.0,
        seq,
        east_m: 0.0,
        north_m: 0.0,
        up_m: 30.0,
        lat_deg,
        lon_deg,
        alt_m: 55.0,
        yaw_rad: 0.0,
        covariance: [
            [4.0, 0.0, 0.0, 0.0],
            [0.0, 5.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0],
            [0.0, 0.0, 0.0, 0.0],
        ],
        method: PoseMethod::SeedLbl,
        towers_used: vec!["A1".into(), "B1".into()],
    }
}

pub fn towers() -> Vec<LandmarkRecord> {
    ["A1", "B1"]
        .iter()
        .enumerate()
        .map(|(i, id)| {
            LandmarkRecord::new(
                *id,
                TowerType::ALL[i],
                30.52 + i as f64 * 0.001,
                114.36,
                25.0,
                35.0,
            )
        })
        .collect()
}

/// An app on two towers, and the sender standing in for the network thread.
pub fn app() -> (Sender<NetEvent>, GsApp) {
    let (tx, rx) = channel();
    let landmarks = towers();
    let datum = map_datum(&landmarks).expect("towers");
    (
        tx,
        GsApp::new(&landmarks, datum, rx, "tcp/127.0.0.1:7447".into()),
    )
}
