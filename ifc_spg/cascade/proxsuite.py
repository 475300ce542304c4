"""The cascade with proxsuite's dense ProxQP (docs/SPEC.md §3), level by level (comparisons)."""

import numpy as np

from ifc_spg.cascade.base import CascadeSolver

__all__ = ['ProxsuiteCascade']

_BIG = 1e30  # what the solvers take as infinity


class ProxsuiteCascade(CascadeSolver):
    """The cascade with proxsuite's dense ProxQP, one warm-started QP object per level shape.

    Args:
        n: Number of joints.
        rho: Regularization weight of qdot_v in the level cost (4.45), > 0.
        eps_abs: ProxQP's absolute tolerance.
    """

    name = 'proxsuite'

    def __init__(self, n: int, rho: float = 0.01, eps_abs: float = 1e-9):
        super().__init__(n, rho)
        from proxsuite import proxqp
        self._proxqp = proxqp
        self._eps = eps_abs
        self._qps: dict = {}

    def solve_level(self, A: np.ndarray, lower: np.ndarray, upper: np.ndarray,
                    A_bar: np.ndarray, b_lo: np.ndarray, b_hi: np.ndarray,
                    box_lo: np.ndarray, box_hi: np.ndarray, eq_rows: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray, bool]:
        """One level's QP over [qdot_v; s] with ProxQP; return ``(qdot_v, s, ok)``."""
        n = self.n
        m = A.shape[0]
        C = np.zeros((m + A_bar.shape[0], n + m))
        C[:m, :n] = A
        C[:m, n:] = -np.eye(m)
        C[m:, :n] = A_bar
        lo = np.concatenate([lower, b_lo])
        hi = np.concatenate([upper, b_hi])
        E, e = C[eq_rows], lo[eq_rows]
        G, il, iu = C[~eq_rows], lo[~eq_rows], hi[~eq_rows]
        il = np.clip(il, -_BIG, _BIG)
        iu = np.clip(iu, -_BIG, _BIG)
        H = np.diag(np.concatenate([np.full(n, self.rho), np.ones(m)]))
        lb = np.concatenate([box_lo, np.full(m, -_BIG)])
        ub = np.concatenate([box_hi, np.full(m, _BIG)])
        key = (n + m, E.shape[0], G.shape[0])
        qp = self._qps.get(key)
        if qp is None:
            qp = self._proxqp.dense.QP(n + m, E.shape[0], G.shape[0], True)
            qp.settings.eps_abs = self._eps
            qp.settings.eps_rel = 0.0
            qp.settings.max_iter = 10000
            qp.settings.verbose = False
            qp.init(H, np.zeros(n + m), E, e, G, il, iu, lb, ub)
            self._qps[key] = qp
        else:
            qp.settings.initial_guess = \
                self._proxqp.InitialGuess.WARM_START_WITH_PREVIOUS_RESULT
            qp.update(H, np.zeros(n + m), E, e, G, il, iu, lb, ub)
        qp.solve()
        ok = qp.results.info.status == self._proxqp.QPSolverOutput.PROXQP_SOLVED
        x = np.array(qp.results.x)
        return x[:n], x[n:], ok
