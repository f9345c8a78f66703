#![doc = include_str!("../README.md")]

mod camera;
pub mod convert;
mod error;
mod intersect;
mod noise;
mod render;
mod scene;
pub mod scenes;

pub use camera::{Camera, DepthRange, Intrinsics, MAX_IMAGE_SIDE};
pub use error::RenderError;
pub use noise::{DepthNoise, NoiseParams};
pub use render::{AMBIENT, Channels, Frame, RayBackend, Renderer};
pub use scene::{PALETTE, Primitive, Rgb8, Scene, SceneObject, ShapeId};

/// The nalgebra version of the public API (poses).
pub use nalgebra;
/// The parry3d version of the shapes in [`Primitive`].
pub use parry3d;
