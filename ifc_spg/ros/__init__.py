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
(a second, independent context in one process), ``executor`` (one reusable single-threaded
executor over a set of nodes), ``spin_until`` and ``describe`` (the start-up log line).
``parse_ros_args`` is the same pure parser in both cases.
"""

import os
import sys

from ifc_spg.ros.qos import latched
from ifc_spg.ros.ros_args import RosArgs, parse_ros_args, remove_ros_args

__all__ = [
    'BACKEND', 'RMW', 'init', 'shutdown', 'ok', 'Node', 'spin', 'spin_once', 'spin_until',
    'executor', 'new_context', 'describe', 'wait_for_acks', 'QoSProfile', 'ReliabilityPolicy',
    'DurabilityPolicy', 'HistoryPolicy', 'qos_profile_sensor_data', 'latched',
    'ParameterDescriptor', 'FloatingPointRange', 'IntegerRange', 'Parameter',
    'SetParametersResult', 'parse_ros_args', 'remove_ros_args', 'RosArgs',
]

ROSPY_WHEELS = ('ros-jazzy-rclpy ros-jazzy-rmw-fastrtps-cpp ros-jazzy-sensor-msgs '
                'ros-jazzy-std-msgs ros-jazzy-geometry-msgs ros-jazzy-diagnostic-msgs')


def _choice():
    value = os.environ.get('IFC_SPG_ROS_BACKEND', '').strip().lower() or 'auto'
    if value not in ('auto', 'rclpy', 'cyclonedds'):
        raise ImportError(f"IFC_SPG_ROS_BACKEND='{value}' is not one of auto, rclpy, cyclonedds")
    return value


def _rclpy_available(choice):
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


if _rclpy_available(_choice()):
    BACKEND = 'rclpy'
    import time as _time
    import weakref as _weakref

    from rcl_interfaces.msg import (
        FloatingPointRange,
        IntegerRange,
        ParameterDescriptor,
        SetParametersResult,
    )
    import rclpy
    from rclpy import ok
    from rclpy.context import Context as _Context
    from rclpy.executors import ExternalShutdownException as _ExternalShutdown
    from rclpy.executors import SingleThreadedExecutor as _Executor
    from rclpy.node import Node as _RclpyNode
    from rclpy.parameter import Parameter
    from rclpy.qos import (
        DurabilityPolicy,
        HistoryPolicy,
        QoSProfile,
        ReliabilityPolicy,
        qos_profile_sensor_data,
    )
    from rclpy.signals import SignalHandlerOptions

    def _rmw():
        from rclpy.utilities import get_rmw_implementation_identifier
        try:
            return get_rmw_implementation_identifier()
        except Exception:  # noqa: BLE001 - only for the start-up log line
            return os.environ.get('RMW_IMPLEMENTATION', 'rmw_fastrtps_cpp')

    RMW = _rmw()
    _nodes = _weakref.WeakSet()

    class Node(_RclpyNode):
        """rclpy's Node, destroyed with its context.

        :func:`shutdown` destroys the nodes of the context it shuts down (as the built-in
        backend does), so that a node does not outlive its context on the graph.
        """

        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            _nodes.add(self)

    def latched(depth=1):  # noqa: F811 - the rclpy flavour of the same profile
        """Reliable, transient-local, keep-last ``depth`` profile."""
        return QoSProfile(depth=depth, durability=DurabilityPolicy.TRANSIENT_LOCAL)

    def init(args=None, *, context=None, **kwargs):
        """rclpy.init, after the ``--ros-args`` are checked; returns the context.

        The same parser as the built-in backend's checks them (clear errors, e.g.
        ``malformed '-p rate=5'``).
        """
        parse_ros_args(sys.argv if args is None else args)
        # rclpy's own handlers shut the context down from a signal thread, under a loop that
        # may be publishing ('publisher's context is invalid'); the programs handle SIGINT and
        # SIGTERM in Python instead (ifc_spg.entry), as the built-in backend does
        kwargs.setdefault('signal_handler_options', SignalHandlerOptions.NO)
        rclpy.init(args=args, context=context, **kwargs)
        return context or rclpy.get_default_context()

    def shutdown(*, context=None):
        """Destroy the nodes of the default (or given) context and shut it down.

        A no-op when it is not initialised.
        """
        ctx = context or rclpy.get_default_context()
        for node in list(_nodes):
            if node.context is ctx:
                _nodes.discard(node)
                try:
                    node.destroy_node()
                except Exception:  # noqa: BLE001,S110 - already destroyed with its handle
                    pass
        rclpy.try_shutdown(context=context)

    def new_context(args=None):
        """A second, initialised context (for a node that must not share the default one)."""
        ctx = _Context()
        init(args=args, context=ctx)
        return ctx

    _executors = _weakref.WeakValueDictionary()

    class _NodesExecutor:
        """A SingleThreadedExecutor over a fixed set of nodes.

        A node taken over by another executor in between is added back before each spin.
        """

        def __init__(self, nodes):
            self.nodes = [_weakref.ref(n) for n in nodes]
            if os.environ.get('IFC_SPG_RCLPY_EXECUTOR') == 'events':
                from rclpy.experimental import EventsExecutor
                self.executor = EventsExecutor(context=nodes[0].context)
            else:
                self.executor = _Executor(context=nodes[0].context)

        def spin_once(self, timeout_sec=None):
            for ref in self.nodes:
                node = ref()
                if node is not None and node.executor is not self.executor:
                    self.executor.add_node(node)
            if not self.executor.context.ok():
                return
            try:
                self.executor.spin_once(timeout_sec=timeout_sec)
            except _ExternalShutdown:  # a signal shut the context down: callers check ok()
                pass
            except Exception:  # the same, between the check above and the wait set's creation
                if self.executor.context.ok():
                    raise

    def wait_for_acks(publisher, timeout_sec=1.0):
        """Wait until every matched reliable reader acknowledged what ``publisher`` sent.

        True if they did within ``timeout_sec`` [s].
        """
        from rclpy.duration import Duration

        return publisher.wait_for_all_acked(Duration(seconds=timeout_sec))

    def spin(node, executor=None):
        """Run callbacks of ``node`` until its context shuts down.

        A signal ends it quietly, as with the built-in backend.
        """
        ex = globals()['executor']((node,)) if executor is None else executor
        while node.context.ok():
            ex.spin_once(timeout_sec=0.1)

    def executor(nodes):
        """The (cached) executor of ``nodes``: ``executor(nodes).spin_once(timeout_sec)``."""
        nodes = (nodes,) if isinstance(nodes, Node) else tuple(nodes)
        key = tuple(id(n) for n in nodes)
        ex = _executors.get(key)
        if ex is None:
            ex = _executors[key] = _NodesExecutor(nodes)
            # the cache holds it weakly: the nodes keep it alive
            for node in nodes:
                node.__dict__.setdefault('_ifc_spg_executors', []).append(ex)
        return ex

    def spin_once(node, *, executor=None, timeout_sec=None):  # noqa: F811
        """Run at most one callback of ``node`` (waiting up to ``timeout_sec`` [s])."""
        if executor is not None:
            return rclpy.spin_once(node, executor=executor, timeout_sec=timeout_sec)
        return globals()['executor']((node,)).spin_once(timeout_sec)

    def spin_until(condition, timeout_sec=5.0, nodes=None):
        """Spin ``nodes`` until ``condition()`` or ``timeout_sec`` [s]; True if it held."""
        if nodes is None:
            raise ValueError('spin_until needs the nodes to spin with rclpy')
        ex = executor(nodes)
        context = ex.executor.context
        deadline = _time.monotonic() + timeout_sec
        while not condition():
            remaining = deadline - _time.monotonic()
            if remaining <= 0 or not context.ok():
                return bool(condition())
            ex.spin_once(timeout_sec=min(remaining, 0.1))
        return True
else:
    BACKEND = 'cyclonedds'
    RMW = 'cyclonedds (built-in, rmw_cyclonedds_cpp wire format)'
    from ifc_spg.ros.dds import Context as _Context
    from ifc_spg.ros.dds import Node, init, ok, spin, spin_once, spin_until
    from ifc_spg.ros.dds import shutdown as _shutdown
    from ifc_spg.ros.parameters import (
        FloatingPointRange,
        IntegerRange,
        Parameter,
        ParameterDescriptor,
        SetParametersResult,
    )
    from ifc_spg.ros.qos import (
        DurabilityPolicy,
        HistoryPolicy,
        QoSProfile,
        ReliabilityPolicy,
        qos_profile_sensor_data,
    )

    def shutdown(*, context=None):
        """Shut the default (or given) context down; a no-op when it is not initialised."""
        _shutdown(context=context)

    def new_context(args=None):
        """A second, initialised context (for a node that must not share the default one)."""
        return _Context(args)

    def executor(nodes):
        """The (cached) executor of ``nodes``: ``executor(nodes).spin_once(timeout_sec)``."""
        nodes = (nodes,) if isinstance(nodes, Node) else tuple(nodes)
        return nodes[0].context.executor(nodes)

    def wait_for_acks(publisher, timeout_sec=1.0):
        """Wait until every matched reliable reader acknowledged what ``publisher`` sent.

        True if they did within ``timeout_sec`` [s].
        """
        return publisher.wait_for_acks(timeout_sec)


def describe():
    """The backend line every node logs at start-up.

    For example ``ROS 2 backend: rclpy on rmw_fastrtps_cpp, ROS_DOMAIN_ID 0``.
    """
    domain = os.environ.get('ROS_DOMAIN_ID', '0') or '0'
    return f'ROS 2 backend: {BACKEND} on {RMW}, ROS_DOMAIN_ID {domain}'
