//! Forward kinematics cross-checked against an independent implementation: the `k`
//! crate (openrr), which parses the same URDF files with its own urdf-rs (0.9) and
//! evaluates them with its own tree (on nalgebra 0.30; values cross at the test
//! boundary as plain `f64`s).
//!
//! Every link pose of every robot must agree to 1e-9 (m for translation, and for each
//! rotation-matrix entry) on 10,000 seeded random configurations drawn inside the
//! joint limits (continuous joints: [-pi, pi]).

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use teleop_kinematics::{KinematicState, LinkId, Robot, robots};

const CONFIGS: usize = 10_000;
const TOL: f64 = 1e-9;

fn urdf_path(file: &str) -> String {
    format!("{}/urdf/{file}", env!("CARGO_MANIFEST_DIR"))
}

/// A pose as plain numbers: translation, then the rotation matrix row by row.
fn ours(p: &nalgebra::Isometry3<f64>) -> [f64; 12] {
    let r = p.rotation.to_rotation_matrix();
    let m = r.matrix();
    let t = p.translation.vector;
    [
        t.x,
        t.y,
        t.z,
        m[(0, 0)],
        m[(0, 1)],
        m[(0, 2)],
        m[(1, 0)],
        m[(1, 1)],
        m[(1, 2)],
        m[(2, 0)],
        m[(2, 1)],
        m[(2, 2)],
    ]
}

/// The same from k's nalgebra 0.30 types.
fn theirs(p: &k::nalgebra::Isometry3<f64>) -> [f64; 12] {
    let r = p.rotation.to_rotation_matrix();
    let m = r.matrix();
    let t = p.translation.vector;
    [
        t.x,
        t.y,
        t.z,
        m[(0, 0)],
        m[(0, 1)],
        m[(0, 2)],
        m[(1, 0)],
        m[(1, 1)],
        m[(1, 2)],
        m[(2, 0)],
        m[(2, 1)],
        m[(2, 2)],
    ]
}

fn random_positions(robot: &Robot, rng: &mut ChaCha8Rng, out: &mut [f64]) {
    for (o, l) in out.iter_mut().zip(robot.dof_limits()) {
        let (lo, hi) = if l.is_bounded() {
            (l.lower, l.upper)
        } else {
            (-std::f64::consts::PI, std::f64::consts::PI)
        };
        *o = rng.random_range(lo..=hi);
    }
}

/// Returns (configurations checked, links per configuration, worst difference).
fn cross_check(file: &str, robot: &Robot, seed: u64) -> (usize, usize, f64) {
    let kchain = k::Chain::<f64>::from_urdf_file(urdf_path(file)).expect("k loads the URDF");
    // Map our DoF order onto k's joint order by name.
    let k_names: Vec<String> = kchain.iter_joints().map(|j| j.name.clone()).collect();
    assert_eq!(k_names.len(), robot.dof(), "k and we count the same DoF");
    let k_to_ours: Vec<usize> = k_names
        .iter()
        .map(|n| robot.dof_index(n).expect("joint known to both"))
        .collect();
    let links: Vec<(LinkId, &k::Node<f64>)> = robot
        .links()
        .iter()
        .map(|l| {
            let node = kchain
                .find_link(&l.name)
                .unwrap_or_else(|| panic!("k has link {}", l.name));
            (robot.link_id(&l.name).expect("own link"), node)
        })
        .inspect(|(id, _)| assert!(id.index() < robot.links().len()))
        .collect();
    assert_eq!(links.len(), robot.links().len());

    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut q = vec![0.0; robot.dof()];
    let mut qk = vec![0.0; robot.dof()];
    let mut state: KinematicState = robot.new_state();
    let mut worst = 0.0_f64;
    for _ in 0..CONFIGS {
        random_positions(robot, &mut rng, &mut q);
        for (dst, &src) in qk.iter_mut().zip(&k_to_ours) {
            *dst = q[src];
        }
        kchain.set_joint_positions_unchecked(&qk);
        kchain.update_transforms();
        robot.update(&mut state, &q).expect("right length");
        for (id, node) in &links {
            let a = ours(&robot.link_pose(&state, *id));
            let b = theirs(&node.world_transform().expect("updated"));
            for (x, y) in a.iter().zip(&b) {
                let d = (x - y).abs();
                worst = worst.max(d);
                assert!(
                    d <= TOL,
                    "{file}: link {} differs by {d:e} at q = {q:?}",
                    robot.link(*id).name
                );
            }
        }
    }
    (CONFIGS, links.len(), worst)
}

#[test]
fn ur5_matches_k_on_10000_configurations() {
    let robot = robots::ur5().expect("embedded URDF");
    let (n, links, worst) = cross_check("ur5.urdf", &robot, 0x05);
    eprintln!("ur5: {n} configurations x {links} links, worst difference {worst:e}");
}

#[test]
fn pr2_arm_with_hand_matches_k_on_10000_configurations() {
    let robot = robots::pr2_arm().expect("embedded URDF");
    assert_eq!(robot.dof(), 5 + 19);
    let (n, links, worst) = cross_check("pr2_right_arm_shadow.urdf", &robot, 0x72);
    eprintln!("pr2: {n} configurations x {links} links, worst difference {worst:e}");
}

#[test]
fn shadow_hand_matches_k_on_10000_configurations() {
    let robot = robots::shadow_hand().expect("embedded URDF");
    let (n, links, worst) = cross_check("shadow_hand.urdf", &robot, 0x5ad0);
    eprintln!("shadow: {n} configurations x {links} links, worst difference {worst:e}");
}

/// The fixed-size 7-joint chain (what the arm IK evaluates) against k's serial chain
/// from `base_link` to `rh_palm`.
#[test]
fn pr2_seven_joint_chain_matches_k_serial_chain() {
    let chain = robots::pr2_arm_chain().expect("embedded URDF");
    let kchain = k::Chain::<f64>::from_urdf_file(urdf_path("pr2_right_arm_shadow.urdf"))
        .expect("k loads the URDF");
    let end = kchain.find_link("rh_palm").expect("palm");
    let serial = k::SerialChain::from_end(end);
    let names: Vec<String> = serial.iter_joints().map(|j| j.name.clone()).collect();
    assert_eq!(
        names,
        teleop_interfaces::joints::PR2_ARM_JOINTS
            .map(String::from)
            .to_vec(),
        "same 7 joints in the same order"
    );
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let limits: Vec<_> = chain.chain().limits().collect();
    for _ in 0..CONFIGS {
        let q = nalgebra::SVector::<f64, 7>::from_fn(|i, _| {
            let l = limits[i];
            if l.is_bounded() {
                rng.random_range(l.lower..=l.upper)
            } else {
                rng.random_range(-std::f64::consts::PI..=std::f64::consts::PI)
            }
        });
        serial.set_joint_positions_unchecked(q.as_slice());
        let a = ours(&chain.end_pose(&q));
        let b = theirs(&serial.end_transform());
        for (x, y) in a.iter().zip(&b) {
            assert!((x - y).abs() <= TOL, "chain end differs at {q:?}");
        }
    }
}
