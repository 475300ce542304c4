"""Joint position, velocity and acceleration limits as bounds on qdot_v (SPEC 4, 4.29-4.33).

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

from typing import NamedTuple

import numpy as np

__all__ = ['JointVelocityLimits', 'VelocityBox', 'joint_velocity_bounds', 'intersect_soft',
           'stopping_velocity']


class VelocityBox(NamedTuple):
    """Bounds on qdot_v in [rad/s]: ``lower <= qdot_v <= upper``."""

    lower: np.ndarray
    upper: np.ndarray


def joint_velocity_bounds(q_v, q_min, q_max, v_max, a_max, dt):
    """Position/velocity shaping (4.32, 4.33) at the virtual configuration.

    Args:
        q_v: Virtual joint positions in [rad] (inside [q_min, q_max]).
        q_min, q_max: Joint position limits in [rad].
        v_max: Joint velocity limits in [rad/s].
        a_max: Joint acceleration limits in [rad/s^2].
        dt: SPG period in [s].
    """
    n = q_v.shape[0]
    d = np.maximum(np.concatenate([q_v - q_min, q_max - q_v]), 0.0)
    stop = np.minimum(stopping_velocity(d, np.concatenate([a_max, a_max]), dt),
                      np.concatenate([v_max, v_max]))
    return VelocityBox(-stop[:n], stop[n:])


def stopping_velocity(distance, a_max, dt):
    """Largest velocity [rad/s] from which braking by a_max dt per tick stops within distance."""
    distance = np.maximum(distance, 0.0)
    c = a_max * dt
    k = np.floor(0.5 * (np.sqrt(1.0 + 8.0 * distance / (c * dt)) - 1.0))
    return (distance / dt + 0.5 * c * k * (k + 1.0)) / (k + 1.0)


def intersect_soft(hard, soft):
    """Intersect ``hard`` with ``soft``; where empty, the point of ``hard`` nearest ``soft``."""
    lower = np.maximum(hard.lower, soft.lower)
    upper = np.minimum(hard.upper, soft.upper)
    empty = lower > upper
    if np.any(empty):
        below = empty & (soft.upper < hard.lower)  # soft box entirely below the hard box
        above = empty & ~below
        lower[below] = upper[below] = hard.lower[below]
        lower[above] = upper[above] = hard.upper[above]
    return VelocityBox(lower, upper)


class JointVelocityLimits:
    """:func:`joint_velocity_bounds` with the robot's constants precomputed (the 2 ms path).

    Args:
        q_min, q_max: Joint position limits in [rad].
        v_max: Joint velocity limits in [rad/s].
        a_max: Joint acceleration limits in [rad/s^2].
        dt: SPG period in [s].
    """

    def __init__(self, q_min, q_max, v_max, a_max, dt):
        self.n = len(q_min)
        self.dt = float(dt)
        self._lim = np.concatenate([-np.asarray(q_min, float), np.asarray(q_max, float)])
        self._sign = np.concatenate([np.ones(self.n), -np.ones(self.n)])
        self._v = np.concatenate([v_max, v_max]).astype(float)
        c = np.concatenate([a_max, a_max]).astype(float) * self.dt
        self._c = c
        self._half_c = 0.5 * c
        self._k_scale = 8.0 / (c * self.dt)
        self._inv_dt = 1.0 / self.dt

    def box(self, q_v):
        """The :class:`VelocityBox` at the virtual configuration ``q_v`` (as the function)."""
        # d = [q_v - q_min; q_max - q_v]
        d = self._lim + self._sign * np.concatenate([q_v, q_v])
        np.maximum(d, 0.0, out=d)
        k = np.floor(0.5 * (np.sqrt(1.0 + self._k_scale * d) - 1.0))
        k1 = k + 1.0
        stop = (d * self._inv_dt + self._half_c * k * k1) / k1
        np.minimum(stop, self._v, out=stop)
        return VelocityBox(-stop[:self.n], stop[self.n:])
