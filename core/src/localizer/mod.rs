//! Localization by landmarks: boxes of bound towers in, a position with yaw and
//! covariance out, one frame at a time. Two methods on the same inputs:
//!
//! - `paper`: the paper's level-camera similar triangles, plain mean over towers;
//! - `rays`: ours: attitude-compensated rays and a robust weighted nonlinear
//!   least squares over (east, north, up, yaw) with the IMU yaw as a prior.
//!
//! The filter that fuses fixes over time lives in `crate::filter`.

mod measurement;
mod paper;
mod robust;
mod single;

use nalgebra::{Matrix4, Point3};
use towernav_geometry::PixelBox;

use crate::landmarks::MapTower;

pub use measurement::Usable;
pub use paper::{Height, paper_lbl, paper_range};
pub use robust::{RobustFix, robust_lbl, robust_lbl_with_height};
pub use single::single_tower_position;

/// Which per-frame estimator the pipeline runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Method {
    /// The paper's method, kept as the baseline.
    Paper,
    /// Ours: attitude-compensated rays, robust multi-tower least squares.
    #[default]
    Rays,
}

/// The names a user may give a method: `paper` (also `seed`, its older name) and `rays`.
pub const METHOD_NAMES: [&str; 3] = ["rays", "paper", "seed"];

impl Method {
    pub fn name(self) -> &'static str {
        match self {
            Self::Paper => "paper",
            Self::Rays => "rays",
        }
    }

    /// The method a user named; `None` for a name that is none of `METHOD_NAMES`.
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "paper" | "seed" => Some(Self::Paper),
            "rays" => Some(Self::Rays),
            _ => None,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LocalizerParams {
    /// Spread of one box edge for a large box, pixels.
    pub edge_sigma_px: f64,
    /// Edges of small boxes are noisier: sigma = edge_sigma_px * (1 + small_box_px / h).
    pub small_box_px: f64,
    /// A learned detector's edges stray in proportion to the box, as its
    /// regression is trained on IoU: this share of the box's height adds to
    /// the spread of its top and bottom, and of its width to that of its
    /// sides (0 for the simulator's oracle, whose noise is in pixels).
    pub edge_sigma_share: f64,
    /// A learned detector seldom carries a box to the image's edge when the
    /// frame cuts a near tower: it stops tens of pixels short, where a foot,
    /// top or side would be. A side of the box within this share of its
    /// height of the border is taken as cut (0 for the simulator's oracle, whose cut boxes
    /// end at the border; [`towernav_geometry::EDGE_MARGIN_PX`] at least).
    pub cut_margin_share: f64,
    /// The spread of a box's edges when the frame cuts the box, times the
    /// spread of a whole one's: a learned detector that sees part of a tower
    /// guesses the rest, and its other edges err far more (1 for the oracle).
    pub cut_sigma_scale: f64,
    /// Boxes shorter than this are not trusted by ours at all.
    pub min_box_height_px: f64,
    /// The paper trusted only large boxes; its method keeps its own threshold.
    pub paper_min_box_height_px: f64,
    /// Spread of the IMU heading, radians: the prior on yaw.
    pub yaw_sigma: f64,
    /// The box centre is not exactly the axis (cross-arms seen obliquely): extra
    /// spread of the centre column as a share of the box width.
    pub centre_width_share: f64,
    /// Scale of the Cauchy loss on a normalised residual.
    pub robust_k: f64,
    /// A fix whose horizontal sigma exceeds this is not reported.
    pub max_horizontal_sigma_m: f64,
}

impl Default for LocalizerParams {
    fn default() -> Self {
        Self {
            edge_sigma_px: 1.0,
            small_box_px: 40.0,
            edge_sigma_share: 0.0,
            cut_margin_share: 0.0,
            cut_sigma_scale: 1.0,
            min_box_height_px: 8.0,
            paper_min_box_height_px: 20.0,
            yaw_sigma: 0.3f64.to_radians(),
            centre_width_share: 0.04,
            robust_k: 2.5,
            max_horizontal_sigma_m: 50.0,
        }
    }
}

/// One bound, measured tower.
#[derive(Debug, Clone, Copy)]
pub struct Observation<'a> {
    pub tower: &'a MapTower,
    /// The box in the ideal pinhole's image: the paper's method knows no lens.
    pub bbox: PixelBox,
    /// The box as the real camera saw it. Ours measures here, through the
    /// lens model: the detector errs in these pixels, and a box the frame's
    /// edge cuts has its top and foot at columns its undistorted box cannot
    /// know.
    pub raw: PixelBox,
    /// Detector confidence, 0..1.
    pub score: f64,
}

impl<'a> Observation<'a> {
    /// A box from a camera with no lens: the real image is the ideal one.
    pub fn new(tower: &'a MapTower, bbox: PixelBox, score: f64) -> Self {
        Self {
            tower,
            bbox,
            raw: bbox,
            score,
        }
    }
}

#[derive(Debug, Clone, PartialEq)]
pub struct Fix {
    pub position_in_world: Point3<f64>,
    pub yaw: f64,
    /// (east, north, up, yaw).
    pub covariance: Matrix4<f64>,
    pub towers_used: Vec<String>,
}
