//! The robot site's physical world on [MuJoCo](https://mujoco.org) through `mujoco-rs`:
//! the PR2 arm with the Shadow hand generated from the project's URDFs ([`mjcf`]), a table
//! with free objects ([`scene`]), the simulated drivers' loops ([`world`]), and the judge
//! of a pick-and-place job from ground truth ([`judge`]).
//!
//! The native library is MuJoCo 3.17.0 from the `mujoco` PyPI wheel, found or installed
//! by the build script ([`library`]); `docs/physics.md` says how to use one of your own.

pub mod error;
pub mod judge;
pub mod library;
pub mod mjcf;
pub mod scene;
pub mod scripted;
pub mod world;

pub use error::PhysicsError;
pub use judge::{
    Failure, JobJudge, JudgeError, PickPlaceConfig, PickPlaceJudge, TargetRegion, TowerConfig,
    TowerJudge, Verdict,
};
pub use scene::{ObjectShape, ObjectSpec, ObjectVariation, SceneSpec, TableSpec};
pub use world::{ARM_DOF, HAND_DOF, PhysicsConfig, PhysicsWorld, RobotParams, world_mjcf};

/// Where the build linked MuJoCo from (the library file and the search step that found
/// it), or `None` when `MUJOCO_DYNAMIC_LINK_DIR` named it.
#[must_use]
pub fn linked_library() -> Option<&'static str> {
    option_env!("TELEOP_MUJOCO_LINKED")
}
