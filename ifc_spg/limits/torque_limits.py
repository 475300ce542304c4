"""The implicit top-level joint-torque-limit task |tau_s| <= tau_max, solved in closed form.

The thesis puts |K (q_v - q)| <= tau_max as an inequality task at the top of every stack
(4.3). Its Jacobian is diagonal (A = K), so its level QP separates per joint::

    min  rho qdot^2 + s^2   s.t.  beta_m <= K qdot - s <= beta_M,  lower <= qdot <= upper

whose solution is the minimizer of rho qdot^2 + dist(K qdot, [beta_m, beta_M])^2 without
the box, projected onto the box. Locking the level (SPEC 3) then confines qdot_v to
[(beta_m + s*)/K, (beta_M + s*)/K] (widened by the cascade's lock band): a box again. So
the level is solved here and folded into the velocity box, exactly as the cascade would
(tested against it), and the remaining levels carry n fewer rows and slacks.
"""

import math

import numpy as np

from ifc_spg import kernels as native
from ifc_spg.limits.joint_limits import VelocityBox
from ifc_spg.tasks.task import Level

__all__ = ['TorqueLimitLevel']


class TorqueLimitLevel:
    """|K (q_v - q)| <= tau_max on the compliant joints, with gain 1/dT (reach the bound in
    one tick at most).

    Args:
        stiffness: Joint stiffness K in [Nm/rad] (n,); 0 for stiff joints (no limit).
        tau_max: Joint torque limits in [Nm] (n,).
        dt: SPG period in [s].
        rho: The cascade's regularization weight.
        lock_tolerance: The cascade's lock band per unit of row norm.
    """

    name = 'torque_limits'

    def __init__(self, stiffness, tau_max, dt, rho, lock_tolerance):
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
        self._zeros = np.zeros(self.idx.size)
        # every joint compliant (the usual case): slices instead of index arrays (no copies)
        self._sel = slice(None) if self.idx.size == K.size else self.idx
        self._native = native.module  # C kernel (ifc_spg.kernels), or None: numpy below
        self._native_idx = None if self.idx.size == K.size else self.idx.astype(np.intp)

    def apply(self, q, qdot, q_v, box):
        """Solve the level; return ``(level, slack, box)`` with the box narrowed by the lock."""
        if self._native is not None:
            lo_b, hi_b, s, lower, upper = self._native.torque_limit(
                q, qdot, q_v, self._native_idx, self.K, self.gain, self._gain_tau,
                self._K_over, self.band, box.lower, box.upper)
            return Level(self.name, self.A, lo_b, hi_b, False), s, VelocityBox(lower, upper)
        i, K = self._sel, self.K
        comp = qdot[i] - self.gain * (q_v[i] - q[i])
        comp *= K                                           # K qdot - Lambda tau_s
        lo_b = comp - self._gain_tau                        # beta_m
        hi_b = comp + self._gain_tau                        # beta_M
        if not math.isfinite(comp @ self._zeros):  # overflow on absurd measurements:
            bad = ~np.isfinite(comp)                 # leave those joints to the box
            lo_b[bad], hi_b[bad] = -np.inf, np.inf
        lower = box.lower.copy()
        upper = box.upper.copy()
        lower_i, upper_i = lower[i], upper[i]  # (views when every joint is compliant)
        # minimizer of rho x^2 + dist(K x, [lo_b, hi_b])^2, projected onto the box
        x = np.minimum(np.maximum(0.0, lo_b), hi_b)
        x *= self._K_over
        np.minimum(np.maximum(x, lower_i), upper_i, out=x)
        Kx = K * x
        s = Kx - np.minimum(np.maximum(Kx, lo_b), hi_b)
        if not math.isfinite(s @ self._zeros):
            s[np.isnan(s)] = 0.0
        lower[i] = np.maximum(lower_i, np.minimum((lo_b + s) / K, x) - self.band)
        upper[i] = np.minimum(upper_i, np.maximum((hi_b + s) / K, x) + self.band)
        return Level(self.name, self.A, lo_b, hi_b, False), s, VelocityBox(lower, upper)
