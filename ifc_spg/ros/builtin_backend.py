"""The built-in flavour of :mod:`ifc_spg.ros`: ROS 2 over Cyclone DDS (:mod:`ifc_spg.ros.dds`).

Imported by :mod:`ifc_spg.ros` when rclpy is not used; use that module, not this one.
"""

from typing import TYPE_CHECKING

from ifc_spg.ros import protocols as _protocols
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
    latched,
    qos_profile_sensor_data,
)

__all__ = [
    'BACKEND',
    'DurabilityPolicy',
    'FloatingPointRange',
    'HistoryPolicy',
    'HotPath',
    'IntegerRange',
    'Node',
    'Parameter',
    'ParameterDescriptor',
    'QoSProfile',
    'RMW',
    'ReliabilityPolicy',
    'SetParametersResult',
    'executor',
    'init',
    'latched',
    'new_context',
    'ok',
    'qos_profile_sensor_data',
    'shutdown',
    'spin',
    'spin_hot',
    'spin_once',
    'spin_until',
    'wait_for_acks',
]

BACKEND = 'cyclonedds'
RMW = 'cyclonedds (built-in, rmw_cyclonedds_cpp wire format)'

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

def spin_hot(node, subscription, timeout_sec=0.1, until=None):
    """:func:`spin`: the built-in executor already serves a subscription without overhead.

    (rclpy's :func:`~ifc_spg.ros.rclpy_backend.spin_hot` takes ``subscription`` out of the
    executor; here its reader's callback runs from the same wait as everything else.) Ends
    when the context shuts down or ``until()`` is True.
    """
    if until is None:
        spin(node)
        return
    ex = executor((node,))
    while node.context.ok() and not until():
        ex.spin_once(timeout_sec)

class HotPath:
    """``subscription`` of ``node`` served by :meth:`spin_once`, as rclpy's :class:`HotPath`.

    The built-in executor already serves a subscription without overhead: its reader's
    callback runs from the same wait as everything else, so this is the node's executor.
    """

    def __init__(self, node, subscription):
        self._executor = executor((node,))

    def spin_once(self, timeout_sec=None):
        """Wait up to ``timeout_sec`` [s] for one round of callbacks."""
        self._executor.spin_once(timeout_sec)

    def close(self):
        """Nothing to give back."""

def wait_for_acks(publisher, timeout_sec=1.0):
    """Wait until every matched reliable reader acknowledged what ``publisher`` sent.

    True if they did within ``timeout_sec`` [s].
    """
    return publisher.wait_for_acks(timeout_sec)


if TYPE_CHECKING:  # this backend's Node meets the Protocol node code is typed with
    def _meets_protocol(node: Node) -> _protocols.Node:
        return node
