"""Checks one kill-and-restart of check_faults.sh from what the listeners recorded: the
other containers kept running, the robots the killed container drives stopped while it
was gone, and it reconnected within 1 s of running again.

    check_faults.py DIR TAG SERVICE KILL_S START_S RUNNING_S "OTHERS_DOWN"

Prints what it measured; exits 1 on a miss."""

import json
import sys
from pathlib import Path

RECONNECT_WITHIN_S = 1.0
# A robot counts as stopped when no joint moves faster than this (rad/s), from this
# long after the kill (the commands' 100 ms deadline, braking at the safety layer's
# acceleration limit, a hand settling into its hold) until the restart.
STOPPED_BELOW_RAD_S = 0.02
SETTLE_S = 0.6
# ... and as moving before the kill when some joint moved faster than this.
MOVING_ABOVE_RAD_S = 0.03

LOCAL_NODES = ["wrist_tracker", "camera_arm", "hand_inference", "local_sim"]
REMOTE_NODES = ["pr2_arm_controller", "shadow_hand_controller", "feedback_publisher", "remote_sim"]

# service -> (node whose status shows it is back, or the site whose nodes' status must
# cross the WAN again; robots that must stop: (recording, must have been moving)).
SERVICES = {
    "pc1-wrist-tracker": ("wrist_tracker", [("r-pr2_arm-state", True), ("l-ur5-state", True)]),
    "pc1-camera-arm": ("camera_arm", [("l-ur5-state", True)]),
    "pc1-hand-inference": ("hand_inference", [("r-shadow_hand-state", False)]),
    "pc3-local-sim": ("local_sim", [("r-pr2_arm-state", True)]),
    "pc2-arm": ("pr2_arm_controller", [("r-pr2_arm-state", True)]),
    "pc2-hand": ("shadow_hand_controller", [("r-shadow_hand-state", False)]),
    "pc2-feedback": ("feedback_publisher", []),
    "robot-sim": ("remote_sim", []),
    "local-router": ("site:local", [("r-pr2_arm-state", True), ("r-shadow_hand-state", False)]),
    "remote-router": ("site:remote", [("displacement:r-pr2_arm-state", True)]),
}


def lines(path):
    if not path.exists():
        return []
    out = []
    for l in path.read_text().splitlines():
        try:
            out.append(json.loads(l))
        except json.JSONDecodeError:
            pass
    return out


def speed(sample):
    return max((abs(v) for v in sample.get("velocity", []) or [0.0]), default=0.0)


def main():
    d, tag, service = Path(sys.argv[1]), sys.argv[2], sys.argv[3]
    kill, start, running = (float(x) for x in sys.argv[4:7])
    others_down = sys.argv[7].split() if len(sys.argv) > 7 else []
    back_by, robots = SERVICES[service]
    ok = True

    def check(cond, text):
        nonlocal ok
        ok &= bool(cond)
        print(f"  {'ok ' if cond else 'BAD'} {text}")

    check(not others_down, "every other container kept running"
          + (f" (down: {', '.join(others_down)})" if others_down else ""))

    for rec, must_move in robots:
        displacement = rec.startswith("displacement:")
        rec = rec.removeprefix("displacement:")
        states = sorted(lines(d / f"{tag}-{rec}.jsonl"), key=lambda s: s["_meta"]["received_s"])
        name = rec.split("-", 1)[1].removesuffix("-state")
        before = [s for s in states if kill - 1.0 <= s["_meta"]["received_s"] <= kill]
        moving = max((speed(s) for s in before), default=0.0)
        if must_move:
            check(moving > MOVING_ABOVE_RAD_S,
                  f"{name} was moving when the container was killed (fastest joint {moving:.3f} rad/s)")
        else:
            print(f"      {name}: fastest joint in the last second before the kill {moving:.3f} rad/s")
        if displacement:
            # The listener's own router was the one killed: compare the arm before the
            # kill with the arm once it is heard again.
            last = [s for s in states if s["_meta"]["received_s"] <= kill]
            after = [s for s in states if s["_meta"]["received_s"] >= start]
            if not (last and after):
                check(False, f"{name} heard before the kill and after the restart")
                continue
            q0, q1 = last[-1]["position"], after[0]["position"]
            moved = max(abs(a - b) for a, b in zip(q0, q1))
            check(moved < 0.05, f"{name} held still while its site's router was down: "
                  f"moved {moved:.4f} rad in {after[0]['_meta']['received_s'] - last[-1]['_meta']['received_s']:.1f} s")
            continue
        gone = [s for s in states if kill + SETTLE_S <= s["_meta"]["received_s"] <= start]
        fastest = max((speed(s) for s in gone), default=None)
        check(fastest is not None and fastest < STOPPED_BELOW_RAD_S,
              f"{name} stopped while the container was gone: fastest joint "
              f"{'-' if fastest is None else f'{fastest:.4f}'} rad/s from {SETTLE_S} s after the kill "
              f"({len(gone)} samples)")

    statuses = lines(d / f"{tag}-r-teleop-status.jsonl") + lines(d / f"{tag}-l-teleop-status.jsonl")
    if back_by.startswith("site:"):
        site = back_by.split(":")[1]
        nodes = LOCAL_NODES if site == "local" else REMOTE_NODES
        # Heard at the other site: across the WAN.
        other = lines(d / f"{tag}-{'r' if site == 'local' else 'l'}-teleop-status.jsonl")
        seen = [s["_meta"]["received_s"] for s in other
                if s["node_name"] in nodes and s["_meta"]["received_s"] > running]
        what = f"the {site} site's nodes heard across the WAN again"
    else:
        seen = [s["_meta"]["received_s"] for s in statuses
                if s["node_name"] == back_by and s["_meta"]["received_s"] > running]
        what = f"{back_by} heard again"
    if seen:
        dt = min(seen) - running
        check(dt <= RECONNECT_WITHIN_S,
              f"{what} {dt:.2f} s after its container was running again "
              f"({min(seen) - start:.2f} s after `start` was issued)")
    else:
        check(False, f"{what} after the restart")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
