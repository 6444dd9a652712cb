//! Annotated frames for the integrator: every confirmed track's box coloured
//! by its binding (green bound, amber unbound, blue pinned by the operator),
//! its track and tower ids, and the pose in the corner.

use image::RgbImage;
use plotters::prelude::*;
use towernav_protocol::{PoseEstimate, TrackReport};

use crate::cmd::loc_plots::register_font;

/// Draw `tracks` and `pose` onto `image` in place.
pub fn annotate(image: &mut RgbImage, tracks: &TrackReport, pose: Option<&PoseEstimate>) {
    if register_font().is_err() {
        return;
    }
    let (w, h) = image.dimensions();
    let root = BitMapBackend::with_buffer(image.as_mut(), (w, h)).into_drawing_area();
    let font = ("sans-serif", 18).into_font();
    for t in &tracks.tracks {
        let colour = match (&t.tower_id, t.pinned) {
            (_, true) => RGBColor(40, 120, 255),
            (Some(_), false) => RGBColor(40, 220, 80),
            (None, false) => RGBColor(255, 180, 0),
        };
        let b = &t.bbox;
        let (x0, y0, x1, y1) = (b.left as i32, b.top as i32, b.right as i32, b.bottom as i32);
        let _ = root.draw(&Rectangle::new(
            [(x0, y0), (x1, y1)],
            colour.stroke_width(2),
        ));
        let label = match &t.tower_id {
            Some(id) => format!("#{} {id}", t.track_id),
            None => format!("#{} ?", t.track_id),
        };
        let _ = root.draw(&Text::new(
            label,
            (x0, (y0 - 20).max(0)),
            font.color(&colour),
        ));
    }
    let text = match pose {
        Some(p) => format!(
            "frame {}  E {:.1} N {:.1} U {:.1} m  ±{:.1} m  towers {}",
            tracks.seq,
            p.east_m,
            p.north_m,
            p.up_m,
            (p.covariance[0][0] + p.covariance[1][1]).max(0.0).sqrt(),
            p.towers_used.join(" ")
        ),
        None => format!("frame {}  no fix", tracks.seq),
    };
    let _ = root.draw(&Text::new(text, (10, 10), font.color(&WHITE)));
    let _ = root.present();
}

#[cfg(test)]
mod tests {
    use super::*;
    use towernav_geometry::PixelBox;
    use towernav_protocol::{NodeId, TowerType, Track};

    #[test]
    fn a_bound_track_is_drawn_green_around_its_box() {
        let mut image = RgbImage::new(200, 120);
        let tracks = TrackReport {
            uav: NodeId::new("u1").expect("valid"),
            time_s: 0.0,
            seq: 3,
            tracks: vec![Track {
                track_id: 7,
                bbox: PixelBox::new(50.0, 40.0, 90.0, 110.0),
                tower_type: TowerType::A,
                tower_id: Some("A1".into()),
                pinned: false,
                confidence: None,
            }],
            session: 0,
        };
        annotate(&mut image, &tracks, None);
        assert_eq!(image.get_pixel(50, 80).0, [40, 220, 80], "left edge");
        assert_eq!(image.get_pixel(70, 80).0, [0, 0, 0], "inside stays");
        // Antialiased white text in the top-left corner.
        let lit = (0..200)
            .flat_map(|x| (0..35).map(move |y| (x, y)))
            .filter(|&(x, y)| image.get_pixel(x, y).0.iter().all(|c| *c > 100))
            .count();
        assert!(lit > 20, "the status text is drawn ({lit} pixels)");
    }
}
