//! Typed rejections, their counters, and configuration errors.
//!
//! A filter that refuses an input returns a [`Rejection`] that names the reason and
//! carries the numbers behind it (`PositionJump { axis: Z, delta_m: 0.62, limit_m:
//! 0.5 }`), and counts it in a [`RejectionCounts`] that a node copies into its status
//! report as `(name, count)` pairs.

use std::fmt;

/// A Cartesian axis of the frame the poses are expressed in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Axis {
    /// x
    X,
    /// y
    Y,
    /// z
    Z,
}

impl Axis {
    /// The three axes in order; `Axis::ALL[i]` is vector component `i`.
    pub const ALL: [Axis; 3] = [Axis::X, Axis::Y, Axis::Z];

    /// Lower-case name (`"x"`).
    pub const fn name(self) -> &'static str {
        match self {
            Axis::X => "x",
            Axis::Y => "y",
            Axis::Z => "z",
        }
    }
}

impl fmt::Display for Axis {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Why a filter refused an input. The filter's state is unchanged by a rejected
/// input: it behaves as if the input had never arrived (apart from counting it).
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum Rejection {
    /// The position moved more than the limit along one axis since the last accepted
    /// pose ([`crate::filters::JumpFilter`]).
    #[error("position jumped {delta_m:.3} m along {axis} (limit {limit_m} m)")]
    PositionJump {
        /// The axis with the largest displacement.
        axis: Axis,
        /// Signed displacement along `axis`, metres.
        delta_m: f64,
        /// The configured limit, metres.
        limit_m: f64,
    },
    /// The orientation changed by more than the limit since the last accepted pose
    /// ([`crate::filters::JumpFilter`]).
    #[error("orientation changed {angle_deg:.1} deg (limit {limit_deg} deg)")]
    OrientationJump {
        /// Angle of the relative rotation, degrees, in `[0, 180]`.
        angle_deg: f64,
        /// The configured limit, degrees.
        limit_deg: f64,
    },
    /// A NaN or infinite number in the input.
    #[error("non-finite value in {field}")]
    NonFinite {
        /// Which input: `"pose.translation"`, `"pose.rotation"`, `"velocity_rad_s"`, ...
        field: &'static str,
    },
    /// A rotation whose quaternion is not of unit norm (beyond
    /// [`QUATERNION_NORM_TOLERANCE`](crate::QUATERNION_NORM_TOLERANCE)), e.g. built
    /// with `new_unchecked` from a wire message.
    #[error("rotation quaternion not normalized: |q| = {norm}")]
    NotNormalized {
        /// The quaternion's norm.
        norm: f64,
    },
    /// The time step is not a finite positive number.
    #[error("invalid time step dt = {dt_s} s (must be finite and > 0)")]
    InvalidTimeStep {
        /// The time step given, seconds.
        dt_s: f64,
    },
    /// A joint velocity command above its limit, under
    /// [`VelocityLimitStrategy::Reject`](crate::filters::VelocityLimitStrategy::Reject).
    #[error("joint {joint}: velocity {velocity_rad_s} rad/s exceeds limit {limit_rad_s} rad/s")]
    JointVelocityLimit {
        /// Joint index in the vector.
        joint: usize,
        /// Commanded velocity, rad/s.
        velocity_rad_s: f64,
        /// Its limit, rad/s.
        limit_rad_s: f64,
    },
    /// A joint velocity command whose change from the previous output needs more than
    /// the joint's acceleration limit, under
    /// [`VelocityLimitStrategy::Reject`](crate::filters::VelocityLimitStrategy::Reject).
    #[error(
        "joint {joint}: acceleration {acceleration_rad_s2} rad/s^2 exceeds limit {limit_rad_s2} rad/s^2"
    )]
    JointAccelerationLimit {
        /// Joint index in the vector.
        joint: usize,
        /// Acceleration the command would need, rad/s².
        acceleration_rad_s2: f64,
        /// Its limit, rad/s².
        limit_rad_s2: f64,
    },
}

/// The reason of a [`Rejection`] without its numbers: the key of a counter.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum RejectionKind {
    /// [`Rejection::PositionJump`]
    PositionJump,
    /// [`Rejection::OrientationJump`]
    OrientationJump,
    /// [`Rejection::NonFinite`]
    NonFinite,
    /// [`Rejection::NotNormalized`]
    NotNormalized,
    /// [`Rejection::InvalidTimeStep`]
    InvalidTimeStep,
    /// [`Rejection::JointVelocityLimit`]
    JointVelocityLimit,
    /// [`Rejection::JointAccelerationLimit`]
    JointAccelerationLimit,
}

impl RejectionKind {
    /// Every kind, in counter order.
    pub const ALL: [RejectionKind; 7] = [
        RejectionKind::PositionJump,
        RejectionKind::OrientationJump,
        RejectionKind::NonFinite,
        RejectionKind::NotNormalized,
        RejectionKind::InvalidTimeStep,
        RejectionKind::JointVelocityLimit,
        RejectionKind::JointAccelerationLimit,
    ];

    /// Counter name, `snake_case` (`"position_jump"`).
    pub const fn name(self) -> &'static str {
        match self {
            RejectionKind::PositionJump => "position_jump",
            RejectionKind::OrientationJump => "orientation_jump",
            RejectionKind::NonFinite => "non_finite",
            RejectionKind::NotNormalized => "not_normalized",
            RejectionKind::InvalidTimeStep => "invalid_time_step",
            RejectionKind::JointVelocityLimit => "joint_velocity_limit",
            RejectionKind::JointAccelerationLimit => "joint_acceleration_limit",
        }
    }

    const fn index(self) -> usize {
        self as usize
    }
}

impl Rejection {
    /// The reason, without the numbers.
    pub const fn kind(&self) -> RejectionKind {
        match self {
            Rejection::PositionJump { .. } => RejectionKind::PositionJump,
            Rejection::OrientationJump { .. } => RejectionKind::OrientationJump,
            Rejection::NonFinite { .. } => RejectionKind::NonFinite,
            Rejection::NotNormalized { .. } => RejectionKind::NotNormalized,
            Rejection::InvalidTimeStep { .. } => RejectionKind::InvalidTimeStep,
            Rejection::JointVelocityLimit { .. } => RejectionKind::JointVelocityLimit,
            Rejection::JointAccelerationLimit { .. } => RejectionKind::JointAccelerationLimit,
        }
    }
}

/// One counter per [`RejectionKind`]. Counters saturate instead of wrapping.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct RejectionCounts {
    counts: [u64; RejectionKind::ALL.len()],
}

impl RejectionCounts {
    /// Counts one rejection.
    pub fn record(&mut self, rejection: &Rejection) {
        let c = &mut self.counts[rejection.kind().index()];
        *c = c.saturating_add(1);
    }

    /// How many rejections of this kind.
    pub fn get(&self, kind: RejectionKind) -> u64 {
        self.counts[kind.index()]
    }

    /// All rejections together.
    pub fn total(&self) -> u64 {
        self.counts.iter().fold(0u64, |a, &c| a.saturating_add(c))
    }

    /// `(kind name, count)` for every kind, zeros included, in [`RejectionKind::ALL`]
    /// order (a status report keeps a stable set of names).
    pub fn iter(&self) -> impl Iterator<Item = (&'static str, u64)> + '_ {
        RejectionKind::ALL
            .iter()
            .map(|k| (k.name(), self.counts[k.index()]))
    }

    /// Counters named `<prefix>.rejected_<kind>`, the naming of node status reports
    /// (`wrist_pose.rejected_position_jump`).
    pub fn named(&self, prefix: &str) -> Vec<(String, u64)> {
        self.iter()
            .map(|(n, c)| (format!("{prefix}.rejected_{n}"), c))
            .collect()
    }

    /// Sets every counter to zero.
    pub fn clear(&mut self) {
        self.counts = Default::default();
    }
}

/// A configuration or limit set that cannot be used. Returned by the constructors;
/// a filter never runs with an invalid configuration.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ConfigError {
    /// A limit that must be finite and strictly positive is not.
    #[error("{name} = {value} must be finite and > 0")]
    NotPositive {
        /// Field name, e.g. `max_linear_velocity_m_s`.
        name: &'static str,
        /// The value given.
        value: f64,
    },
    /// A value outside its allowed range.
    #[error("{name} = {value} is outside {min}..={max}")]
    OutOfRange {
        /// Field name.
        name: &'static str,
        /// The value given.
        value: f64,
        /// Smallest allowed value.
        min: f64,
        /// Largest allowed value.
        max: f64,
    },
    /// A per-joint limit that must be finite and strictly positive is not.
    #[error("joint {joint}: {name} = {value} must be finite and > 0")]
    JointNotPositive {
        /// Joint index.
        joint: usize,
        /// Field name, e.g. `max_velocity_rad_s`.
        name: &'static str,
        /// The value given.
        value: f64,
    },
    /// Position limits that are NaN or with lower above upper. Infinite limits are
    /// allowed (continuous joints).
    #[error("joint {joint}: position limits [{lower_rad}, {upper_rad}] rad are not an interval")]
    JointPositionLimits {
        /// Joint index.
        joint: usize,
        /// Lower limit, rad.
        lower_rad: f64,
        /// Upper limit, rad.
        upper_rad: f64,
    },
    /// The initial state handed to a constructor (e.g. the robot's current pose) is
    /// not usable.
    #[error("invalid initial state: {0}")]
    InitialState(#[source] Rejection),
}

/// Checks `value` is finite and > 0.
pub(crate) fn positive(name: &'static str, value: f64) -> Result<(), ConfigError> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(ConfigError::NotPositive { name, value })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kinds_are_in_counter_order_and_named_uniquely() {
        for (i, k) in RejectionKind::ALL.iter().enumerate() {
            assert_eq!(k.index(), i);
        }
        let mut names: Vec<_> = RejectionKind::ALL.iter().map(|k| k.name()).collect();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), RejectionKind::ALL.len());
    }

    #[test]
    fn counts_record_and_name() {
        let mut c = RejectionCounts::default();
        c.record(&Rejection::NonFinite { field: "x" });
        c.record(&Rejection::NonFinite { field: "y" });
        c.record(&Rejection::InvalidTimeStep { dt_s: -1.0 });
        assert_eq!(c.get(RejectionKind::NonFinite), 2);
        assert_eq!(c.total(), 3);
        assert_eq!(c.iter().count(), RejectionKind::ALL.len());
        assert!(c.iter().any(|p| p == ("invalid_time_step", 1)));
        assert!(
            c.named("wrist_pose")
                .contains(&("wrist_pose.rejected_non_finite".to_string(), 2))
        );
        c.clear();
        assert_eq!(c.total(), 0);
    }

    #[test]
    fn messages_carry_numbers() {
        let r = Rejection::PositionJump {
            axis: Axis::Z,
            delta_m: -0.62,
            limit_m: 0.5,
        };
        assert_eq!(
            r.to_string(),
            "position jumped -0.620 m along z (limit 0.5 m)"
        );
    }
}
