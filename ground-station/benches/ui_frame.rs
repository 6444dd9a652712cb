//! The ground station's CPU cost per UI frame with 10 UAVs at 30 Hz: each
//! frame takes the messages of 1/60 s (poses, tracks, truth for every UAV),
//! lays out every panel and tessellates the result. GPU rasterization is not
//! included (see the README for the real window's frame rate under Xvfb).
//!
//! `cargo bench -p towernav-ground-station --bench ui_frame`

use criterion::{Criterion, criterion_group, criterion_main};
use towernav_geometry::PixelBox;
use towernav_ground_station::events::NetEvent;
use towernav_ground_station::test_support::{app, pose};
use towernav_protocol::{NodeId, TowerType, Track, TrackReport, TruthPose};

const UAVS: usize = 10;

fn bench(c: &mut Criterion) {
    let (tx, _commands, mut app) = app();
    let ctx = egui::Context::default();
    let input = || egui::RawInput {
        screen_rect: Some(egui::Rect::from_min_size(
            egui::Pos2::ZERO,
            egui::vec2(1600.0, 900.0),
        )),
        ..Default::default()
    };
    let mut seq = 0u64;
    let feed = |seq: u64| {
        for u in 0..UAVS {
            let name = format!("uav{u:02}");
            let lat = 30.52 + 1e-6 * seq as f64 + 1e-4 * u as f64;
            let lon = 114.36 + 2e-6 * seq as f64;
            let _ = tx.send(NetEvent::Pose(pose(&name, lat, lon, seq)));
            let uav = NodeId::new(name).expect("valid");
            let _ = tx.send(NetEvent::Truth(TruthPose {
                uav: uav.clone(),
                time_s: seq as f64 / 30.0,
                seq,
                lat_deg: lat + 1e-6,
                lon_deg: lon,
                alt_m: 55.0,
            }));
            let _ = tx.send(NetEvent::Tracks(TrackReport {
                uav,
                time_s: seq as f64 / 30.0,
                seq,
                tracks: (0..12)
                    .map(|i| Track {
                        track_id: i,
                        bbox: PixelBox::new(
                            100.0 * i as f64,
                            200.0,
                            100.0 * i as f64 + 40.0,
                            420.0,
                        ),
                        tower_type: TowerType::ALL[i as usize % 4],
                        tower_id: Some("A1".into()),
                        pinned: false,
                        confidence: Some(0.9),
                    })
                    .collect(),
                session: 0,
            }));
        }
    };
    // Full trails first: the worst case of a long session.
    for s in 0..5000 {
        feed(s);
        if s.is_multiple_of(500) {
            let _ = ctx.run_ui(input(), |ui| app.show(ui, s as f64 / 30.0));
        }
    }
    seq += 5000;
    let mut frame = 0u64;
    c.bench_function("ui frame, 10 UAVs at 30 Hz, full trails", |b| {
        b.iter(|| {
            // Two frames of 60 Hz UI per 30 Hz message.
            if frame.is_multiple_of(2) {
                feed(seq);
                seq += 1;
            }
            frame += 1;
            let out = ctx.run_ui(input(), |ui| app.show(ui, seq as f64 / 30.0));
            ctx.tessellate(out.shapes, out.pixels_per_point)
        })
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
