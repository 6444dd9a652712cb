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
        coast_s: 0.0,
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

/// What an edge sends for frame `seq`: its tracks (one, track 7, bound to
/// A1), then its preview as the network thread decodes it.
pub fn frame_events(uav: &str, seq: u64) -> Vec<NetEvent> {
    use towernav_geometry::PixelBox;
    use towernav_protocol::{Keys, Preview, Track, TrackReport};
    let node = NodeId::new(uav).expect("valid");
    let tracks = NetEvent::Tracks(TrackReport {
        uav: node.clone(),
        time_s: seq as f64 / 30.0,
        seq,
        tracks: vec![Track {
            track_id: 7,
            bbox: PixelBox::new(600.0, 200.0, 660.0, 400.0),
            tower_type: TowerType::A,
            tower_id: Some("A1".into()),
            pinned: false,
            confidence: Some(0.9),
        }],
        session: 1,
    });
    let preview = Preview {
        uav: node.clone(),
        time_s: seq as f64 / 30.0,
        seq,
        frame_width: 1280,
        frame_height: 720,
        jpeg: jpeg(64, 36, [90, 120, 160]),
    };
    let bytes = towernav_protocol::encode(&preview).expect("encode");
    let key = Keys::new(NodeId::new("demo").expect("valid")).uav_key::<Preview>(&node);
    let preview = crate::events::decode_sample(&key, &bytes).expect("a preview");
    vec![tracks, preview]
}
