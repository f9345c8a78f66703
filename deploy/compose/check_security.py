#!/usr/bin/env python3
"""Checks what check_security.sh recorded: the PR2 arm controller's counters and an arm
encoder sample before the attempts, after the unauthorised peers, after the operator
identity's bad samples, after the identity claims; the robot site's graph and the
samples it heard during the claims; the admin-space replies each identity got.

    check_security.py DIR WRIST_CLAIM_GID ARM_CLAIM_GID
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


def named(path: Path, node: str) -> int:
    """How many sessions announce `node` in a `teleop node list` output."""
    return sum(1 for line in path.read_text().splitlines() if line.split()[:1] == [f"/{node}"])


def heard(path: Path) -> list:
    """(publisher GID, announcing node) of each sample in a `topic echo --format json`."""
    out = []
    for line in path.read_text().splitlines():
        try:
            meta = json.loads(line)["_meta"]
        except (json.JSONDecodeError, KeyError):
            continue
        out.append((meta.get("publisher_gid"), meta.get("publisher_node")))
    return out


def replies(path: Path):
    """The number of replies `teleop query` printed, None if it did not get that far."""
    for line in reversed(path.read_text().splitlines()):
        parts = line.split()
        if len(parts) == 4 and parts[1] == "replies," and parts[3] == "errors":
            return int(parts[0])
    return None


def claims(d: Path, wrist_gid: str, arm_gid: str, q_before: list) -> list:
    fails = []
    wrist_nodes, arm_nodes = named(d / "claim-wrist.nodes", "wrist_tracker"), named(d / "claim-arm.nodes", "pr2_arm_controller")
    wrist, arm_cmds = heard(d / "claim-wrist.echo"), heard(d / "claim-arm.echo")
    fake_wrist = sum(1 for g, _ in wrist if g == wrist_gid)
    fake_arm = sum(1 for g, _ in arm_cmds if g == arm_gid)
    real_arm = sum(1 for g, n in arm_cmds if n == "pr2_arm_controller" and g != arm_gid)
    real_wrist = sum(1 for g, n in wrist if n == "wrist_tracker" and g != wrist_gid)
    q3 = arm(d / "claimed.arm")
    print(f"security: identity claims: `wrist_tracker` announced by {wrist_nodes} session(s) at the robot site "
          f"while hand inference's identity claimed it, its poses heard {fake_wrist} times (the real tracker's "
          f"{real_wrist}); `pr2_arm_controller` "
          f"announced by {arm_nodes} while the feedback publisher's identity claimed it, its commands heard "
          f"{fake_arm} times (the real controller's {real_arm}); arm moved {max(abs(x - y) for x, y in zip(q_before, q3)) * 1e3:.2f} mrad")
    if wrist_nodes != 1:
        fails.append(f"{wrist_nodes} sessions announce wrist_tracker at the robot site")
    if arm_nodes != 1:
        fails.append(f"{arm_nodes} sessions announce pr2_arm_controller at the robot site")
    if fake_wrist or fake_arm:
        fails.append(f"claimed identities were heard: {fake_wrist} wrist poses, {fake_arm} arm commands")
    if real_wrist == 0:
        fails.append("no pose of the real wrist tracker heard during the claim (the check sees nothing)")
    if real_arm == 0:
        fails.append("no command of the real arm controller heard during the claim (the check sees nothing)")
    if max(abs(x - y) for x, y in zip(q_before, q3)) > 2e-3:
        fails.append("the arm moved during the identity claims")
    admin = {p.stem[len("admin-"):]: replies(p) for p in sorted(d.glob("admin-*.log"))}
    print("security: admin space (@/**) replies: " + ", ".join(f"{k} {v}" for k, v in admin.items()))
    for who, n in admin.items():
        if n is None:
            fails.append(f"the admin-space query as {who} did not run (see admin-{who}.log)")
        elif who.startswith("teleop-observer"):
            if n < 1:
                fails.append(f"the observer got no admin-space reply ({who})")
        elif n != 0:
            fails.append(f"{who} got {n} admin-space replies")
    if len(admin) != 5:
        fails.append(f"{len(admin)} admin-space queries recorded, expected 5")
    return fails


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
    fails += claims(d, sys.argv[2], sys.argv[3], q2)
    if fails:
        sys.exit("security: FAILED: " + "; ".join(fails))
    print("security: passed")


if __name__ == "__main__":
    main()
