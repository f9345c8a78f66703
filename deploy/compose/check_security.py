#!/usr/bin/env python3
"""Checks what check_security.sh recorded: the PR2 arm controller's counters and an arm
encoder sample before the attempts, after the unauthorised peers, after the operator
identity's bad samples.

    check_security.py DIR
"""
import json
import sys
from pathlib import Path

NODE = "pr2_arm_controller"


def counters(path: Path) -> dict:
    last = None
    for line in path.read_text().splitlines():
        try:
            msg = json.loads(line)
        except json.JSONDecodeError:
            continue
        if msg.get("node_name") == NODE:
            last = msg
    if last is None:
        sys.exit(f"security: no status of {NODE} in {path}")
    return dict(zip(last["counter_names"], last["counter_values"]))


def arm(path: Path) -> list:
    for line in path.read_text().splitlines():
        try:
            return json.loads(line)["position"]
        except (json.JSONDecodeError, KeyError):
            continue
    sys.exit(f"security: no arm state in {path}")


def main() -> None:
    d = Path(sys.argv[1])
    before, unauth, injected = (counters(d / f"{n}.status") for n in ("before", "unauthorised", "injected"))
    q0, q1, q2 = (arm(d / f"{n}.arm") for n in ("before", "unauthorised", "injected"))
    delta = lambda a, b, k: b.get(k, 0) - a.get(k, 0)
    moved = lambda a, b: max(abs(x - y) for x, y in zip(a, b))
    fails = []

    got = {k: delta(before, unauth, k) for k in ("wrist_pose.received", "operator_input.received", "arm.engagements")}
    print(f"security: unauthorised peers (4 of them, 2 s each of clutch + poses at 50 Hz): "
          f"reached the arm controller: wrist poses {got['wrist_pose.received']}, pedals "
          f"{got['operator_input.received']}; engagements {got['arm.engagements']}; "
          f"arm moved {moved(q0, q1) * 1e3:.2f} mrad")
    fails += [f"{k} +{v} from unauthorised peers" for k, v in got.items() if v != 0]
    if moved(q0, q1) > 2e-3:
        fails.append(f"the arm moved {moved(q0, q1)} rad")

    expect = {
        "wrist_pose.rejected_decode": (5, 5),
        "wrist_pose.rejected_from_future": (5, 5),
        "wrist_pose.rejected_out_of_order": (3, 3),
        # Refused when the controller takes the newest pose (30 Hz; sent at 10 Hz).
        "wrist_pose.rejected_non_finite": (1, 5),
    }
    got = {k: delta(unauth, injected, k) for k in expect}
    received = delta(unauth, injected, "wrist_pose.received")
    print(f"security: operator identity across the WAN, 18 bad samples and 1 good: received {received}, "
          + ", ".join(f"{k.split('.', 1)[1]} +{v}" for k, v in got.items())
          + f"; engagements +{delta(unauth, injected, 'arm.engagements')}; arm moved {moved(q1, q2) * 1e3:.2f} mrad")
    if received != 19:
        fails.append(f"{received} of 19 wrist samples reached the robot site")
    for k, (lo, hi) in expect.items():
        if not lo <= got[k] <= hi:
            fails.append(f"{k} +{got[k]}, expected {lo}..{hi}")
    if delta(unauth, injected, "arm.engagements") != 0:
        fails.append("the arm engaged")
    if moved(q1, q2) > 2e-3:
        fails.append(f"the arm moved {moved(q1, q2)} rad")
    if fails:
        sys.exit("security: FAILED: " + "; ".join(fails))
    print("security: passed")


if __name__ == "__main__":
    main()
