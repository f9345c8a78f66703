"""Reads a bag `teleop record` wrote with two independent implementations and decodes
every message with each:

* the `mcap` reader with `mcap-ros2-support`'s decoder (Foxglove's Python packages):
  each MCAP file, the `ros2` profile, every message decoded from its channel's
  `ros2msg` schema text;
* `rosbags` (Ternaris): the bag directory through its metadata.yaml, as a rosbag2 bag,
  the project's own types registered from the bag's message definitions, the standard
  ones from its ROS 2 Jazzy type store.

    python check_bag.py BAG_DIR

Prints one JSON object: {"mcap": {topic: count}, "rosbags": {topic: count},
"profile": ..., "qos": {topic: offered_qos_profiles present}}; exits 1 if a message
does not decode or the two readers disagree."""

import json
import sys
from pathlib import Path

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_typestore, get_types_from_msg

SEPARATOR = "=" * 80 + "\n"


def with_mcap(bag: Path):
    counts, qos, profiles = {}, {}, set()
    for path in sorted(bag.glob("*.mcap")):
        with path.open("rb") as f:
            reader = make_reader(f, decoder_factories=[DecoderFactory()])
            profiles.add(reader.get_header().profile)
            for _schema, channel, _message, decoded in reader.iter_decoded_messages():
                if decoded is None:
                    raise SystemExit(f"{channel.topic}: not decoded")
                counts[channel.topic] = counts.get(channel.topic, 0) + 1
                qos[channel.topic] = "offered_qos_profiles" in channel.metadata
    return counts, qos, sorted(profiles)


def with_rosbags(bag: Path):
    store = get_typestore(Stores.ROS2_JAZZY)
    counts = {}
    with Reader(bag) as reader:
        types = {}
        for c in reader.connections:
            parts = c.msgdef.data.split(SEPARATOR)
            named = [(c.msgtype, parts[0])]
            for part in parts[1:]:
                header, _, text = part.partition("\n")
                name = header.removeprefix("MSG: ").strip()
                pkg, _, typ = name.partition("/")
                named.append((f"{pkg}/msg/{typ}", text))
            for name, text in named:
                if name not in store.types and name not in types:
                    types.update(get_types_from_msg(text, name))
        store.register(types)
        for connection, _timestamp, raw in reader.messages():
            store.deserialize_cdr(raw, connection.msgtype)
            counts[connection.topic] = counts.get(connection.topic, 0) + 1
    return counts


def main():
    bag = Path(sys.argv[1])
    counts, qos, profiles = with_mcap(bag)
    rb = with_rosbags(bag)
    print(json.dumps({"mcap": counts, "rosbags": rb, "profile": profiles, "qos": qos}))
    if counts != rb:
        print("the two readers disagree", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
