"""Checks one kill-and-restart of check_faults.sh from what the listeners recorded: the
other containers kept running, the robots the killed container drives stopped while it
was gone, and it reconnected within 1 s of running again (a router: 1.5 s).

    check_faults.py DIR TAG SERVICE KILL_S KILLED_S START_S RUNNING_S "OTHERS_DOWN"

KILL_S and KILLED_S: when the kill was issued and when the engine said it was done;
START_S and RUNNING_S the same for the start (s since the epoch).

Prints what it measured; exits 1 on a miss.

    check_faults.py --wait-moving RECORDING WITHIN_S ABOVE_RAD_S

waits (at most WITHIN_S) until the growing recording shows a joint faster than
ABOVE_RAD_S over its newest window; exits 1 if it never does."""

import json
import os
import sys
import time
from pathlib import Path

RECONNECT_WITHIN_S = 1.0
# A router's figure also holds its process's start, the routers' TLS session across
# the WAN and their declarations before the first sample crosses: 0.49-1.01 s measured
# (docs/deployment.md), one run over a 1 s bound.
ROUTER_RECONNECT_WITHIN_S = 1.5
# A joint's speed is its displacement over WINDOW_S, not the velocity a sample reports:
# on MuJoCo the reported velocity of the PR2's wrist joints carries contact chatter
# while the fingers, still driven, close (single samples of 0.04-0.16 rad/s, alternating
# in sign, with no displacement: a CI run of 2026-12-05 and its reproduction here); the
# reported velocity's peak is printed beside it. At rest the windowed speed is
# 0.002-0.006 rad/s (encoder noise), a clutched motion 0.03-0.5.
WINDOW_S = 0.1
# A robot counts as stopped when no joint moves faster than this (rad/s), from this
# long after the kill (the commands' 100 ms deadline, braking at the safety layer's
# acceleration limit, a hand settling into its hold) until the restart.
STOPPED_BELOW_RAD_S = 0.02
SETTLE_S = 0.6
# ... and as moving before the kill when some joint moved faster than this.
MOVING_ABOVE_RAD_S = 0.03

# How a robot must behave while the container is gone:
#   "stop": no joint faster than STOPPED_BELOW_RAD_S from SETTLE_S after the kill (the
#           PR2 braked by its controller's watchdogs or the hardware safety layer; a
#           hand whose controller died, stopped by the safety layer);
#   "hold": the Shadow hand controller holds the last posture (its targets' source is
#           gone): the controller counts hand.hold.stale_target and the posture, each
#           joint averaged over HOLD_WINDOW_S, drifts less than HOLD_DRIFT_RAD between
#           the first and the last window. (Not a stillness check: the fingers settle
#           into the hold, and before the arm stopped too they were knocked about at
#           4-9 rad/s with 0.001 rad of drift, docs/deployment.md.)
#   "displacement": the listener's own router was the one killed, nothing is heard
#           while it is gone: the arm before the kill against the arm once heard again.
HOLD_WINDOW_S = 0.25
HOLD_DRIFT_RAD = 0.3
DISPLACEMENT_RAD = 0.05
# The time a moving arm may take to stop after its last state heard, in the
# "displacement" check: the hardware's command timeout (0.1 s), braking, a state period.
# (A CI run of 2026-12-07 compared against the state at the moment the kill was issued,
# while the router still carried commands for a moment: 0.061 rad for an arm at
# 0.275 rad/s; from the last state heard it had moved 0.040 rad, i.e. stopped in 0.15 s.)
STOP_BUDGET_S = 0.3

# service -> (node whose status shows it is back, or for a router "site:<site>": its
# site's stream across the WAN heard again at the other site, the operator's wrist
# poses (320 Hz) at the robot's, the PR2's joint states (100 Hz) at the operator's;
# the nodes' statuses come once a second, too coarse for a 1 s bound; robots:
# (recording, mode, must have been moving)).
SERVICES = {
    "pc1-wrist-tracker": ("wrist_tracker", [("r-pr2_arm-state", "stop", True),
                                            ("l-ur5-state", "stop", True)]),
    "pc1-camera-arm": ("camera_arm", [("l-ur5-state", "stop", True)]),
    # The arm stops too when either of the hand's commanders is gone (the arm
    # controller's hand_nodes): an arm that went on would carry the held hand into the
    # scene's objects (a CI run of 2026-12-04: posture drift 0.79 rad).
    "pc1-hand-inference": ("hand_inference", [("r-shadow_hand-state", "hold", False),
                                              ("r-pr2_arm-state", "stop", True)]),
    "pc3-local-sim": ("local_sim", [("r-pr2_arm-state", "stop", True)]),
    "pc2-arm": ("pr2_arm_controller", [("r-pr2_arm-state", "stop", True)]),
    "pc2-hand": ("shadow_hand_controller", [("r-shadow_hand-state", "stop", False),
                                            ("r-pr2_arm-state", "stop", True)]),
    "pc2-feedback": ("feedback_publisher", []),
    "robot-sim": ("remote_sim", []),
    "local-router": ("site:local", [("r-pr2_arm-state", "stop", True)]),
    "remote-router": ("site:remote", [("r-pr2_arm-state", "displacement", True)]),
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


def t_of(sample):
    return sample["_meta"]["received_s"]


def mean_position(samples):
    n = len(samples)
    return [sum(s["position"][j] for s in samples) / n for j in range(len(samples[0]["position"]))]


def counter_rise(statuses, node, counter, t0, t1):
    """How much a node's counter rose between its last status before t0 and its first
    status after t1 (None if either is missing)."""
    mine = sorted((s for s in statuses if s["node_name"] == node), key=t_of)
    a = [s for s in mine if t_of(s) <= t0]
    b = [s for s in mine if t_of(s) >= t1]
    if not (a and b):
        return None

    def value(s):
        return dict(zip(s["counter_names"], s["counter_values"])).get(counter, 0)

    return value(b[0]) - value(a[-1])


def reported_speed(sample):
    """The fastest joint by the velocity the sample reports, rad/s."""
    return max((abs(v) for v in sample.get("velocity", []) or [0.0]), default=0.0)


def stamp_of(sample):
    """The sample's own time (its header's stamp), else when it was received."""
    try:
        st = sample["header"]["stamp"]
        return st["sec"] + st["nanosec"] * 1e-9
    except (KeyError, TypeError):
        return t_of(sample)


def window_speeds(states):
    """(t, fastest joint's displacement over the next WINDOW_S / its duration) for each
    sample of a time-sorted recording that has a sample WINDOW_S or more later; t is
    when the window's first sample was received, the duration from the samples' own
    stamps (the listener receives in bursts)."""
    out, j = [], 0
    for i, s in enumerate(states):
        j = max(j, i + 1)
        while j < len(states) and stamp_of(states[j]) < stamp_of(s) + WINDOW_S:
            j += 1
        if j >= len(states):
            break
        dt = stamp_of(states[j]) - stamp_of(s)
        if dt <= 0:
            continue
        moved = max((abs(a - b) for a, b in zip(states[j]["position"], s["position"])), default=0.0)
        out.append((t_of(s), moved / dt))
    return out


def wait_moving(path, within_s, above_rad_s):
    """Until `within_s` has passed: whether the recording at `path`, as it grows, shows
    some joint faster than `above_rad_s` over its newest full window (the kill's
    trigger, check_faults.sh)."""
    deadline = time.time() + within_s
    while time.time() < deadline:
        try:
            with open(path, "rb") as f:
                f.seek(max(0, os.path.getsize(path) - 16384))
                rows = [json.loads(l) for l in f.read().splitlines()[1:]]
            speeds = window_speeds(rows)
            if speeds and speeds[-1][1] > above_rad_s:
                return True
        except (OSError, ValueError, KeyError):
            pass
        time.sleep(0.05)
    return False


def main():
    if sys.argv[1] == "--wait-moving":
        # check_faults.py --wait-moving RECORDING WITHIN_S ABOVE_RAD_S
        return 0 if wait_moving(sys.argv[2], float(sys.argv[3]), float(sys.argv[4])) else 1
    d, tag, service = Path(sys.argv[1]), sys.argv[2], sys.argv[3]
    kill, killed, start, running = (float(x) for x in sys.argv[4:8])
    others_down = sys.argv[8].split() if len(sys.argv) > 8 else []
    back_by, robots = SERVICES[service]
    ok = True

    def check(cond, text):
        nonlocal ok
        ok &= bool(cond)
        print(f"  {'ok ' if cond else 'BAD'} {text}")

    check(not others_down, "every other container kept running"
          + (f" (down: {', '.join(others_down)})" if others_down else ""))

    statuses = lines(d / f"{tag}-r-teleop-status.jsonl") + lines(d / f"{tag}-l-teleop-status.jsonl")
    for rec, mode, must_move in robots:
        states = sorted(lines(d / f"{tag}-{rec}.jsonl"), key=t_of)
        speeds = window_speeds(states)
        name = rec.split("-", 1)[1].removesuffix("-state")
        # Windows that end by the kill.
        moving = max((v for t, v in speeds if kill - 1.0 <= t <= kill - WINDOW_S), default=0.0)
        if must_move:
            check(moving > MOVING_ABOVE_RAD_S,
                  f"{name} was moving when the container was killed (fastest joint "
                  f"{moving:.3f} rad/s over {WINDOW_S} s windows in the second before)")
        if mode == "displacement":
            # The last state heard before the router went down (nothing is heard from
            # then until the restart) against the first heard again.
            last = [s for s in states if t_of(s) <= start]
            after = [s for s in states if t_of(s) >= start]
            if not (last and after):
                check(False, f"{name} heard before the kill and after the restart")
                continue
            q0, q1 = last[-1]["position"], after[0]["position"]
            moved = max(abs(a - b) for a, b in zip(q0, q1))
            # A moving arm needs a moment to stop once its commands stop arriving (the
            # hardware's command timeout, then braking): what it may travel grows with
            # its speed at the last state heard.
            v = max((abs(x) for x in last[-1].get("velocity") or [0.0]), default=0.0)
            allowed = DISPLACEMENT_RAD + v * STOP_BUDGET_S
            check(moved < allowed, f"{name} held still while its site's router was down: "
                  f"moved {moved:.4f} rad in {t_of(after[0]) - t_of(last[-1]):.1f} s after "
                  f"the last state heard (fastest joint then {v:.3f} rad/s: at most "
                  f"{allowed:.3f} rad, {DISPLACEMENT_RAD} + a stop within {STOP_BUDGET_S} s)")
        elif mode == "hold":
            gone = [s for s in states if killed + SETTLE_S <= t_of(s) <= start]
            if not gone:
                check(False, f"{name} heard while the container was gone")
                continue
            first = [s for s in gone if t_of(s) <= t_of(gone[0]) + HOLD_WINDOW_S]
            last = [s for s in gone if t_of(s) >= t_of(gone[-1]) - HOLD_WINDOW_S]
            drift = max(abs(a - b) for a, b in zip(mean_position(first), mean_position(last)))
            holds = counter_rise(statuses, "shadow_hand_controller", "hand.hold.stale_target",
                                 kill, start)
            check(holds is not None and holds > 0 and drift < HOLD_DRIFT_RAD,
                  f"{name} held its posture while its targets' source was gone: "
                  f"hand.hold.stale_target +{holds}, posture drift {drift:.3f} rad over "
                  f"{t_of(gone[-1]) - t_of(gone[0]):.1f} s (joints averaged over {HOLD_WINDOW_S} s)")
        else:
            # Windows wholly between SETTLE_S after the kill and the restart.
            gone = [v for t, v in speeds if killed + SETTLE_S <= t <= start - WINDOW_S]
            fastest = max(gone, default=None)
            reported = max((reported_speed(s) for s in states
                            if killed + SETTLE_S <= t_of(s) <= start), default=0.0)
            # When it came to rest: the first window after the kill from which on every
            # window until the restart is below the threshold.
            after_kill = [(t, v) for t, v in speeds if kill <= t <= start - WINDOW_S]
            rest = None
            for i, (t, _) in enumerate(after_kill):
                if all(v < STOPPED_BELOW_RAD_S for _, v in after_kill[i:]):
                    rest = max(0.0, t - kill)
                    break
            check(fastest is not None and fastest < STOPPED_BELOW_RAD_S,
                  f"{name} stopped while the container was gone: fastest joint "
                  f"{'-' if fastest is None else f'{fastest:.4f}'} rad/s over {WINDOW_S} s "
                  f"windows from {SETTLE_S} s after the kill until the restart ({len(gone)} "
                  f"windows; reported velocity peak {reported:.3f} rad/s); at rest "
                  f"{'never' if rest is None else f'{rest * 1000:.0f} ms after the kill was issued'}")

    if back_by.startswith("site:"):
        site = back_by.split(":")[1]
        # Heard at the other site: across the WAN.
        rec, stream = (("r-teleop-wrist_pose", "the wrist poses at the robot site")
                       if site == "local" else
                       ("l-pr2-joint_states", "the PR2 joint states at the operator site"))
        seen = [t_of(s) for s in lines(d / f"{tag}-{rec}.jsonl") if t_of(s) > running]
        what = f"the {site} site heard across the WAN again ({stream})"
    else:
        seen = [s["_meta"]["received_s"] for s in statuses
                if s["node_name"] == back_by and s["_meta"]["received_s"] > running]
        what = f"{back_by} heard again"
    bound = ROUTER_RECONNECT_WITHIN_S if back_by.startswith("site:") else RECONNECT_WITHIN_S
    if seen:
        dt = min(seen) - running
        check(dt <= bound,
              f"{what} {dt:.2f} s after its container was running again "
              f"({min(seen) - start:.2f} s after `start` was issued)")
    else:
        check(False, f"{what} after the restart")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
