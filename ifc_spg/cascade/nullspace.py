"""Baseline: hierarchical nullspace mapping (SPEC 5, Sec. 3.2.6, Alg. C.1/C.2).

Kept for comparisons, not the default. Equality tasks only::

    qdot = 0, N = I
    for each level: A <- A with clamped-joint columns zeroed
                    b <- beta - A qdot;  A <- A N
                    qdot <- qdot + A^{+lambda} b;  N <- N - A^+ A

checklimits (C.2) clamps joints within dl_crit of a limit that move towards it; the loop
repeats with the union of clamped joints until no new joint is clamped.
"""

import numpy as np

from ifc_spg.errors import SolverError

__all__ = ['NullspaceCascade']


def _damped_pinv(A, damping):
    return A.T @ np.linalg.inv(A @ A.T + damping ** 2 * np.eye(A.shape[0]))


class NullspaceCascade:
    """Hierarchical nullspace mapping with joint clamping.

    Args:
        n: Number of joints.
        damping: lambda of the damped inverse used for the step (2.17/2.18).
        critical_distance: dl_crit in [rad] of checklimits.
        rcond: Relative cut-off of the undamped pseudo-inverse used for N (3.48).
    """

    name = 'nullspace'

    def __init__(self, n, damping=1e-3, critical_distance=0.02, rcond=1e-10):
        self.n = int(n)
        self.damping = float(damping)
        self.critical_distance = float(critical_distance)
        self.rcond = float(rcond)

    def solve(self, levels, q_v, q_min, q_max):
        """Return ``(qdot_v, clamped_joints)`` for equality ``levels`` at virtual q_v."""
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
            near_hi = (q_max - q_v < self.critical_distance) & (qdot > 0)
            near_lo = (q_v - q_min < self.critical_distance) & (qdot < 0)
            new = (near_hi | near_lo) & ~clamped
            if not np.any(new):
                break
            clamped |= new
        return qdot, np.flatnonzero(clamped)
