//! Pinhole camera: intrinsics, depth range and pose.

use nalgebra::{Isometry3, Matrix3, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};

use crate::RenderError;

/// Largest accepted image width or height (px).
pub const MAX_IMAGE_SIDE: u32 = 16_384;

/// Pinhole intrinsics without distortion, in the ROS `camera_info` / OpenCV convention.
///
/// A point `(X, Y, Z)` in the camera's optical frame (metres, `Z > 0` in front) projects
/// to pixel coordinates `u = fx * X / Z + cx`, `v = fy * Y / Z + cy`. Integer pixel
/// coordinates are pixel *centres*: pixel `(0, 0)` covers `[-0.5, 0.5) x [-0.5, 0.5)`,
/// so an image `width` px wide spans `u` in `[-0.5, width - 0.5)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Intrinsics {
    fx: f64,
    fy: f64,
    cx: f64,
    cy: f64,
    width: u32,
    height: u32,
}

impl Intrinsics {
    /// Intrinsics from focal lengths and principal point (all in pixels).
    ///
    /// # Errors
    /// [`RenderError::ZeroSize`], [`RenderError::TooLarge`],
    /// [`RenderError::NonFiniteIntrinsic`] or [`RenderError::NonPositiveFocalLength`].
    pub fn new(
        fx: f64,
        fy: f64,
        cx: f64,
        cy: f64,
        width: u32,
        height: u32,
    ) -> Result<Self, RenderError> {
        check_size(width, height)?;
        for (name, value) in [("fx", fx), ("fy", fy), ("cx", cx), ("cy", cy)] {
            if !value.is_finite() {
                return Err(RenderError::NonFiniteIntrinsic { name, value });
            }
        }
        for (name, value) in [("fx", fx), ("fy", fy)] {
            if value <= 0.0 {
                return Err(RenderError::NonPositiveFocalLength { name, value });
            }
        }
        Ok(Self {
            fx,
            fy,
            cx,
            cy,
            width,
            height,
        })
    }

    /// Intrinsics from the full horizontal and vertical fields of view (degrees), with the
    /// principal point at the image centre `((width - 1) / 2, (height - 1) / 2)`.
    ///
    /// The field of view is measured between the outer pixel *edges*:
    /// `fx = (width / 2) / tan(hfov / 2)`.
    ///
    /// # Errors
    /// [`RenderError::FovOutOfRange`] unless both angles lie in the open interval
    /// (0, 180) deg, plus the errors of [`Intrinsics::new`].
    pub fn from_fov_deg(
        width: u32,
        height: u32,
        horizontal_fov_deg: f64,
        vertical_fov_deg: f64,
    ) -> Result<Self, RenderError> {
        check_size(width, height)?;
        for (name, value_deg) in [
            ("horizontal", horizontal_fov_deg),
            ("vertical", vertical_fov_deg),
        ] {
            // `contains` is false for NaN too.
            if !(value_deg > 0.0 && value_deg < 180.0) {
                return Err(RenderError::FovOutOfRange { name, value_deg });
            }
        }
        let fx = (f64::from(width) / 2.0) / (horizontal_fov_deg.to_radians() / 2.0).tan();
        let fy = (f64::from(height) / 2.0) / (vertical_fov_deg.to_radians() / 2.0).tan();
        Self::new(
            fx,
            fy,
            (f64::from(width) - 1.0) / 2.0,
            (f64::from(height) - 1.0) / 2.0,
            width,
            height,
        )
    }

    /// RealSense SR300-like depth stream: 640x480 with a 73 x 59 deg field of view
    /// (fx ~ 432.4 px, fy ~ 424.2 px), principal point at the image centre.
    #[must_use]
    pub fn sr300() -> Self {
        // 73 / 2 = 36.5 deg, 59 / 2 = 29.5 deg; the values are constants of the datasheet.
        let fx = 320.0 / 36.5_f64.to_radians().tan();
        let fy = 240.0 / 29.5_f64.to_radians().tan();
        Self {
            fx,
            fy,
            cx: 319.5,
            cy: 239.5,
            width: 640,
            height: 480,
        }
    }

    /// The same camera cut down to the window `width x height` whose top-left pixel is
    /// `(u0, v0)`: the principal point shifts by `(u0, v0)`, focal lengths stay.
    ///
    /// # Errors
    /// [`RenderError::ZeroSize`] or [`RenderError::CropOutOfImage`].
    pub fn cropped(&self, u0: u32, v0: u32, width: u32, height: u32) -> Result<Self, RenderError> {
        check_size(width, height)?;
        let fits_u = u0.checked_add(width).is_some_and(|end| end <= self.width);
        let fits_v = v0.checked_add(height).is_some_and(|end| end <= self.height);
        if !(fits_u && fits_v) {
            return Err(RenderError::CropOutOfImage {
                u0,
                v0,
                width,
                height,
                image_width: self.width,
                image_height: self.height,
            });
        }
        Ok(Self {
            cx: self.cx - f64::from(u0),
            cy: self.cy - f64::from(v0),
            width,
            height,
            ..*self
        })
    }

    /// The same field of view sampled on a `width x height` grid (an image resize):
    /// focal lengths scale by the size ratios and the principal point follows the
    /// pixel-centre convention, `cx' = (cx + 0.5) * width' / width - 0.5`.
    ///
    /// Crop-then-resize is how the hand network's 96x96 input is cut from the depth
    /// image, e.g. `Intrinsics::sr300().cropped(u0, v0, 270, 270)?.resized(96, 96)?`.
    ///
    /// # Errors
    /// [`RenderError::ZeroSize`] or [`RenderError::TooLarge`].
    pub fn resized(&self, width: u32, height: u32) -> Result<Self, RenderError> {
        check_size(width, height)?;
        let sx = f64::from(width) / f64::from(self.width);
        let sy = f64::from(height) / f64::from(self.height);
        Ok(Self {
            fx: self.fx * sx,
            fy: self.fy * sy,
            cx: (self.cx + 0.5) * sx - 0.5,
            cy: (self.cy + 0.5) * sy - 0.5,
            width,
            height,
        })
    }

    /// Horizontal focal length (px).
    #[must_use]
    pub fn fx(&self) -> f64 {
        self.fx
    }
    /// Vertical focal length (px).
    #[must_use]
    pub fn fy(&self) -> f64 {
        self.fy
    }
    /// Principal point, column (px).
    #[must_use]
    pub fn cx(&self) -> f64 {
        self.cx
    }
    /// Principal point, row (px).
    #[must_use]
    pub fn cy(&self) -> f64 {
        self.cy
    }
    /// Image width (px).
    #[must_use]
    pub fn width(&self) -> u32 {
        self.width
    }
    /// Image height (px).
    #[must_use]
    pub fn height(&self) -> u32 {
        self.height
    }
    /// Full horizontal field of view between the outer pixel edges (deg).
    #[must_use]
    pub fn horizontal_fov_deg(&self) -> f64 {
        let left = (-0.5 - self.cx) / self.fx;
        let right = (f64::from(self.width) - 0.5 - self.cx) / self.fx;
        (right.atan() - left.atan()).to_degrees()
    }
    /// Full vertical field of view between the outer pixel edges (deg).
    #[must_use]
    pub fn vertical_fov_deg(&self) -> f64 {
        let top = (-0.5 - self.cy) / self.fy;
        let bottom = (f64::from(self.height) - 0.5 - self.cy) / self.fy;
        (bottom.atan() - top.atan()).to_degrees()
    }

    /// Projects a point given in the optical frame (m) to pixel coordinates; `None`
    /// when the point is not in front of the camera (`Z <= 0`).
    #[must_use]
    pub fn project(&self, p_camera_m: &Point3<f64>) -> Option<(f64, f64)> {
        (p_camera_m.z > 0.0).then(|| {
            (
                self.fx * p_camera_m.x / p_camera_m.z + self.cx,
                self.fy * p_camera_m.y / p_camera_m.z + self.cy,
            )
        })
    }

    /// The viewing ray through pixel coordinates `(u, v)`, in the optical frame, scaled
    /// so that its Z component is 1: the point at depth `Z` is `Z * ray`.
    #[must_use]
    pub fn ray_through(&self, u: f64, v: f64) -> Vector3<f64> {
        Vector3::new((u - self.cx) / self.fx, (v - self.cy) / self.fy, 1.0)
    }
}

impl Default for Intrinsics {
    /// [`Intrinsics::sr300`].
    fn default() -> Self {
        Self::sr300()
    }
}

fn check_size(width: u32, height: u32) -> Result<(), RenderError> {
    if width == 0 || height == 0 {
        return Err(RenderError::ZeroSize { width, height });
    }
    if width > MAX_IMAGE_SIDE || height > MAX_IMAGE_SIDE {
        return Err(RenderError::TooLarge {
            width,
            height,
            max: MAX_IMAGE_SIDE,
        });
    }
    Ok(())
}

/// Valid depth interval of the sensor (m), measured along the optical axis (Z).
///
/// A pixel whose nearest surface lies outside `[min_m, max_m]` has no return: depth 0,
/// and also background in the grey, colour and id images. Surfaces closer than `min_m`
/// still occlude what lies behind them, as on a real sensor.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DepthRange {
    min_m: f64,
    max_m: f64,
}

impl DepthRange {
    /// Largest representable depth: 65 535 mm, the limit of a `16UC1` image.
    pub const MAX_REPRESENTABLE_M: f64 = 65.535;

    /// A range `[min_m, max_m]` in metres.
    ///
    /// # Errors
    /// [`RenderError::InvalidDepthRange`] unless `0 <= min_m < max_m <= 65.535`.
    pub fn new(min_m: f64, max_m: f64) -> Result<Self, RenderError> {
        if min_m >= 0.0 && min_m < max_m && max_m <= Self::MAX_REPRESENTABLE_M {
            Ok(Self { min_m, max_m })
        } else {
            Err(RenderError::InvalidDepthRange { min_m, max_m })
        }
    }

    /// The SR300's 0.2 - 1.2 m.
    #[must_use]
    pub fn sr300() -> Self {
        Self {
            min_m: 0.2,
            max_m: 1.2,
        }
    }

    /// Near limit (m).
    #[must_use]
    pub fn min_m(&self) -> f64 {
        self.min_m
    }

    /// Far limit (m).
    #[must_use]
    pub fn max_m(&self) -> f64 {
        self.max_m
    }
}

impl Default for DepthRange {
    /// [`DepthRange::sr300`].
    fn default() -> Self {
        Self::sr300()
    }
}

/// A posed pinhole camera.
///
/// `world_from_camera` maps points from the camera's *optical* frame into the world
/// frame. The optical frame follows ROS (REP 103 `*_optical_frame`): +Z forward along the
/// viewing direction, +X right in the image, +Y down in the image, origin at the centre
/// of projection. A NaN pose renders an empty frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// Projection model and image size.
    pub intrinsics: Intrinsics,
    /// Valid depth interval.
    pub range: DepthRange,
    /// Pose of the optical frame in the world frame (m).
    pub world_from_camera: Isometry3<f64>,
}

impl Camera {
    /// A camera with the given intrinsics, range and pose.
    #[must_use]
    pub fn new(
        intrinsics: Intrinsics,
        range: DepthRange,
        world_from_camera: Isometry3<f64>,
    ) -> Self {
        Self {
            intrinsics,
            range,
            world_from_camera,
        }
    }

    /// SR300-like camera (640x480, 73 x 59 deg, 0.2 - 1.2 m) at the given pose.
    #[must_use]
    pub fn sr300(world_from_camera: Isometry3<f64>) -> Self {
        Self::new(Intrinsics::sr300(), DepthRange::sr300(), world_from_camera)
    }

    /// Optical-frame pose of a camera at `eye` looking at `target`, with `up` (world
    /// frame) pointing up in the image: Z = towards the target, X = Z x up, Y = Z x X.
    ///
    /// # Errors
    /// [`RenderError::InvalidPose`] if a point is not finite, `eye == target`, or `up` is
    /// parallel to the viewing direction.
    pub fn look_at(
        eye: &Point3<f64>,
        target: &Point3<f64>,
        up: &Vector3<f64>,
    ) -> Result<Isometry3<f64>, RenderError> {
        let finite = eye
            .iter()
            .chain(target.iter())
            .chain(up.iter())
            .all(|v| v.is_finite());
        if !finite {
            return Err(RenderError::InvalidPose {
                what: "look_at input is not finite",
            });
        }
        let z = (target - eye)
            .try_normalize(1e-12)
            .ok_or(RenderError::InvalidPose {
                what: "look_at eye and target coincide",
            })?;
        let x = z
            .cross(up)
            .try_normalize(1e-9)
            .ok_or(RenderError::InvalidPose {
                what: "look_at up is parallel to the viewing direction",
            })?;
        let y = z.cross(&x);
        let rotation = Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[x, y, z]));
        Ok(Isometry3::from_parts(
            Translation3::from(eye.coords),
            UnitQuaternion::from_rotation_matrix(&rotation),
        ))
    }
}

impl Default for Camera {
    /// SR300-like camera at the world origin.
    fn default() -> Self {
        Self::sr300(Isometry3::identity())
    }
}
