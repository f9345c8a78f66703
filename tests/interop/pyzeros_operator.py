"""An operator station written on pyzeros (an independent ROS 2 client on Zenoh, PyPI),
for tests/ros2_clients.rs: ROS 2 nodes named `wrist_tracker` (the wrist pose and the
pedals) and `hand_inference` (alive only: the arm moves while the nodes commanding its
hand are) drive the robot site.

Timeline, from `ready`: the enable switch pressed at 0.5 s, the clutch at 1 s; the
wrist pose (100 Hz) rests for 1.5 s, then moves +0.10 m along x over 2 s and rests.
Exits after --duration-s.
"""

import argparse
import json
import sys
import time
import zenoh
import pyzeros
from ros2_pyterfaces.cyclone.std_msgs.msg import Header
from ros2_pyterfaces.cyclone.builtin_interfaces.msg import Time
from ros2_pyterfaces.cyclone.geometry_msgs.msg import Point, Pose, PoseStamped, Quaternion

from pyzeros_types import OperatorInput


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--connect", required=True)
    ap.add_argument("--domain", type=int, required=True)
    ap.add_argument("--duration-s", type=float, default=8.0)
    args = ap.parse_args()
    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("connect/endpoints", json.dumps([args.connect]))
    conf.insert_json5("scouting/multicast/enabled", "false")
    session = zenoh.open(conf)

    import asyncio

    async def run() -> None:
        tracker = pyzeros.Node(name="wrist_tracker", session=session, domain_id=args.domain)
        hand = pyzeros.Node(name="hand_inference", session=session, domain_id=args.domain)
        pose_pub = pyzeros.Pub(PoseStamped, "/teleop/wrist_pose", session=tracker)
        input_pub = pyzeros.Pub(OperatorInput, "/teleop/operator_input", session=tracker)
        # Compile the serializers (pyzeros does it on first use, behind a lock another
        # process may hold) before the clock runs: one message of each type through the
        # whole publishing path, the pedals released. Serializing alone left the first
        # publish to compile (17 s once, on a cold cache beside the decoding test): the
        # station's clock ran out after one pose.
        now = time.time_ns()
        first = Header(
            stamp=Time(sec=now // 1_000_000_000, nanosec=now % 1_000_000_000),
            frame_id="tracker",
        )
        pose_pub.publish(
            PoseStamped(
                header=first,
                pose=Pose(
                    position=Point(x=0.0, y=0.0, z=1.0),
                    orientation=Quaternion(x=0.0, y=0.0, z=0.0, w=1.0),
                ),
            )
        )
        input_pub.publish(
            OperatorInput(header=first, clutch=False, enable=False, motion_scale=1.0)
        )
        print("ready", flush=True)
        start = time.monotonic()
        k = 0
        while (t := time.monotonic() - start) < args.duration_s:
            now = time.time_ns()
            header = Header(
                stamp=Time(sec=now // 1_000_000_000, nanosec=now % 1_000_000_000),
                frame_id="tracker",
            )
            x = 0.10 * min(1.0, max(0.0, (t - 1.5) / 2.0))
            pose_pub.publish(
                PoseStamped(
                    header=header,
                    pose=Pose(
                        position=Point(x=x, y=0.0, z=1.0),
                        orientation=Quaternion(x=0.0, y=0.0, z=0.0, w=1.0),
                    ),
                )
            )
            if k % 2 == 0:
                input_pub.publish(
                    OperatorInput(
                        header=header, clutch=t >= 1.0, enable=t >= 0.5, motion_scale=1.0
                    )
                )
            k += 1
            await asyncio.sleep(max(0.0, start + k * 0.01 - time.monotonic()))
        # The nodes live as long as the station does (an unreferenced node's token goes).
        del hand

    try:
        asyncio.run(run())
    finally:
        session.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
