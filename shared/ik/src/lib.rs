//! Goal-based inverse kinematics for serial chains, in the spirit of bio_ik: a weighted
//! sum of goals on the chain's tip (pose, position, orientation, direction, look-at) or
//! on intermediate frames (position, direction),
//! joint-space regularization toward a reference, and minimum-distance goals, solved by
//! a bounded Levenberg–Marquardt iteration on fixed-size matrices (no heap use in the
//! inner loop).
//!
//! * **Tracking** ([`Solver::solve_tracking`]): warm start from the last solution, a
//!   short iteration budget; for control loops (one call per control step).
//! * **Cold** ([`Solver::solve_cold`]): random restarts from uniformly sampled joint
//!   vectors until the goals are met or the restart budget is spent. Deterministic for
//!   a given seed (the optional wall-clock cap is the only source of variation).
//!
//! Joint limits are always respected: every iterate is clamped into the limits.
//! Failure is an explicit [`IkFailure`] carrying the best solution found and its
//! residuals; callers decide to hold, clamp or use it.
//!
//! # Goal semantics
//!
//! All targets are in the chain's base frame; "tip" is the chain's tip link.
//!
//! | goal | residual | satisfied when |
//! |---|---|---|
//! | [`Goal::Pose`] | position error (m) and `rotation_scale` x rotation-vector error | both within the tolerances |
//! | [`Goal::Position`] | tip position - target | `|e| <= position_tolerance_m` |
//! | [`Goal::Orientation`] | rotation vector of `R * R_target^T` | angle `<= orientation_tolerance_rad` |
//! | [`Goal::Direction`] | `R * axis - direction` | angle between them within tolerance |
//! | [`Goal::LookAt`] | `R * axis - unit(point - tip)` | angle within tolerance |
//! | [`Goal::JointRegularization`] | `q - reference` | always (a preference, not a constraint) |
//! | [`Goal::FramePosition`] | point in frame `k` - target | `|e| <= position_tolerance_m` |
//! | [`Goal::FrameDirection`] | `R_k * axis - direction` | angle within tolerance |
//! | [`Goal::MinDistance`] | `max(0, min_distance - d(q))` | `d(q) >= min_distance - position_tolerance_m` |
//!
//! Each residual is multiplied by the square root of its weight, so the solver minimizes
//! `sum_i weight_i |e_i|^2`.

mod solver;

pub use solver::{
    ColdBudget, DistanceConstraint, FailureKind, Goal, GoalResidual, IkFailure, IkSettings,
    Solution, Solver,
};
