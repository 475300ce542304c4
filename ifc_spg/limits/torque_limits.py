"""The implicit top-level joint-torque-limit task |tau_s| <= tau_max, solved in closed form.

The thesis puts |K (q_v - q)| <= tau_max as an inequality task at the top of every stack
(4.3). Its Jacobian is diagonal (A = K), so its level QP separates per joint::

    min  rho qdot^2 + s^2   s.t.  beta_m <= K qdot - s <= beta_M,  lower <= qdot <= upper

whose solution is the minimizer of rho qdot^2 + dist(K qdot, [beta_m, beta_M])^2 without
the box, projected onto the box. Locking the level (docs/SPEC.md §3) then confines qdot_v to
[(beta_m + s*)/K, (beta_M + s*)/K] (widened by the cascade's lock band): a box again. So
the level is solved here and folded into the velocity box, exactly as the cascade would
(tested against it), and the remaining levels carry n fewer rows and slacks.
"""

from types import ModuleType

import numpy as np

from ifc_spg import kernels as _kernels
from ifc_spg.limits.joint_limits import VelocityBox
from ifc_spg.tasks.task import Level

__all__ = ['TorqueLimitLevel']


class TorqueLimitLevel:
    """The joint-torque-limit level, solved in closed form.

    |K (q_v - q)| <= tau_max on the compliant joints, with gain 1/dT (reach the bound in one
    tick at most).

    Args:
        stiffness: Joint stiffness K in [Nm/rad] (n,); 0 for stiff joints (no limit).
        tau_max: Joint torque limits in [Nm] (n,).
        dt: SPG period in [s].
        rho: The cascade's regularization weight.
        lock_tolerance: The cascade's lock band per unit of row norm.
        kernels: The kernels module (default :data:`ifc_spg.kernels.active`).
    """

    name = 'torque_limits'

    def __init__(self, stiffness: np.ndarray, tau_max: np.ndarray, dt: float, rho: float,
                 lock_tolerance: float, *, kernels: ModuleType | None = None):
        K = np.asarray(stiffness, dtype=float)
        self.idx = np.flatnonzero(K > 0)
        self.K = K[self.idx]
        self.tau_max = np.asarray(tau_max, dtype=float)[self.idx]
        self.gain = 1.0 / float(dt)
        self.rho = float(rho)
        self.band = lock_tolerance * (1.0 + self.K) / self.K
        A = np.zeros((self.idx.size, K.size))
        A[np.arange(self.idx.size), self.idx] = self.K
        A.setflags(write=False)
        self.A = A
        self._gain_tau = self.gain * self.tau_max
        self._K_over = self.K / (self.rho + self.K * self.K)
        self._kernels = _kernels.resolve(kernels)
        # every joint compliant (the usual case): no index array
        self._idx = None if self.idx.size == K.size else self.idx.astype(np.intp)

    def apply(self, q: np.ndarray, qdot: np.ndarray, q_v: np.ndarray, box: VelocityBox
              ) -> tuple[Level, np.ndarray, VelocityBox]:
        """Solve the level; return ``(level, slack, box)`` with the box narrowed by the lock."""
        lo_b, hi_b, s, lower, upper = self._kernels.torque_limit(
            q, qdot, q_v, self._idx, self.K, self.gain, self._gain_tau, self._K_over,
            self.band, box.lower, box.upper)
        return Level(self.name, self.A, lo_b, hi_b, False), s, VelocityBox(lower, upper)
