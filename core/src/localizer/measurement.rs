//! What a box says about the pose, in the real image's pixels: the predicted
//! rows of a tower's top and foot and the column of its axis, drawn through
//! the lens, with their Jacobians with respect to (east, north, up, yaw), and
//! the spread of each measured edge.
//!
//! The real image is where the detector drew the box and erred: its top is
//! the apex's row at the apex's column, which an undistorted box cannot know
//! when the frame's edge cuts a side.
//!
//! Roll and pitch come from the IMU and are held fixed; the camera mount is
//! folded in with them, so the same code serves any attitude.

use nalgebra::{Point3, RowVector4};
use towernav_geometry::{Cut, EDGE_MARGIN_PX, FrameCamera, Intrinsics, PixelBox, Projected};

use super::{LocalizerParams, Observation};

/// One scalar measurement: its value, prediction, Jacobian row and spread.
#[derive(Debug, Clone, Copy)]
pub struct Residual {
    pub r: f64,
    pub jacobian: RowVector4<f64>,
    pub sigma: f64,
}

/// Which of a box's three numbers can be trusted: an edge that touches the
/// image border is where the image ends, not where the tower does.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Usable {
    pub centre: bool,
    pub top: bool,
    pub bottom: bool,
}

impl Usable {
    pub fn of(o: &Observation<'_>, k: &Intrinsics, params: &LocalizerParams) -> Self {
        Self::of_box(&o.raw, k, params)
    }

    /// The same for a box in the real image, without its tower.
    pub fn of_box(raw: &PixelBox, k: &Intrinsics, params: &LocalizerParams) -> Self {
        let margin = EDGE_MARGIN_PX.max(params.cut_margin_share * raw.height());
        let cut = Cut::in_frame_within(raw, k, margin);
        Self {
            centre: !cut.side(),
            top: !cut.top,
            bottom: !cut.bottom,
        }
    }

    pub fn count(self) -> usize {
        usize::from(self.centre) + usize::from(self.top) + usize::from(self.bottom)
    }
}

/// Spread of the box's top or bottom in the real image: grows for small
/// boxes, with the box's height for a learned detector, and for low scores.
pub fn edge_sigma(o: &Observation<'_>, params: &LocalizerParams) -> f64 {
    spread(o, params, o.raw.height())
}

/// Spread of the box's left or right side: as `edge_sigma`, but a learned
/// detector's share goes with the box's width. A tower's box is several
/// times taller than wide, and its centre column strays a pixel where its
/// ends stray several.
pub fn side_sigma(o: &Observation<'_>, params: &LocalizerParams) -> f64 {
    spread(o, params, o.raw.width())
}

fn spread(o: &Observation<'_>, params: &LocalizerParams, extent: f64) -> f64 {
    let h = o.raw.height().max(1.0);
    let score = if o.score.is_finite() {
        o.score.clamp(0.0, 1.0)
    } else {
        0.0
    };
    (params.edge_sigma_px * (1.0 + params.small_box_px / h)
        + params.edge_sigma_share * extent.max(0.0))
        * (1.0 + 0.5 * (1.0 - score))
}

/// The usable residuals of one observation at state (position, yaw); `out` is cleared first.
/// Returns `false` when the tower is behind the camera at this state.
pub fn residuals(
    o: &Observation<'_>,
    usable: Usable,
    camera: &FrameCamera,
    position: &Point3<f64>,
    yaw: f64,
    params: &LocalizerParams,
    out: &mut Vec<Residual>,
) -> bool {
    out.clear();
    let (Some(top), Some(foot)) = (
        camera.project_through_lens(&o.tower.top_in_world(), position, yaw),
        camera.project_through_lens(&o.tower.foot_in_world, position, yaw),
    ) else {
        return false;
    };
    let k = &camera.k;
    let cut = if usable.count() < 3 {
        params.cut_sigma_scale
    } else {
        1.0
    };
    let sigma_e = edge_sigma(o, params) * cut;
    let sigma_side = side_sigma(o, params) * cut;
    let (sh, sv) = (o.tower.sigma_horizontal_m, o.tower.sigma_vertical_m);
    // A survey error moves the whole tower: sideways by sh, in range by sh, up by sv.
    let survey_v = |p: &Projected| {
        let range_share = (p.v - k.cy) / p.depth;
        (k.fy * sv / p.depth).powi(2) + (range_share * sh).powi(2)
    };
    let b = &o.raw;
    if usable.centre {
        let predicted = 0.5 * (top.u + foot.u);
        let width_term = params.centre_width_share * b.width();
        let sigma2 = 0.5 * sigma_side * sigma_side
            + width_term * width_term
            + (k.fx * sh / foot.depth).powi(2);
        out.push(Residual {
            r: b.center_x() - predicted,
            jacobian: 0.5 * (top.du + foot.du),
            sigma: sigma2.sqrt(),
        });
    }
    if usable.top {
        out.push(Residual {
            r: b.top - top.v,
            jacobian: top.dv,
            sigma: (sigma_e * sigma_e + survey_v(&top)).sqrt(),
        });
    }
    if usable.bottom {
        out.push(Residual {
            r: b.bottom - foot.v,
            jacobian: foot.dv,
            sigma: (sigma_e * sigma_e + survey_v(&foot)).sqrt(),
        });
    }
    true
}
