"""Decodes one sample of every topic type of the project with pyzeros (an independent
ROS 2 client on Zenoh, PyPI), for tests/ros2_clients.rs.

The standard types come from ros2_pyterfaces; the project's own `.msg` types
(shared/msgs/msg/) and tf2_msgs/TFMessage (not in ros2_pyterfaces) are defined on
pyzeros's side from their ROS 2 definitions (pyzeros_types.py). pyzeros subscribes with its own type
hashes in the rmw_zenoh data keys, so a sample arrives only where its hash equals the
project's.

Prints `ready`, then one JSON line per topic when its first sample is decoded:
{"topic": ..., "type": ..., "hash": ..., "msg": {field: value, ...}}; exits when every
topic has been decoded or after --timeout-s.
"""

import argparse
import dataclasses
import json
import sys
import threading
import time
import numpy as np
import zenoh
import pyzeros
from ros2_pyterfaces.cyclone.std_msgs.msg import Header, Float64MultiArray
from ros2_pyterfaces.cyclone.geometry_msgs.msg import PoseStamped
from ros2_pyterfaces.cyclone.sensor_msgs.msg import JointState, Image, CompressedImage

from pyzeros_types import (
    FingertipPressures,
    JointCommand,
    NodeStatus,
    OperatorInput,
    TFMessage,
)


TYPES = {
    t.get_type_name(): t
    for t in (
        PoseStamped,
        JointState,
        OperatorInput,
        FingertipPressures,
        Image,
        CompressedImage,
        JointCommand,
        NodeStatus,
        Header,
        TFMessage,
        Float64MultiArray,
    )
}


def plain(value):
    """A decoded message as JSON values: fields by name, sequences as lists."""
    if dataclasses.is_dataclass(value):
        return {f.name: plain(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, (bytes, bytearray, memoryview)):
        return list(bytes(value))
    if isinstance(value, np.ndarray):
        return [plain(v) for v in value.tolist()]
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--connect", required=True)
    ap.add_argument("--domain", type=int, required=True)
    ap.add_argument("--topics", required=True, help="topic=pkg/msg/Type,...")
    ap.add_argument("--timeout-s", type=float, default=60.0)
    args = ap.parse_args()
    wanted = dict(item.split("=", 1) for item in args.topics.split(","))

    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("connect/endpoints", json.dumps([args.connect]))
    conf.insert_json5("scouting/multicast/enabled", "false")
    session = zenoh.open(conf)
    node = pyzeros.Node(name="pyzeros_decoder", session=session, domain_id=args.domain)
    done = {}
    lock = threading.Lock()
    all_done = threading.Event()

    def subscriber(topic: str, msg_type):
        def on_sample(sample: zenoh.Sample) -> None:
            msg = msg_type.deserialize(sample.payload.to_bytes())
            with lock:
                if topic in done:
                    return
                done[topic] = True
                line = {
                    "topic": topic,
                    "type": msg_type.get_type_name(),
                    "hash": msg_type.hash_rihs01(),
                    "msg": plain(msg),
                }
                print(json.dumps(line), flush=True)
                if len(done) == len(wanted):
                    all_done.set()

        return on_sample

    # Compile the serializers first (pyzeros does it on first use) by a round trip.
    for t in TYPES.values():
        t.deserialize(t().serialize())
    subs = [
        pyzeros.sub.RawSub(TYPES[ty], topic, callback=subscriber(topic, TYPES[ty]), session=node)
        for topic, ty in wanted.items()
    ]
    print("ready", flush=True)
    ok = all_done.wait(args.timeout_s)
    for s in subs:
        s.close()
    session.close()
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
