"""Lists the ROS 2 graph's topics with their types through zenoh-ros2-sdk (ROBOTIS,
PyPI), a graph tool nobody here wrote, for deploy/teleop/tests/launch.rs.

`zenoh-ros2 topic list -t` opens a session and queries the liveliness tokens at once:
against an rmw_zenoh router that is enough, but among peers without a router (as
`teleop launch` runs) a fresh session has reached only some of them. This does what
the tool's own daemon does: one session, kept open while it reaches the peers
(multicast scouting on loopback), then the tool's own discovery
(`zenoh_ros2_sdk.discovery.get_topic_names_and_types`), printed as the CLI prints it:
`<topic> [<type>]` per line.

Usage: graph_oracle.py DOMAIN_ID SETTLE_S
"""

import os
import sys
import time

os.environ["ZENOH_CONFIG_OVERRIDE"] = (
    'connect/endpoints=[];scouting/multicast/enabled=true;scouting/multicast/interface="lo"'
)

from zenoh_ros2_sdk.discovery import get_topic_names_and_types  # noqa: E402
from zenoh_ros2_sdk.session import ZenohSession  # noqa: E402


def main() -> int:
    domain_id, settle_s = int(sys.argv[1]), float(sys.argv[2])
    ZenohSession.get_instance()
    time.sleep(settle_s)
    for topic, types in get_topic_names_and_types(domain_id=domain_id, timeout=2.0):
        print(f"{topic} [{', '.join(types)}]")
    sys.stdout.flush()
    os._exit(0)


if __name__ == "__main__":
    sys.exit(main())
