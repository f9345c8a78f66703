//! FK and FK + Jacobian per call for each robot, with the `k` crate (openrr) on the
//! same URDF files and the same configurations side by side.
//!
//! `cargo bench --workspace --bench fk`; medians are in
//! `$CARGO_TARGET_DIR/criterion/<group>/<name>/new/estimates.json`.
#![allow(missing_docs)]

use std::hint::black_box;
use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use nalgebra::{Matrix6xX, Point3, SVector};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use teleop_kinematics::{Robot, robots};

const N_CONFIGS: usize = 1024;

fn urdf_path(file: &str) -> String {
    format!("{}/urdf/{file}", env!("CARGO_MANIFEST_DIR"))
}

fn configs(limits: &[teleop_kinematics::JointLimits], seed: u64) -> Vec<Vec<f64>> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..N_CONFIGS)
        .map(|_| {
            limits
                .iter()
                .map(|l| {
                    if l.is_bounded() {
                        rng.random_range(l.lower..=l.upper)
                    } else {
                        rng.random_range(-3.0..=3.0)
                    }
                })
                .collect()
        })
        .collect()
}

fn load_k(file: &str) -> k::Chain<f64> {
    match k::Chain::<f64>::from_urdf_file(urdf_path(file)) {
        Ok(c) => c,
        Err(e) => panic!("k cannot load {file}: {e}"),
    }
}

fn serial_chain<const N: usize>(
    c: &mut Criterion,
    group: &str,
    file: &str,
    base: &str,
    tip: &str,
    seed: u64,
) {
    let robot = Robot::from_urdf_file(urdf_path(file)).expect("urdf");
    let chain = robot.chain(base, tip).expect("chain");
    let fixed = chain.fixed::<N>().expect("dof");
    let limits: Vec<_> = chain.limits().collect();
    let qs = configs(&limits, seed);
    let qs_fixed: Vec<SVector<f64, N>> = qs.iter().map(|q| SVector::from_column_slice(q)).collect();

    let kchain = load_k(file);
    let end = kchain.find_link(tip).expect("tip in k");
    let root = kchain.find_link(base).expect("base in k");
    let serial = k::SerialChain::from_end_to_root(end, root);
    let k_names: Vec<String> = serial.iter_joints().map(|j| j.name.clone()).collect();
    let ours_names: Vec<&str> = chain.joint_names().collect();
    assert_eq!(k_names, ours_names, "same joint order");

    let mut g = c.benchmark_group(group);
    let mut i = 0;
    g.bench_function("ours_fixedchain_fk", |b| {
        b.iter(|| {
            i = (i + 1) % N_CONFIGS;
            black_box(fixed.end_pose(black_box(&qs_fixed[i])))
        })
    });
    g.bench_function("ours_fixedchain_fk_jac", |b| {
        b.iter(|| {
            i = (i + 1) % N_CONFIGS;
            black_box(fixed.end_pose_and_jacobian(black_box(&qs_fixed[i])))
        })
    });
    let mut jac = Matrix6xX::zeros(N);
    g.bench_function("ours_chain_slice_fk_jac", |b| {
        b.iter(|| {
            i = (i + 1) % N_CONFIGS;
            black_box(
                chain
                    .end_pose_and_jacobian_into(black_box(&qs[i]), &mut jac)
                    .expect("sizes"),
            )
        })
    });
    g.bench_function("k_serialchain_fk", |b| {
        b.iter(|| {
            i = (i + 1) % N_CONFIGS;
            serial.set_joint_positions_unchecked(black_box(&qs[i]));
            black_box(serial.end_transform())
        })
    });
    g.bench_function("k_serialchain_fk_jac", |b| {
        b.iter(|| {
            i = (i + 1) % N_CONFIGS;
            serial.set_joint_positions_unchecked(black_box(&qs[i]));
            let pose = serial.end_transform();
            black_box((pose, k::jacobian(&serial)))
        })
    });
    g.finish();
}

fn ur5(c: &mut Criterion) {
    serial_chain::<6>(
        c,
        "ur5_camera_6dof",
        "ur5.urdf",
        "base_link",
        "camera_optical_frame",
        1,
    );
}

fn pr2(c: &mut Criterion) {
    serial_chain::<7>(
        c,
        "pr2_palm_7dof",
        "pr2_right_arm_shadow.urdf",
        "base_link",
        "rh_palm",
        2,
    );
}

/// The whole hand tree: all 19 DoF updated once, then the five fingertip poses (and
/// Jacobians), as a retargeting IK evaluates per iteration.
fn shadow(c: &mut Criterion) {
    let robot = robots::shadow_hand().expect("urdf");
    let limits: Vec<_> = robot.dof_limits().collect();
    let qs = configs(&limits, 3);
    let tips: Vec<_> = robots::shadow::TIPS
        .iter()
        .map(|t| robot.link_id(t).expect("tip"))
        .collect();
    let mut state = robot.new_state();
    let mut jac = Matrix6xX::zeros(robot.dof());

    let kchain = load_k("shadow_hand.urdf");
    let k_order: Vec<usize> = kchain
        .iter_joints()
        .map(|j| robot.dof_index(&j.name).expect("joint"))
        .collect();
    let qs_k: Vec<Vec<f64>> = qs
        .iter()
        .map(|q| k_order.iter().map(|&i| q[i]).collect())
        .collect();
    let k_tips: Vec<&k::Node<f64>> = robots::shadow::TIPS
        .iter()
        .map(|t| kchain.find_link(t).expect("tip in k"))
        .collect();
    let k_serials: Vec<k::SerialChain<f64>> =
        k_tips.iter().map(|t| k::SerialChain::from_end(t)).collect();

    let mut g = c.benchmark_group("shadow_tree_19dof_5tips");
    let mut i = 0;
    g.bench_function("ours_tree_fk_5tips", |b| {
        b.iter(|| {
            i = (i + 1) % N_CONFIGS;
            robot.update(&mut state, black_box(&qs[i])).expect("len");
            for t in &tips {
                black_box(robot.link_pose(&state, *t));
            }
        })
    });
    g.bench_function("ours_tree_fk_5tips_5jac", |b| {
        b.iter(|| {
            i = (i + 1) % N_CONFIGS;
            robot.update(&mut state, black_box(&qs[i])).expect("len");
            for t in &tips {
                black_box(
                    robot
                        .link_jacobian_into(&state, *t, &Point3::origin(), &mut jac)
                        .expect("cols"),
                );
            }
        })
    });
    g.bench_function("k_tree_fk_5tips", |b| {
        b.iter(|| {
            i = (i + 1) % N_CONFIGS;
            kchain.set_joint_positions_unchecked(black_box(&qs_k[i]));
            kchain.update_transforms();
            for t in &k_tips {
                black_box(t.world_transform());
            }
        })
    });
    g.bench_function("k_tree_fk_5jac", |b| {
        b.iter(|| {
            i = (i + 1) % N_CONFIGS;
            kchain.set_joint_positions_unchecked(black_box(&qs_k[i]));
            kchain.update_transforms();
            for s in &k_serials {
                black_box(k::jacobian(s));
            }
        })
    });
    g.finish();
}

fn config() -> Criterion {
    Criterion::default()
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2))
        .sample_size(50)
}

criterion_group! { name = benches; config = config(); targets = ur5, pr2, shadow }
criterion_main!(benches);
