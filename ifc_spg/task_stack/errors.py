"""The one error type of the task-stack language: where, what and how to fix it."""

from __future__ import annotations

from collections.abc import Iterable

from ifc_spg.errors import IfcSpgError

__all__ = ['TaskStackError', 'format_path']


def format_path(path: Iterable[str | int]) -> str:
    """Return ``tasks[2].subspace`` for the path tuple ``('tasks', 2, 'subspace')``."""
    out = ''
    for p in path:
        if isinstance(p, int):
            out += f'[{p}]'
        else:
            out += ('.' if out else '') + str(p)
    return out


class TaskStackError(IfcSpgError):
    """A task stack is malformed or does not fit the robot model.

    The message reads ``SOURCE:LINE:COLUMN: PATH: REASON`` (the parts that are known).

    Attributes:
        reason: The reason, naming the bad value, the valid choices and the fix.
        path: Path of the offending field as a tuple (``('tasks', 2, 'subspace')``).
        line: 1-based line in the source text, or None (JSON objects, built in code).
        column: 1-based column, or None.
        source: Name of the source (file name), or None.
    """

    def __init__(self, reason: object, path: Iterable[str | int] = (), line: int | None = None,
                 column: int | None = None, source: str | None = None) -> None:
        self.reason = str(reason)
        self.path = tuple(path)
        self.line = line
        self.column = column
        self.source = source
        super().__init__(self._message())

    @property
    def location(self) -> str:
        """``tasks[2].subspace`` (empty for the document root)."""
        return format_path(self.path)

    def _message(self) -> str:
        where = []
        if self.source:
            where.append(str(self.source))
        if self.line is not None:
            where.append(f'line {self.line}' + (f', column {self.column}'
                                                 if self.column is not None else ''))
        head = ' '.join(where[:1]) + (f' ({where[1]})' if len(where) > 1 else '') \
            if self.source else ', '.join(where)
        parts = [p for p in (head, self.location) if p]
        return ': '.join(parts + [self.reason])

    def with_source(self, source: str) -> TaskStackError:
        """Return a copy of this error naming ``source`` (e.g. a file name)."""
        return TaskStackError(self.reason, self.path, self.line, self.column, source)
