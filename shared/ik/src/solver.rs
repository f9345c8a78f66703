//! The solver: goals, settings, Levenberg–Marquardt core, tracking and cold modes.

use std::sync::Arc;
use std::time::{Duration, Instant};

use nalgebra::{Isometry3, Matrix3, SMatrix, SVector, Unit, UnitQuaternion, Vector3};
use teleop_kinematics::FixedChain;

/// A distance that must stay above a threshold, computed from the chain's frames (one
/// per moving joint after its motion, then the tip; base frame). Implemented by the
/// collision layer (robot links vs. external volumes, link pairs).
pub trait DistanceConstraint<const N: usize>: Send + Sync {
    /// The current distance in metres (negative when penetrating).
    fn distance(&self, frames: &[Isometry3<f64>]) -> f64;
}

/// One goal of an IK problem. See the crate docs for the exact residuals.
#[derive(Clone)]
#[non_exhaustive]
pub enum Goal<const N: usize> {
    /// Full pose of the tip. `rotation_scale` converts radians of rotation error into
    /// the same units as metres of position error (bio_ik's default is 0.5).
    Pose {
        target: Isometry3<f64>,
        weight: f64,
        rotation_scale: f64,
    },
    /// Position of the tip origin.
    Position { target: Vector3<f64>, weight: f64 },
    /// Orientation of the tip.
    Orientation {
        target: UnitQuaternion<f64>,
        weight: f64,
    },
    /// The tip's `axis` (in the tip frame) points along `direction` (base frame).
    Direction {
        axis: Unit<Vector3<f64>>,
        direction: Unit<Vector3<f64>>,
        weight: f64,
    },
    /// The tip's `axis` (in the tip frame, e.g. a camera's optical axis +Z) points at
    /// `point` (base frame).
    LookAt {
        axis: Unit<Vector3<f64>>,
        point: Vector3<f64>,
        weight: f64,
    },
    /// Stay close to `reference` (e.g. the robot's current joints).
    JointRegularization {
        reference: SVector<f64, N>,
        weight: f64,
    },
    /// Position of a point fixed in one of the chain's frames: `frame` indexes the
    /// frames of [`Chain::frames_into`](teleop_kinematics::Chain::frames_into) (the
    /// moving joints' frames after their motion, `0..N`, then the tip, `N`), `offset`
    /// is the point in that frame. For goals on intermediate links (a finger's middle
    /// joint, a forearm).
    FramePosition {
        frame: usize,
        offset: Vector3<f64>,
        target: Vector3<f64>,
        weight: f64,
    },
    /// Frame `frame`'s `axis` (in that frame) points along `direction` (base frame).
    FrameDirection {
        frame: usize,
        axis: Unit<Vector3<f64>>,
        direction: Unit<Vector3<f64>>,
        weight: f64,
    },
    /// Keep `constraint`'s distance at or above `min_distance_m`.
    MinDistance {
        constraint: Arc<dyn DistanceConstraint<N>>,
        min_distance_m: f64,
        weight: f64,
    },
}

impl<const N: usize> std::fmt::Debug for Goal<N> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Goal::Pose { target, weight, .. } => f
                .debug_struct("Pose")
                .field("target", target)
                .field("weight", weight)
                .finish(),
            Goal::Position { target, weight } => f
                .debug_struct("Position")
                .field("target", target)
                .field("weight", weight)
                .finish(),
            Goal::Orientation { target, weight } => f
                .debug_struct("Orientation")
                .field("target", target)
                .field("weight", weight)
                .finish(),
            Goal::Direction {
                axis,
                direction,
                weight,
            } => f
                .debug_struct("Direction")
                .field("axis", axis)
                .field("direction", direction)
                .field("weight", weight)
                .finish(),
            Goal::LookAt {
                axis,
                point,
                weight,
            } => f
                .debug_struct("LookAt")
                .field("axis", axis)
                .field("point", point)
                .field("weight", weight)
                .finish(),
            Goal::JointRegularization { weight, .. } => f
                .debug_struct("JointRegularization")
                .field("weight", weight)
                .finish(),
            Goal::FramePosition {
                frame,
                offset,
                target,
                weight,
            } => f
                .debug_struct("FramePosition")
                .field("frame", frame)
                .field("offset", offset)
                .field("target", target)
                .field("weight", weight)
                .finish(),
            Goal::FrameDirection {
                frame,
                axis,
                direction,
                weight,
            } => f
                .debug_struct("FrameDirection")
                .field("frame", frame)
                .field("axis", axis)
                .field("direction", direction)
                .field("weight", weight)
                .finish(),
            Goal::MinDistance {
                min_distance_m,
                weight,
                ..
            } => f
                .debug_struct("MinDistance")
                .field("min_distance_m", min_distance_m)
                .field("weight", weight)
                .finish(),
        }
    }
}

impl<const N: usize> Goal<N> {
    /// A pose goal with weight 1 and bio_ik's rotation scale 0.5.
    pub fn pose(target: Isometry3<f64>) -> Self {
        Goal::Pose {
            target,
            weight: 1.0,
            rotation_scale: 0.5,
        }
    }

    /// Checks weights and targets are finite (and weights non-negative).
    fn validate(&self) -> Result<(), &'static str> {
        let finite = |v: f64| v.is_finite();
        let weight = match self {
            Goal::Pose {
                target,
                weight,
                rotation_scale,
            } => {
                if !(finite(*rotation_scale) && *rotation_scale >= 0.0) {
                    return Err("rotation_scale must be finite and >= 0");
                }
                if !target.translation.vector.iter().all(|v| v.is_finite())
                    || !target.rotation.coords.iter().all(|v| v.is_finite())
                {
                    return Err("pose target is not finite");
                }
                *weight
            }
            Goal::Position { target, weight } => {
                if !target.iter().all(|v| v.is_finite()) {
                    return Err("position target is not finite");
                }
                *weight
            }
            Goal::Orientation { target, weight } => {
                if !target.coords.iter().all(|v| v.is_finite()) {
                    return Err("orientation target is not finite");
                }
                *weight
            }
            Goal::Direction {
                axis,
                direction,
                weight,
            } => {
                if !axis.iter().chain(direction.iter()).all(|v| v.is_finite()) {
                    return Err("direction goal vectors are not finite");
                }
                *weight
            }
            Goal::LookAt {
                axis,
                point,
                weight,
            } => {
                if !axis.iter().chain(point.iter()).all(|v| v.is_finite()) {
                    return Err("look-at goal vectors are not finite");
                }
                *weight
            }
            Goal::JointRegularization { reference, weight } => {
                if !reference.iter().all(|v| v.is_finite()) {
                    return Err("regularization reference is not finite");
                }
                *weight
            }
            Goal::FramePosition {
                frame,
                offset,
                target,
                weight,
            } => {
                if *frame > N || N + 1 > MAX_FRAMES {
                    return Err("frame index beyond the chain's tip (N)");
                }
                if !offset.iter().chain(target.iter()).all(|v| v.is_finite()) {
                    return Err("frame position goal vectors are not finite");
                }
                *weight
            }
            Goal::FrameDirection {
                frame,
                axis,
                direction,
                weight,
            } => {
                if *frame > N || N + 1 > MAX_FRAMES {
                    return Err("frame index beyond the chain's tip (N)");
                }
                if !axis.iter().chain(direction.iter()).all(|v| v.is_finite()) {
                    return Err("frame direction goal vectors are not finite");
                }
                *weight
            }
            Goal::MinDistance {
                min_distance_m,
                weight,
                ..
            } => {
                if !finite(*min_distance_m) {
                    return Err("min_distance_m is not finite");
                }
                *weight
            }
        };
        if !(weight.is_finite() && weight >= 0.0) {
            return Err("weight must be finite and >= 0");
        }
        Ok(())
    }
}

/// Solver settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IkSettings {
    /// Position tolerance of pose/position goals, metres.
    pub position_tolerance_m: f64,
    /// Angular tolerance of pose/orientation/direction/look-at goals, radians.
    pub orientation_tolerance_rad: f64,
    /// Iteration budget of one tracking solve.
    pub tracking_iterations: u32,
    /// Iteration budget of one cold attempt (before a restart).
    pub cold_iterations: u32,
    /// Initial Levenberg–Marquardt damping.
    pub initial_damping: f64,
    /// Finite-difference step for minimum-distance goals, radians.
    pub distance_fd_step: f64,
    /// Cold mode: after this many iterations of an attempt, an iteration that keeps
    /// more than `slow_progress_ratio` of the cost abandons the attempt (restart).
    pub patience_iterations: u32,
    pub slow_progress_ratio: f64,
}

impl Default for IkSettings {
    fn default() -> Self {
        Self {
            position_tolerance_m: 1e-5,
            orientation_tolerance_rad: 1e-5,
            tracking_iterations: 20,
            cold_iterations: 60,
            initial_damping: 1e-3,
            distance_fd_step: 1e-6,
            patience_iterations: 4,
            slow_progress_ratio: 0.8,
        }
    }
}

/// Restart budget of a cold solve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ColdBudget {
    /// Random restarts after the first attempt.
    pub max_restarts: u32,
    /// Optional wall-clock cap. A cap makes the result depend on the machine's speed;
    /// leave it `None` for bit-reproducible results.
    pub time_limit: Option<Duration>,
}

impl Default for ColdBudget {
    fn default() -> Self {
        Self {
            max_restarts: 200,
            time_limit: None,
        }
    }
}

/// How far one goal is from being met at the returned solution.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GoalResidual {
    /// Index of the goal in the problem.
    pub goal: usize,
    /// Position error in metres (0 where the goal has none).
    pub position_m: f64,
    /// Angular error in radians (0 where the goal has none).
    pub angle_rad: f64,
    /// Weighted squared residual: this goal's share of the cost.
    pub cost: f64,
    /// Whether the goal is met within the tolerances.
    pub satisfied: bool,
}

/// A joint vector and how well it meets the goals.
#[derive(Debug, Clone, PartialEq)]
pub struct Solution<const N: usize> {
    pub q: SVector<f64, N>,
    /// Tip pose at `q` (base frame).
    pub tip: Isometry3<f64>,
    /// Largest position error over the goals, metres.
    pub position_error_m: f64,
    /// Largest angular error over the goals, radians.
    pub orientation_error_rad: f64,
    /// Total weighted cost.
    pub cost: f64,
    /// Per-goal residuals, in goal order.
    pub residuals: Vec<GoalResidual>,
    /// Levenberg–Marquardt iterations spent (all attempts).
    pub iterations: u32,
    /// Random restarts used (cold mode).
    pub restarts: u32,
}

/// Why a solve failed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum FailureKind {
    /// The iteration or restart budget ran out before the goals were met.
    NotConverged,
    /// A goal has a non-finite target or a negative/non-finite weight; the solver did
    /// not move from the (clamped) start.
    InvalidGoal { index: usize, reason: &'static str },
    /// The start vector is not finite.
    InvalidStart,
}

/// A failed solve: why, and the best solution found.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("IK failed ({kind:?}): best position error {:.3e} m, orientation error {:.3e} rad", best.position_error_m, best.orientation_error_rad)]
pub struct IkFailure<const N: usize> {
    pub kind: FailureKind,
    pub best: Box<Solution<N>>,
}

/// Accumulated normal equations at one joint vector.
struct Eval<const N: usize> {
    cost: f64,
    h: SMatrix<f64, N, N>,
    g: SVector<f64, N>,
    satisfied: bool,
}

/// An IK solver for one fixed-size chain.
#[derive(Debug, Clone)]
pub struct Solver<const N: usize> {
    chain: FixedChain<N>,
    lower: SVector<f64, N>,
    upper: SVector<f64, N>,
    settings: IkSettings,
}

/// Most frames a chain may have for frame goals and distance constraints (N + 1).
const MAX_FRAMES: usize = 32;

/// The chain's frames at one joint vector, for frame goals.
struct Frames {
    frames: [Isometry3<f64>; MAX_FRAMES],
}

/// Range used to sample continuous (unbounded) joints in cold mode.
const UNBOUNDED_SAMPLE: f64 = std::f64::consts::PI;

impl<const N: usize> Solver<N> {
    pub fn new(chain: FixedChain<N>, settings: IkSettings) -> Self {
        Self {
            lower: chain.lower_limits(),
            upper: chain.upper_limits(),
            chain,
            settings,
        }
    }

    pub fn chain(&self) -> &FixedChain<N> {
        &self.chain
    }
    pub fn settings(&self) -> &IkSettings {
        &self.settings
    }

    fn clamp(&self, q: &SVector<f64, N>) -> SVector<f64, N> {
        SVector::from_fn(|i, _| q[i].clamp(self.lower[i], self.upper[i]))
    }

    /// One short solve warm-started at `q_start` (e.g. the last solution).
    ///
    /// # Errors
    /// [`IkFailure`] with the best solution if the goals are not met within
    /// [`IkSettings::tracking_iterations`].
    pub fn solve_tracking(
        &self,
        goals: &[Goal<N>],
        q_start: &SVector<f64, N>,
    ) -> Result<Solution<N>, IkFailure<N>> {
        self.check_inputs(goals, q_start)?;
        let (q, iterations, ok) = self.lm(
            goals,
            self.clamp(q_start),
            self.settings.tracking_iterations,
            false,
        );
        let sol = self.solution(goals, q, iterations, 0);
        if ok {
            Ok(sol)
        } else {
            Err(IkFailure {
                kind: FailureKind::NotConverged,
                best: Box::new(sol),
            })
        }
    }

    /// Random restarts until success: the first attempt starts at `seed_q` (if given),
    /// the others at joint vectors drawn uniformly within the limits from a generator
    /// seeded with `seed`.
    ///
    /// # Errors
    /// [`IkFailure`] with the lowest-cost solution if every attempt failed.
    pub fn solve_cold(
        &self,
        goals: &[Goal<N>],
        seed_q: Option<&SVector<f64, N>>,
        seed: u64,
        budget: ColdBudget,
    ) -> Result<Solution<N>, IkFailure<N>> {
        let mut rng = SplitMix64(seed ^ 0x9E37_79B9_7F4A_7C15);
        let start_time = Instant::now();
        let mut best: Option<(f64, SVector<f64, N>)> = None;
        let mut total_iterations = 0;
        for attempt in 0..=budget.max_restarts {
            let q0 = match (attempt, seed_q) {
                (0, Some(q)) => {
                    self.check_inputs(goals, q)?;
                    self.clamp(q)
                }
                _ => {
                    let q = self.random_q(&mut rng);
                    if attempt == 0 {
                        self.check_inputs(goals, &q)?;
                    }
                    q
                }
            };
            let (q, iterations, ok) = self.lm(goals, q0, self.settings.cold_iterations, true);
            total_iterations += iterations;
            if ok {
                return Ok(self.solution(goals, q, total_iterations, attempt));
            }
            let cost = self.evaluate(goals, &q, false).cost;
            if best.as_ref().is_none_or(|(c, _)| cost < *c) {
                best = Some((cost, q));
            }
            if budget
                .time_limit
                .is_some_and(|limit| start_time.elapsed() >= limit)
            {
                break;
            }
        }
        let q = best.map_or_else(|| self.clamp(&SVector::zeros()), |(_, q)| q);
        Err(IkFailure {
            kind: FailureKind::NotConverged,
            best: Box::new(self.solution(goals, q, total_iterations, budget.max_restarts)),
        })
    }

    /// A joint vector drawn uniformly within the limits.
    pub fn random_q_from_seed(&self, seed: u64) -> SVector<f64, N> {
        self.random_q(&mut SplitMix64(seed))
    }

    fn random_q(&self, rng: &mut SplitMix64) -> SVector<f64, N> {
        SVector::from_fn(|i, _| {
            let lo = if self.lower[i].is_finite() {
                self.lower[i]
            } else {
                -UNBOUNDED_SAMPLE
            };
            let hi = if self.upper[i].is_finite() {
                self.upper[i]
            } else {
                UNBOUNDED_SAMPLE
            };
            lo + (hi - lo) * rng.next_f64()
        })
    }

    fn check_inputs(&self, goals: &[Goal<N>], q: &SVector<f64, N>) -> Result<(), IkFailure<N>> {
        let fail = |kind| {
            let q0 = SVector::from_fn(|i, _| {
                if q[i].is_finite() {
                    q[i].clamp(self.lower[i], self.upper[i])
                } else {
                    0.0f64.clamp(self.lower[i], self.upper[i])
                }
            });
            Err(IkFailure {
                kind,
                best: Box::new(self.solution(&[], q0, 0, 0)),
            })
        };
        if !q.iter().all(|v| v.is_finite()) {
            return fail(FailureKind::InvalidStart);
        }
        for (index, g) in goals.iter().enumerate() {
            if let Err(reason) = g.validate() {
                return fail(FailureKind::InvalidGoal { index, reason });
            }
        }
        Ok(())
    }

    /// Bounded Levenberg–Marquardt with Marquardt scaling; iterates are clamped into
    /// the joint limits. Returns the last iterate, the iterations spent and whether the
    /// goals are met.
    fn lm(
        &self,
        goals: &[Goal<N>],
        mut q: SVector<f64, N>,
        max_iterations: u32,
        abandon_slow: bool,
    ) -> (SVector<f64, N>, u32, bool) {
        let mut cur = self.evaluate(goals, &q, true);
        let mut lambda = self.settings.initial_damping;
        let mut it = 0;
        while it < max_iterations {
            if cur.satisfied {
                return (q, it, true);
            }
            it += 1;
            let mut accepted = false;
            for _ in 0..12 {
                let mut a = cur.h;
                for i in 0..N {
                    a[(i, i)] += lambda * (cur.h[(i, i)] + 1e-9);
                }
                let Some(chol) = a.cholesky() else {
                    lambda *= 10.0;
                    continue;
                };
                let step = -chol.solve(&cur.g);
                let q_new = self.clamp(&(q + step));
                let next = self.evaluate(goals, &q_new, true);
                if next.cost < cur.cost {
                    // Near a solution LM converges fast; slow progress after a few
                    // iterations means a local minimum or a limit: better to restart.
                    if abandon_slow
                        && it > self.settings.patience_iterations
                        && next.cost > self.settings.slow_progress_ratio * cur.cost
                    {
                        return (q_new, it, next.satisfied);
                    }
                    q = q_new;
                    cur = next;
                    lambda = (lambda * 0.3).max(1e-12);
                    accepted = true;
                    break;
                }
                lambda *= 5.0;
            }
            if !accepted {
                // Stuck in a local minimum or against a limit: give up this attempt.
                break;
            }
        }
        let ok = cur.satisfied;
        (q, it, ok)
    }

    /// Cost, normal equations (if `with_system`) and satisfaction at `q`.
    fn evaluate(&self, goals: &[Goal<N>], q: &SVector<f64, N>, with_system: bool) -> Eval<N> {
        let (tip, jac) = self.chain.end_pose_and_jacobian(q);
        let jv: SMatrix<f64, 3, N> = jac.fixed_rows::<3>(0).into_owned();
        let jw: SMatrix<f64, 3, N> = jac.fixed_rows::<3>(3).into_owned();
        let p = tip.translation.vector;
        let r = tip.rotation;
        let mut e = Eval {
            cost: 0.0,
            h: SMatrix::zeros(),
            g: SVector::zeros(),
            satisfied: true,
        };
        let tol_p = self.settings.position_tolerance_m;
        let tol_a = self.settings.orientation_tolerance_rad;
        let frames = self.frames_if_needed(goals, q);
        let add3 = |e: &mut Eval<N>, w: f64, res: Vector3<f64>, j: &SMatrix<f64, 3, N>| {
            e.cost += w * res.norm_squared();
            if with_system {
                let jt = j.transpose();
                e.h += (jt * j) * w;
                e.g += (jt * res) * w;
            }
        };
        for goal in goals {
            match goal {
                Goal::Pose {
                    target,
                    weight,
                    rotation_scale,
                } => {
                    let ep = p - target.translation.vector;
                    let er = rotation_error(&r, &target.rotation);
                    add3(&mut e, *weight, ep, &jv);
                    add3(&mut e, *weight * rotation_scale * rotation_scale, er, &jw);
                    e.satisfied &= ep.norm() <= tol_p && er.norm() <= tol_a;
                }
                Goal::Position { target, weight } => {
                    let ep = p - target;
                    add3(&mut e, *weight, ep, &jv);
                    e.satisfied &= ep.norm() <= tol_p;
                }
                Goal::Orientation { target, weight } => {
                    let er = rotation_error(&r, target);
                    add3(&mut e, *weight, er, &jw);
                    e.satisfied &= er.norm() <= tol_a;
                }
                Goal::Direction {
                    axis,
                    direction,
                    weight,
                } => {
                    let d = r * axis.into_inner();
                    let res = d - direction.into_inner();
                    let j = -skew(&d) * jw;
                    add3(&mut e, *weight, res, &j);
                    e.satisfied &= angle_between(&d, direction) <= tol_a;
                }
                Goal::LookAt {
                    axis,
                    point,
                    weight,
                } => {
                    let d = r * axis.into_inner();
                    let v = point - p;
                    let dist = v.norm();
                    if dist > 1e-9 {
                        let u = v / dist;
                        let res = d - u;
                        let j =
                            -skew(&d) * jw + (Matrix3::identity() - u * u.transpose()) / dist * jv;
                        add3(&mut e, *weight, res, &j);
                        e.satisfied &= angle_between(&d, &u) <= tol_a;
                    }
                }
                Goal::JointRegularization { reference, weight } => {
                    let res = q - reference;
                    e.cost += weight * res.norm_squared();
                    if with_system {
                        for i in 0..N {
                            e.h[(i, i)] += weight;
                        }
                        e.g += res * *weight;
                    }
                }
                Goal::FramePosition {
                    frame,
                    offset,
                    target,
                    weight,
                } => {
                    if let Some(f) = &frames {
                        let point = f.frames[*frame] * nalgebra::Point3::from(*offset);
                        let ep = point.coords - target;
                        let (jv_k, _) = self.frame_jacobian(f, *frame, &point.coords);
                        add3(&mut e, *weight, ep, &jv_k);
                        e.satisfied &= ep.norm() <= tol_p;
                    }
                }
                Goal::FrameDirection {
                    frame,
                    axis,
                    direction,
                    weight,
                } => {
                    if let Some(f) = &frames {
                        let fk = &f.frames[*frame];
                        let d = fk.rotation * axis.into_inner();
                        let res = d - direction.into_inner();
                        let (_, jw_k) = self.frame_jacobian(f, *frame, &fk.translation.vector);
                        let j = -skew(&d) * jw_k;
                        add3(&mut e, *weight, res, &j);
                        e.satisfied &= angle_between(&d, direction) <= tol_a;
                    }
                }
                Goal::MinDistance {
                    constraint,
                    min_distance_m,
                    weight,
                } => {
                    let d = self.distance(constraint.as_ref(), q);
                    let violation = (min_distance_m - d).max(0.0);
                    e.cost += weight * violation * violation;
                    e.satisfied &= d >= min_distance_m - tol_p;
                    if with_system && violation > 0.0 {
                        let h = self.settings.distance_fd_step;
                        let mut grad = SVector::<f64, N>::zeros();
                        for i in 0..N {
                            let mut qi = *q;
                            qi[i] += h;
                            let di = self.distance(constraint.as_ref(), &qi);
                            // d(violation)/dq_i = -(d_i - d)/h while active.
                            grad[i] = -(di - d) / h;
                        }
                        e.h += grad * grad.transpose() * *weight;
                        e.g += grad * (violation * weight);
                    }
                }
            }
        }
        e
    }

    /// The chain's frames at `q` when some goal needs them.
    fn frames_if_needed(&self, goals: &[Goal<N>], q: &SVector<f64, N>) -> Option<Frames> {
        let needed = goals
            .iter()
            .any(|g| matches!(g, Goal::FramePosition { .. } | Goal::FrameDirection { .. }));
        if !needed || N + 1 > MAX_FRAMES {
            return None;
        }
        let mut f = Frames {
            frames: [Isometry3::identity(); MAX_FRAMES],
        };
        self.chain
            .chain()
            .frames_into(q.as_slice(), &mut f.frames[..=N])
            .ok()?;
        Some(f)
    }

    /// Linear (of `point`, base frame) and angular Jacobians of frame `k`: the joints
    /// up to `k` move it, the others do not.
    fn frame_jacobian(
        &self,
        f: &Frames,
        k: usize,
        point: &Vector3<f64>,
    ) -> (SMatrix<f64, 3, N>, SMatrix<f64, 3, N>) {
        let mut jv = SMatrix::<f64, 3, N>::zeros();
        let mut jw = SMatrix::<f64, 3, N>::zeros();
        for (j, joint) in self.chain.joints().iter().enumerate().take((k + 1).min(N)) {
            let frame = &f.frames[j];
            let axis = frame.rotation * joint.axis.into_inner();
            if joint.prismatic {
                jv.set_column(j, &axis);
            } else {
                jw.set_column(j, &axis);
                jv.set_column(j, &axis.cross(&(point - frame.translation.vector)));
            }
        }
        (jv, jw)
    }

    fn distance(&self, constraint: &dyn DistanceConstraint<N>, q: &SVector<f64, N>) -> f64 {
        let mut frames = [Isometry3::identity(); MAX_FRAMES];
        let frames = &mut frames[..(N + 1).min(MAX_FRAMES)];
        if self
            .chain
            .chain()
            .frames_into(q.as_slice(), frames)
            .is_err()
        {
            return f64::NEG_INFINITY;
        }
        constraint.distance(frames)
    }

    /// Builds the full report at `q`.
    fn solution(
        &self,
        goals: &[Goal<N>],
        q: SVector<f64, N>,
        iterations: u32,
        restarts: u32,
    ) -> Solution<N> {
        let tip = self.chain.end_pose(&q);
        let p = tip.translation.vector;
        let r = tip.rotation;
        let tol_p = self.settings.position_tolerance_m;
        let tol_a = self.settings.orientation_tolerance_rad;
        let frames = self.frames_if_needed(goals, &q);
        let mut residuals = Vec::with_capacity(goals.len());
        for (i, goal) in goals.iter().enumerate() {
            let (pos, ang, cost) = match goal {
                Goal::Pose {
                    target,
                    weight,
                    rotation_scale,
                } => {
                    let ep = (p - target.translation.vector).norm();
                    let er = rotation_error(&r, &target.rotation).norm();
                    (ep, er, weight * (ep * ep + (rotation_scale * er).powi(2)))
                }
                Goal::Position { target, weight } => {
                    let ep = (p - target).norm();
                    (ep, 0.0, weight * ep * ep)
                }
                Goal::Orientation { target, weight } => {
                    let er = rotation_error(&r, target).norm();
                    (0.0, er, weight * er * er)
                }
                Goal::Direction {
                    axis,
                    direction,
                    weight,
                } => {
                    let d = r * axis.into_inner();
                    (
                        0.0,
                        angle_between(&d, direction),
                        weight * (d - direction.into_inner()).norm_squared(),
                    )
                }
                Goal::LookAt {
                    axis,
                    point,
                    weight,
                } => {
                    let d = r * axis.into_inner();
                    let v = point - p;
                    if v.norm() > 1e-9 {
                        let u = v.normalize();
                        (0.0, angle_between(&d, &u), weight * (d - u).norm_squared())
                    } else {
                        (0.0, 0.0, 0.0)
                    }
                }
                Goal::JointRegularization { reference, weight } => {
                    (0.0, 0.0, weight * (q - reference).norm_squared())
                }
                Goal::FramePosition {
                    frame,
                    offset,
                    target,
                    weight,
                } => match &frames {
                    Some(f) => {
                        let point = f.frames[*frame] * nalgebra::Point3::from(*offset);
                        let ep = (point.coords - target).norm();
                        (ep, 0.0, weight * ep * ep)
                    }
                    None => (f64::INFINITY, 0.0, f64::INFINITY),
                },
                Goal::FrameDirection {
                    frame,
                    axis,
                    direction,
                    weight,
                } => match &frames {
                    Some(f) => {
                        let d = f.frames[*frame].rotation * axis.into_inner();
                        (
                            0.0,
                            angle_between(&d, direction),
                            weight * (d - direction.into_inner()).norm_squared(),
                        )
                    }
                    None => (0.0, f64::INFINITY, f64::INFINITY),
                },
                Goal::MinDistance {
                    constraint,
                    min_distance_m,
                    weight,
                } => {
                    let d = self.distance(constraint.as_ref(), &q);
                    let v = (min_distance_m - d).max(0.0);
                    (v, 0.0, weight * v * v)
                }
            };
            let satisfied = match goal {
                Goal::JointRegularization { .. } => true,
                _ => pos <= tol_p && ang <= tol_a,
            };
            residuals.push(GoalResidual {
                goal: i,
                position_m: pos,
                angle_rad: ang,
                cost,
                satisfied,
            });
        }
        Solution {
            position_error_m: residuals.iter().map(|r| r.position_m).fold(0.0, f64::max),
            orientation_error_rad: residuals.iter().map(|r| r.angle_rad).fold(0.0, f64::max),
            cost: residuals.iter().map(|r| r.cost).sum(),
            q,
            tip,
            residuals,
            iterations,
            restarts,
        }
    }
}

/// Rotation vector (axis x angle, base frame) taking `target` to `current`.
fn rotation_error(current: &UnitQuaternion<f64>, target: &UnitQuaternion<f64>) -> Vector3<f64> {
    (current * target.inverse()).scaled_axis()
}

fn angle_between(a: &Vector3<f64>, b: &Vector3<f64>) -> f64 {
    // atan2 of |a x b| and a.b is accurate for small angles, unlike acos.
    a.cross(b).norm().atan2(a.dot(b))
}

fn skew(v: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0)
}

/// SplitMix64: a tiny, fast, seedable generator (enough for sampling start vectors).
struct SplitMix64(u64);

impl SplitMix64 {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    fn next_f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
}
