"""The project's own message types (shared/msgs/msg/*.msg) and tf2_msgs/TFMessage (not
in ros2_pyterfaces), defined on pyzeros's side from their ROS 2 definitions, for the
interop scripts beside this file. pyzeros computes their RIHS01 hashes itself."""

from dataclasses import dataclass, field

from ros2_pyterfaces.cyclone.idl import IdlStruct, types
from ros2_pyterfaces.cyclone.std_msgs.msg import Header
from ros2_pyterfaces.cyclone.geometry_msgs.msg import TransformStamped


@dataclass
class TFMessage(IdlStruct, typename="tf2_msgs/msg/TFMessage"):
    transforms: types.sequence[TransformStamped] = field(default_factory=list)


@dataclass
class OperatorInput(IdlStruct, typename="teleop_msgs/msg/OperatorInput"):
    header: Header = field(default_factory=Header)
    clutch: bool = False
    enable: bool = False
    camera_stop: bool = False
    motion_scale: types.float64 = 1.0


@dataclass
class FingertipPressures(IdlStruct, typename="teleop_msgs/msg/FingertipPressures"):
    header: Header = field(default_factory=Header)
    ff: types.float64 = 0.0
    mf: types.float64 = 0.0
    rf: types.float64 = 0.0
    lf: types.float64 = 0.0
    th: types.float64 = 0.0


@dataclass
class JointCommand(IdlStruct, typename="teleop_msgs/msg/JointCommand"):
    header: Header = field(default_factory=Header)
    mode: str = ""
    name: types.sequence[str] = field(default_factory=list)
    position: types.sequence[types.float64] = field(default_factory=list)
    velocity: types.sequence[types.float64] = field(default_factory=list)
    effort: types.sequence[types.float64] = field(default_factory=list)
    stiffness: types.sequence[types.float64] = field(default_factory=list)
    damping: types.sequence[types.float64] = field(default_factory=list)
    max_effort: types.sequence[types.float64] = field(default_factory=list)


@dataclass
class NodeStatus(IdlStruct, typename="teleop_msgs/msg/NodeStatus"):
    header: Header = field(default_factory=Header)
    node_name: str = ""
    lifecycle_state: types.uint8 = 0
    counter_names: types.sequence[str] = field(default_factory=list)
    counter_values: types.sequence[types.uint64] = field(default_factory=list)
    last_error: str = ""
