"""Baseline: hierarchical nullspace mapping (SPEC 5, Sec. 3.2.6, Alg. C.1/C.2).

Kept for comparisons, not the default. Equality tasks only::

    qdot = 0, N = I
    for each level: A <- A with clamped-joint columns zeroed
                    b <- beta - A qdot;  A <- A N
                    qdot <- qdot + A^{+lambda} b;  N <- N - A^+ A

checklimits (C.2) clamps joints within dl_crit of a limit that move towards it; the loop
repeats with the union of clamped joints until no new joint is clamped. The result is
clipped into the velocity box afterwards (the box is no constraint of the mapping), so the
implicit torque-limit level, whose lock the cascades take as hard bounds, is not available.
"""

from collections.abc import Sequence
import math

import numpy as np

from ifc_spg.cascade.base import CascadeResult
from ifc_spg.errors import SolverError
from ifc_spg.limits.joint_limits import VelocityBox
from ifc_spg.tasks.task import Level

__all__ = ['NullspaceCascade']


def _damped_pinv(A: np.ndarray, damping: float) -> np.ndarray:
    return A.T @ np.linalg.inv(A @ A.T + damping ** 2 * np.eye(A.shape[0]))


class NullspaceCascade:
    """Hierarchical nullspace mapping with joint clamping.

    Args:
        n: Number of joints.
        rho: Unused (the cascades' regularization, accepted for
            :func:`~ifc_spg.cascade.make_solver`).
        q_min: Lower joint position limits in [rad] of checklimits (None: unlimited).
        q_max: Upper joint position limits in [rad] of checklimits (None: unlimited).
        damping: lambda of the damped inverse used for the step (2.17/2.18).
        critical_distance: dl_crit in [rad] of checklimits.
        rcond: Relative cut-off of the undamped pseudo-inverse used for N (3.48).
    """

    name = 'nullspace'
    supports_inequalities = False
    supports_torque_limits = False
    lock_tolerance = 1e-9

    def __init__(self, n: int, rho: float = 0.01, *, q_min: np.ndarray | None = None,
                 q_max: np.ndarray | None = None, damping: float = 1e-3,
                 critical_distance: float = 0.02, rcond: float = 1e-10):
        self.n = int(n)
        self.q_min = np.full(self.n, -np.inf) if q_min is None else np.asarray(q_min, float)
        self.q_max = np.full(self.n, np.inf) if q_max is None else np.asarray(q_max, float)
        self._zeros = np.zeros(self.n)
        self.damping = float(damping)
        self.critical_distance = float(critical_distance)
        self.rcond = float(rcond)

    def prepare(self, dims: Sequence[int], equalities: Sequence[bool]) -> None:
        """Nothing to build ahead of a stack."""

    def solve(self, levels: Sequence[Level], box: VelocityBox,
              q_v: np.ndarray | None = None) -> CascadeResult:
        """Solve the levels by the nullspace mapping, clipped into the box.

        The mapping at the virtual configuration ``q_v`` (None: no joint is clamped),
        clipped into ``box``; a non-finite solution holds (zero velocity clipped into the
        box, status 'hold').
        """
        qdot, _ = self.mapping(levels, q_v)
        status = 'ok'
        if not math.isfinite(qdot @ self._zeros):
            qdot, status = np.zeros(self.n), 'hold'
        return CascadeResult(np.clip(qdot, box.lower, box.upper), [], status, -1)

    def mapping(self, levels: Sequence[Level], q_v: np.ndarray | None
                ) -> tuple[np.ndarray, np.ndarray]:
        """The nullspace mapping with joint clamping.

        Return ``(qdot_v, clamped_joints)`` for equality ``levels`` at virtual q_v (None:
        no joint is clamped).
        """
        q_min, q_max = self.q_min, self.q_max
        for lev in levels:
            if not lev.equality:
                raise SolverError(f"the nullspace baseline handles equality tasks only; task "
                                  f"'{lev.name}' is an inequality (use solver 'daqp')")
        n = self.n
        clamped = np.zeros(n, dtype=bool)
        for _ in range(n + 1):
            qdot = np.zeros(n)
            N = np.eye(n)
            for lev in levels:
                A = lev.A * ~clamped
                b = lev.lower - A @ qdot
                AN = A @ N
                qdot = qdot + _damped_pinv(AN, self.damping) @ b
                N = N - np.linalg.pinv(AN, rcond=self.rcond) @ AN
            if q_v is None:
                break
            near_hi = (q_max - q_v < self.critical_distance) & (qdot > 0)
            near_lo = (q_v - q_min < self.critical_distance) & (qdot < 0)
            new = (near_hi | near_lo) & ~clamped
            if not np.any(new):
                break
            clamped |= new
        return qdot, np.flatnonzero(clamped)
