"""Checks the compose run's end-of-run report (report.json of `teleop report`) against
the local-site goals the launch test asserts on one machine: the camera within 1 cm on
average and 3 cm at worst of its goal with the hand fully in view in >= 99.5 % of
frames, the PR2 within 5 mm on average of the scaled operator motion over one clutch
engagement, hand joints within 1.2x the shipped model's offline error, every latency
stage measured. Prints each figure with its goal; exits 1 on a miss, 3 on a miss in a
run where the PR2 arm made a safety stop on a stale wrist pose."""

import json
import sys

OFFLINE_TEST_MEAN_ERROR_RAD = 0.0948  # docs/hand-inference.md, the shipped model

def main(path: str) -> int:
    with open(path, encoding="utf-8") as f:
        r = json.load(f)
    checks = [
        ("depth frames", r["depth_frames"], ">", 300),
        ("hand fully in view", r["fraction_hand_fully_in_view"], ">=", 0.995),
        ("camera error mean (m)", r["camera_position_error_m"]["mean"], "<=", 0.01),
        ("camera error max (m)", r["camera_position_error_m"]["max"], "<=", 0.03),
        ("clutch engagements", r["clutch_engagements"], "==", 1),
        ("PR2 samples", r["pr2_position_error_m"]["samples"], ">", 500),
        ("PR2 error mean (m)", r["pr2_position_error_m"]["mean"], "<=", 0.005),
        ("finger target frames", r["finger_target_frames"], ">", 0.8 * r["depth_frames"]),
        ("hand joint error mean (rad)", r["hand_joint_mean_error_rad"]["mean"], "<=",
         1.2 * OFFLINE_TEST_MEAN_ERROR_RAD),
    ]
    for stage in r["latency"]:
        checks.append((f"latency samples: {stage['stage']}", stage["samples"], ">", 100))
    ops = {">": lambda a, b: a > b, ">=": lambda a, b: a >= b,
           "<=": lambda a, b: a <= b, "==": lambda a, b: a == b}
    failed = 0
    for name, value, op, goal in checks:
        ok = ops[op](value, goal)
        failed += not ok
        print(f"  {'ok ' if ok else 'BAD'} {name}: {value:.4g} (goal {op} {goal:.4g})")
    if failed and r.get("pr2_stops", {}).get("stale_wrist_pose", 0) > 0:
        # The PR2 arm made a safety stop on a wrist pose older than its deadline (a
        # stall of the poses on the way, > 100 ms): it then waits for a fresh clutch
        # press the scripted operator does not make, and the figures above measure
        # that stop, not the tracking. Exit 3 tells the compose test so.
        print("  the PR2 arm made a safety stop on a stale wrist pose during the task "
              f"(pr2_stops: {r['pr2_stops']})")
        return 3
    return 1 if failed else 0

if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
