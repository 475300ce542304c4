"""The ROS 2 layer: rclpy when importable, else the built-in Cyclone DDS wire backend.

Node code is written once against this module::

    from ifc_spg import ros
    from ifc_spg.ros.msg import JointState

    ros.init(args=sys.argv)
    node = ros.Node('talker')
    pub = node.create_publisher(JointState, 'joint_states', 10)
    node.create_timer(0.002, lambda: pub.publish(JointState(name=['a1'], position=[0.0])))
    ros.spin(node)

``BACKEND`` says which one is active ('rclpy' or 'cyclonedds'); set ``IFC_SPG_ROS_BACKEND=
cyclonedds`` to force the built-in one even where rclpy is installed. ``parse_ros_args`` is the
same pure parser in both cases.
"""

import os

from ifc_spg.ros.qos import latched
from ifc_spg.ros.ros_args import RosArgs, parse_ros_args, remove_ros_args

__all__ = [
    'BACKEND', 'init', 'shutdown', 'ok', 'Node', 'spin', 'spin_once', 'spin_until',
    'QoSProfile', 'ReliabilityPolicy', 'DurabilityPolicy', 'HistoryPolicy',
    'qos_profile_sensor_data', 'latched', 'ParameterDescriptor', 'FloatingPointRange',
    'IntegerRange', 'Parameter', 'parse_ros_args', 'remove_ros_args', 'RosArgs',
]


def _rclpy_available():
    if os.environ.get('IFC_SPG_ROS_BACKEND', '').lower() == 'cyclonedds':
        return False
    try:
        import rclpy  # noqa: F401
        import sensor_msgs.msg  # noqa: F401
    except ImportError:
        return False
    return True


if _rclpy_available():
    BACKEND = 'rclpy'
    import time as _time

    from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
    import rclpy
    from rclpy import init, ok, shutdown, spin, spin_once
    from rclpy.node import Node
    from rclpy.parameter import Parameter
    from rclpy.qos import (
        DurabilityPolicy,
        HistoryPolicy,
        QoSProfile,
        ReliabilityPolicy,
        qos_profile_sensor_data,
    )

    def latched(depth=1):  # noqa: F811 - the rclpy flavour of the same profile
        """Reliable, transient-local, keep-last ``depth`` profile."""
        return QoSProfile(depth=depth, durability=DurabilityPolicy.TRANSIENT_LOCAL)

    def spin_until(condition, timeout_sec=5.0, nodes=None):
        """Spin ``nodes`` until ``condition()`` or ``timeout_sec`` [s]; True if it held."""
        nodes = [nodes] if isinstance(nodes, Node) else list(nodes or [])
        if not nodes:
            raise ValueError('spin_until needs the nodes to spin with rclpy')
        executor = rclpy.executors.SingleThreadedExecutor()
        for node in nodes:
            executor.add_node(node)
        deadline = _time.monotonic() + timeout_sec
        try:
            while not condition():
                remaining = deadline - _time.monotonic()
                if remaining <= 0:
                    return bool(condition())
                executor.spin_once(timeout_sec=min(remaining, 0.1))
        finally:
            for node in nodes:
                executor.remove_node(node)
        return True
else:
    BACKEND = 'cyclonedds'
    from ifc_spg.ros.dds import Node, init, ok, shutdown, spin, spin_once, spin_until
    from ifc_spg.ros.parameters import (
        FloatingPointRange,
        IntegerRange,
        Parameter,
        ParameterDescriptor,
    )
    from ifc_spg.ros.qos import (
        DurabilityPolicy,
        HistoryPolicy,
        QoSProfile,
        ReliabilityPolicy,
        qos_profile_sensor_data,
    )
