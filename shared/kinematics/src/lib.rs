#![doc = include_str!("../README.md")]

pub mod chain;
pub mod error;
pub mod fk;
pub mod gravity;
pub mod model;
pub mod robots;

pub use chain::{Chain, ChainJoint, FixedChain};
pub use error::KinematicsError;
pub use fk::KinematicState;
pub use gravity::GravityModel;
pub use model::{
    CollisionShape, Inertial, Joint, JointId, JointKind, JointLimits, Link, LinkId, Robot, Shape,
};
pub use nalgebra;
