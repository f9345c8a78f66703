//! The last safety layer, tried from outside as an intruder would: raw over-limit
//! commands published straight onto the hardware topics. A peer that is not the site's
//! controller is refused; one that gets past the identity check (here: it names itself
//! after the controller) is limited — joint speeds, the end-effector speed cap,
//! acceleration, effort — and the robot stops when its commands stop. Every refusal
//! and limitation is counted in the simulator's status.
#![allow(clippy::unwrap_used)]

use std::time::Duration;

use nalgebra::SVector;
use teleop_bus::{Bus, Received};
use teleop_hardware::safety::ArmSafety;
use teleop_hardware::{ArmCommand, HandCommand, wire};
use teleop_interfaces::joints::PR2_ARM_JOINTS;
use teleop_interfaces::topics;
use teleop_msgs::JointState;
use teleop_sim_nodes::remote_sim::{self, SimNodeConfig, SimSafetyConfig};
use teleop_system_tests::{free_port, isolated_pair};

/// Publishes `arm` and `hand` (those given) at 100 Hz for `duration` while collecting
/// arm and hand states.
async fn flood(
    arm_pub: &teleop_bus::Publisher<JointState>,
    hand_pub: &teleop_bus::Publisher<teleop_msgs::JointCommand>,
    arm: Option<&ArmCommand<7>>,
    hand: Option<&HandCommand>,
    duration: Duration,
    arm_states: &teleop_bus::Subscriber<JointState>,
    hand_states: &teleop_bus::Subscriber<JointState>,
) -> (Vec<Received<JointState>>, Vec<Received<JointState>>) {
    let (mut a, mut h) = (Vec::new(), Vec::new());
    let until = tokio::time::Instant::now() + duration;
    while tokio::time::Instant::now() < until {
        if let Some(arm) = arm {
            arm_pub
                .put(&wire::arm_command_msg(&PR2_ARM_JOINTS, arm, 0.0))
                .unwrap();
        }
        if let Some(hand) = hand {
            hand_pub.put(&wire::hand_command_msg(hand, 0.0)).unwrap();
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
        while let Some(r) = arm_states.try_recv() {
            a.push(r);
        }
        while let Some(r) = hand_states.try_recv() {
            h.push(r);
        }
    }
    (a, h)
}

fn positions(states: &[Received<JointState>]) -> Vec<SVector<f64, 7>> {
    states
        .iter()
        .map(|r| {
            wire::arm_state(&PR2_ARM_JOINTS, &r.msg)
                .unwrap()
                .position_rad
        })
        .collect()
}

fn velocities(states: &[Received<JointState>]) -> Vec<(SVector<f64, 7>, SVector<f64, 7>)> {
    states
        .iter()
        .map(|r| {
            let s = wire::arm_state(&PR2_ARM_JOINTS, &r.msg).unwrap();
            (s.position_rad, s.velocity_rad_s)
        })
        .collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn raw_over_limit_commands_are_refused_or_limited_and_counted() {
    let (hub, spoke) = isolated_pair(25, free_port().unwrap());
    let sim = SimNodeConfig {
        bus: hub,
        ..Default::default()
    };
    let sim_task = tokio::spawn(remote_sim::run(sim, Some(Duration::from_secs(9))));
    tokio::time::sleep(Duration::from_millis(300)).await;
    let probe = Bus::open("probe", &spoke).await.unwrap();
    let arm_states = probe.subscriber(&topics::HW_PR2_ARM_STATE).await.unwrap();
    let hand_states = probe.subscriber(&topics::HW_HAND_STATE).await.unwrap();
    let over_arm = ArmCommand {
        velocity_rad_s: SVector::repeat(5.0),
    };
    let over_hand = HandCommand::Effort(SVector::repeat(10.0));

    // 1. A foreign peer: refused, the arm does not move, the hand does not squeeze.
    let intruder = Bus::open("intruder", &spoke).await.unwrap();
    let arm_pub = intruder
        .publisher(&topics::HW_PR2_ARM_COMMAND)
        .await
        .unwrap();
    let hand_pub = intruder.publisher(&topics::HW_HAND_COMMAND).await.unwrap();
    tokio::time::sleep(Duration::from_millis(500)).await;
    let (a, h) = flood(
        &arm_pub,
        &hand_pub,
        Some(&over_arm),
        Some(&over_hand),
        Duration::from_secs(1),
        &arm_states,
        &hand_states,
    )
    .await;
    let q = positions(&a);
    let moved = q.iter().map(|x| (x - q[0]).amax()).fold(0.0, f64::max);
    println!("foreign peer, 5 rad/s for 1 s: arm moved {moved:.5} rad");
    assert!(
        moved < 2e-3,
        "the arm moved {moved} rad on a foreign peer's command"
    );
    let effort = h
        .iter()
        .map(|r| wire::hand_state(&r.msg, None).unwrap().effort_nm.amax())
        .fold(0.0, f64::max);
    assert!(
        effort < 1.0,
        "the hand took the foreign effort: {effort} N m"
    );
    drop((arm_pub, hand_pub, intruder));

    // 2. A peer past the identity check (it calls itself the controller): limited.
    let impostor = Bus::open("pr2_arm_controller", &spoke).await.unwrap();
    let hand_impostor = Bus::open("shadow_hand_controller", &spoke).await.unwrap();
    let arm_pub = impostor
        .publisher(&topics::HW_PR2_ARM_COMMAND)
        .await
        .unwrap();
    let hand_pub = hand_impostor
        .publisher(&topics::HW_HAND_COMMAND)
        .await
        .unwrap();
    tokio::time::sleep(Duration::from_millis(500)).await;
    let chain = teleop_kinematics::robots::pr2_arm_chain().unwrap();
    let safety = ArmSafety::new(chain.clone(), SimSafetyConfig::default().arm).unwrap();
    let fastest_tool = |states: &[Received<JointState>]| {
        velocities(states)
            .iter()
            .map(|(pos, vel)| safety.tool_speed_m_s(pos, vel))
            .fold(0.0, f64::max)
    };
    // The hand first, alone: its efforts are clamped. Closing every finger at the cap
    // at once jerks the wrist (the fingers' reaction on the palm: the first CI failure
    // of this test, 0.465 m/s at the tool point, was that jerk caught by the arm's
    // check while both were flooded together), so the arm's limits are judged on a
    // flood of its own below.
    let (a, h) = flood(
        &arm_pub,
        &hand_pub,
        None,
        Some(&over_hand),
        Duration::from_secs(1),
        &arm_states,
        &hand_states,
    )
    .await;
    let hand_efforts: Vec<f64> = h
        .iter()
        .map(|r| wire::hand_state(&r.msg, None).unwrap().effort_nm.amax())
        .collect();
    let worst = hand_efforts.iter().copied().fold(0.0, f64::max);
    println!(
        "controller-named peer, 10 N m: hand efforts at most {worst:.3} N m (the wrist's tool point jerked to {:.3} m/s)",
        fastest_tool(&a)
    );
    assert!(
        worst <= 2.0 + 1e-9 && worst > 1.0,
        "hand effort {worst} N m"
    );
    // The released hand settles before the arm's flood.
    tokio::time::sleep(Duration::from_millis(500)).await;
    let (a, _) = flood(
        &arm_pub,
        &hand_pub,
        Some(&over_arm),
        None,
        Duration::from_secs(1),
        &arm_states,
        &hand_states,
    )
    .await;
    let limits = chain.velocity_limits();
    let qv = velocities(&a);
    let q = positions(&a);
    let moved = q.iter().map(|x| (x - q[0]).amax()).fold(0.0, f64::max);
    for (_, vel) in &qv {
        // Measured velocities carry 2e-3 rad/s of noise.
        for i in 0..7 {
            assert!(
                vel[i].abs() <= limits[i] + 0.01,
                "joint {i} at {} rad/s, limit {}",
                vel[i],
                limits[i]
            );
        }
    }
    let fastest_tool = fastest_tool(&a);
    println!(
        "controller-named peer, 5 rad/s for 1 s: arm moved {moved:.3} rad, fastest tool point {fastest_tool:.3} m/s"
    );
    assert!(moved > 0.01, "the limited command still moves the arm");
    // The safety layer limits the commanded tool speed to 0.25 m/s. The simulated arm is
    // physical (MuJoCo): its joints track the driver's reference with a real arm's
    // dynamics, the coupling between joints included (a joint stepped alone overshoots
    // its command by up to 5 % and moves the others at up to 0.11x its speed, test
    // `each_arm_joint_follows_its_command_and_moves_the_others_little`; with every joint
    // accelerating at once these add up at the tool), so what is measured may exceed
    // the command by a quarter, never by the 20x of the raw command.
    assert!(
        fastest_tool <= 0.25 * 1.25,
        "tool point at {fastest_tool} m/s"
    );

    // A NaN command is refused.
    let mut nan = wire::arm_command_msg(&PR2_ARM_JOINTS, &ArmCommand::stop(), 0.0);
    nan.velocity[3] = f64::NAN;
    arm_pub.put(&nan).unwrap();

    // 3. Commands stop: the arm brakes to a standstill on its own.
    tokio::time::sleep(Duration::from_millis(600)).await;
    while arm_states.try_recv().is_some() {}
    let still = wire::arm_state(
        &PR2_ARM_JOINTS,
        &arm_states
            .recv_timeout(Duration::from_secs(1))
            .await
            .unwrap()
            .msg,
    )
    .unwrap();
    assert!(
        still.velocity_rad_s.amax() < 0.02,
        "still moving: {:?}",
        still.velocity_rad_s
    );
    drop((arm_pub, hand_pub, impostor, hand_impostor));

    // 4. Every refusal and limitation is counted.
    let report = sim_task.await.unwrap().unwrap();
    let get = |n: &str| {
        report
            .counter(n)
            .unwrap_or_else(|| panic!("no counter {n}: {:?}", report.counters))
    };
    for (name, at_least) in [
        ("pr2_arm.command.rejected_foreign", 50),
        ("shadow_hand.command.rejected_foreign", 50),
        ("pr2_arm.command_refused.non_finite", 1),
        ("safety.arm.limited.tool_speed", 1),
        ("safety.arm.limited.acceleration", 1),
        ("safety.arm.limited.timeout", 1),
        ("safety.hand.limited.effort", 50),
    ] {
        println!("{name} = {}", get(name));
        assert!(get(name) >= at_least, "{name} = {}", get(name));
    }
    // The pick scene's job was judged all along (no observation refused) and, with
    // nobody doing it, not done.
    assert_eq!(get("job.judge_errors"), 0);
    assert_eq!(get("job.succeeded"), 0);
    assert_eq!(get("job.lifted"), 0);
}
