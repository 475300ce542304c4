"""Joint position, velocity and acceleration limits as bounds on qdot_v (docs/SPEC.md §4).

The limits apply to the commanded q_v, so the shaping uses q_v (the sources write q)::

    lower = max{(q_m - q_v)/dT, -v_M, -sqrt(2 a_M (q_v - q_m))}
    upper = min{(q_M - q_v)/dT,  v_M,  sqrt(2 a_M (q_M - q_v))}

The braking term sqrt(2 a_M d) of the sources is the continuous-time stopping curve; sampled
every dT it asks for decelerations above a_M close to a limit. We use its exact
discrete-time counterpart: the largest v from which the velocities v, v - c, v - 2c, ...
(c = a_M dT) cover at most the distance d before reaching zero. With
k = floor((sqrt(1 + 8 d / (c dT)) - 1) / 2)::

    v_stop(d) = (d / dT + c k (k + 1) / 2) / (k + 1)      (~ sqrt(2 a_M d) - c / 2)

It includes the one-step term d / dT (k = 0: v_stop <= d / dT always), and a q_v braking
along it never needs more than a_M (v_stop(d - dT v_stop(d)) >= v_stop(d) - c).
This box always contains 0 while q_v is inside its limits. The acceleration box
[qdot_prev - a_M dT, qdot_prev + a_M dT] (4.31) is intersected softly: where the two do
not intersect, position safety wins (the nearest point of the position box is taken).
"""

from types import ModuleType
from typing import NamedTuple

import numpy as np

from ifc_spg import kernels as _kernels

__all__ = ['JointVelocityLimits', 'VelocityBox', 'joint_velocity_bounds', 'intersect_soft',
           'stopping_velocity']


class VelocityBox(NamedTuple):
    """Bounds on qdot_v in [rad/s]: ``lower <= qdot_v <= upper``."""

    lower: np.ndarray
    upper: np.ndarray


def joint_velocity_bounds(q_v: np.ndarray, q_min: np.ndarray, q_max: np.ndarray,
                          v_max: np.ndarray, a_max: np.ndarray, dt: float) -> VelocityBox:
    """Position/velocity shaping (4.32, 4.33) at the virtual configuration.

    Args:
        q_v: Virtual joint positions in [rad] (inside [q_min, q_max]).
        q_min: Lower joint position limits in [rad].
        q_max: Upper joint position limits in [rad].
        v_max: Joint velocity limits in [rad/s].
        a_max: Joint acceleration limits in [rad/s^2].
        dt: SPG period in [s].
    """
    n = q_v.shape[0]
    d = np.maximum(np.concatenate([q_v - q_min, q_max - q_v]), 0.0)
    stop = np.minimum(stopping_velocity(d, np.concatenate([a_max, a_max]), dt),
                      np.concatenate([v_max, v_max]))
    return VelocityBox(-stop[:n], stop[n:])


def stopping_velocity(distance: np.ndarray, a_max: np.ndarray, dt: float) -> np.ndarray:
    """Largest velocity [rad/s] from which braking by a_max dt per tick stops within distance."""
    distance = np.maximum(distance, 0.0)
    c = a_max * dt
    k = np.floor(0.5 * (np.sqrt(1.0 + 8.0 * distance / (c * dt)) - 1.0))
    return (distance / dt + 0.5 * c * k * (k + 1.0)) / (k + 1.0)


def intersect_soft(hard: VelocityBox, soft: VelocityBox) -> VelocityBox:
    """Intersect ``hard`` with ``soft``; where empty, the point of ``hard`` nearest ``soft``.

    Both ends of ``soft`` clipped into ``hard``: where the boxes overlap this is their
    intersection; where ``soft`` lies below (above) ``hard`` both ends become hard.lower
    (hard.upper).
    """
    lower = np.minimum(np.maximum(soft.lower, hard.lower), hard.upper)
    upper = np.maximum(np.minimum(soft.upper, hard.upper), hard.lower)
    return VelocityBox(lower, upper)


class JointVelocityLimits:
    """:func:`joint_velocity_bounds` with the robot's constants precomputed (the 2 ms path).

    Args:
        q_min: Lower joint position limits in [rad].
        q_max: Upper joint position limits in [rad].
        v_max: Joint velocity limits in [rad/s].
        a_max: Joint acceleration limits in [rad/s^2].
        dt: SPG period in [s].
        kernels: The kernels module (default :data:`ifc_spg.kernels.active`).
    """

    def __init__(self, q_min: np.ndarray, q_max: np.ndarray, v_max: np.ndarray,
                 a_max: np.ndarray, dt: float, *, kernels: ModuleType | None = None):
        self.n = len(q_min)
        self.dt = float(dt)
        self._q_min = np.asarray(q_min, float)
        self._q_max = np.asarray(q_max, float)
        self._v = np.concatenate([v_max, v_max]).astype(float)
        c = np.concatenate([a_max, a_max]).astype(float) * self.dt
        self._half_c = 0.5 * c
        # k = floor((sqrt(1 + 8 d / (c dT)) - 1) / 2) = floor(sqrt(1/4 + 2 d / (c dT)) - 1/2)
        self._k_scale = 2.0 / (c * self.dt)
        self._inv_dt = 1.0 / self.dt
        self._d = np.zeros(2 * self.n)
        # Far from the limits the box is (-v_max, v_max): v_stop grows with d, so beyond
        # the first distance where it reaches v_max (found by bisection) it stays there.
        lo, hi = np.zeros(2 * self.n), np.full(2 * self.n, 1.0)
        while np.any(stopping_velocity(hi, 2 * self._half_c / self.dt, self.dt) < self._v):
            hi *= 2.0
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            reached = stopping_velocity(mid, 2 * self._half_c / self.dt, self.dt) >= self._v
            hi = np.where(reached, mid, hi)
            lo = np.where(reached, lo, mid)
        self._d_free = hi  # v_stop(d_free) >= v_max
        free = (-self._v[:self.n].copy(), self._v[self.n:].copy())
        for b in free:
            b.setflags(write=False)
        self._free_box = VelocityBox(*free)
        self._kernels = _kernels.resolve(kernels)

    def box(self, q_v: np.ndarray) -> VelocityBox:
        """The :class:`VelocityBox` at the virtual configuration ``q_v`` (as the function).

        The returned arrays may be read-only (shared between ticks far from the limits).
        """
        box = self._kernels.limits_box(q_v, self._q_min, self._q_max, self._d_free,
                                       self._k_scale, self._half_c, self._inv_dt, self._v)
        return self._free_box if box is None else VelocityBox(*box)
