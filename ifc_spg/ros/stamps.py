"""Stamps and nanoseconds, converted in one place.

``builtin_interfaces/Time`` (and ``Duration``) fields to integer nanoseconds and back:

    from ifc_spg.ros.stamps import stamp_to_ns, set_stamp
    ns = stamp_to_ns(msg.header.stamp)        # sec * 1e9 + nanosec, as an int
    set_stamp(msg.header.stamp, ns)            # sec, nanosec = divmod(ns, 1e9)
"""

from typing import Any

__all__ = ['NS_PER_S', 'join_ns', 'set_stamp', 'split_ns', 'stamp_to_ns', 'stamp_to_sec']

NS_PER_S = 1_000_000_000


def join_ns(sec: float, nanosec: float) -> int:
    """``sec`` and ``nanosec`` (ints, or floats holding ints) as integer nanoseconds."""
    return int(sec) * NS_PER_S + int(nanosec)


def split_ns(ns: int) -> tuple[int, int]:
    """Integer nanoseconds as ``(sec, nanosec)``, nanosec in [0, 1e9)."""
    sec, nanosec = divmod(int(ns), NS_PER_S)
    return sec, nanosec


def stamp_to_ns(stamp: Any) -> int:
    """A ``builtin_interfaces/Time`` or ``Duration`` (``sec``, ``nanosec``) as integer ns."""
    return join_ns(stamp.sec, stamp.nanosec)


def stamp_to_sec(stamp: Any) -> float:
    """A ``builtin_interfaces/Time`` or ``Duration`` in seconds (float)."""
    return int(stamp.sec) + int(stamp.nanosec) * 1e-9


def set_stamp(stamp: Any, ns: int) -> Any:
    """Write integer nanoseconds ``ns`` into ``stamp``'s ``sec`` and ``nanosec``; ``stamp``."""
    stamp.sec, stamp.nanosec = split_ns(ns)
    return stamp
