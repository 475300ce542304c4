"""Trajectory generators: task bounds alpha(t) with analytic rates (the default feed-forward).

All generators are :class:`~ifc_spg.tasks.bounds.Bound` subclasses in the task's subspace
coordinates (m components); t is the task time in [s] (seconds since the stack became
active). Values that depend on the task value at activation (``init``) are given as an
:class:`Anchor` and resolved by :meth:`Bound.activate`, which returns a new, resolved
generator (the one in the spec stays reusable).

==============  ===========================================================================
generator       value (per component k)
==============  ===========================================================================
Circle          in the plane (i, j): c + r [cos(2 pi f t + phi), sin(2 pi f t + phi)];
                the other components keep their value at activation
Sine            center + offset + amplitude sin(2 pi frequency t + phase) (Lissajous when
                the frequencies differ)
SquareWave      center + offsets[0] for the first ``duty`` of each period, then
                center + offsets[1]; optional min-jerk ``transition`` [s] between them
Ramp            from -> to in ``duration`` after ``delay``, linear or min-jerk profile
==============  ===========================================================================
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ifc_spg.errors import IfcSpgError
from ifc_spg.tasks.bounds import Bound

__all__ = ['Anchor', 'Circle', 'Ramp', 'Sine', 'SquareWave', 'min_jerk']

TWO_PI = 2.0 * np.pi


def min_jerk(s: float) -> tuple[float, float]:
    """Min-jerk profile ``(p(s), dp/ds(s))`` for s in [0, 1] (clipped)."""
    s = min(max(float(s), 0.0), 1.0)
    return s ** 3 * (10.0 - 15.0 * s + 6.0 * s * s), 30.0 * s * s * (1.0 - s) ** 2


class Anchor:
    """A vector whose entries are numbers or ``init`` (the task value at activation).

    Args:
        values: Numbers (entries under ``init_mask`` are ignored), shape (k,).
        init_mask: True where the entry is the value at activation.
    """

    def __init__(self, values: Any, init_mask: Any = None) -> None:
        self.values = np.array(values, dtype=float).reshape(-1)
        self.init_mask = np.zeros(self.values.size, dtype=bool) if init_mask is None \
            else np.array(init_mask, dtype=bool).reshape(-1)
        if self.init_mask.size != self.values.size:
            raise IfcSpgError('anchor: values and init_mask differ in size')

    @classmethod
    def init(cls, size: int) -> Anchor:
        """An anchor that is the value at activation in every component."""
        return cls(np.zeros(size), np.ones(size, dtype=bool))

    def resolve(self, init_value: np.ndarray) -> np.ndarray:
        """Return the numbers, with ``init`` entries taken from ``init_value``."""
        return np.where(self.init_mask, init_value, self.values)

    def __repr__(self) -> str:
        return 'Anchor([' + ', '.join('init' if m else f'{v:g}' for v, m in
                                      zip(self.values, self.init_mask)) + '])'


class _Generator(Bound):
    """Base of the generators: ``activate`` returns a resolved copy, then ``evaluate``."""

    dim: int

    def __init__(self, dim: int) -> None:
        self.dim = int(dim)
        self._init: np.ndarray | None = None

    def activate(self, init_value: np.ndarray) -> _Generator:
        """Return a copy resolved against the task value at activation (this one unchanged)."""
        init_value = np.array(init_value, dtype=float).reshape(-1)
        if init_value.size != self.dim:
            raise IfcSpgError(f'{type(self).__name__}: task value at activation has '
                              f'{init_value.size} components, expected {self.dim}')
        out = object.__new__(type(self))
        out.__dict__.update(self.__dict__)
        out._init = init_value
        out._resolve(init_value)
        return out

    def _resolve(self, init_value: np.ndarray) -> None:
        """Resolve anchors from the task value at activation (subclasses)."""

    def evaluate(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Return ``(value (m,), rate (m,))`` at task time ``t`` [s] (after :meth:`activate`)."""
        if self._init is None:
            raise IfcSpgError(f'{type(self).__name__}: activate() before evaluate() (the '
                              'generator needs the task value at activation)')
        return self._evaluate(float(t))

    def _evaluate(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        raise NotImplementedError


class Circle(_Generator):
    """Circle in the plane of components ``(i, j)``.

    Args:
        dim: Task dimension m.
        plane: Component indices (i, j).
        radius: Radius r (task units, e.g. [m]).
        frequency: Revolutions per second f in [Hz] (negative: the other direction).
        phase: Angle phi at t = 0 in [rad].
        center: :class:`Anchor` of 2 (the centre c), or None.
        start: :class:`Anchor` of 2, the point at t = 0 (c = start - r [cos phi, sin phi]);
            used when ``center`` is None (default: the value at activation).
    """

    def __init__(self, dim: int, *, plane: tuple[int, int], radius: float, frequency: float,
                 phase: float = 0.0, center: Anchor | None = None,
                 start: Anchor | None = None) -> None:
        super().__init__(dim)
        self.plane = (int(plane[0]), int(plane[1]))
        self.radius = float(radius)
        self.omega = TWO_PI * float(frequency)
        self.phase = float(phase)
        self.center = center
        self.start = Anchor.init(2) if center is None and start is None else start

    def _resolve(self, init_value: np.ndarray) -> None:
        i, j = self.plane
        here = init_value[[i, j]]
        if self.center is not None:
            self._c = self.center.resolve(here)
        else:
            if self.start is None:  # __init__ requires center or start
                raise IfcSpgError('internal: circle without center or start')
            self._c = self.start.resolve(here) - self.radius * np.array(
                [np.cos(self.phase), np.sin(self.phase)])
        self._value = init_value.copy()
        self._rate = np.zeros(self.dim)

    def _evaluate(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        i, j = self.plane
        a = self.omega * t + self.phase
        c, s = np.cos(a), np.sin(a)
        value, rate = self._value.copy(), self._rate.copy()
        value[i] = self._c[0] + self.radius * c
        value[j] = self._c[1] + self.radius * s
        rate[i] = -self.radius * self.omega * s
        rate[j] = self.radius * self.omega * c
        return value, rate


class Sine(_Generator):
    """Per-component sine: ``center + offset + amplitude sin(2 pi frequency t + phase)``.

    Args:
        dim: Task dimension m.
        amplitude, frequency, phase, offset: Per component, shape (m,); frequency in
            [Hz], phase in [rad].
        center: :class:`Anchor` of m (default: the value at activation).
    """

    def __init__(self, dim: int, *, amplitude: Any, frequency: Any, phase: Any = 0.0,
                 offset: Any = 0.0, center: Anchor | None = None) -> None:
        super().__init__(dim)
        shape = (self.dim,)
        self.amplitude = np.broadcast_to(np.asarray(amplitude, float), shape).copy()
        self.omega = TWO_PI * np.broadcast_to(np.asarray(frequency, float), shape)
        self.phase = np.broadcast_to(np.asarray(phase, float), shape).copy()
        self.offset = np.broadcast_to(np.asarray(offset, float), shape).copy()
        self.center = Anchor.init(self.dim) if center is None else center

    def _resolve(self, init_value: np.ndarray) -> None:
        self._base = self.center.resolve(init_value) + self.offset

    def _evaluate(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        a = self.omega * t + self.phase
        return (self._base + self.amplitude * np.sin(a),
                self.amplitude * self.omega * np.cos(a))


class SquareWave(_Generator):
    """Switching offset (Table 3.7's y_offset(t)): two levels alternating with a period.

    Args:
        dim: Task dimension m.
        offsets: The two offsets added to ``center``, shape (2, m).
        period: Period T in [s] (one cycle: first level, then second).
        duty: Fraction of the period spent at the first level, in (0, 1).
        transition: Min-jerk blend time in [s] at each switch (0: a step), at most the
            shorter of the two phases.
        center: :class:`Anchor` of m (default: the value at activation).
    """

    def __init__(self, dim: int, *, offsets: Any, period: float, duty: float = 0.5,
                 transition: float = 0.0, center: Anchor | None = None) -> None:
        super().__init__(dim)
        self.offsets = np.broadcast_to(np.asarray(offsets, float), (2, self.dim)).copy()
        self.period = float(period)
        self.duty = float(duty)
        self.transition = float(transition)
        self.center = Anchor.init(self.dim) if center is None else center

    def _resolve(self, init_value: np.ndarray) -> None:
        c = self.center.resolve(init_value)
        self._levels = c + self.offsets

    def _evaluate(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        lo, hi = self._levels
        t = max(t, 0.0)
        tau = t % self.period
        switch = self.duty * self.period
        if tau < switch:
            cur, prev, since = lo, hi, tau
            if t < self.period:  # the first segment starts at its level, no blend
                return cur.copy(), np.zeros(self.dim)
        else:
            cur, prev, since = hi, lo, tau - switch
        if self.transition > 0.0 and since < self.transition:
            p, dp = min_jerk(since / self.transition)
            return prev + (cur - prev) * p, (cur - prev) * dp / self.transition
        return cur.copy(), np.zeros(self.dim)


class Ramp(_Generator):
    """Point to point in ``duration`` seconds after ``delay``, linear or min-jerk.

    Args:
        dim: Task dimension m.
        start: :class:`Anchor` of m, the value before the motion (default: at activation).
        end: :class:`Anchor` of m, the value after it; entries under ``end_same`` take the
            start value. None: ``start + delta``.
        delta: Displacement (m,), used when ``end`` is None.
        end_same: Mask of ``end`` entries equal to the start value.
        duration: Motion time in [s] (> 0).
        delay: Wait before the motion in [s] (>= 0).
        profile: 'linear' or 'min_jerk'.
    """

    PROFILES = ('linear', 'min_jerk')

    def __init__(self, dim: int, *, duration: float, start: Anchor | None = None,
                 end: Anchor | None = None, delta: Any = 0.0, end_same: Any = None,
                 delay: float = 0.0, profile: str = 'linear') -> None:
        super().__init__(dim)
        if profile not in self.PROFILES:
            raise IfcSpgError(f"ramp profile '{profile}' unknown; use one of "
                              f"{', '.join(self.PROFILES)}")
        self.profile = profile
        self.duration = float(duration)
        self.delay = float(delay)
        self.start = Anchor.init(self.dim) if start is None else start
        self.end = end
        self.end_same = np.zeros(self.dim, bool) if end_same is None \
            else np.asarray(end_same, bool)
        self.delta = np.broadcast_to(np.asarray(delta, float), (self.dim,)).copy()

    def _resolve(self, init_value: np.ndarray) -> None:
        a = self.start.resolve(init_value)
        if self.end is None:
            b = a + self.delta
        else:
            b = np.where(self.end_same, a, self.end.resolve(init_value))
        self._a, self._d = a, b - a

    def _evaluate(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        s = (t - self.delay) / self.duration
        if self.profile == 'linear':
            if s <= 0.0 or s >= 1.0:
                p, dp = min(max(s, 0.0), 1.0), 0.0
            else:
                p, dp = s, 1.0
        else:
            p, dp = min_jerk(s)
        return self._a + self._d * p, self._d * (dp / self.duration)
