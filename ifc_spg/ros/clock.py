"""ROS time: ``node.get_clock().now()`` returning a Time with ``to_msg()``, as rclpy."""

import time

from ifc_spg.ros import messages

__all__ = ['Time', 'Clock', 'Duration']


class Duration:
    """A span of time in [ns] (``Duration(seconds=0.5)``)."""

    def __init__(self, *, seconds=0, nanoseconds=0):
        self.nanoseconds = int(round(seconds * 1e9)) + int(nanoseconds)


class Time:
    """A point on the system clock in [ns] since the epoch."""

    __slots__ = ('nanoseconds',)

    def __init__(self, *, seconds=0, nanoseconds=0):
        self.nanoseconds = int(round(seconds * 1e9)) + int(nanoseconds)

    def to_msg(self):
        """builtin_interfaces/msg/Time of this time."""
        msg = messages.Time.__new__(messages.Time)
        msg.sec, msg.nanosec = divmod(self.nanoseconds, 1_000_000_000)
        return msg

    @classmethod
    def from_msg(cls, msg):
        """Time from a builtin_interfaces/msg/Time."""
        return cls(nanoseconds=msg.sec * 1_000_000_000 + msg.nanosec)

    def seconds_nanoseconds(self):
        """``(sec, nanosec)``."""
        return divmod(self.nanoseconds, 1_000_000_000)

    def __sub__(self, other):
        if isinstance(other, Time):
            return Duration(nanoseconds=self.nanoseconds - other.nanoseconds)
        return Time(nanoseconds=self.nanoseconds - other.nanoseconds)

    def __add__(self, other):
        return Time(nanoseconds=self.nanoseconds + other.nanoseconds)

    def __eq__(self, other):
        return isinstance(other, Time) and other.nanoseconds == self.nanoseconds

    def __lt__(self, other):
        return self.nanoseconds < other.nanoseconds

    def __repr__(self):
        return f'Time(nanoseconds={self.nanoseconds})'


class Clock:
    """The system (wall) clock, like rclpy's default ROS clock without /clock."""

    def now(self):
        """Current time."""
        return Time(nanoseconds=time.time_ns())
