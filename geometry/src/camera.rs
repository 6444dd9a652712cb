//! The camera: pinhole intrinsics, lens distortion, mount on the body,
//! projection and rays.
//!
//! Camera frame is optical: x right, y down, z forward along the optical axis.

use nalgebra::{Isometry3, Matrix3, Point2, Point3, Rotation3, UnitQuaternion, Vector2, Vector3};
use serde::{Deserialize, Serialize};

use crate::distortion::Distortion;
use crate::frames::{Attitude, Pose};
use crate::pixel_box::PixelBox;

/// Pinhole intrinsics in pixels; the lens's distortion is [`Distortion`], beside them.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Intrinsics {
    pub width: u32,
    pub height: u32,
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
}

impl Intrinsics {
    /// Square pixels, principal point at the image centre, from a horizontal field of view.
    pub fn from_hfov(width: u32, height: u32, hfov_deg: f64) -> Self {
        let f = f64::from(width) / 2.0 / (hfov_deg.to_radians() / 2.0).tan();
        Self {
            width,
            height,
            fx: f,
            fy: f,
            cx: f64::from(width) / 2.0,
            cy: f64::from(height) / 2.0,
        }
    }

    /// The same camera at `factor` times the resolution (0.5: half size).
    pub fn scaled(&self, factor: f64) -> Self {
        Self {
            width: ((f64::from(self.width) * factor).ceil() as u32).max(1),
            height: ((f64::from(self.height) * factor).ceil() as u32).max(1),
            fx: self.fx * factor,
            fy: self.fy * factor,
            cx: self.cx * factor,
            cy: self.cy * factor,
        }
    }

    pub fn contains(&self, pixel: &Point2<f64>) -> bool {
        pixel.x >= 0.0
            && pixel.y >= 0.0
            && pixel.x <= f64::from(self.width)
            && pixel.y <= f64::from(self.height)
    }
}

/// How the camera sits on the body (FLU), in radians and metres. The angles
/// turn a camera that looks along the body's nose, as [`crate::Attitude`]
/// turns the body: `yaw` to the left, `pitch` up, `roll` right side down.
/// The lever arm is the camera's centre from the body's origin.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(default)]
pub struct CameraMount {
    pub roll: f64,
    pub pitch: f64,
    pub yaw: f64,
    pub lever_arm_m: [f64; 3],
}

impl CameraMount {
    /// A camera on the nose, tilted by `pitch` (up positive).
    pub fn tilted(pitch: f64) -> Self {
        Self {
            pitch,
            ..Self::default()
        }
    }

    pub fn body_from_camera(&self) -> UnitQuaternion<f64> {
        // Columns: the camera's right, down and forward axes written in FLU.
        let optical_in_flu = Matrix3::new(0.0, 0.0, 1.0, -1.0, 0.0, 0.0, 0.0, -1.0, 0.0);
        let base =
            UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(optical_in_flu));
        UnitQuaternion::from_axis_angle(&Vector3::z_axis(), self.yaw)
            * UnitQuaternion::from_axis_angle(&Vector3::y_axis(), -self.pitch)
            * UnitQuaternion::from_axis_angle(&Vector3::x_axis(), self.roll)
            * base
    }

    pub fn lever_arm(&self) -> Vector3<f64> {
        Vector3::from(self.lever_arm_m)
    }
}

/// The box spanned by the mapped midpoints of a box's four edges.
fn map_box_by_midpoints(
    b: &PixelBox,
    map: impl Fn(&Point2<f64>) -> Option<Point2<f64>>,
) -> Option<PixelBox> {
    let (xm, ym) = ((b.left + b.right) / 2.0, (b.top + b.bottom) / 2.0);
    let top = map(&Point2::new(xm, b.top))?;
    let foot = map(&Point2::new(xm, b.bottom))?;
    let left = map(&Point2::new(b.left, ym))?;
    let right = map(&Point2::new(b.right, ym))?;
    Some(PixelBox::new(left.x, top.y, right.x, foot.y))
}

/// See [`PinholeCamera::ray_grid`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RayGrid {
    pub at_origin: Vector3<f64>,
    pub per_u: Vector3<f64>,
    pub per_v: Vector3<f64>,
}

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PinholeCamera {
    pub intrinsics: Intrinsics,
    pub mount: CameraMount,
    #[serde(default)]
    pub distortion: Distortion,
}

impl PinholeCamera {
    /// The paper's camera: 1280x720 with a 70 degree horizontal field of view, level mount.
    pub fn default_hd() -> Self {
        Self {
            intrinsics: Intrinsics::from_hfov(1280, 720, 70.0),
            mount: CameraMount::default(),
            distortion: Distortion::None,
        }
    }

    /// A camera without lens distortion.
    pub fn pinhole(intrinsics: Intrinsics, mount: CameraMount) -> Self {
        Self {
            intrinsics,
            mount,
            distortion: Distortion::None,
        }
    }

    /// The same camera with an ideal lens: what the geometry downstream of
    /// [`Self::undistort_box`] works in.
    pub fn ideal(&self) -> Self {
        Self {
            distortion: Distortion::None,
            ..*self
        }
    }

    pub fn world_from_camera(&self, pose: &Pose) -> Isometry3<f64> {
        let world_from_body = pose.world_from_body();
        Isometry3::from_parts(
            (world_from_body * Point3::from(self.mount.lever_arm())).into(),
            world_from_body.rotation * self.mount.body_from_camera(),
        )
    }

    /// How far the world's vertical leans at the image centre, radians
    /// clockwise on screen, at `attitude` (mount included): a banked turn
    /// leans the towers by about the roll. Turning the image clockwise by
    /// minus this sets them upright. 0 when the camera looks straight up or down.
    pub fn lean_of_vertical(&self, attitude: &Attitude) -> f64 {
        let pose = Pose {
            position_in_world: Point3::origin(),
            attitude: *attitude,
        };
        let camera_from_world = self.world_from_camera(&pose).rotation.inverse();
        // The vertical through the point the optical axis sees 10 m ahead.
        let ahead = Point3::new(0.0, 0.0, 10.0);
        let up = ahead + camera_from_world * Vector3::z();
        let ideal = self.ideal();
        match (ideal.project(&ahead), ideal.project(&up)) {
            (Some(a), Some(b)) if (b - a).norm() > 1e-9 => {
                // Upright, the top is straight above (-y on screen).
                let d = b - a;
                d.x.atan2(-d.y)
            }
            _ => 0.0,
        }
    }

    /// Pixel of a point in the camera frame, through the lens; `None` behind
    /// or on the image plane.
    pub fn project(&self, point_in_camera: &Point3<f64>) -> Option<Point2<f64>> {
        let p = point_in_camera;
        if p.z <= 1e-6 {
            return None;
        }
        let d = self.distortion.distort_ray(p.x, p.y, p.z)?;
        Some(self.pixel_of_normalized(d))
    }

    /// Ray through a pixel in the camera frame, scaled so that z = 1; the
    /// lens's distortion undone. A pixel the lens model cannot invert (far
    /// outside its calibrated field) gets the ideal pinhole's ray.
    pub fn ray(&self, pixel: &Point2<f64>) -> Vector3<f64> {
        let d = self.normalized_of_pixel(pixel);
        let p = self.distortion.undistort(d).unwrap_or(d);
        Vector3::new(p.x, p.y, 1.0)
    }

    /// Where a pixel of the real image lands in the ideal camera's image
    /// ([`Self::ideal`]); `None` where the lens model cannot be inverted.
    pub fn undistort_pixel(&self, pixel: &Point2<f64>) -> Option<Point2<f64>> {
        if self.distortion.is_none() {
            return Some(*pixel);
        }
        let p = self.distortion.undistort(self.normalized_of_pixel(pixel))?;
        Some(self.pixel_of_normalized(p))
    }

    /// A pixel of the image where the lens model cannot be inverted (or
    /// does not come back to itself), on a grid over the whole image with
    /// its border: such a calibration is wrong, or was fitted on a smaller
    /// part of the image than the frames show.
    pub fn uninvertible_pixel(&self) -> Option<Point2<f64>> {
        if self.distortion.is_none() {
            return None;
        }
        let k = &self.intrinsics;
        let (w, h) = (f64::from(k.width), f64::from(k.height));
        const STEPS: usize = 32;
        (0..=STEPS)
            .flat_map(|i| (0..=STEPS).map(move |j| (i, j)))
            .map(|(i, j)| Point2::new(w * i as f64 / STEPS as f64, h * j as f64 / STEPS as f64))
            .find(|p| {
                self.undistort_pixel(p)
                    .is_none_or(|q| (self.distort_pixel(&q) - p).norm() > 1e-6)
            })
    }

    /// Where a pixel of the ideal camera's image lands in the real one.
    pub fn distort_pixel(&self, ideal: &Point2<f64>) -> Point2<f64> {
        if self.distortion.is_none() {
            return *ideal;
        }
        self.pixel_of_normalized(self.distortion.distort(self.normalized_of_pixel(ideal)))
    }

    /// A detector's box in the ideal camera's image, from its top, foot,
    /// left and right edge midpoints, each undistorted: the points the
    /// localizer reads (a tower's top and foot, its column). Corners are
    /// left out: they lie off a tower, and undistorting them would stretch
    /// its height. Points are mapped, never whole images. `None` where the
    /// lens model cannot be inverted.
    pub fn undistort_box(&self, b: &PixelBox) -> Option<PixelBox> {
        if self.distortion.is_none() {
            return Some(*b);
        }
        map_box_by_midpoints(b, |p| self.undistort_pixel(p))
    }

    /// An ideal-camera box drawn back onto the real image (the inverse of
    /// [`Self::undistort_box`]).
    pub fn distort_box(&self, b: &PixelBox) -> PixelBox {
        if self.distortion.is_none() {
            return *b;
        }
        map_box_by_midpoints(b, |p| Some(self.distort_pixel(p))).unwrap_or(*b)
    }

    fn normalized_of_pixel(&self, pixel: &Point2<f64>) -> Vector2<f64> {
        let k = &self.intrinsics;
        Vector2::new((pixel.x - k.cx) / k.fx, (pixel.y - k.cy) / k.fy)
    }

    fn pixel_of_normalized(&self, p: Vector2<f64>) -> Point2<f64> {
        let k = &self.intrinsics;
        Point2::new(k.cx + k.fx * p.x, k.cy + k.fy * p.y)
    }

    /// World-frame rays of the ideal pinhole for every pixel at once:
    /// `ray(u, v) = at_origin + u * per_u + v * per_v` (unnormalised, the
    /// camera-frame ray with z = 1 rotated into the world); distortion is not
    /// in it (renderers draw the ideal image and then bend it).
    /// Renderers step along a row by adding `per_u`, with no per-pixel matrix product.
    pub fn ray_grid(&self, world_from_camera: &Isometry3<f64>) -> RayGrid {
        let k = &self.intrinsics;
        let r = world_from_camera.rotation.to_rotation_matrix();
        let m = r.matrix();
        let per_u: Vector3<f64> = m.column(0) / k.fx;
        let per_v: Vector3<f64> = m.column(1) / k.fy;
        RayGrid {
            at_origin: m.column(2) - per_u * k.cx - per_v * k.cy,
            per_u,
            per_v,
        }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn level_camera_looks_along_body_forward() {
        let cam = PinholeCamera::default_hd();
        let pose = Pose {
            position_in_world: Point3::new(0.0, 0.0, 30.0),
            attitude: Attitude::level(std::f64::consts::FRAC_PI_2),
        };
        let world_from_camera = cam.world_from_camera(&pose);
        let axis = world_from_camera.rotation * Vector3::z();
        assert!(
            (axis - Vector3::y()).norm() < 1e-12,
            "optical axis must point north"
        );
        let down = world_from_camera.rotation * Vector3::y();
        assert!(
            (down + Vector3::z()).norm() < 1e-12,
            "image down must be world down"
        );
    }

    /// A tower standing in front of a banked camera: its image leans as
    /// `lean_of_vertical` says (against the roll), measured from the
    /// projections of its foot and top.
    #[test]
    fn the_vertical_leans_against_the_roll() {
        let camera = PinholeCamera::default_hd();
        assert!(camera.lean_of_vertical(&Attitude::level(0.7)).abs() < 1e-9);
        for (roll, pitch) in [(0.3, 0.0), (-0.2, -0.1), (0.25, -0.3)] {
            let attitude = Attitude {
                roll,
                pitch,
                yaw: 0.4,
            };
            let pose = Pose {
                position_in_world: Point3::new(0.0, 0.0, 30.0),
                attitude,
            };
            let lean = camera.lean_of_vertical(&attitude);
            // A vertical line where the optical axis meets the scene.
            let cfw = camera.world_from_camera(&pose);
            let hit = cfw * Point3::new(0.0, 0.0, 100.0);
            let (foot, top) = (hit - Vector3::z() * 5.0, hit + Vector3::z() * 5.0);
            let px = |p: Point3<f64>| camera.project(&(cfw.inverse() * p)).expect("in view");
            let d = px(top) - px(foot);
            let measured = d.x.atan2(-d.y);
            assert!((lean - measured).abs() < 1e-6, "{lean} vs {measured}");
            assert!(
                lean * roll < 0.0,
                "leans against the roll: {lean}, roll {roll}"
            );
        }
    }

    #[test]
    fn point_ahead_projects_to_principal_point() {
        let cam = PinholeCamera::default_hd();
        let px = cam.project(&Point3::new(0.0, 0.0, 50.0)).expect("in front");
        assert!((px.x - 640.0).abs() < 1e-9 && (px.y - 360.0).abs() < 1e-9);
        assert!(cam.project(&Point3::new(0.0, 0.0, -5.0)).is_none());
    }

    proptest! {
        #[test]
        fn ray_inverts_projection(x in -50.0f64..50.0, y in -50.0f64..50.0, z in 1.0f64..500.0) {
            let cam = PinholeCamera::default_hd();
            let p = Point3::new(x, y, z);
            let px = cam.project(&p).expect("z > 0");
            let back = cam.ray(&px) * z;
            prop_assert!((back - p.coords).norm() < 1e-6);
        }
    }

    proptest! {
        #[test]
        fn ray_grid_matches_the_per_pixel_ray(
            u in 0.0f64..1280.0, v in 0.0f64..720.0,
            roll in -0.5f64..0.5, pitch in -0.5f64..0.5, yaw in -3.1f64..3.1,
        ) {
            let cam = PinholeCamera::default_hd();
            let pose = Pose {
                position_in_world: Point3::new(1.0, 2.0, 30.0),
                attitude: Attitude { roll, pitch, yaw },
            };
            let world_from_camera = cam.world_from_camera(&pose);
            let grid = cam.ray_grid(&world_from_camera);
            let direct = world_from_camera.rotation * cam.ray(&Point2::new(u, v));
            let stepped = grid.at_origin + grid.per_u * u + grid.per_v * v;
            prop_assert!((direct - stepped).norm() < 1e-9);
        }
    }

    /// Lenses as calibration tools report them, at 1280x720: a strong
    /// barrel radial-tangential (a small UAV's wide lens) and a fisheye.
    pub(crate) fn lenses() -> [PinholeCamera; 3] {
        let intrinsics = Intrinsics {
            width: 1280,
            height: 720,
            fx: 900.0,
            fy: 898.0,
            cx: 645.3,
            cy: 357.9,
        };
        let with = |distortion| PinholeCamera {
            intrinsics,
            mount: CameraMount::default(),
            distortion,
        };
        [
            with(Distortion::None),
            with(Distortion::RadialTangential {
                k1: -0.28,
                k2: 0.08,
                p1: 1e-3,
                p2: -2e-3,
                k3: -0.01,
            }),
            with(Distortion::Fisheye {
                k1: -0.02,
                k2: 0.01,
                k3: -0.004,
                k4: 0.0006,
            }),
        ]
    }

    proptest! {
        /// Every pixel of the image, unprojected and projected again, comes
        /// back to itself, for each lens model.
        #[test]
        fn unproject_then_project_round_trips_over_the_whole_image(
            u in 0.0f64..=1280.0, v in 0.0f64..=720.0, depth in 0.5f64..2000.0,
        ) {
            for cam in lenses() {
                let pixel = Point2::new(u, v);
                let point = Point3::from(cam.ray(&pixel) * depth);
                let back = cam.project(&point).expect("ahead");
                prop_assert!((back - pixel).norm() < 1e-6, "{:?}: {pixel} -> {back}", cam.distortion);
                let ideal = cam.undistort_pixel(&pixel).expect("invertible");
                prop_assert!((cam.distort_pixel(&ideal) - pixel).norm() < 1e-6);
            }
        }
    }

    #[test]
    fn an_undistorted_box_holds_its_undistorted_top_and_foot() {
        let cam = lenses()[1];
        let b = PixelBox::new(1000.0, 80.0, 1030.0, 600.0);
        let ideal = cam.undistort_box(&b).expect("invertible");
        let top = cam
            .undistort_pixel(&Point2::new(1015.0, 80.0))
            .expect("top");
        let foot = cam
            .undistort_pixel(&Point2::new(1015.0, 600.0))
            .expect("foot");
        assert!((ideal.top - top.y).abs() < 1e-9 && (ideal.bottom - foot.y).abs() < 1e-9);
        assert!(
            ideal.height() > b.height(),
            "barrel undistortion stretches the edges"
        );
        // Back on the real image, for drawing: within a pixel or so (the
        // ideal box's top midpoint is not quite the undistorted top).
        let again = cam.distort_box(&ideal);
        for (back, was) in [
            (again.top, b.top),
            (again.bottom, b.bottom),
            (again.left, b.left),
            (again.right, b.right),
        ] {
            assert!((back - was).abs() < 1.5, "{again:?} against {b:?}");
        }
    }

    #[test]
    fn the_mount_turns_the_camera_and_the_lever_arm_moves_it() {
        let mount = CameraMount {
            roll: 0.0,
            pitch: -0.3,
            yaw: std::f64::consts::FRAC_PI_2,
            lever_arm_m: [0.1, 0.0, -0.05],
        };
        let cam = PinholeCamera::pinhole(Intrinsics::from_hfov(1280, 720, 70.0), mount);
        let pose = Pose {
            position_in_world: Point3::new(0.0, 0.0, 30.0),
            attitude: Attitude::level(0.0),
        };
        let world_from_camera = cam.world_from_camera(&pose);
        let axis = world_from_camera.rotation * Vector3::z();
        // Body faces east; the camera is turned to the left (north) and down.
        assert!(
            axis.y > 0.9 && axis.z < -0.25 && axis.x.abs() < 1e-9,
            "{axis}"
        );
        let centre = world_from_camera.translation.vector;
        assert!((centre - Vector3::new(0.1, 0.0, 29.95)).norm() < 1e-12);
    }

    /// Fixed cases computed with OpenCV 5.1.0 (opencv-python-headless, float64):
    /// `cv2.projectPoints(points, 0, 0, K, D)` and `cv2.fisheye.projectPoints`
    /// for the projections; `cv2.undistortPoints(pixels, K, D, criteria=(COUNT|EPS,
    /// 200, 1e-14))` and `cv2.fisheye.undistortPoints` (same criteria) for the
    /// normalized undistorted points. K and D are [`lenses`]'s.
    #[test]
    fn projection_and_undistortion_agree_with_opencv() {
        const POINTS: [[f64; 3]; 4] = [
            [0.0, 0.0, 10.0],
            [3.0, -1.5, 10.0],
            [-6.2, 3.3, 10.0],
            [7.0, 3.9, 10.0],
        ];
        const PROJECTED: [[[f64; 2]; 4]; 2] = [
            [
                [645.3, 357.9],
                [906.457030664063, 227.611659146484],
                [151.540050661442, 620.09511825195],
                [1178.716899838296, 655.648104106298],
            ],
            [
                [645.3, 357.9],
                [905.289660095097, 228.194047352557],
                [161.902548447182, 614.620431528964],
                [1172.487622466797, 650.966109746542],
            ],
        ];
        const PIXELS: [[f64; 2]; 4] = [
            [10.0, 20.0],
            [1270.0, 700.0],
            [640.0, 100.0],
            [300.0, 500.0],
        ];
        const UNDISTORTED: [[[f64; 2]; 4]; 2] = [
            [
                [-0.892116240763, -0.478234013359],
                [0.888054512176, 0.484663164886],
                [-0.005857505527, -0.294420567016],
                [-0.402777846075, 0.166087872213],
            ],
            [
                [-0.922958514558, -0.491991602204],
                [0.901708273658, 0.494895831294],
                [-0.006066586952, -0.295859876748],
                [-0.408791132406, 0.168602938226],
            ],
        ];
        let [_, radtan, fisheye] = lenses();
        for (m, cam) in [radtan, fisheye].iter().enumerate() {
            for (p, expected) in POINTS.iter().zip(PROJECTED[m]) {
                let px = cam.project(&Point3::from(*p)).expect("ahead");
                assert!(
                    (px - Point2::from(expected)).norm() < 1e-6,
                    "{:?}: {px} against OpenCV's {expected:?}",
                    cam.distortion
                );
            }
            for (px, expected) in PIXELS.iter().zip(UNDISTORTED[m]) {
                let ray = cam.ray(&Point2::from(*px));
                assert!(
                    (ray.x - expected[0]).abs() < 1e-9 && (ray.y - expected[1]).abs() < 1e-9,
                    "{:?}: {ray} against OpenCV's {expected:?}",
                    cam.distortion
                );
            }
        }
    }
}
