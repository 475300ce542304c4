"""Task bounds as functions of task time.

A bound gives, at task time t [s] (seconds since the stack became active), a value in the
task's subspace coordinates and its rate (the default feed-forward, 4.25-4.28, docs/SPEC.md §2).
``INIT`` marks a bound captured from the task value at activation. Trajectory generators
(circle, sine, ramp, ...) subclass :class:`Bound`.
"""

from __future__ import annotations

import abc
from typing import Any

import numpy as np

from ifc_spg.errors import IfcSpgError

__all__ = ['Bound', 'Constant', 'Init', 'INIT', 'as_bound']


class Bound(abc.ABC):
    """A task bound alpha(t) with rate d(alpha)/dt, in subspace coordinates (abstract).

    Subclasses implement :meth:`evaluate`; :meth:`activate` resolves values that depend on
    the task value at activation (``init``) and returns the bound to use.
    """

    dim: int | None = None  # the number of components m; None: any (resolved on activation)

    def activate(self, init_value: np.ndarray) -> Bound:
        """Return the bound to use once the task is active.

        Args:
            init_value: The task value at activation, shape (m,).
        """
        return self

    @abc.abstractmethod
    def evaluate(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Return ``(value (m,), rate (m,))`` at task time ``t`` in [s]."""


class Constant(Bound):
    """A constant bound (rate zero); ``np.inf`` entries mean unbounded."""

    def __init__(self, value: Any) -> None:
        v = np.array(value, dtype=float).reshape(-1)
        if np.isnan(v).any():
            raise IfcSpgError(f'bound values must not be NaN, got {v.tolist()}')
        v.setflags(write=False)
        self.value = v
        self.dim = v.size
        self._rate = np.zeros(v.size)
        self._rate.setflags(write=False)

    def evaluate(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Return the value and a zero rate (read-only arrays) at any ``t``."""
        return self.value, self._rate

    def __repr__(self) -> str:
        return f'Constant({self.value.tolist()})'


class Init(Bound):
    """The task value at activation, per component (``mask`` selects which components).

    Components not in ``mask`` take ``other`` (a :class:`Constant` of the full dimension).
    """

    def __init__(self, mask: Any = None, other: Bound | None = None) -> None:
        self.mask = None if mask is None else np.asarray(mask, dtype=bool)
        self.other = other

    def activate(self, init_value: np.ndarray) -> Constant:
        """Return the :class:`Constant` of ``init_value`` (under ``mask``; ``other`` elsewhere)."""
        init_value = np.asarray(init_value, dtype=float)
        if self.mask is None:
            return Constant(init_value)
        if self.other is None:
            raise IfcSpgError('Init(mask=...) needs the bound of the other components')
        value = np.array(self.other.evaluate(0.0)[0], dtype=float)
        value[self.mask] = init_value[self.mask]
        return Constant(value)

    def evaluate(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Raise: ``init`` has no value before activation; evaluate what activate returns."""
        raise IfcSpgError('an init bound has no value before activation; evaluate the bound '
                          'that activate(init_value) returns')

    def __repr__(self) -> str:
        return 'Init()' if self.mask is None else f'Init(mask={self.mask.tolist()})'


INIT = Init()


def as_bound(x: Any, dim: int, what: str) -> Bound:
    """Convert a user value (number, sequence, 'init' or a Bound) into a Bound.

    Args:
        x: The value (``None`` is handled by the caller).
        dim: Expected dimension m.
        what: Name used in error messages (e.g. ``'lower'``).
    """
    if isinstance(x, Bound):
        if x.dim is not None and x.dim != dim:
            raise IfcSpgError(f'{what}: expected {dim} values, got {x.dim}')
        return x
    if isinstance(x, str):
        if x == 'init':
            return INIT
        raise IfcSpgError(f"{what}: expected a number, a list, 'init' or a trajectory, got {x!r}")
    v = np.array(x, dtype=float).reshape(-1)
    if v.size == 1 and dim != 1:
        v = np.full(dim, v[0])
    if v.size != dim:
        raise IfcSpgError(f'{what}: expected {dim} values (one per subspace direction), '
                          f'got {v.size}: {v.tolist()}')
    return Constant(v)
