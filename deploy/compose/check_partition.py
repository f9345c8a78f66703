"""Checks a cut of the commands during a clutched motion (a WAN partition, or the
commanding wrist tracker's container paused), from what a listener on the robot
site's LAN recorded (`teleop topic echo --format json` of /teleop/wrist_pose and
/teleop/status): the PR2 arm controller stopped within 100 ms of the deadline of the
last valid wrist pose it could have had before the cut, it refused the stale commands
the link released when it returned (for a partition: `--released-late`), and it stayed
stopped until a fresh clutch press reached it: no Active report and no new engagement
before a report whose `arm.stop.clutch_released` rose. (The simulated operator lets go
of the pedal and presses it again when the display shows the arm's Fault, as a person
would: teleop_sim::operator_site::reclutch; the arm may follow again after that.)

    check_partition.py WRIST.jsonl STATUS.jsonl CUT_S RESTORED_S [--released-late]

Prints what it measured; exits 1 on a miss. Exits 2 when the premise did not hold:
the arm was not Active (clutched, moving) when the commands were cut, because it had
stopped before for a reason of its own (a stall of the wrist poses on a loaded
machine, say); then nothing about the cut can be judged, it prints the arm's reports
before the cut and why it stopped, and the caller may run the cut again."""

import json
import sys

WRIST_POSE_DEADLINE_S = 0.100  # the topic table's deadline; the arm's pose_deadline_s
STOP_WITHIN_S = 0.100          # the bound after that deadline
ACTIVE = 2


def lines(path):
    with open(path, encoding="utf-8") as f:
        return [json.loads(l) for l in f if l.strip().startswith("{")]


def counter(status, name):
    try:
        return status["counter_values"][status["counter_names"].index(name)]
    except ValueError:
        return None


def explain(arm, wrist, last):
    """The arm's reports in the 8 s before the cut (time before the last wrist pose,
    lifecycle state, stop counters that rose since the report before) and the gaps of
    more than 100 ms between the wrist poses a listener on the robot's LAN received."""
    before = None
    for s in arm:
        t = s["_meta"]["sent_s"] - last
        if -8.0 <= t <= 0.5:
            rose = {n: v - (counter(before, n) or 0) for n, v in
                    zip(s["counter_names"], s["counter_values"])
                    if n.startswith("arm.stop.") and before is not None
                    and v > (counter(before, n) or 0)}
            print(f"      {t:+7.3f} s  lifecycle {s['lifecycle_state']}  stops {rose or '-'}")
        before = s
    near = [t for t in wrist if last - 8.0 <= t <= last]
    gaps = [(a - last, b - a) for a, b in zip(near, near[1:]) if b - a > WRIST_POSE_DEADLINE_S]
    print("      wrist pose gaps > 100 ms before the cut: "
          + (", ".join(f"{1e3 * g:.0f} ms at {t:+.3f} s" for t, g in gaps) or "none"))


def main(wrist_path, status_path, partition_on_s, partition_off_s, released_late):
    on, off = float(partition_on_s), float(partition_off_s)
    wrist = sorted(w["_meta"]["received_s"] for w in lines(wrist_path))
    arm = [s for s in lines(status_path) if s["node_name"] == "pr2_arm_controller"]
    arm.sort(key=lambda s: s["_meta"]["sent_s"])
    ok = True

    def check(cond, text):
        nonlocal ok
        ok &= cond
        print(f"  {'ok ' if cond else 'BAD'} {text}")

    # The cut: the longest silence of the wrist poses around the cut (the
    # commands that set it take a moment to reach the emulator).
    window = [t for t in wrist if on - 1.0 <= t <= off + 2.0]
    gaps = [(b - a, a, b) for a, b in zip(window, window[1:])]
    check(bool(gaps), f"wrist poses around the cut ({len(window)})")
    if not gaps:
        return 1
    silence, last, back = max(gaps)
    check(silence >= 1.5, f"the wrist poses fell silent for {silence:.2f} s (cut 2 s)")
    deadline = last + WRIST_POSE_DEADLINE_S
    at_cut = [s for s in arm if s["_meta"]["sent_s"] <= last]
    if not (at_cut and at_cut[-1]["lifecycle_state"] == ACTIVE):
        print("  --  the arm was not Active (clutched, moving) when the commands were cut:"
              " the cut cannot be judged; its reports before the cut:")
        explain(arm, wrist, last)
        return 2
    print("  ok  the arm was Active (clutched, moving) when the commands were cut")
    stops = [s for s in arm if s["_meta"]["sent_s"] > last and s["lifecycle_state"] != ACTIVE]
    check(bool(stops), "the arm left Active after the cut")
    if not stops:
        return 1
    stop = stops[0]["_meta"]["sent_s"]
    late = stop - deadline
    check(late <= STOP_WITHIN_S,
          f"stopped {1e3 * (stop - last):.0f} ms after the last valid wrist pose, "
          f"{1e3 * late:.0f} ms after its deadline (bound {1e3 * STOP_WITHIN_S:.0f} ms)")
    # A fresh clutch press: the first report after the stop in which the arm counted a
    # release of the clutch (the release clears its latch; the press that follows may
    # engage it again).
    released_at_stop = counter(stops[0], "arm.stop.clutch_released") or 0
    release = next((s for s in arm if s["_meta"]["sent_s"] > stop
                    and (counter(s, "arm.stop.clutch_released") or 0) > released_at_stop), None)
    until = release["_meta"]["sent_s"] if release else float("inf")
    before = [s for s in arm if stop < s["_meta"]["sent_s"] < until]
    resumed = [s for s in before if s["lifecycle_state"] == ACTIVE]
    check(not resumed, f"stayed stopped until a fresh clutch press ({len(resumed)} Active reports "
          f"before it; the last report {arm[-1]['_meta']['sent_s'] - back:.1f} s after the poses "
          "came back)")
    engaged_at_cut = counter(at_cut[-1], "arm.engagements")
    engaged_before = counter(before[-1] if before else stops[0], "arm.engagements")
    check(engaged_before == engaged_at_cut,
          f"no new engagement before a fresh clutch press (arm.engagements {engaged_at_cut} -> "
          f"{engaged_before})")
    if release:
        engaged_end = counter(arm[-1], "arm.engagements")
        print(f"  the clutch was released {release['_meta']['sent_s'] - stop:.2f} s after the stop"
              f" and pressed again; arm.engagements at the end {engaged_end}")
    else:
        print("  no fresh clutch press reached the arm")
    stale_at_cut = counter(at_cut[-1], "wrist_pose.rejected_stale") or 0
    stale_end = counter(arm[-1], "wrist_pose.rejected_stale") or 0
    if released_late:
        check(stale_end > stale_at_cut,
              f"the stale wrist poses the link released were refused ({stale_at_cut} -> {stale_end})")
    else:
        print(f"  wrist poses refused as stale after the cut: {stale_end - stale_at_cut}")
    reasons = {n: v for n, v in zip(arm[-1]["counter_names"], arm[-1]["counter_values"])
               if n.startswith("arm.stop.") and v}
    print(f"  stop counters at the end: {reasons}")
    return 0 if ok else 1


if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    sys.exit(main(*args[:4], released_late="--released-late" in sys.argv))
