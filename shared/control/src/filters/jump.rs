//! Jump filter for a tracked 6D pose stream (thesis ch. 7.4).
//!
//! "To avoid rapid motions caused by instability of the PhaseSpace system or
//! accidental human errors, the position movements more than 50 cm along any axes or
//! the orientation change over 60° around any axes between two frames are omitted."
//!
//! # Semantics
//!
//! A pose `p` is compared with the **last accepted** pose `r` (not with the previous
//! frame, which may itself have been rejected; see below). It is rejected if
//!
//! * any component of `p`'s translation or quaternion is NaN or infinite ([`Rejection::NonFinite`]), or its quaternion's norm differs from 1 by
//!   more than [`QUATERNION_NORM_TOLERANCE`] ([`Rejection::NotNormalized`]);
//! * **position**: `|p.x - r.x|`, `|p.y - r.y|` or `|p.z - r.z|` is greater than
//!   `max_position_jump_m`. The axes are those of the frame both poses are expressed
//!   in (the parent frame, e.g. the UR5 base). This is the thesis' per-axis test:
//!   the Euclidean displacement of an accepted pose can reach `sqrt(3)` times the
//!   limit. [`Rejection::PositionJump`] names the axis with the largest displacement.
//! * **orientation**: the angle of the relative rotation `r⁻¹ p` (the angle of its
//!   axis-angle form, in `[0, 180]` deg, independent of the frame it is written in)
//!   is greater than `max_orientation_jump_deg` ([`Rejection::OrientationJump`]).
//!   This is the conservative reading of "around any axes": no rotation vector
//!   component, no twist about any axis (swing-twist decomposition) and, for limits
//!   up to 90 deg, none of the roll/pitch/yaw angles of the relative rotation can
//!   exceed the total angle, so every per-axis reading accepts what this one accepts
//!   (the tests check the roll/pitch/yaw claim).
//!
//! Equality with a limit is accepted. Checks run in the order above; the first
//! failing one is reported.
//!
//! # Reference pose, gaps and re-acquisition
//!
//! The reference is the last *accepted* pose. Comparing with the previous frame
//! instead (a literal reading of "between two frames") would accept a persistent jump
//! one frame after it happened — the frame after the jump is close to the jumped one —
//! and would reject the return to normal after a single glitch. With the last
//! accepted pose as reference, **the filter never auto-accepts a jump**: however long
//! the jumped poses persist, they are rejected, and a time gap does not loosen the
//! test (the filter takes no time at all).
//!
//! Re-acquisition is explicit: [`JumpFilter::reset`] forgets the reference so that
//! the next valid pose is accepted whatever it is. The node calls it when the
//! operator re-engages the clutch (the relative-control reference is re-taken at the
//! same moment) or when tracking is deliberately restarted. A freshly built filter
//! accepts its first valid pose. [`JumpFilter::consecutive_rejections`] tells a
//! status report that the stream is stuck behind a jump.

use nalgebra::Isometry3;
use serde::{Deserialize, Serialize};

use crate::QUATERNION_NORM_TOLERANCE;
use crate::error::{Axis, ConfigError, Rejection, RejectionCounts, positive};

/// Limits of the [`JumpFilter`]. Defaults are the thesis values (ch. 7.4).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct JumpFilterConfig {
    /// Largest accepted displacement along each axis since the last accepted pose,
    /// metres. Default 0.5.
    pub max_position_jump_m: f64,
    /// Largest accepted relative rotation angle since the last accepted pose,
    /// degrees, in `(0, 180]`. Default 60.
    pub max_orientation_jump_deg: f64,
}

impl Default for JumpFilterConfig {
    fn default() -> Self {
        Self {
            max_position_jump_m: 0.5,
            max_orientation_jump_deg: 60.0,
        }
    }
}

impl JumpFilterConfig {
    /// Checks every limit.
    ///
    /// # Errors
    ///
    /// [`ConfigError`] naming the first field that is not finite and positive, or an
    /// orientation limit above 180 deg (which could never trigger).
    pub fn validate(&self) -> Result<(), ConfigError> {
        positive("max_position_jump_m", self.max_position_jump_m)?;
        positive("max_orientation_jump_deg", self.max_orientation_jump_deg)?;
        if self.max_orientation_jump_deg > 180.0 {
            return Err(ConfigError::OutOfRange {
                name: "max_orientation_jump_deg",
                value: self.max_orientation_jump_deg,
                min: 0.0,
                max: 180.0,
            });
        }
        Ok(())
    }
}

/// Rejects poses that jump away from the last accepted pose; see the
/// [module docs](self) for the exact semantics.
#[derive(Debug, Clone)]
pub struct JumpFilter {
    config: JumpFilterConfig,
    max_orientation_jump_rad: f64,
    reference: Option<Isometry3<f64>>,
    accepted: u64,
    consecutive_rejections: u64,
    rejections: RejectionCounts,
}

impl JumpFilter {
    /// A filter with no reference: the first valid pose is accepted.
    ///
    /// # Errors
    ///
    /// The config's [`JumpFilterConfig::validate`] error.
    pub fn new(config: JumpFilterConfig) -> Result<Self, ConfigError> {
        config.validate()?;
        Ok(Self {
            config,
            max_orientation_jump_rad: config.max_orientation_jump_deg.to_radians(),
            reference: None,
            accepted: 0,
            consecutive_rejections: 0,
            rejections: RejectionCounts::default(),
        })
    }

    /// Accepts `pose` (it becomes the new reference and is returned) or rejects it
    /// (the reference stays; the rejection is counted).
    ///
    /// # Errors
    ///
    /// [`Rejection::NonFinite`], [`Rejection::NotNormalized`],
    /// [`Rejection::PositionJump`] or [`Rejection::OrientationJump`].
    pub fn filter(&mut self, pose: &Isometry3<f64>) -> Result<Isometry3<f64>, Rejection> {
        match self.check(pose) {
            Ok(()) => {
                self.reference = Some(*pose);
                self.accepted = self.accepted.saturating_add(1);
                self.consecutive_rejections = 0;
                Ok(*pose)
            }
            Err(r) => {
                self.rejections.record(&r);
                self.consecutive_rejections = self.consecutive_rejections.saturating_add(1);
                Err(r)
            }
        }
    }

    /// What [`filter`](Self::filter) would decide, without changing anything.
    ///
    /// # Errors
    ///
    /// As [`filter`](Self::filter).
    pub fn check(&self, pose: &Isometry3<f64>) -> Result<(), Rejection> {
        check_pose(pose, "pose.translation", "pose.rotation")?;
        let Some(reference) = &self.reference else {
            return Ok(());
        };
        let delta = pose.translation.vector - reference.translation.vector;
        let i = delta.iamax();
        if delta[i].abs() > self.config.max_position_jump_m {
            return Err(Rejection::PositionJump {
                axis: Axis::ALL[i],
                delta_m: delta[i],
                limit_m: self.config.max_position_jump_m,
            });
        }
        let angle_rad = reference.rotation.angle_to(&pose.rotation);
        if angle_rad > self.max_orientation_jump_rad {
            return Err(Rejection::OrientationJump {
                angle_deg: angle_rad.to_degrees(),
                limit_deg: self.config.max_orientation_jump_deg,
            });
        }
        Ok(())
    }

    /// Forgets the reference: the next valid pose is accepted whatever it is. Call it
    /// when the clutch re-engages or tracking is deliberately restarted. Counters are
    /// kept.
    pub fn reset(&mut self) {
        self.reference = None;
        self.consecutive_rejections = 0;
    }

    /// The last accepted pose, `None` after construction or [`reset`](Self::reset).
    pub fn reference(&self) -> Option<&Isometry3<f64>> {
        self.reference.as_ref()
    }

    /// The limits in use.
    pub fn config(&self) -> &JumpFilterConfig {
        &self.config
    }

    /// Poses accepted so far.
    pub fn accepted(&self) -> u64 {
        self.accepted
    }

    /// Rejections since the last accepted pose or reset. A value that keeps growing
    /// means the stream is stuck behind a jump and needs [`reset`](Self::reset).
    pub fn consecutive_rejections(&self) -> u64 {
        self.consecutive_rejections
    }

    /// Rejections per reason.
    pub fn rejections(&self) -> &RejectionCounts {
        &self.rejections
    }
}

/// Finite translation and rotation, unit quaternion; the field names go into
/// [`Rejection::NonFinite`].
pub(crate) fn check_pose(
    pose: &Isometry3<f64>,
    t_field: &'static str,
    r_field: &'static str,
) -> Result<(), Rejection> {
    if !pose.translation.vector.iter().all(|x| x.is_finite()) {
        return Err(Rejection::NonFinite { field: t_field });
    }
    let q = pose.rotation.quaternion();
    if !q.coords.iter().all(|x| x.is_finite()) {
        return Err(Rejection::NonFinite { field: r_field });
    }
    let norm = q.norm();
    if (norm - 1.0).abs() > QUATERNION_NORM_TOLERANCE {
        return Err(Rejection::NotNormalized { norm });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::RejectionKind;
    use nalgebra::{Quaternion, Translation3, UnitQuaternion, Vector3};

    fn pose(x: f64, y: f64, z: f64, rot: UnitQuaternion<f64>) -> Isometry3<f64> {
        Isometry3::from_parts(Translation3::new(x, y, z), rot)
    }

    fn filter() -> JumpFilter {
        JumpFilter::new(JumpFilterConfig::default()).unwrap()
    }

    #[test]
    fn first_pose_is_accepted_and_becomes_reference() {
        let mut f = filter();
        let p = pose(
            3.0,
            -2.0,
            1.0,
            UnitQuaternion::from_euler_angles(1.0, 2.0, 3.0),
        );
        assert_eq!(f.filter(&p), Ok(p));
        assert_eq!(f.reference(), Some(&p));
        assert_eq!(f.accepted(), 1);
    }

    #[test]
    fn position_jump_per_axis_at_and_above_the_limit() {
        for (i, axis) in Axis::ALL.iter().enumerate() {
            let mut f = filter();
            let r = Isometry3::identity();
            f.filter(&r).unwrap();
            let mut d = Vector3::zeros();
            d[i] = -0.5;
            // Exactly the limit: accepted (and becomes the new reference).
            let at = pose(d.x, d.y, d.z, UnitQuaternion::identity());
            assert!(f.filter(&at).is_ok());
            // 0.51 m further along the same axis: rejected, names the axis.
            d[i] = -1.01;
            let over = pose(d.x, d.y, d.z, UnitQuaternion::identity());
            match f.filter(&over) {
                Err(Rejection::PositionJump {
                    axis: a,
                    delta_m,
                    limit_m,
                }) => {
                    assert_eq!(a, *axis);
                    assert!((delta_m + 0.51).abs() < 1e-12);
                    assert_eq!(limit_m, 0.5);
                }
                other => panic!("{other:?}"),
            }
        }
    }

    #[test]
    fn position_test_is_per_axis_not_euclidean() {
        let mut f = filter();
        f.filter(&Isometry3::identity()).unwrap();
        // 0.45 m along every axis: 0.78 m Euclidean, accepted by the thesis' rule.
        assert!(
            f.filter(&pose(0.45, 0.45, -0.45, UnitQuaternion::identity()))
                .is_ok()
        );
    }

    #[test]
    fn orientation_jump_uses_the_total_relative_angle() {
        let mut f = filter();
        let base = UnitQuaternion::from_euler_angles(0.3, -0.2, 1.0);
        f.filter(&pose(0.0, 0.0, 0.0, base)).unwrap();
        // 50 deg about x and 50 deg about y: each single-axis rotation is under 60 deg,
        // the combined rotation is ~69 deg: rejected (conservative reading).
        let rel = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), 50f64.to_radians())
            * UnitQuaternion::from_axis_angle(&Vector3::y_axis(), 50f64.to_radians());
        match f.filter(&pose(0.0, 0.0, 0.0, base * rel)) {
            Err(Rejection::OrientationJump {
                angle_deg,
                limit_deg,
            }) => {
                assert!(angle_deg > 65.0 && angle_deg < 75.0, "{angle_deg}");
                assert_eq!(limit_deg, 60.0);
            }
            other => panic!("{other:?}"),
        }
        // 59.9 deg about an oblique axis: accepted.
        let axis = nalgebra::Unit::new_normalize(Vector3::new(1.0, -2.0, 0.5));
        let ok = base * UnitQuaternion::from_axis_angle(&axis, 59.9f64.to_radians());
        assert!(f.filter(&pose(0.0, 0.0, 0.0, ok)).is_ok());
    }

    #[test]
    fn orientation_uses_the_short_way_round() {
        let mut f = filter();
        f.filter(&Isometry3::identity()).unwrap();
        // q and -q are the same rotation: a sign flip of the quaternion is no jump.
        let q = UnitQuaternion::from_euler_angles(0.1, 0.2, 0.3);
        let neg = UnitQuaternion::new_unchecked(-q.into_inner());
        f.filter(&pose(0.0, 0.0, 0.0, q)).unwrap();
        assert!(f.filter(&pose(0.0, 0.0, 0.0, neg)).is_ok());
    }

    #[test]
    fn total_angle_bounds_every_per_axis_reading() {
        // For relative rotations up to 60 deg (and any up to 90), roll, pitch, yaw and
        // rotation-vector components never exceed the total angle.
        let mut worst: f64 = 0.0;
        let steps = 24;
        for a in 0..steps {
            for b in 0..steps {
                let theta = std::f64::consts::PI * a as f64 / steps as f64;
                let phi = 2.0 * std::f64::consts::PI * b as f64 / steps as f64;
                let axis = Vector3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), {
                    theta.cos()
                });
                for k in 1..=30 {
                    let angle = (90.0 * k as f64 / 30.0).to_radians();
                    let q = UnitQuaternion::from_scaled_axis(axis * angle);
                    let (r, p, y) = q.euler_angles();
                    let m = r.abs().max(p.abs()).max(y.abs());
                    assert!(
                        m <= angle + 1e-9,
                        "axis {axis:?} angle {angle}: rpy {r} {p} {y}"
                    );
                    assert!(q.scaled_axis().amax() <= angle + 1e-12);
                    worst = worst.max(m / angle);
                }
            }
        }
        assert!(worst <= 1.0 + 1e-9);
    }

    #[test]
    fn never_auto_accepts_a_persistent_jump_until_reset() {
        let mut f = filter();
        f.filter(&Isometry3::identity()).unwrap();
        let jumped = pose(0.0, 0.8, 0.0, UnitQuaternion::identity());
        for _ in 0..1000 {
            assert!(matches!(
                f.filter(&jumped),
                Err(Rejection::PositionJump { axis: Axis::Y, .. })
            ));
        }
        assert_eq!(f.consecutive_rejections(), 1000);
        assert_eq!(f.reference(), Some(&Isometry3::identity()));
        // Near the reference again: accepted, the glitch is over.
        assert!(
            f.filter(&pose(0.01, 0.0, 0.0, UnitQuaternion::identity()))
                .is_ok()
        );
        assert_eq!(f.consecutive_rejections(), 0);
        // The clutch re-engages: the next pose is accepted wherever it is.
        f.filter(&jumped).unwrap_err();
        f.reset();
        assert_eq!(f.reference(), None);
        assert_eq!(f.filter(&jumped), Ok(jumped));
        assert_eq!(f.rejections().get(RejectionKind::PositionJump), 1001);
    }

    #[test]
    fn non_finite_and_unnormalized_are_rejected_even_as_first_pose() {
        let mut f = filter();
        let nan_t = pose(f64::NAN, 0.0, 0.0, UnitQuaternion::identity());
        assert_eq!(
            f.filter(&nan_t),
            Err(Rejection::NonFinite {
                field: "pose.translation"
            })
        );
        let inf_r = Isometry3::from_parts(
            Translation3::identity(),
            UnitQuaternion::new_unchecked(Quaternion::new(f64::INFINITY, 0.0, 0.0, 0.0)),
        );
        assert_eq!(
            f.filter(&inf_r),
            Err(Rejection::NonFinite {
                field: "pose.rotation"
            })
        );
        let unnormalized = Isometry3::from_parts(
            Translation3::identity(),
            UnitQuaternion::new_unchecked(Quaternion::new(0.9, 0.0, 0.0, 0.0)),
        );
        assert!(matches!(
            f.filter(&unnormalized),
            Err(Rejection::NotNormalized { norm }) if (norm - 0.9).abs() < 1e-12
        ));
        assert_eq!(f.reference(), None);
        assert_eq!(f.rejections().total(), 3);
        let counts: Vec<_> = f.rejections().iter().filter(|(_, c)| *c > 0).collect();
        assert_eq!(counts, vec![("non_finite", 2), ("not_normalized", 1)]);
    }

    #[test]
    fn config_defaults_parse_and_validate() {
        let c: JumpFilterConfig = toml::from_str("").unwrap();
        assert_eq!(c, JumpFilterConfig::default());
        let c: JumpFilterConfig = toml::from_str("max_position_jump_m = 0.3").unwrap();
        assert_eq!(c.max_position_jump_m, 0.3);
        assert_eq!(c.max_orientation_jump_deg, 60.0);
        assert!(toml::from_str::<JumpFilterConfig>("max_jump = 1.0").is_err());
        for bad in [
            JumpFilterConfig {
                max_position_jump_m: 0.0,
                ..Default::default()
            },
            JumpFilterConfig {
                max_orientation_jump_deg: f64::NAN,
                ..Default::default()
            },
            JumpFilterConfig {
                max_orientation_jump_deg: 181.0,
                ..Default::default()
            },
        ] {
            assert!(JumpFilter::new(bad).is_err(), "{bad:?}");
        }
    }
}
