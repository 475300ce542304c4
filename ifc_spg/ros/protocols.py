"""What node code needs of a ROS node, publisher, timer and logger, as typing Protocols.

rclpy's classes and the built-in backend's (:mod:`ifc_spg.ros.dds`) both meet them (each
backend module checks it statically), so code that takes a node, e.g.
``MarkerPublisher(node: Node, ...)``, is typed once for either backend. Messages, message
classes and QoS profiles are ``Any`` here: each backend has its own classes (the dynamic seam).
"""

from collections.abc import Callable
from typing import Any, Protocol

__all__ = ['Logger', 'Node', 'Publisher', 'Timer']


class Logger(Protocol):
    """A node's logger (``node.get_logger()``)."""

    def debug(self, message: str, /) -> object:
        """Log ``message`` at DEBUG."""
        ...

    def info(self, message: str, /) -> object:
        """Log ``message`` at INFO."""
        ...

    def warning(self, message: str, /) -> object:
        """Log ``message`` at WARN."""
        ...

    def error(self, message: str, /) -> object:
        """Log ``message`` at ERROR."""
        ...


class Publisher(Protocol):
    """A publisher (``node.create_publisher(...)``)."""

    def publish(self, msg: Any, /) -> None:  # a message of the backend's class
        """Publish ``msg``."""
        ...

    def get_subscription_count(self) -> int:
        """The number of matched subscriptions."""
        ...


class Timer(Protocol):
    """A timer (``node.create_timer(...)``)."""

    def cancel(self) -> None:
        """Stop it."""
        ...


class Node(Protocol):
    """A ROS node of either backend (``ifc_spg.ros.Node``)."""

    def get_name(self) -> str:
        """The node name."""
        ...

    def get_logger(self) -> Logger:
        """The node's logger."""
        ...

    def create_publisher(self, msg_type: Any, topic: str, qos_profile: Any, /) -> Publisher:
        """A publisher of ``msg_type`` on ``topic`` (a QoSProfile or a depth)."""
        ...

    def create_subscription(self, msg_type: Any, topic: str, callback: Callable[[Any], None],
                            qos_profile: Any, /) -> Any:
        """A subscription calling ``callback(msg)`` (a QoSProfile or a depth)."""
        ...

    def create_timer(self, timer_period_sec: float, callback: Callable[[], Any], /) -> Timer:
        """A timer calling ``callback()`` every ``timer_period_sec`` [s]."""
        ...

    def declare_parameter(self, name: str, value: Any = None, descriptor: Any = None,
                          /) -> Any:
        """Declare parameter ``name`` (its value: the override, else ``value``)."""
        ...

    def destroy_subscription(self, subscription: Any, /) -> Any:
        """Destroy a subscription of this node."""
        ...

    def destroy_timer(self, timer: Any, /) -> Any:
        """Destroy a timer of this node."""
        ...

    def add_on_set_parameters_callback(self, callback: Callable[[list[Any]], Any], /) -> Any:
        """Call ``callback(parameters)`` before parameters are set (it accepts or refuses)."""
        ...

    def set_parameters(self, parameter_list: list[Any], /) -> list[Any]:
        """Set parameters; the SetParametersResult of each."""
        ...

    def destroy_node(self) -> Any:
        """Destroy the node and its entities."""
        ...
