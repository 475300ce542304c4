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

import math
from typing import NamedTuple

import numpy as np

from ifc_spg.errors import SolverError, did_you_mean

__all__ = ['CascadeResult', 'CascadeSolver', 'DaqpCascade', 'ProxsuiteCascade', 'SOLVERS',
           'build_levels', 'make_solver', 'level_violation']

_BIG = 1e30  # what the solvers take as infinity
_EQ = 5      # DAQP sense flag: equality constraint (ACTIVE | IMMUTABLE)
_IMMUTABLE = 4


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
    lock_tolerance = 1e-9  # half-width of a locked row's band, per unit of its 1-norm

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
            band = self.lock_tolerance * (1.0 + np.abs(lev.A).sum(axis=1))
            lo = np.where(eq_cur, a, np.minimum(lev.lower + s, a)) - band
            hi = np.where(eq_cur, a, np.maximum(lev.upper + s, a)) + band
            A_bar = np.vstack([lev.A, A_bar]) if m else A_bar
            b_lo = np.concatenate([lo, b_lo])
            b_hi = np.concatenate([hi, b_hi])
            eq_bar = np.concatenate([np.zeros(m, dtype=bool), eq_bar])
        return CascadeResult(np.clip(qdot, box_lo, box_hi), slacks, 'ok', -1,
                             _outside(qdot, box_lo, box_hi))


def _outside(x, lo, hi):
    return float(max(np.max(lo - x, initial=0.0), np.max(x - hi, initial=0.0)))


class DaqpCascade(CascadeSolver):
    """The cascade with DAQP (exact dual active-set QP, PyPI ``daqp``).

    The rows of all levels are stacked once per tick in priority order; level i solves
    over the rows of levels 0..i with slack columns on its own rows only, and writes its
    locked bounds in place. Nothing is re-assembled between levels.
    """

    name = 'daqp'

    def __init__(self, n, rho=0.01, primal_tol=1e-6):
        super().__init__(n, rho)
        import daqp
        self._solve = daqp.solve
        self._solve_model = lambda model: model.solve()
        self._settings = {'primal_tol': float(primal_tol)}
        self._ws = {}
        self.cold_retries = 0

    def solve(self, levels, box):
        """Solve the cascade (fast path: one stacked problem, only bounds change per level).

        All levels share one constraint matrix [A_all, -I_R] over w = [qdot_v; s_1..s_k]:
        level i frees its own slacks, fixes the others to zero (so the rows of the higher
        levels are hard, at their locked bounds) and leaves the rows of lower levels
        unbounded. The QP of level i is then exactly (4.45)-(4.48).
        """
        if not levels:
            return super().solve(levels, box)
        n = self.n
        ms = [lev.A.shape[0] for lev in levels]
        R = sum(ms)
        ws = self._ws.get(R)
        if ws is None:
            ws = self._ws[R] = _Workspace(n, R, self.rho, self._settings)
        C, bu, bl, sense = ws.C, ws.bu, ws.bl, ws.sense
        A_all = C[:, :n]
        row = 0
        for lev, m in zip(levels, ms):
            A_all[row:row + m] = lev.A
            bl[n + R + row:n + R + row + m] = lev.lower
            bu[n + R + row:n + R + row + m] = lev.upper
            row += m
        np.abs(A_all, out=ws.abs_A)
        # lock band of every row: lock_tolerance per unit of the row's 1-norm (see below)
        band = ws.abs_A.sum(axis=1)
        band += 1.0
        band *= self.lock_tolerance
        lo_rows = bl[n + R:]
        hi_rows = bu[n + R:]
        np.maximum(lo_rows, -_BIG, out=lo_rows)
        np.minimum(hi_rows, _BIG, out=hi_rows)
        eq_all = lo_rows == hi_rows
        eq_sense = np.where(eq_all, _EQ, 0)
        orig_lo = lo_rows.copy()
        orig_hi = hi_rows.copy()
        # lower levels start unbounded; slacks start fixed at zero
        lo_rows[:] = -_BIG
        hi_rows[:] = _BIG
        np.maximum(box.lower, -_BIG, out=bl[:n])
        np.minimum(box.upper, _BIG, out=bu[:n])
        bl[n:n + R] = 0.0
        bu[n:n + R] = 0.0
        sense[:] = 0
        sense[n:n + R] = _EQ
        row_sense = sense[n + R:]
        zeros = ws.f
        qdot = np.minimum(np.maximum(0.0, bl[:n]), bu[:n])
        slacks = []
        start = 0
        a_sent = False
        for i, m in enumerate(ms):
            end = start + m
            sl = slice(start, end)
            slack = slice(n + start, n + end)
            if not levels[i].equality and _satisfied(a := A_all[sl] @ qdot, orig_lo[sl],
                                                     orig_hi[sl]):
                # The current solution already satisfies this level with zero slack. It
                # minimizes rho |qdot|^2 over everything the higher levels allow, so it is
                # this level's optimum too: no QP needed (typical for inactive
                # inequalities: obstacles, boxes, torque bands).
                slacks.append(np.zeros(m))
                lo = np.minimum(orig_lo[sl], a)
                hi = np.maximum(orig_hi[sl], a)
                lo -= band[sl]
                hi += band[sl]
                lo_rows[sl] = lo
                hi_rows[sl] = hi
                start = end
                continue
            lo_rows[sl] = orig_lo[sl]
            hi_rows[sl] = orig_hi[sl]
            row_sense[sl] = eq_sense[sl]
            bl[slack] = -_BIG
            bu[slack] = _BIG
            sense[slack] = 0
            if not a_sent:
                ws.model.update(A=C, bupper=bu, blower=bl, sense=sense)
                a_sent = True
            else:
                ws.model.update(bupper=bu, blower=bl, sense=sense)
            x, _, flag, _ = self._solve_model(ws.model)
            if flag != 1:
                # the warm-started workspace can end in a false 'infeasible' on degenerate
                # levels (a higher level locked at a vertex of the box); a cold solve of the
                # same problem is exact, so retry once before giving up
                self.cold_retries += 1
                # (DAQP writes its working set into `sense`: keep only the equality flags)
                cold = np.where(sense & _IMMUTABLE, _EQ, 0).astype(np.int32)
                x, _, flag, _ = self._solve(ws.H, ws.f, C, bu, bl, cold, **self._settings)
            # x @ 0 is 0 for any finite x and NaN otherwise (cheaper than isfinite().all())
            if flag != 1 or not math.isfinite(x @ zeros):
                slacks.extend(np.full(lv.A.shape[0], np.nan) for lv in levels[i:])
                return _result(qdot, bl[:n], bu[:n], slacks, 'hold' if i == 0 else 'fallback',
                               i)
            qdot = x[:n]
            s = x[slack]
            slacks.append(s)
            a = A_all[sl] @ qdot
            # lock: [lower + s*, upper + s*] (A qdot* for equality rows), widened by a band
            # of lock_tolerance relative to the row norm. Locked equality rows of several
            # levels are often redundant (higher levels may fix qdot_v completely); exact
            # equalities would then be inconsistent by round-off and the level infeasible.
            if levels[i].equality:
                lo = a.copy()
                hi = a
            else:
                lo = np.minimum(orig_lo[sl] + s, a)
                hi = np.maximum(orig_hi[sl] + s, a)
                eq = eq_all[sl]
                if eq.any():
                    lo[eq] = a[eq]
                    hi[eq] = a[eq]
            lo -= band[sl]
            hi += band[sl]
            lo_rows[sl] = lo
            hi_rows[sl] = hi
            row_sense[sl] = 0
            # lock: the slacks of this level are fixed to zero from now on
            bl[slack] = 0.0
            bu[slack] = 0.0
            sense[slack] = _EQ
            start = end
        return _result(qdot, bl[:n], bu[:n], slacks, 'ok', -1)


class _Workspace:
    """Preallocated stacked problem of a cascade with R task rows over n joints, and the
    DAQP model (workspace) that solves it; only bounds (and A once per tick) change."""

    def __init__(self, n, R, rho, settings):
        self.C = np.zeros((R, n + R))
        self.C[:, n:] = -np.eye(R)
        self.H = np.diag(np.concatenate([np.full(n, rho), np.ones(R)]))
        self.f = np.zeros(n + R)
        self.bu = np.zeros(n + R + R)
        self.bl = np.zeros(n + R + R)
        self.sense = np.zeros(n + R + R, dtype=np.int32)
        self.abs_A = np.zeros((R, n))
        import daqp
        self.model = daqp.Model()
        self.model.setup(self.H, self.f, self.C, self.bu, self.bl, self.sense)
        settings_ = dict(self.model.settings)
        settings_.update(settings)
        self.model.settings = settings_


def _satisfied(a, lo, hi):
    """True if lo <= a <= hi everywhere."""
    return np.maximum(lo - a, a - hi).max() <= 0.0


def _result(qdot, lo, hi, slacks, status, failed):
    clipped = np.minimum(np.maximum(qdot, lo), hi)
    clipped -= qdot
    outside = float(np.abs(clipped).max())
    clipped += qdot
    return CascadeResult(clipped, slacks, status, failed, outside)


_EYES = {}


def _eye(m):
    e = _EYES.get(m)
    if e is None:
        e = _EYES[m] = np.eye(m)
    return e


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


SOLVERS = {'daqp': DaqpCascade, 'proxsuite': ProxsuiteCascade}


def make_solver(name, n, rho=0.01):
    """Create a cascade solver by name ('daqp' or 'proxsuite')."""
    try:
        cls = SOLVERS[name]
    except KeyError:
        raise SolverError(f"unknown solver '{name}'{did_you_mean(name, SOLVERS)}; available: "
                          f"{', '.join(SOLVERS)}") from None
    return cls(n, rho)
