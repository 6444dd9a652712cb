//! A tower's view from one box: the rays a camera of known pose draws
//! through it, and whether the frame cut it.

use nalgebra::{Isometry3, Point2, Vector3};
use towernav_geometry::{Cut, EDGE_MARGIN_PX, PinholeCamera, PixelBox};

use super::TowerView;

impl TowerView {
    /// The view a box gives at `time_s` from a camera at `world_from_camera`:
    /// `None` for a box the frame's side cuts (its centre is off the axis);
    /// a box the frame's top or bottom cuts gives its bearing but no
    /// height. The top and foot rays go where the tower's vertical plane
    /// crosses the box's top and bottom rows, which a banked frame moves
    /// off the centre column.
    pub fn of_box(
        camera: &PinholeCamera,
        world_from_camera: &Isometry3<f64>,
        b: &PixelBox,
        time_s: f64,
    ) -> Option<Self> {
        let cut = Cut::in_frame_within(b, &camera.intrinsics, EDGE_MARGIN_PX);
        if cut.side() {
            return None;
        }
        let to_world = world_from_camera.rotation;
        let cx = b.center_x();
        let centre = camera.ray(&Point2::new(cx, (b.top + b.bottom) / 2.0));
        let up_in_camera = to_world.inverse() * Vector3::z();
        let on_row = |row: f64| {
            let ray = camera
                .ray_on_row_in_vertical_plane(&centre, &up_in_camera, row, cx)
                .unwrap_or_else(|| camera.ray(&Point2::new(cx, row)));
            to_world * ray
        };
        Some(Self {
            time_s,
            camera_in_world: world_from_camera.translation.vector.into(),
            centre_ray: to_world * centre,
            top_ray: on_row(b.top),
            foot_ray: on_row(b.bottom),
            cut: cut.end(),
        })
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::Point3;
    use towernav_geometry::{Attitude, Pose};

    use super::*;

    /// Where the view's ray along `ray` reaches the axis at `axis`: up.
    fn up_at_axis(view: &TowerView, ray: &Vector3<f64>, axis: &Point2<f64>) -> f64 {
        let c = view.camera_in_world;
        let along = (axis - c.xy()).norm() / ray.xy().norm();
        c.z + ray.z * along
    }

    /// A 40 m tower seen from a camera banked 20 degrees: the view's top and
    /// foot rays give its height to a centimetre, where the box's centre
    /// column gives it several per cent short.
    #[test]
    fn a_banked_view_measures_the_towers_height() {
        let camera = PinholeCamera::default_hd();
        let pose = Pose {
            position_in_world: Point3::new(0.0, 0.0, 35.0),
            attitude: Attitude {
                roll: 20f64.to_radians(),
                pitch: -0.1,
                yaw: 0.2,
            },
        };
        let world_from_camera = camera.world_from_camera(&pose);
        let ahead = world_from_camera.rotation * Vector3::z();
        let axis = Point2::from(ahead.xy().normalize() * 120.0);
        let foot = Point3::new(axis.x, axis.y, 2.0);
        let top = foot + Vector3::z() * 40.0;
        let px = |p: &Point3<f64>| {
            camera
                .project(&(world_from_camera.inverse() * p))
                .expect("in view")
        };
        let (t, f) = (px(&top), px(&foot));
        // The box a detector draws: upright, around the leaning tower.
        let b = PixelBox::new(t.x.min(f.x) - 6.0, t.y, t.x.max(f.x) + 6.0, f.y);
        let view = TowerView::of_box(&camera, &world_from_camera, &b, 1.0).expect("a view");
        assert!(!view.cut);
        let height =
            up_at_axis(&view, &view.top_ray, &axis) - up_at_axis(&view, &view.foot_ray, &axis);
        assert!((height - 40.0).abs() < 0.01, "{height}");
        let centre_column =
            |row: f64| world_from_camera.rotation * camera.ray(&Point2::new(b.center_x(), row));
        let naive = up_at_axis(&view, &centre_column(b.top), &axis)
            - up_at_axis(&view, &centre_column(b.bottom), &axis);
        assert!(naive < 39.0, "{naive}");
    }

    /// A box at the frame's top is cut there; one at its side gives no view.
    #[test]
    fn a_box_the_border_cuts_is_marked_or_left_out() {
        let camera = PinholeCamera::default_hd();
        let at = camera.world_from_camera(&Pose {
            position_in_world: Point3::new(0.0, 0.0, 30.0),
            attitude: Attitude::level(0.0),
        });
        let view = |b: PixelBox| TowerView::of_box(&camera, &at, &b, 0.0);
        let whole = view(PixelBox::new(600.0, 40.0, 660.0, 500.0)).expect("a view");
        assert!(!whole.cut);
        let at_top = view(PixelBox::new(600.0, 1.0, 660.0, 500.0)).expect("a view");
        assert!(at_top.cut);
        assert!(view(PixelBox::new(1.0, 200.0, 60.0, 600.0)).is_none());
    }
}
