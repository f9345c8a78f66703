"""Checks a dataset written by `teleop export lerobot` with LeRobot itself.

Usage: check_lerobot.py BAG DATASET --fps N --max-age-ms MS --min-episode-s S

Independent of the exporter: the bag is read with Foxglove's MCAP reader and its ROS 2
decoder, the episodes (clutch engagements: clutch and enable held) and every frame's
expected values are derived here from the documented rule (frame k of an episode at
start + k/fps, each input's newest message stamped at or before it and at most
MAX-AGE old; frames missing an input cut the episode; runs shorter than MIN-EPISODE
dropped), and compared with what `lerobot.datasets.lerobot_dataset.LeRobotDataset`
loads: frame and episode counts, every state and action value, timestamps, task text,
and each camera frame decoded from the video against the JPEG it should be.

Prints one JSON object; exits 1 with the first mismatch named.
"""

import argparse
import io
import json
import math
import pathlib
import sys

import numpy as np
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from PIL import Image

PR2 = ["r_shoulder_pan_joint", "r_shoulder_lift_joint", "r_upper_arm_roll_joint",
       "r_elbow_flex_joint", "r_forearm_roll_joint", "rh_WRJ2", "rh_WRJ1"]
FINGERS = ["rh_FFJ4", "rh_FFJ3", "rh_FFJ2", "rh_MFJ4", "rh_MFJ3", "rh_MFJ2", "rh_RFJ4",
           "rh_RFJ3", "rh_RFJ2", "rh_LFJ5", "rh_LFJ4", "rh_LFJ3", "rh_LFJ2", "rh_THJ5",
           "rh_THJ4", "rh_THJ3", "rh_THJ2"]


def stamp(msg):
    return msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec


def by_name(msg, names, values=None):
    values = msg.position if values is None else values
    if len(values) != len(msg.name):
        return None
    pos = dict(zip(msg.name, values))
    if not all(n in pos and math.isfinite(pos[n]) for n in names):
        return None
    return [pos[n] for n in names]


def read_bag(bag):
    files = sorted(pathlib.Path(bag).glob("*.mcap")) if pathlib.Path(bag).is_dir() else [bag]
    streams = {k: [] for k in ["arm", "hand", "forces", "wrist", "pedals", "fingers",
                            "arm_command", "hand_command", "top", "side"]}
    factory = DecoderFactory()
    decoders = {}
    for f in files:
        with open(f, "rb") as fh:
            # File order; equal stamps are ordered by arrival (log time) below.
            for schema, channel, message in make_reader(fh).iter_messages(log_time_order=False):
                t = channel.topic
                if schema.id not in decoders:
                    decoders[schema.id] = factory.decoder_for(channel.message_encoding, schema)
                try:
                    # A malformed message is skipped, as the exporter must skip it.
                    msg = decoders[schema.id](message.data)
                    s = stamp(msg)
                except Exception:  # noqa: BLE001 - any undecodable message
                    continue
                add(streams, t, msg, s, message.log_time)
    for k in streams:
        # By stamp, equal stamps by arrival (stable: then file order); the last wins.
        streams[k].sort(key=lambda sv: (sv[0], sv[2]))
        streams[k] = [(s, v) for s, v, _ in streams[k]]
    return streams


def add(streams, t, msg, s, log_time):
    """Adds one decoded message to its input's stream, if it is usable."""
    if s <= 0:
        return
    v = None
    if t == "/teleop/pr2/joint_states":
        key, v = "arm", by_name(msg, PR2)
    elif t == "/teleop/shadow/joint_states":
        key, v = "hand", by_name(msg, FINGERS)
    elif t == "/teleop/hand/joint_targets":
        key, v = "fingers", by_name(msg, FINGERS)
    elif t == "/teleop/hw/pr2_arm/command":
        key, v = "arm_command", by_name(msg, PR2, msg.velocity)
    elif t == "/teleop/hw/shadow_hand/command":
        key = "hand_command"
        v = by_name(msg, FINGERS) if msg.mode in ("position", "impedance") else None
    elif t == "/teleop/shadow/fingertip_pressures":
        key, v = "forces", [msg.ff, msg.mf, msg.rf, msg.lf, msg.th]
    elif t == "/teleop/wrist_pose":
        p, q = msg.pose.position, msg.pose.orientation
        key, v = "wrist", [p.x, p.y, p.z, q.x, q.y, q.z, q.w]
    elif t == "/teleop/operator_input":
        key, v = "pedals", (bool(msg.clutch), bool(msg.enable), msg.motion_scale)
        if not math.isfinite(msg.motion_scale):
            v = None
    elif t in ("/teleop/remote_camera/top/image/compressed",
               "/teleop/remote_camera/side/image/compressed"):
        key = "top" if "/top/" in t else "side"
        data = bytes(msg.data)
        v = data if "jpeg" in msg.format and data[:2] == b"\xff\xd8" else None
    else:
        return
    if v is None or (isinstance(v, list) and not all(math.isfinite(x) for x in v)):
        return
    streams[key].append((s, v, log_time))


def newest(stream, t, max_age):
    # Newest message stamped at or before t.
    lo, hi = 0, len(stream)
    while lo < hi:
        mid = (lo + hi) // 2
        if stream[mid][0] <= t:
            lo = mid + 1
        else:
            hi = mid
    if lo == 0 or t - stream[lo - 1][0] > max_age:
        return None
    return stream[lo - 1][1]


def expected_frames(streams, fps, max_age_ns, min_frames, inputs):
    episodes = []
    pedals = streams["pedals"]
    intervals, start = [], None
    for t, (clutch, enable, _) in pedals:
        if clutch and enable and start is None:
            start = t
        elif not (clutch and enable) and start is not None:
            intervals.append((start, t))
            start = None
    if start is not None and pedals[-1][0] > start:
        intervals.append((start, pedals[-1][0]))
    missing = 0
    for a, b in intervals:
        n = (b - a) * fps // 1_000_000_000
        rows = []
        for k in range(n):
            t = a + k * 1_000_000_000 // fps
            row = {key: newest(streams[key], t, max_age_ns) for key in inputs}
            if any(v is None for v in row.values()):
                missing += 1
                row = None
            rows.append(row)
        run = []
        for row in rows + [None]:
            if row is not None:
                run.append(row)
                continue
            if len(run) >= min_frames:
                episodes.append(run)
            run = []
    return episodes, missing


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("bag")
    ap.add_argument("dataset")
    ap.add_argument("--fps", type=int, required=True)
    ap.add_argument("--max-age-ms", type=float, required=True)
    ap.add_argument("--min-episode-s", type=float, required=True)
    ap.add_argument("--task", required=True)
    ap.add_argument("--action", choices=["operator", "robot"], default="operator")
    args = ap.parse_args()

    from lerobot.datasets.lerobot_dataset import LeRobotDataset
    import torch

    streams = read_bag(args.bag)
    views = [k for k in ("top", "side") if streams[k]]
    commands = ["wrist", "pedals", "fingers"] if args.action == "operator" else \
        ["arm_command", "hand_command"]
    inputs = ["arm", "hand"] + (["forces"] if streams["forces"] else []) + commands + views
    min_frames = max(1, math.ceil(args.min_episode_s * args.fps))
    episodes, missing = expected_frames(
        streams, args.fps, round(args.max_age_ms * 1e6), min_frames, inputs)

    ds = LeRobotDataset("teleop/check", root=args.dataset)
    fail = []

    def check(cond, what):
        if not cond:
            fail.append(what)
        return cond

    total = sum(len(e) for e in episodes)
    check(ds.fps == args.fps, f"fps {ds.fps} != {args.fps}")
    check(ds.meta.total_episodes == len(episodes),
          f"episodes {ds.meta.total_episodes} != {len(episodes)} derived from the bag")
    check(len(ds) == total, f"frames {len(ds)} != {total} derived from the bag")
    check(sorted(ds.meta.video_keys) == sorted(f"observation.images.{v}" for v in views),
          f"video keys {ds.meta.video_keys}")
    state_err = action_err = 0.0
    image_mad = []
    wrong_views = 0
    i = 0
    for e, rows in enumerate(episodes):
        for k, row in enumerate(rows):
            if i >= len(ds) or fail:
                break
            item = ds[i]
            i += 1
            want_state = np.array(row["arm"] + row["hand"], dtype=np.float32)
            if args.action == "operator":
                clutch, enable, scale = row["pedals"]
                want_action = np.array(row["wrist"] + [float(clutch), float(enable), scale] +
                                       row["fingers"], dtype=np.float32)
            else:
                want_action = np.array(row["arm_command"] + row["hand_command"], dtype=np.float32)
            state_err = max(state_err, float(np.abs(item["observation.state"].numpy() - want_state).max()))
            action_err = max(action_err, float(np.abs(item["action"].numpy() - want_action).max()))
            check(item["episode_index"].item() == e, f"frame {i - 1}: episode {item['episode_index']} != {e}")
            check(item["frame_index"].item() == k, f"frame {i - 1}: frame_index {item['frame_index']} != {k}")
            check(abs(item["timestamp"].item() - k / args.fps) < 1e-4,
                  f"frame {i - 1}: timestamp {item['timestamp'].item()} != {k / args.fps}")
            check(item["task"] == args.task, f"frame {i - 1}: task {item['task']!r}")
            if "forces" in row:
                f = item["observation.fingertip_forces"].numpy()
                check(np.array_equal(f, np.array(row["forces"], dtype=np.float32)),
                      f"frame {i - 1}: fingertip forces {f} != {row['forces']}")
            for v in views:
                got = item[f"observation.images.{v}"].numpy()  # C, H, W in [0, 1]
                want = np.asarray(Image.open(io.BytesIO(row[v])).convert("RGB"),
                                  dtype=np.float32).transpose(2, 0, 1) / 255.0
                if not check(got.shape == want.shape, f"frame {i - 1} {v}: shape {got.shape} != {want.shape}"):
                    break
                mad = float(np.abs(got - want).mean())
                image_mad.append(mad)
                # The right view, not a neighbour: closer to the expected JPEG than to
                # every other view of the episode that differs from it.
                others = {r[v] for r in rows if r[v] != row[v]}
                for o in list(others)[:8]:
                    ow = np.asarray(Image.open(io.BytesIO(o)).convert("RGB"),
                                    dtype=np.float32).transpose(2, 0, 1) / 255.0
                    if float(np.abs(got - ow).mean()) <= mad:
                        wrong_views += 1
                        break
    check(state_err == 0.0, f"observation.state differs by up to {state_err}")
    check(action_err == 0.0, f"action differs by up to {action_err}")
    check(wrong_views == 0, f"{wrong_views} frames show another view than the bag's")
    if image_mad:
        check(max(image_mad) < 0.02, f"a decoded view differs from its JPEG by {max(image_mad):.4f} on average")
    # A training loader takes it as it is.
    loader = torch.utils.data.DataLoader(ds, batch_size=8, shuffle=True)
    batch = next(iter(loader))
    check(tuple(batch["observation.state"].shape) == (min(8, len(ds)), 24),
          f"batch state shape {tuple(batch['observation.state'].shape)}")
    print(json.dumps({
        "frames": len(ds),
        "episodes": ds.meta.total_episodes,
        "expected_frames": total,
        "expected_episodes": len(episodes),
        "frames_missing": missing,
        "state_max_error": state_err,
        "action_max_error": action_err,
        "image_mean_abs_diff_max": max(image_mad) if image_mad else None,
        "wrong_views": wrong_views,
        "views": views,
        "failures": fail,
    }))
    return 1 if fail else 0


if __name__ == "__main__":
    sys.exit(main())
