//! Typed errors of the renderer.

use crate::scene::ShapeId;

/// Everything that can go wrong when configuring a camera, a scene or a noise model.
///
/// Rendering itself cannot fail: once a [`Camera`](crate::Camera) and a
/// [`Scene`](crate::Scene) exist they are valid.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum RenderError {
    /// Width or height is zero.
    #[error("image size must be non-zero, got {width}x{height}")]
    ZeroSize {
        /// Requested width (px).
        width: u32,
        /// Requested height (px).
        height: u32,
    },
    /// Width or height exceeds [`MAX_IMAGE_SIDE`](crate::MAX_IMAGE_SIDE).
    #[error("image size {width}x{height} exceeds the limit of {max} px per side")]
    TooLarge {
        /// Requested width (px).
        width: u32,
        /// Requested height (px).
        height: u32,
        /// The limit (px).
        max: u32,
    },
    /// An intrinsic parameter (focal length, principal point) is NaN or infinite.
    #[error("intrinsic parameter {name} must be finite, got {value}")]
    NonFiniteIntrinsic {
        /// `fx`, `fy`, `cx` or `cy`.
        name: &'static str,
        /// The offending value.
        value: f64,
    },
    /// A focal length is zero or negative.
    #[error("focal length {name} must be > 0 px, got {value}")]
    NonPositiveFocalLength {
        /// `fx` or `fy`.
        name: &'static str,
        /// The offending value (px).
        value: f64,
    },
    /// A field of view is not inside the open interval (0, 180) degrees.
    #[error("field of view {name} must lie in (0, 180) deg, got {value_deg}")]
    FovOutOfRange {
        /// `horizontal` or `vertical`.
        name: &'static str,
        /// The offending value (deg).
        value_deg: f64,
    },
    /// A crop window does not fit inside the image.
    #[error(
        "crop window {width}x{height} at ({u0}, {v0}) does not fit a {image_width}x{image_height} image"
    )]
    CropOutOfImage {
        /// Left column of the window (px).
        u0: u32,
        /// Top row of the window (px).
        v0: u32,
        /// Window width (px).
        width: u32,
        /// Window height (px).
        height: u32,
        /// Image width (px).
        image_width: u32,
        /// Image height (px).
        image_height: u32,
    },
    /// The depth range is not `0 <= min < max <= 65.535 m` with finite bounds.
    #[error("depth range must satisfy 0 <= min < max <= 65.535 m, got [{min_m}, {max_m}] m")]
    InvalidDepthRange {
        /// Near limit (m).
        min_m: f64,
        /// Far limit (m).
        max_m: f64,
    },
    /// A shape dimension is zero, negative or not finite.
    #[error("shape dimension {name} must be finite and > 0 m, got {value}")]
    InvalidShapeDimension {
        /// Which dimension (`radius`, `half_extent`, ...).
        name: &'static str,
        /// The offending value (m).
        value: f64,
    },
    /// A pose contains NaN or infinite values, or a camera look-at is degenerate.
    #[error("pose is not finite or not well defined: {what}")]
    InvalidPose {
        /// What was wrong.
        what: &'static str,
    },
    /// The scene already holds the maximum number of shapes.
    #[error("a scene holds at most {max} shapes")]
    TooManyShapes {
        /// The limit.
        max: usize,
    },
    /// The shape id does not belong to this scene.
    #[error("unknown shape id {0:?}")]
    UnknownShape(ShapeId),
    /// A noise parameter is out of its domain.
    #[error("noise parameter {name} is out of range: {value}")]
    InvalidNoiseParameter {
        /// The parameter's field name.
        name: &'static str,
        /// The offending value.
        value: f64,
    },
}
