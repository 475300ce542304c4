"""Strict-priority hierarchical QP cascade (SPEC 3, Sec. 4.1.4, Alg. C.3).

Variables w = [qdot_v; s] with s the slack of the current level. For i = 1..k::

    min 1/2 w^T diag(rho I_n, I_m) w
    s.t. beta_m,i <= A_i qdot_v - s <= beta_M,i          (current level, soft via s)
         b_m <= A_bar qdot_v <= b_M                      (all higher levels, hard)
         lower <= qdot_v <= upper                        (joint limits and PSPM, hard)

then the level is locked: its rows join A_bar with bounds [beta_m + s*, beta_M + s*]
(exactly A_i qdot_v* for equality rows, so round-off never makes a later level
infeasible). A level whose solve fails keeps the previous level's solution.

Solvers share one interface (:class:`CascadeSolver`): ``daqp`` (dual active set, exact,
default) and ``proxsuite`` (dense proximal ALM, warm started). Building the levels
(:func:`build_levels`) is separate from solving them (STYLE #3).
"""

from typing import NamedTuple

import numpy as np

from ifc_spg.errors import SolverError, did_you_mean

__all__ = ['CascadeResult', 'CascadeSolver', 'DaqpCascade', 'ProxsuiteCascade', 'SOLVERS',
           'build_levels', 'make_solver', 'level_violation']

_BIG = 1e30  # what the solvers take as infinity
_EQ = 5      # DAQP sense flag: equality constraint


class CascadeResult(NamedTuple):
    """Outcome of one cascade solve.

    Attributes:
        qdot_v: Virtual joint velocity in [rad/s] (n,), always finite and inside the box.
        slacks: Optimal slack s* of each level (list of (m_i,) arrays).
        status: 'ok', 'fallback' (a level failed; the previous level's solution is used)
            or 'hold' (the first level failed; zero velocity clipped into the box).
        failed_level: Index of the failed level, or -1.
        box_violation: How far the solver's raw solution lay outside the box (>= 0) before
            it was clipped; solver tolerance only.
    """

    qdot_v: np.ndarray
    slacks: list
    status: str
    failed_level: int
    box_violation: float = 0.0


def build_levels(tasks, kin, t):
    """Return the list of :class:`~ifc_spg.tasks.Level` of ``tasks`` (highest first)."""
    return [task.level(kin, t) for task in tasks]


def level_violation(level, qdot_v):
    """Return the per-row violation of a level's bounds by ``qdot_v`` (>= 0), shape (m,)."""
    a = level.A @ qdot_v
    return np.maximum(np.maximum(level.lower - a, a - level.upper), 0.0)


class CascadeSolver:
    """Interface: solve a list of levels under a joint velocity box.

    Args:
        n: Number of joints.
        rho: Regularization weight of qdot_v in the level cost (4.45), > 0.
    """

    name = 'base'

    def __init__(self, n, rho=0.01):
        if not (np.isfinite(rho) and rho > 0):
            raise SolverError(f'rho must be a finite number > 0, got {rho!r}')
        self.n = int(n)
        self.rho = float(rho)

    def solve_level(self, A, lower, upper, A_bar, b_lo, b_hi, box_lo, box_hi, eq_rows):
        """Solve one level; return ``(qdot_v, s, ok)``.

        ``eq_rows`` is a bool mask over the rows [A; A_bar] that are equalities.
        """
        raise NotImplementedError

    def solve(self, levels, box):
        """Solve the cascade; return a :class:`CascadeResult`.

        Args:
            levels: Levels, highest priority first.
            box: :class:`~ifc_spg.limits.VelocityBox` on qdot_v.
        """
        n = self.n
        box_lo = np.asarray(box.lower, dtype=float)
        box_hi = np.asarray(box.upper, dtype=float)
        qdot = np.clip(np.zeros(n), box_lo, box_hi)
        A_bar = np.zeros((0, n))
        b_lo = np.zeros(0)
        b_hi = np.zeros(0)
        eq_bar = np.zeros(0, dtype=bool)
        slacks = []
        for i, lev in enumerate(levels):
            m = lev.A.shape[0]
            eq_cur = lev.lower == lev.upper
            x, s, ok = self.solve_level(lev.A, lev.lower, lev.upper, A_bar, b_lo, b_hi,
                                        box_lo, box_hi, np.concatenate([eq_cur, eq_bar]))
            if not ok or not (np.all(np.isfinite(x)) and np.all(np.isfinite(s))):
                slacks.extend(np.full(lev.A.shape[0], np.nan) for lev in levels[i:])
                status = 'hold' if i == 0 else 'fallback'
                return CascadeResult(np.clip(qdot, box_lo, box_hi), slacks, status, i,
                                     _outside(qdot, box_lo, box_hi))
            qdot = x
            slacks.append(s)
            a = lev.A @ x
            lo = np.where(eq_cur, a, np.minimum(lev.lower + s, a))
            hi = np.where(eq_cur, a, np.maximum(lev.upper + s, a))
            A_bar = np.vstack([lev.A, A_bar]) if m else A_bar
            b_lo = np.concatenate([lo, b_lo])
            b_hi = np.concatenate([hi, b_hi])
            eq_bar = np.concatenate([eq_cur, eq_bar])
        return CascadeResult(np.clip(qdot, box_lo, box_hi), slacks, 'ok', -1,
                             _outside(qdot, box_lo, box_hi))


def _outside(x, lo, hi):
    return float(max(np.max(lo - x, initial=0.0), np.max(x - hi, initial=0.0)))


class DaqpCascade(CascadeSolver):
    """The cascade with DAQP (exact dual active-set QP, PyPI ``daqp``)."""

    name = 'daqp'

    def __init__(self, n, rho=0.01):
        super().__init__(n, rho)
        import daqp
        self._solve = daqp.solve
        self._H = {}

    def solve_level(self, A, lower, upper, A_bar, b_lo, b_hi, box_lo, box_hi, eq_rows):
        n = self.n
        m = A.shape[0]
        H = self._H.get(m)
        if H is None:
            H = np.diag(np.concatenate([np.full(n, self.rho), np.ones(m)]))
            self._H[m] = H
        r = A_bar.shape[0]
        C = np.zeros((m + r, n + m))
        C[:m, :n] = A
        C[:m, n:] = -np.eye(m)
        C[m:, :n] = A_bar
        bu = np.concatenate([box_hi, np.full(m, _BIG), upper, b_hi])
        bl = np.concatenate([box_lo, np.full(m, -_BIG), lower, b_lo])
        np.clip(bu, -_BIG, _BIG, out=bu)
        np.clip(bl, -_BIG, _BIG, out=bl)
        sense = np.zeros(n + m + m + r, dtype=np.int32)
        sense[n + m:][eq_rows] = _EQ
        x, _, flag, _ = self._solve(H, np.zeros(n + m), C, bu, bl, sense, primal_tol=1e-9)
        return x[:n], x[n:], flag == 1


class ProxsuiteCascade(CascadeSolver):
    """The cascade with proxsuite's dense ProxQP, one warm-started QP object per level shape."""

    name = 'proxsuite'

    def __init__(self, n, rho=0.01, eps_abs=1e-9):
        super().__init__(n, rho)
        from proxsuite import proxqp
        self._proxqp = proxqp
        self._eps = eps_abs
        self._qps = {}

    def solve_level(self, A, lower, upper, A_bar, b_lo, b_hi, box_lo, box_hi, eq_rows):
        n = self.n
        m = A.shape[0]
        C = np.zeros((m + A_bar.shape[0], n + m))
        C[:m, :n] = A
        C[:m, n:] = -np.eye(m)
        C[m:, :n] = A_bar
        lo = np.concatenate([lower, b_lo])
        hi = np.concatenate([upper, b_hi])
        E, e = C[eq_rows], lo[eq_rows]
        I, il, iu = C[~eq_rows], lo[~eq_rows], hi[~eq_rows]
        il = np.clip(il, -_BIG, _BIG)
        iu = np.clip(iu, -_BIG, _BIG)
        H = np.diag(np.concatenate([np.full(n, self.rho), np.ones(m)]))
        lb = np.concatenate([box_lo, np.full(m, -_BIG)])
        ub = np.concatenate([box_hi, np.full(m, _BIG)])
        key = (n + m, E.shape[0], I.shape[0])
        qp = self._qps.get(key)
        if qp is None:
            qp = self._proxqp.dense.QP(n + m, E.shape[0], I.shape[0], True)
            qp.settings.eps_abs = self._eps
            qp.settings.eps_rel = 0.0
            qp.settings.max_iter = 10000
            qp.settings.verbose = False
            qp.init(H, np.zeros(n + m), E, e, I, il, iu, lb, ub)
            self._qps[key] = qp
        else:
            qp.settings.initial_guess = \
                self._proxqp.InitialGuess.WARM_START_WITH_PREVIOUS_RESULT
            qp.update(H, np.zeros(n + m), E, e, I, il, iu, lb, ub)
        qp.solve()
        ok = qp.results.info.status == self._proxqp.QPSolverOutput.PROXQP_SOLVED
        x = np.array(qp.results.x)
        return x[:n], x[n:], ok


SOLVERS = {'daqp': DaqpCascade, 'proxsuite': ProxsuiteCascade}


def make_solver(name, n, rho=0.01):
    """Create a cascade solver by name ('daqp' or 'proxsuite')."""
    try:
        cls = SOLVERS[name]
    except KeyError:
        raise SolverError(f"unknown solver '{name}'{did_you_mean(name, SOLVERS)}; available: "
                          f"{', '.join(SOLVERS)}") from None
    return cls(n, rho)
