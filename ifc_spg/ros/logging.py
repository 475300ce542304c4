"""A node logger with rclpy's call shapes: ``get_logger().info('...')``.

Lines go to stderr as rcutils formats them by default:
``[INFO] [1700000000.123456789] [node_name]: message``.
"""

import sys
import time
from typing import Any, TextIO

__all__ = ['Logger', 'LEVELS']

LEVELS = {'debug': 10, 'info': 20, 'warn': 30, 'error': 40, 'fatal': 50}


class Logger:
    """Severity-filtered logger; ``once=True`` and ``throttle_duration_sec=`` as rclpy."""

    def __init__(self, name: str, level: str = 'info', stream: TextIO | None = None) -> None:
        self.name = name
        self.level = LEVELS.get(level, 20)
        self.stream = stream
        self._once: set[int | None] = set()  # call-site line numbers
        self._last: dict[int | None, float] = {}

    def set_level(self, level: str) -> None:
        """Set the severity threshold ('debug', 'info', 'warn', 'error', 'fatal')."""
        self.level = LEVELS.get(str(level).lower(), self.level)

    def get_child(self, suffix: str) -> 'Logger':
        """A logger named ``name.suffix`` with the same level."""
        child = Logger(f'{self.name}.{suffix}', stream=self.stream)
        child.level = self.level
        return child

    def _log(self, severity: str, message: str, once: bool = False,
             throttle_duration_sec: float | None = None, **_: object) -> bool:
        if LEVELS[severity] < self.level:
            return False
        key = sys._getframe(2).f_lineno if (once or throttle_duration_sec) else None
        if once:
            if key in self._once:
                return False
            self._once.add(key)
        if throttle_duration_sec:
            now = time.monotonic()
            if now - self._last.get(key, -1e18) < throttle_duration_sec:
                return False
            self._last[key] = now
        stamp = time.time_ns()
        line = (f'[{severity.upper()}] [{stamp // 10**9}.{stamp % 10**9:09d}] '
                f'[{self.name}]: {message}\n')
        (self.stream or sys.stderr).write(line)
        return True

    def debug(self, message: str, **kwargs: Any) -> bool:
        """Log at DEBUG."""
        return self._log('debug', message, **kwargs)

    def info(self, message: str, **kwargs: Any) -> bool:
        """Log at INFO."""
        return self._log('info', message, **kwargs)

    def warn(self, message: str, **kwargs: Any) -> bool:
        """Log at WARN."""
        return self._log('warn', message, **kwargs)

    warning = warn

    def error(self, message: str, **kwargs: Any) -> bool:
        """Log at ERROR."""
        return self._log('error', message, **kwargs)

    def fatal(self, message: str, **kwargs: Any) -> bool:
        """Log at FATAL."""
        return self._log('fatal', message, **kwargs)
