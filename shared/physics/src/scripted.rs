//! A scripted grasp for the tests and the benchmark: a cube under the palm of the arm's
//! zero posture (palm down, fingers forward), the fingers closed by a joint PD loop at
//! the simulation rate (the Shadow hand's own position loop), the arm lifting it through
//! the driver's velocity loop and carrying it sideways; optionally putting it down there,
//! letting go and returning to the starting posture (a whole pick-and-place job). No
//! operator and no controller node: it exercises the world alone.

use nalgebra::Point3;
use teleop_kinematics::Robot;

use crate::error::PhysicsError;
use crate::scene::{SceneSpec, TableSpec, cube};
use crate::world::{ARM_DOF, HAND_DOF, PhysicsConfig, PhysicsWorld, RobotParams};

/// Where the cube sits relative to the palm of the zero posture.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CubeUnderPalm {
    /// Side of the cube, m.
    pub side_m: f64,
    /// Gap between the palm's surface and the cube's top, m.
    pub gap_m: f64,
    /// Offset of the cube's centre from the palm origin along the fingers, m.
    pub along_fingers_m: f64,
}

impl Default for CubeUnderPalm {
    fn default() -> Self {
        Self {
            side_m: 0.05,
            gap_m: 0.004,
            along_fingers_m: 0.05,
        }
    }
}

/// The palm's half thickness in the description (its collision box is 24 mm), m.
const PALM_HALF_THICKNESS_M: f64 = 0.012;

impl CubeUnderPalm {
    /// The world: the robot at its zero posture, a table whose top carries the cube at
    /// the set gap below the palm.
    ///
    /// # Errors
    /// The robot description lacks the palm link.
    pub fn config(&self, robot: &Robot) -> Result<PhysicsConfig, PhysicsError> {
        let mut state = robot.new_state();
        let palm_id = robot
            .link_id(teleop_kinematics::robots::shadow::PALM)
            .map_err(|e| PhysicsError::Model(e.to_string()))?;
        robot
            .update(&mut state, &vec![0.0; robot.dof()])
            .map_err(|e| PhysicsError::Model(e.to_string()))?;
        let palm = robot.link_pose(&state, palm_id);
        // The palm faces -y of its frame (down at the zero posture).
        let centre = palm
            * Point3::new(
                0.0,
                -(PALM_HALF_THICKNESS_M + self.side_m / 2.0 + self.gap_m),
                self.along_fingers_m,
            );
        let top = centre.z - self.side_m / 2.0;
        Ok(PhysicsConfig {
            robot: RobotParams::default(),
            scene: SceneSpec {
                table: Some(TableSpec {
                    top_z_m: top,
                    centre_xy_m: [centre.x, centre.y],
                    ..TableSpec::default()
                }),
                objects: vec![cube("cube", self.side_m, [centre.x, centre.y], top)],
            },
            timestep_s: 0.001,
            arm_initial_rad: [0.0; ARM_DOF],
            hand_initial_rad: [0.0; HAND_DOF],
        })
    }
}

/// The script: close the hand, lift, carry, hold; with `place_and_return`, after the
/// carry: lower (as long as the lift), open (as long as the closing), raise, carry back,
/// lower, hold.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GraspLiftCarry {
    /// Close the fingers at all (false: the same arm motion with the hand open).
    pub close_hand: bool,
    /// Closing starts here and takes `close_s`, s.
    pub close_start_s: f64,
    pub close_s: f64,
    /// Final J3 and J2 of the four fingers, rad.
    pub finger_flex_rad: f64,
    /// Final THJ5, THJ4, THJ2, rad.
    pub thumb_rad: [f64; 3],
    /// The hand loop's gains, N m/rad and N m s/rad.
    pub kp: f64,
    pub kd: f64,
    /// Shoulder lift velocity (negative raises the arm) over `lift_s`, rad/s.
    pub lift_start_s: f64,
    pub lift_s: f64,
    pub lift_rad_s: f64,
    /// Shoulder pan velocity over `carry_s` after the lift, rad/s.
    pub carry_s: f64,
    pub carry_rad_s: f64,
    /// Put the cube down after the carry, let go and go back to the start.
    pub place_and_return: bool,
}

impl Default for GraspLiftCarry {
    fn default() -> Self {
        Self {
            close_hand: true,
            close_start_s: 0.2,
            close_s: 1.0,
            finger_flex_rad: 1.3,
            thumb_rad: [0.6, 1.1, 0.3],
            kp: 2.0,
            kd: 0.05,
            lift_start_s: 1.5,
            lift_s: 1.5,
            lift_rad_s: -0.2,
            carry_s: 1.5,
            carry_rad_s: 0.3,
            place_and_return: false,
        }
    }
}

impl GraspLiftCarry {
    /// The hand's joint targets at time `t_s`.
    #[must_use]
    pub fn hand_targets(&self, t_s: f64) -> [f64; HAND_DOF] {
        let mut target = [0.0; HAND_DOF];
        if !self.close_hand {
            return target;
        }
        let mut c = ((t_s - self.close_start_s) / self.close_s).clamp(0.0, 1.0);
        if self.place_and_return {
            let open_start = self.carry_end_s() + self.lift_s;
            c -= ((t_s - open_start) / self.close_s).clamp(0.0, 1.0);
        }
        // FF, MF, RF: J4 J3 J2 at 0..3, 3..6, 6..9; LF: J5 J4 J3 J2 at 9..13; TH 13..17.
        for j3 in [1, 4, 7, 11] {
            target[j3] = self.finger_flex_rad * c;
            target[j3 + 1] = self.finger_flex_rad * c;
        }
        target[13] = self.thumb_rad[0] * c;
        target[14] = self.thumb_rad[1] * c;
        target[16] = self.thumb_rad[2] * c;
        target
    }

    fn carry_end_s(&self) -> f64 {
        self.lift_start_s + self.lift_s + self.carry_s
    }

    /// When the script's last motion ends, s.
    #[must_use]
    pub fn end_s(&self) -> f64 {
        if self.place_and_return {
            // lower, open, raise, carry back, lower
            self.carry_end_s() + 3.0 * self.lift_s + self.close_s + self.carry_s
        } else {
            self.carry_end_s()
        }
    }

    /// The arm's velocity command at time `t_s`.
    #[must_use]
    pub fn arm_velocity(&self, t_s: f64) -> [f64; ARM_DOF] {
        let mut v = [0.0; ARM_DOF];
        let mut phases = vec![
            (self.lift_s, 1, self.lift_rad_s),
            (self.carry_s, 0, self.carry_rad_s),
        ];
        if self.place_and_return {
            phases.extend([
                (self.lift_s, 1, -self.lift_rad_s),
                (self.close_s, 0, 0.0),
                (self.lift_s, 1, self.lift_rad_s),
                (self.carry_s, 0, -self.carry_rad_s),
                (self.lift_s, 1, -self.lift_rad_s),
            ]);
        }
        let mut from = self.lift_start_s;
        for (duration, joint, speed) in phases {
            if (from..from + duration).contains(&t_s) {
                v[joint] = speed;
            }
            from += duration;
        }
        v
    }

    /// One step of the script on `world`: the hand loop, the arm command, the step.
    ///
    /// # Errors
    /// From [`PhysicsWorld::step`].
    pub fn step(&self, world: &mut PhysicsWorld) -> Result<(), PhysicsError> {
        let t = world.time_s();
        let target = self.hand_targets(t);
        let q = world.hand_position();
        let v = world.hand_velocity();
        let tau: [f64; HAND_DOF] =
            std::array::from_fn(|i| self.kp * (target[i] - q[i]) - self.kd * v[i]);
        world.set_hand_torques(&tau)?;
        world.command_arm_velocity(&self.arm_velocity(t))?;
        world.step()
    }
}
