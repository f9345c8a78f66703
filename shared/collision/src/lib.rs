#![doc = include_str!("../README.md")]

mod body;
pub mod chain;
pub mod error;
pub mod geometry;
pub mod model;
pub mod robots;
pub mod segments;
pub mod volume;

pub use body::LinkBody;
pub use chain::{ChainBodies, ChainSelfDistance, ChainVolumeDistance};
pub use error::CollisionError;
pub use geometry::{PlacedShape, Primitive};
pub use model::{AllowReason, CollisionModel, LinkPairProximity, ModelSettings, VolumeProximity};
pub use volume::{ExternalVolume, HandDimensions};
