"""SIGINT and SIGTERM end a node's loop (``spg_node``, ``sim_bridge``).

While the loop runs, either signal raises ``KeyboardInterrupt`` where the interpreter is, so a
node blocked in a wait wakes at once. That point may be inside an extension's call back into
Python: rclpy's ``take_message`` builds the Python message through pybind11, which turns an
exception raised there into ``RuntimeError: Unable to convert call argument '0' to Python
object`` — seen once: ``sim_bridge`` in lockstep, SIGTERM'd by a test, ended with that
traceback and status 1. So any exception that surfaces after a signal arrived is the stop too
(:meth:`StopSignals.stopped_by`); one before any signal is an error, as before.
"""

from __future__ import annotations

import signal
from types import FrameType
from typing import Any

__all__ = ['StopSignals']


class StopSignals:
    """Context manager: SIGINT/SIGTERM raise ``KeyboardInterrupt`` inside it.

    Example::

        with StopSignals() as stops:
            try:
                loop()
            except BaseException as exc:
                if not stops.stopped_by(exc):
                    raise
            finally:
                stops.ignore()  # a second signal must not interrupt the clean-up
                clean_up()

    The previous handlers are back on exit.
    """

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self) -> None:
        #: the first signal received (None: none yet)
        self.received: int | None = None
        self._previous: dict[int, Any] = {}

    def __enter__(self) -> StopSignals:
        self._previous = {s: signal.signal(s, self._raise) for s in self.SIGNALS}
        return self

    def _raise(self, signum: int, frame: FrameType | None) -> None:
        if self.received is None:
            self.received = signum
        raise KeyboardInterrupt

    def stopped_by(self, exc: BaseException) -> bool:
        """Whether ``exc`` ends the loop as a stop (else it is an error to re-raise)."""
        return isinstance(exc, KeyboardInterrupt) or self.received is not None

    def ignore(self) -> None:
        """Ignore both signals from now on (during the clean-up)."""
        for sig in self._previous:
            signal.signal(sig, signal.SIG_IGN)

    def __exit__(self, *exc_info: object) -> None:
        for sig, handler in self._previous.items():
            signal.signal(sig, handler)
