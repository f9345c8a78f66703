//! Which grasp of the pick scene's can holds? The world alone (no operator, no network):
//! the arm is put at a posture, the can stands on a table where the grasp would find it
//! relative to the palm, the hand closes to the Shadow targets a human synergy retargets
//! to (the labels the hand network is trained on) through a PD loop with an effort
//! limit, the arm lifts (shoulder lift) and carries (shoulder pan), then holds still; the
//! can's rise and tilt after the closing, the lift and the hold are printed per
//! candidate, and how many still held it 10 cm up at the end.
//!
//! Candidates: the top grasp from the pick job's start posture
//! (`teleop_sim::PICK_TOP_GRASP_POSTURE_RAD`: the can's axis 6-9 cm along the fingers,
//! its top 0-3 cm below the palm, 1 cm to either side) and the side grasp from the
//! posture searched earlier (docs/physics.md), for the power, power/precision and
//! precision postures.
//!
//!     cargo run --release -p teleop-sim --example grasp_study [-- NAME-FILTER]
//!
//! With a filter (a part of the candidates' names) it also prints the can's motion
//! every 0.25 s. Environment: `GRASP_HOLD_S` (default 10), `GRASP_KP` (N m/rad, default
//! 10), `GRASP_MAX_EFFORT` (N m, default 1), `GRASP_JITTER` (rad: the targets change
//! every 1/30 s by up to this much, as the hand network's estimates do),
//! `GRASP_TARGETS` (17 angles, rad: one more posture, e.g. what the hand network sent
//! in a run), `GRASP_IMPRATIO` (MuJoCo's `impratio` instead of the default),
//! `GRASP_FK=FILE` (instead: the palm's turn over a recorded run's arm joint states,
//! lines of a time and 7 angles), `GRASP_OBJECT` (another object than the can, its top
//! where the can's would be: `box:HX,HY,HZ` half extents or `cylinder:R,HH`, m; its
//! mass that of wood, 600 kg/m^3).

use nalgebra::{Isometry3, Point3, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use teleop_hand_model::human::HumanHand;
use teleop_hand_model::retarget::{RetargetSettings, Retargeter};
use teleop_hand_model::sampling::Synergy;
use teleop_kinematics::robots;
use teleop_physics::scene::{ObjectShape, ObjectSpec, SceneSpec, TableSpec, can};
use teleop_physics::world::{ARM_DOF, HAND_DOF, PhysicsConfig, PhysicsWorld, RobotParams};

const KD: f64 = 0.1;

/// `name` from the environment as a number, or `default`.
fn env_f64(name: &str, default: f64) -> f64 {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse::<f64>().ok())
        .unwrap_or(default)
}

/// The study's settings, read from the environment once.
struct Settings {
    /// The hand's steady grasp loop: the adaptive controller's stiffness ends near its
    /// maximum against an object and its effort at the hold limit. N m/rad, N m.
    kp: f64,
    max_effort: f64,
    /// The targets change every 1/30 s by up to this much, rad.
    jitter: f64,
    hold_s: f64,
    robot: RobotParams,
    /// The object grasped, placed with its centre at the origin on a table at z = 0.
    object: ObjectSpec,
}

/// `GRASP_OBJECT`: `box:HX,HY,HZ` or `cylinder:R,HH` (m), wood; the can without it.
fn object_from_env() -> anyhow::Result<ObjectSpec> {
    let Ok(spec) = std::env::var("GRASP_OBJECT") else {
        return Ok(can("can", [0.0; 2], 0.0));
    };
    let (kind, sizes) = spec
        .split_once(':')
        .ok_or_else(|| anyhow::anyhow!("GRASP_OBJECT {spec:?}: expected KIND:SIZES"))?;
    let v: Vec<f64> = sizes
        .split(',')
        .map(|x| x.trim().parse::<f64>())
        .collect::<Result<_, _>>()?;
    let (shape, volume) = match (kind, v.as_slice()) {
        ("box", [x, y, z]) => (
            ObjectShape::Box {
                half_m: [*x, *y, *z],
            },
            8.0 * x * y * z,
        ),
        ("cylinder", [r, h]) => (
            ObjectShape::Cylinder {
                radius_m: *r,
                half_height_m: *h,
            },
            std::f64::consts::PI * r * r * 2.0 * h,
        ),
        _ => anyhow::bail!("GRASP_OBJECT {spec:?}: box:HX,HY,HZ or cylinder:R,HH"),
    };
    Ok(ObjectSpec {
        name: "object".to_owned(),
        shape,
        mass_kg: 600.0 * volume,
        friction: 0.8,
        position_m: [0.0, 0.0, shape.half_height_m()],
        yaw_rad: 0.0,
        free: true,
        rgba: [0.2, 0.6, 0.2, 1.0],
    })
}

impl Settings {
    fn from_env() -> anyhow::Result<Self> {
        let mut robot = RobotParams::default();
        robot.impratio = env_f64("GRASP_IMPRATIO", robot.impratio);
        Ok(Self {
            kp: env_f64("GRASP_KP", 10.0),
            max_effort: env_f64("GRASP_MAX_EFFORT", 1.0),
            jitter: env_f64("GRASP_JITTER", 0.0),
            hold_s: env_f64("GRASP_HOLD_S", 10.0),
            robot,
            object: object_from_env()?,
        })
    }
}

/// The palm's pose at arm posture `arm` (the robot's other joints neutral).
fn palm_pose(
    robot: &teleop_kinematics::Robot,
    arm: &[f64; ARM_DOF],
) -> anyhow::Result<Isometry3<f64>> {
    let mut q = robot.neutral_positions();
    for (i, name) in teleop_interfaces::joints::PR2_ARM_JOINTS.iter().enumerate() {
        q[robot.dof_index(name)?] = arm[i];
    }
    let mut kin = robot.new_state();
    robot.update(&mut kin, &q)?;
    Ok(robot.link_pose(&kin, robot.link_id(robots::shadow::PALM)?))
}

/// How far an object's axis leans from the vertical, deg.
fn tilt_deg(p: &Isometry3<f64>) -> f64 {
    (p.rotation * Vector3::z())
        .angle(&Vector3::z())
        .to_degrees()
}

struct Candidate {
    name: String,
    arm: [f64; ARM_DOF],
    /// The can's centre in the palm frame (-y out of the palm, z along the fingers), m.
    can_in_palm: [f64; 3],
    /// Moved down (world) from there, m.
    below_m: f64,
    targets: [f64; HAND_DOF],
}

fn shadow_targets(
    hand: &HumanHand,
    retargeter: &Retargeter,
    a: Synergy,
    b: Synergy,
    t: f64,
    closure: f64,
) -> anyhow::Result<[f64; HAND_DOF]> {
    let pose = a.posture().lerp(&b.posture(), t);
    let pose = Synergy::Open.posture().lerp(&pose, closure);
    Ok(retargeter.retarget(&hand.keypoints(&pose), None)?.joints)
}

fn run(
    robot: &teleop_kinematics::Robot,
    settings: &Settings,
    c: &Candidate,
    open: &[f64; HAND_DOF],
    trace: bool,
) -> anyhow::Result<(String, f64)> {
    let palm = palm_pose(robot, &c.arm)?;
    let centre = palm * Point3::from(Vector3::from(c.can_in_palm)) - Vector3::z() * c.below_m;
    // The object's top where the can's would be.
    let half = settings.object.shape.half_height_m();
    let centre = centre + Vector3::z() * (can("can", [0.0; 2], 0.0).shape.half_height_m() - half);
    let top = centre.z - half;
    let config = PhysicsConfig {
        robot: settings.robot.clone(),
        scene: SceneSpec {
            table: Some(TableSpec {
                top_z_m: top,
                centre_xy_m: [centre.x, centre.y],
                ..TableSpec::default()
            }),
            objects: vec![ObjectSpec {
                position_m: [centre.x, centre.y, centre.z],
                ..settings.object.clone()
            }],
        },
        timestep_s: 0.001,
        arm_initial_rad: c.arm,
        hand_initial_rad: *open,
    };
    let mut world = PhysicsWorld::new(robot, &config)?;
    if trace {
        let n = palm.rotation * -Vector3::y();
        let f = palm.rotation * Vector3::z();
        println!(
            "  palm faces [{:.2} {:.2} {:.2}], fingers [{:.2} {:.2} {:.2}]",
            n.x, n.y, n.z, f.x, f.y, f.z
        );
    }
    let can_pose = |w: &PhysicsWorld| w.object_poses()[0].1;
    let start = can_pose(&world);
    let (close_s, lift_s, carry_s) = (2.5, 1.5, 1.5);
    let mut settled_after_close = None;
    let mut lifted = None;
    let end_s = 0.3 + close_s + 0.5 + lift_s + carry_s + settings.hold_s;
    // The targets' frame-to-frame change, as the hand network's estimates (30 Hz).
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let mut noise = [0.0; HAND_DOF];
    let mut frame = -1.0;
    while world.time_s() < end_s {
        let t = world.time_s();
        let s = ((t - 0.3) / close_s).clamp(0.0, 1.0);
        if (t * 30.0).floor() > frame {
            frame = (t * 30.0).floor();
            noise = std::array::from_fn(|_| settings.jitter * rng.random_range(-1.0..=1.0));
        }
        let target: [f64; HAND_DOF] =
            std::array::from_fn(|i| open[i] + (c.targets[i] - open[i] + noise[i]) * s);
        let hq = world.hand_position();
        let hv = world.hand_velocity();
        let (kp, max_effort) = (settings.kp, settings.max_effort);
        let tau: [f64; HAND_DOF] = std::array::from_fn(|i| {
            (kp * (target[i] - hq[i]) - KD * hv[i]).clamp(-max_effort, max_effort)
        });
        world.set_hand_torques(&tau)?;
        let lift_from = 0.3 + close_s + 0.5;
        let mut v = [0.0; ARM_DOF];
        if (lift_from..lift_from + lift_s).contains(&t) {
            v[1] = -0.2;
        } else if (lift_from + lift_s..lift_from + lift_s + carry_s).contains(&t) {
            v[0] = 0.2;
        }
        world.command_arm_velocity(&v)?;
        world.step()?;
        if trace && (world.time_s() * 1000.0).round() as i64 % 250 == 0 {
            let p = can_pose(&world);
            let d = p.translation.vector - start.translation.vector;
            let palm_now = world.body_pose(robots::shadow::PALM)?;
            let local = palm_now.inverse() * Point3::from(p.translation.vector);
            println!(
                "  t {:5.2} can moved [{:6.1} {:6.1} {:6.1}] mm tilt {:5.1} | in palm [{:6.3} {:6.3} {:6.3}] | contacts {} tips {:?}",
                world.time_s(),
                d.x * 1e3,
                d.y * 1e3,
                d.z * 1e3,
                tilt_deg(&p),
                local.x,
                local.y,
                local.z,
                world.contact_count(),
                world
                    .fingertip_forces_n()
                    .map(|f| (f * 10.0).round() / 10.0)
            );
        }
        if settled_after_close.is_none() && world.time_s() >= lift_from {
            settled_after_close = Some(can_pose(&world));
        }
        if lifted.is_none() && world.time_s() >= lift_from + lift_s {
            lifted = Some(can_pose(&world));
        }
    }
    let closed = settled_after_close.unwrap_or(start);
    let lifted = lifted.unwrap_or(start);
    let end = can_pose(&world);
    let push = (closed.translation.vector - start.translation.vector).norm() * 1000.0;
    let line = format!(
        "{:<44} closed: pushed {:5.1} mm tilt {:5.1} deg | lifted {:6.1} mm tilt {:5.1} | end rise {:6.1} mm tilt {:5.1}",
        c.name,
        push,
        tilt_deg(&closed),
        (lifted.translation.z - start.translation.z) * 1000.0,
        tilt_deg(&lifted),
        (end.translation.z - start.translation.z) * 1000.0,
        tilt_deg(&end),
    );
    Ok((line, end.translation.z - start.translation.z))
}

/// `GRASP_FK=FILE`: lines of a time and the 7 arm joint angles (rad, a recorded run's
/// joint states); prints the palm's turn from the first line's and where it faces.
fn palm_turns(robot: &teleop_kinematics::Robot, path: &str) -> anyhow::Result<()> {
    let mut first: Option<nalgebra::UnitQuaternion<f64>> = None;
    for line in std::fs::read_to_string(path)?.lines() {
        let v: Vec<f64> = line
            .split_whitespace()
            .map(str::parse::<f64>)
            .collect::<Result<_, _>>()?;
        if v.len() != 8 {
            anyhow::bail!("{path}: expected a time and 7 angles per line: {line}");
        }
        let arm: [f64; ARM_DOF] = std::array::from_fn(|i| v[i + 1]);
        let palm = palm_pose(robot, &arm)?;
        let r0 = *first.get_or_insert(palm.rotation);
        let n = palm.rotation * -Vector3::y();
        let f = palm.rotation * Vector3::z();
        println!(
            "{:6.2} palm [{:.3} {:.3} {:.3}] turned {:5.1} deg, faces [{:.2} {:.2} {:.2}], fingers [{:.2} {:.2} {:.2}]",
            v[0],
            palm.translation.x,
            palm.translation.y,
            palm.translation.z,
            (r0.inverse() * palm.rotation).angle().to_degrees(),
            n.x,
            n.y,
            n.z,
            f.x,
            f.y,
            f.z
        );
    }
    Ok(())
}

fn main() -> anyhow::Result<()> {
    let robot = robots::pr2_arm()?;
    if let Ok(path) = std::env::var("GRASP_FK") {
        return palm_turns(&robot, &path);
    }
    let settings = Settings::from_env()?;
    let hand = HumanHand::average();
    let retargeter = Retargeter::new(RetargetSettings::default())?;
    let open = shadow_targets(&hand, &retargeter, Synergy::Open, Synergy::Open, 0.0, 1.0)?;
    let fmt = |j: &[f64; HAND_DOF]| {
        j.iter()
            .map(|v| format!("{v:.2}"))
            .collect::<Vec<_>>()
            .join(" ")
    };
    println!("open      {}", fmt(&open));
    let mut postures = Vec::new();
    for (a, b, t, closure) in [
        (Synergy::Power, Synergy::Power, 0.0, 0.6),
        (Synergy::Power, Synergy::Power, 0.0, 0.8),
        (Synergy::Power, Synergy::Power, 0.0, 1.0),
        (Synergy::Power, Synergy::Precision, 0.5, 1.0),
        (Synergy::Precision, Synergy::Precision, 0.0, 1.0),
    ] {
        let j = shadow_targets(&hand, &retargeter, a, b, t, closure)?;
        let name = format!("{}-{}{:.1} c{closure:.1}", a.name(), b.name(), t);
        println!("{name:<28} {}", fmt(&j));
        postures.push((name, j));
    }
    // `GRASP_TARGETS`: 17 comma-separated joint targets (rad) tried as one more posture,
    // e.g. the hand network's output recorded during a run.
    if let Ok(list) = std::env::var("GRASP_TARGETS") {
        let v: Vec<f64> = list
            .split(',')
            .map(|x| x.trim().parse::<f64>())
            .collect::<Result<_, _>>()?;
        let j: [f64; HAND_DOF] = v
            .try_into()
            .map_err(|_| anyhow::anyhow!("GRASP_TARGETS must hold {HAND_DOF} angles"))?;
        postures.push(("given".to_owned(), j));
    }
    let mut candidates = Vec::new();
    // The top grasp from the searched start posture (fingers 20 deg up, turned 15 deg):
    // the can's axis `along` the fingers from the palm's origin, its top 1 cm below the
    // palm's surface there, and around that by a few mm to cm.
    let p20 = teleop_sim::PICK_TOP_GRASP_POSTURE_RAD;
    for (pname, targets) in &postures {
        for along in [0.06, 0.075, 0.09] {
            for (dx, dz) in [
                (0.0, 0.0),
                (0.0, 0.01),
                (0.0, 0.02),
                (0.0, -0.005),
                (0.0, -0.01),
                (0.01, 0.0),
                (-0.01, 0.0),
            ] {
                candidates.push(Candidate {
                    name: format!("p20 z{along:.3} x{dx:+.2} h{dz:+.3} {pname}"),
                    arm: p20,
                    can_in_palm: [dx, -0.017, along],
                    below_m: 0.125 + dz,
                    targets: *targets,
                });
            }
        }
        // The side grasp from the earlier searched posture (docs/physics.md).
        for along in [0.07, 0.10] {
            candidates.push(Candidate {
                name: format!("side z{along:.2} {pname}"),
                arm: [-0.577, 0.272, -1.338, -1.323, -3.466, -0.15, -0.166],
                can_in_palm: [0.0, -0.052, along],
                below_m: 0.0,
                targets: *targets,
            });
        }
    }
    let only = std::env::args().nth(1);
    let (mut tried, mut held) = (0, 0);
    for c in &candidates {
        if only.as_ref().is_some_and(|o| !c.name.contains(o.as_str())) {
            continue;
        }
        tried += 1;
        match run(&robot, &settings, c, &open, only.is_some()) {
            Ok((line, rise_m)) => {
                // Held: still 10 cm up at the end of the hold.
                if rise_m > 0.1 {
                    held += 1;
                }
                println!("{line}");
            }
            Err(e) => println!("{:<44} error: {e}", c.name),
        }
    }
    println!("held at the end: {held} of {tried}");
    Ok(())
}
