"""A ros2_control robot stand-in written on pyzeros (an independent ROS 2 client on
Zenoh, PyPI), for tests/ros2_control.rs.

It behaves as a robot under ros2_control with two controllers:
  * a forward command controller (--controller, default forward_velocity_controller):
    takes std_msgs/msg/Float64MultiArray on /<controller>/commands, one value per joint
    in its `joints` order, velocities, (--mode position) positions or (--mode effort)
    efforts, and (as the real controller does) keeps the last command forever;
  * joint_state_broadcaster: publishes sensor_msgs/msg/JointState on --state-topic
    (default /joint_states) at 100 Hz, joints in an order of its own, with one extra joint the arm does not have.
The "hardware" integrates the commanded velocities through a first-order lag (time
constant --lag-s) and clamps them to its own velocity limit (--max-velocity) and the
positions to +-3 rad. With --mode effort each joint is a rigid body on a damped axis,
I q'' = tau - b q' (--inertia kg m^2, --damping N m s/rad, 1 ms steps), the effort
clamped to --max-effort; the broadcaster then publishes at --state-hz (the controller
manager's update rate).

With --imposter, a third node called `imposter` also publishes /joint_states (all
positions 3.0): a receiver that takes the broadcaster's samples only, by publisher GID,
must drop every one of them.

Every command received is logged to --log as one JSON line {"t": wall s, "data": [...]}
(flushed at once), so the test can check what reached the robot.
"""

import argparse
import asyncio
import json
import sys
import threading
import time

import numpy as np
import zenoh
import pyzeros
from pyzeros.builtin_msgs import Attachment
from ros2_pyterfaces.cyclone.std_msgs.msg import Float64MultiArray
from ros2_pyterfaces.cyclone.sensor_msgs.msg import JointState
from ros2_pyterfaces.cyclone.std_msgs.msg import Header
from ros2_pyterfaces.cyclone.builtin_interfaces.msg import Time


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--listen", required=True, help="zenoh endpoint, e.g. tcp/127.0.0.1:7447")
    ap.add_argument("--domain", type=int, required=True)
    ap.add_argument("--joints", required=True, help="comma-separated, the controller's order")
    ap.add_argument("--start", required=True, help="comma-separated start positions, rad")
    ap.add_argument("--log", required=True)
    ap.add_argument("--duration-s", type=float, default=60.0)
    ap.add_argument("--lag-s", type=float, default=0.03)
    ap.add_argument("--max-velocity", type=float, default=3.0)
    ap.add_argument("--imposter", action="store_true")
    ap.add_argument("--mode", choices=["velocity", "position", "effort"], default="velocity")
    ap.add_argument("--inertia", type=float, default=2e-4)
    ap.add_argument("--damping", type=float, default=0.01)
    ap.add_argument("--max-effort", type=float, default=1.0)
    ap.add_argument("--state-hz", type=float, default=100.0)
    ap.add_argument("--controller", default="forward_velocity_controller")
    ap.add_argument("--state-topic", default="/joint_states")
    args = ap.parse_args()
    joints = args.joints.split(",")
    q = [float(v) for v in args.start.split(",")]
    assert len(q) == len(joints), "one start position per joint"

    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("listen/endpoints", json.dumps([args.listen]))
    conf.insert_json5("scouting/multicast/enabled", "false")
    session = zenoh.open(conf)

    lock = threading.Lock()
    # A position controller starts holding where the robot is.
    command = list(q) if args.mode == "position" else [0.0] * len(joints)
    log = open(args.log, "w", encoding="utf-8")

    def on_command(sample: zenoh.Sample) -> None:
        msg = Float64MultiArray.deserialize(sample.payload.to_bytes())
        data = [float(v) for v in msg.data]
        with lock:
            if len(data) == len(joints):
                command[:] = data
            log.write(json.dumps({"t": time.time(), "data": data}) + "\n")
            log.flush()

    async def run() -> None:
        controller = pyzeros.Node(name=args.controller, session=session, domain_id=args.domain)
        broadcaster = pyzeros.Node(
            name="joint_state_broadcaster", session=session, domain_id=args.domain
        )
        sub = pyzeros.sub.RawSub(
            Float64MultiArray,
            f"/{args.controller}/commands",
            callback=on_command,
            session=controller,
        )
        pub = pyzeros.Pub(JointState, args.state_topic, session=broadcaster)
        imposter_pub = None
        if args.imposter:
            imposter = pyzeros.Node(name="imposter", session=session, domain_id=args.domain)
            imposter_pub = pyzeros.Pub(JointState, args.state_topic, session=imposter)
        # The broadcaster's order: reversed, with an extra joint in the middle.
        order = list(reversed(range(len(joints))))
        names = [joints[i] for i in order]
        names.insert(2, "torso_lift_joint")
        # pyzeros compiles its serializers on first use (tens of seconds on a fresh
        # machine): do it before saying ready.
        JointState(name=["a"], position=[0.0], velocity=[0.0], effort=[0.0]).serialize()
        Attachment(
            sequence_number=np.int64(0),
            source_timestamp=np.int64(0),
            source_gid=np.zeros(16, dtype=np.uint8),
        ).serialize()
        Float64MultiArray.deserialize(Float64MultiArray(data=[0.0]).serialize())
        print("ready", flush=True)
        v = [0.0] * len(joints)
        dt = 0.01 if args.mode != "effort" else 1.0 / args.state_hz
        start = time.monotonic()
        k = 0
        while time.monotonic() - start < args.duration_s:
            with lock:
                target = list(command)
            alpha = min(1.0, dt / args.lag_s)
            for i in range(len(joints)):
                if args.mode == "effort":
                    tau = max(-args.max_effort, min(args.max_effort, target[i]))
                    steps = max(1, round(dt / 0.001))
                    h = dt / steps
                    for _ in range(steps):
                        # Semi-implicit Euler; the axis's own damping implicit.
                        v[i] = (v[i] + h * tau / args.inertia) / (1.0 + h * args.damping / args.inertia)
                        q[i] += h * v[i]
                        if abs(q[i]) > 3.0:
                            q[i] = max(-3.0, min(3.0, q[i]))
                            v[i] = 0.0
                    continue
                if args.mode == "velocity":
                    want = target[i]
                else:
                    # The position controller's own loop: toward the target.
                    want = (target[i] - q[i]) / max(args.lag_s, dt)
                want = max(-args.max_velocity, min(args.max_velocity, want))
                v[i] += alpha * (want - v[i])
                q[i] = max(-3.0, min(3.0, q[i] + v[i] * dt))
            now = time.time_ns()
            stamp = Time(sec=now // 1_000_000_000, nanosec=now % 1_000_000_000)
            pos = [q[i] for i in order]
            vel = [v[i] for i in order]
            pos.insert(2, 0.1)
            vel.insert(2, 0.0)
            pub.publish(
                JointState(
                    header=Header(stamp=stamp, frame_id=""),
                    name=names,
                    position=pos,
                    velocity=vel,
                    effort=[0.0] * len(names),
                )
            )
            if imposter_pub is not None and k % 10 == 0:
                imposter_pub.publish(
                    JointState(
                        header=Header(stamp=stamp, frame_id=""),
                        name=names,
                        position=[3.0] * len(names),
                        velocity=[0.0] * len(names),
                        effort=[0.0] * len(names),
                    )
                )
            k += 1
            await asyncio.sleep(max(0.0, start + k * dt - time.monotonic()))
        sub.close()

    try:
        asyncio.run(run())
    finally:
        session.close()
        log.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
