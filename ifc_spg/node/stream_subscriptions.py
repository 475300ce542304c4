"""spg_node's subscriptions to the topics of streamed task references (both backends).

A stack with ``equal: {stream: TOPIC}`` tasks (:mod:`ifc_spg.tasks.stream`) needs a
subscription per topic while that stack runs or waits to take over; :meth:`sync` creates the
missing ones and removes those no stack uses any more. Each message goes to
:meth:`SpgRunner.handle_reference <ifc_spg.node.core.SpgRunner.handle_reference>` with the
topic as the stack wrote it. The readers are best effort (they match reliable and
best-effort publishers; a teleoperation stream wants the newest sample, not every one).
"""

import functools
from typing import Any

from ifc_spg import ros
from ifc_spg.node.core import SpgRunner
from ifc_spg.ros import msg
from ifc_spg.ros.protocols import Node as RosNode

__all__ = ['StreamSubscriptions']

_CLASSES = {'geometry_msgs/msg/PoseStamped': msg.PoseStamped,
            'sensor_msgs/msg/JointState': msg.JointState,
            'geometry_msgs/msg/WrenchStamped': msg.WrenchStamped}


class StreamSubscriptions:
    """Subscriptions that feed a runner's streamed references.

    Args:
        node: The ``ifc_spg.ros.Node``.
        runner: The :class:`~ifc_spg.node.core.SpgRunner`.
    """

    def __init__(self, node: RosNode, runner: SpgRunner) -> None:
        self.node, self.runner = node, runner
        self.subs: dict[str, Any] = {}  # topic -> subscription (of either backend)
        self._key: tuple[int, ...] | None = None

    def _on_reference(self, topic: str, message: Any) -> None:
        self.runner.handle_reference(topic, message)

    def sync(self) -> None:
        """Subscribe to the topics of the running and pending stacks' streams (only them)."""
        streams = self.runner.streams()
        key = tuple(id(s) for s in streams)
        if key == self._key:
            return
        self._key = key
        wanted = {s.topic: s.msgtype for s in streams}
        for topic in [t for t in self.subs if t not in wanted]:
            self.node.destroy_subscription(self.subs.pop(topic))
        for topic, msgtype in wanted.items():
            if topic not in self.subs:
                self.subs[topic] = self.node.create_subscription(
                    _CLASSES[msgtype], topic, functools.partial(self._on_reference, topic),
                    ros.qos_profile_sensor_data)
                self.node.get_logger().info(f"following '{topic}' ({msgtype}) for a "
                                            'streamed task')
