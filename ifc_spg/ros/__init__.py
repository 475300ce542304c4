"""The ROS 2 layer: rclpy when importable, else the built-in Cyclone DDS wire backend.

Node code is written once against this module::

    from ifc_spg import ros
    from ifc_spg.ros.msg import JointState

    ros.init(args=sys.argv)
    node = ros.Node('talker')
    pub = node.create_publisher(JointState, 'joint_states', 10)
    node.create_timer(0.002, lambda: pub.publish(JointState(name=['a1'], position=[0.0])))
    ros.spin(node)

``BACKEND`` says which one is active ('rclpy' or 'cyclonedds') and ``RMW`` which middleware
carries it ('rmw_fastrtps_cpp' from the Jazzy wheels, or whatever ``RMW_IMPLEMENTATION`` names;
'cyclonedds (built-in)'). ``IFC_SPG_ROS_BACKEND`` chooses: ``cyclonedds`` forces the built-in
backend even where rclpy is installed, ``rclpy`` requires rclpy (an ImportError names the wheels
otherwise), unset or ``auto`` takes rclpy where it imports. Beyond rclpy's own names the module
offers the few helpers both backends need to behave alike in tools and tests: ``new_context``
(a second, independent context in one process), ``spin_hot`` and ``HotPath`` (one
subscription served ahead of the executor, in a loop or one wait at a time: rclpy's hot
path), ``executor`` (one reusable single-threaded executor over a set of nodes),
``spin_until`` and ``describe`` (the start-up log line).
``parse_ros_args`` is the same pure parser in both cases. The two flavours live in
``rclpy_backend.py`` and ``builtin_backend.py``; this module only picks one, on first use of
one of its names: importing a submodule (``ifc_spg.ros.stamps``, ``.cdr``, ``.messages``) loads
neither rclpy nor Cyclone DDS.
"""

import os
from typing import TYPE_CHECKING, Any

from ifc_spg.ros.ros_args import RosArgs, parse_ros_args, remove_ros_args

__all__ = [
    'BACKEND', 'RMW', 'init', 'shutdown', 'ok', 'Node', 'spin', 'spin_hot', 'spin_once',
    'spin_until', 'HotPath', 'HOT_PATHS', 'COMMAND_INTERFACES',
    'executor', 'new_context', 'describe', 'wait_for_acks', 'QoSProfile', 'ReliabilityPolicy',
    'DurabilityPolicy', 'HistoryPolicy', 'qos_profile_sensor_data', 'latched',
    'ParameterDescriptor', 'FloatingPointRange', 'IntegerRange', 'Parameter',
    'SetParametersResult', 'parse_ros_args', 'remove_ros_args', 'RosArgs',
]

ROSPY_WHEELS = ('ros-jazzy-rclpy ros-jazzy-rmw-fastrtps-cpp ros-jazzy-sensor-msgs '
                'ros-jazzy-std-msgs ros-jazzy-geometry-msgs ros-jazzy-diagnostic-msgs')


#: How a node serves its hot subscription on rclpy (the ``hot_path`` parameter of spg_node and
#: sim_bridge): its own wait (:class:`HotPath`) or rclpy's executor
HOT_PATHS = ('wait_set', 'executor')

#: The command topic's message types (spg_node's ``command.interface``, sim_bridge's
#: ``command_interface``): JointState, Float64MultiArray, JointTrajectory
COMMAND_INTERFACES = ('joint_state', 'float64_multi_array', 'joint_trajectory')


def _choice() -> str:
    value = os.environ.get('IFC_SPG_ROS_BACKEND', '').strip().lower() or 'auto'
    if value not in ('auto', 'rclpy', 'cyclonedds'):
        raise ImportError(f"IFC_SPG_ROS_BACKEND='{value}' is not one of auto, rclpy, cyclonedds")
    return value


def _rclpy_available(choice: str) -> bool:
    if choice == 'cyclonedds':
        return False
    try:
        import rclpy  # noqa: F401
        import sensor_msgs.msg  # noqa: F401
    except ImportError as exc:
        if choice == 'rclpy':
            raise ImportError(f'IFC_SPG_ROS_BACKEND=rclpy but rclpy does not import ({exc}); '
                              f'source a ROS 2 Jazzy install or pip install {ROSPY_WHEELS}, '
                              'or unset it to use the built-in backend') from exc
        return False
    return True


# the backend's names, resolved on first use (PEP 562): importing a submodule (stamps, cdr,
# messages: the wire format and time helpers offline MCAP I/O uses) loads no DDS library.
# mypy checks the code written against this module with the built-in backend's names (always
# importable, and the API both backends share); rclpy_backend.py is checked on its own
if TYPE_CHECKING:
    from ifc_spg.ros.builtin_backend import (
        BACKEND,
        RMW,
        DurabilityPolicy,
        FloatingPointRange,
        HistoryPolicy,
        HotPath,
        IntegerRange,
        Node,
        Parameter,
        ParameterDescriptor,
        QoSProfile,
        ReliabilityPolicy,
        SetParametersResult,
        executor,
        init,
        latched,
        new_context,
        ok,
        qos_profile_sensor_data,
        shutdown,
        spin,
        spin_hot,
        spin_once,
        spin_until,
        wait_for_acks,
    )

_OWN = frozenset(('describe', 'parse_ros_args', 'remove_ros_args', 'RosArgs', 'HOT_PATHS',
                  'COMMAND_INTERFACES'))
_BACKEND_NAMES = tuple(name for name in __all__ if name not in _OWN)


def _resolve() -> None:
    """Pick the backend (once) and bind its names in this module."""
    if 'BACKEND' in globals():
        return
    if _rclpy_available(_choice()):
        from ifc_spg.ros import rclpy_backend
        chosen = vars(rclpy_backend)
    else:
        from ifc_spg.ros import builtin_backend
        chosen = vars(builtin_backend)
    globals().update({name: chosen[name] for name in _BACKEND_NAMES})


if not TYPE_CHECKING:  # mypy sees the names above, and still flags a misspelt one
    def __getattr__(name: str) -> Any:
        # only the backend's names: ``from ifc_spg.ros import stamps`` asks for 'stamps' first
        if name not in _BACKEND_NAMES:
            raise AttributeError(f'module {__name__!r} has no attribute {name!r}')
        _resolve()
        return globals()[name]

    def __dir__() -> list[str]:
        return sorted(set(globals()) | set(__all__))


def describe() -> str:
    """The backend line every node logs at start-up.

    For example ``ROS 2 backend: rclpy on rmw_fastrtps_cpp, ROS_DOMAIN_ID 0``.
    """
    _resolve()
    domain = os.environ.get('ROS_DOMAIN_ID', '0') or '0'
    return f'ROS 2 backend: {BACKEND} on {RMW}, ROS_DOMAIN_ID {domain}'
