//! Fixtures shared by the ground station's tests and benches.

use std::sync::mpsc::Sender;

use tokio::sync::mpsc::UnboundedReceiver;
use towernav_landmark_db::{Author, LandmarkDb};
use towernav_protocol::{LandmarkRecord, NodeId, PoseEstimate, PoseMethod, TowerType};

use crate::app::{GsApp, GsOptions};
use crate::events::NetEvent;
use crate::net::{NetCommand, NetLink};

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
        method: PoseMethod::PaperLbl,
        towers_used: vec!["A1".into(), "B1".into()],
    }
}

/// A JPEG of one colour, as an edge's preview carries.
pub fn jpeg(width: u32, height: u32, rgb: [u8; 3]) -> Vec<u8> {
    let mut jpeg = Vec::new();
    image::RgbImage::from_pixel(width, height, image::Rgb(rgb))
        .write_to(
            &mut std::io::Cursor::new(&mut jpeg),
            image::ImageFormat::Jpeg,
        )
        .expect("jpeg");
    jpeg
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

/// An app on an in-memory database of two towers; the sender stands in for the
/// network thread, the receiver gets what the app asks the network to do.
pub fn app() -> (Sender<NetEvent>, UnboundedReceiver<NetCommand>, GsApp) {
    let mut db = LandmarkDb::open_in_memory().expect("in-memory database");
    db.upsert_all(
        &towers(),
        &Author {
            by: "test".into(),
            at_unix_s: 0,
        },
    )
    .expect("towers");
    let (tx, commands, link) = NetLink::detached();
    let app = GsApp::new(db, link, GsOptions::default()).expect("app");
    (tx, commands, app)
}
