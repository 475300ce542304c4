"""Strict-priority hierarchical QP cascade (SPEC 3, Sec. 4.1.4, Alg. C.3).

Variables w = [qdot_v; s] with s the slack of the current level. For i = 1..k::

    min 1/2 w^T diag(rho I_n, I_m) w
    s.t. beta_m,i <= A_i qdot_v - s <= beta_M,i          (current level, soft via s)
         b_m <= A_bar qdot_v <= b_M                      (all higher levels, hard)
         lower <= qdot_v <= upper                        (joint limits and PSPM, hard)

then the level is locked: its rows join A_bar with bounds [beta_m + s*, beta_M + s*]
(A_i qdot_v* for equality rows), widened by a band of 1e-9 per unit row norm. A level
whose solve fails (after the retries of :class:`DaqpCascade`) keeps the previous level's
solution.

Solvers share one interface (:class:`CascadeSolver`): ``daqp`` (dual active set, exact,
default) and ``proxsuite`` (dense proximal ALM, warm started). Building the levels
(:func:`build_levels`) is separate from solving them (STYLE #3).
"""

import math
from typing import NamedTuple

import numpy as np

from ifc_spg import kernels as native
from ifc_spg.errors import SolverError, did_you_mean

__all__ = ['CascadeResult', 'CascadeSolver', 'DaqpCascade', 'ProxsuiteCascade', 'SOLVERS',
           'build_levels', 'make_solver', 'level_violation']

_BIG = 1e30  # what the solvers take as infinity
_TINY = 1e-300  # floor of a row norm (an all-zero row stays zero when scaled)
_EQ = 5  # DAQP sense flag: equality constraint (ACTIVE | IMMUTABLE)


class CascadeResult(NamedTuple):
    """Outcome of one cascade solve.

    Attributes:
        qdot_v: Virtual joint velocity in [rad/s] (n,), always finite and inside the box.
        slacks: Optimal slack s* of each level (list of (m_i,) arrays).
        status: 'ok', 'fallback' (a level failed; the previous level's solution is used)
            or 'hold' (the first level failed; zero velocity clipped into the box).
        failed_level: Index of the failed level, or -1.
    """

    qdot_v: np.ndarray
    slacks: list
    status: str
    failed_level: int


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
                return CascadeResult(np.clip(qdot, box_lo, box_hi), slacks, status, i)
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
        return CascadeResult(np.clip(qdot, box_lo, box_hi), slacks, 'ok', -1)


class DaqpCascade(CascadeSolver):
    """The cascade with DAQP (exact dual active-set QP, PyPI ``daqp``).

    The rows of all levels are stacked once per tick in priority order. An equality level
    needs no slack variables: with s = A_i qdot_v - beta_i free, (4.45)-(4.48) is exactly

        min 1/2 qdot_v^T (rho I + A_i^T A_i) qdot_v - (A_i^T beta_i)^T qdot_v

    under the locked higher rows and the box (n variables). An inequality level the current
    solution already satisfies is locked without a QP; one that it violates is solved with
    its slacks, (4.45)-(4.48) as written.

    Each level index has its own DAQP model over views of the stacked workspace (the box
    and the higher levels' rows, scaled to unit norm); DAQP keeps a model's working set
    between solves, so every level starts from its own active set of the last tick. A
    failed solve retries cold with the locked bands widened to contain the current
    solution, then in the slack form, then with the bands widened by the solver's
    tolerance (degenerate vertices), before the level is given up.

    The cost's condition number grows like |A_i|^2 / rho; below rho = 1e-6 (only used to
    compare with pseudo-inverses) equality levels also take the slack form.
    """

    name = 'daqp'

    def __init__(self, n, rho=0.01, primal_tol=1e-6):
        super().__init__(n, rho)
        import daqp
        self._solve = daqp.solve
        self._solve_model = lambda model: model.solve()
        self._settings = {'primal_tol': float(primal_tol)}
        self._ws = {}
        self._normal_form = self.rho >= 1e-6
        self.cold_retries = 0
        self.relaxed_retries = 0
        self._relax = float(primal_tol)
        self._native = native.module  # C kernels of the row arithmetic, or None (numpy)

    @property
    def model_count(self):
        """DAQP models built so far (workspaces and per-level models are kept for reuse)."""
        return sum(len(ws._levels) for ws in self._ws.values())

    def prepare(self, dims, equalities):
        """Build, before a stack is active, the workspace and the DAQP model of each level a
        stack with these level sizes and kinds will solve (normal-form models of equality
        levels, warm-started slack models of inequality levels), so that its first tick does
        no setup (issue: a first or stack-switch tick of 1-1.8 ms against a 0.1 ms median).
        """
        R = int(sum(dims))
        if not R:
            return
        ws = self._ws.get(R)
        if ws is None:
            ws = self._ws[R] = _Workspace(self.n, R, self.rho, self._settings)
        start = 0
        for i, (m, equality) in enumerate(zip(dims, equalities)):
            end = start + int(m)
            if equality and self._normal_form:
                ws.level(i, start)
            elif not equality:
                ws.slack_level(i, start, end, self.rho)
            start = end

    def solve(self, levels, box):
        """Solve the cascade; return a :class:`CascadeResult` (see the class docstring)."""
        if not levels:
            return super().solve(levels, box)
        n = self.n
        ms = [lev.A.shape[0] for lev in levels]
        R = sum(ms)
        ws = self._ws.get(R)
        if ws is None:
            ws = self._ws[R] = _Workspace(n, R, self.rho, self._settings)
        A_all, orig_lo, orig_hi = ws.A, ws.orig_lo, ws.orig_hi
        bl, bu, lo_rows, hi_rows = ws.bl, ws.bu, ws.lo_rows, ws.hi_rows
        norm, band, nat = ws.norm, ws.band, self._native
        # The models see the rows scaled to unit norm (the same constraints; DAQP's
        # tolerances are absolute, and a wrench row of norm ~400 next to pose rows of
        # norm ~1 otherwise made levels falsely infeasible).
        # Lock band of every row: lock_tolerance (1 + |row|_1), in unit-row coordinates.
        # Locked equality rows of several levels are often redundant (higher levels may fix
        # qdot_v completely); exact equalities would then be inconsistent by round-off.
        if nat is not None:
            nat.stack_rows(levels, A_all, orig_lo, orig_hi, norm, ws.A_unit, band,
                           self.lock_tolerance)
        else:
            _stack_rows(levels, ms, ws, self.lock_tolerance)
        bl[:n] = box.lower  # (DAQP takes +-inf as unbounded)
        bu[:n] = box.upper
        qdot = None  # no level solved yet: the point of the box nearest zero (made on demand)
        slacks = []
        start = 0
        for i, (lev, m) in enumerate(zip(levels, ms)):
            end = start + m
            sl = slice(start, end)
            A_i = A_all[sl]
            if lev.equality and self._normal_form:
                beta = orig_lo[sl]
                H, H_diag, f, model = ws.level(i, start)
                if nat is not None:
                    nat.normal_form(A_i, beta, self.rho, H, f)
                else:
                    np.dot(A_i.T, A_i, out=H)
                    H_diag += self.rho
                    np.dot(beta, A_i, out=f)
                    np.negative(f, out=f)  # f = -A_i^T beta
                # Each level index has its own DAQP model, which keeps its working set: the
                # solve starts from this level's active bounds and rows of the last tick.
                if start:
                    model.update(H=H, f=f, A=ws.A_unit[:start], blower=bl[:n + start])
                else:  # the first level: the box only
                    model.update(H=H, f=f, blower=bl[:n])
                x, _, flag, _ = self._solve_model(model)
                if flag != 1:
                    # a warm start can end in a false 'infeasible' on degenerate levels (a
                    # higher level locked at a vertex of the box); retry cold, with the locked
                    # bands widened to contain the current solution
                    self.cold_retries += 1
                    _widen(ws, qdot, start)
                    model.update(blower=bl[:n + start], sense=ws.cold_sense[:n + start])
                    x, _, flag, _ = self._solve_model(model)
                # x @ f is finite for any finite x and NaN otherwise (cheaper than isfinite)
                if flag == 1 and math.isfinite(x @ f):
                    # lock (4.60)-(4.62) at A_i qdot_v +- band; the last level needs no lock
                    lock = end < R
                    if nat is not None:
                        qdot, s = nat.accept(x, bl, bu, ws.A_unit[sl], norm[sl], beta,
                                             band[sl], lo_rows[sl] if lock else None,
                                             hi_rows[sl] if lock else None)
                        slacks.append(s)
                    else:
                        qdot, a_unit = _accept(ws, x, start, end)
                        slacks.append(a_unit * norm[sl] - beta)
                        if lock:
                            np.subtract(a_unit, band[sl], out=lo_rows[sl])
                            np.add(a_unit, band[sl], out=hi_rows[sl])
                    start = end
                    continue
                # retry in the slack form (better conditioned)
                w, flag = self._solve_with_slacks(ws, start, end)
            elif not lev.equality:
                if qdot is None:
                    qdot = np.minimum(np.maximum(0.0, bl[:n]), bu[:n])
                # If the current solution satisfies this level with zero slack, it minimizes
                # rho |qdot|^2 over everything the higher levels allow, so it is this level's
                # optimum too: no QP needed (typical for inactive inequalities: obstacles,
                # boxes, torque bands). Its lock [lower + s*, upper + s*] is its own bounds
                # (s* = 0; they contain the solution), in unit-row coordinates.
                if nat is not None:
                    done = nat.lock_if_satisfied(A_i, qdot, orig_lo[sl], orig_hi[sl], norm[sl],
                                                 band[sl], lo_rows[sl], hi_rows[sl])
                else:
                    done = _lock_if_satisfied(ws, qdot, start, end)
                if done:
                    slacks.append(np.zeros(m))
                    start = end
                    continue
                w, flag = self._solve_slack_level(ws, i, start, end)  # warm started
                if flag != 1:
                    self.cold_retries += 1
                    _widen(ws, qdot, start)
                    w, flag = self._solve_with_slacks(ws, start, end)
            else:  # an equality level with rho < 1e-6
                w, flag = self._solve_with_slacks(ws, start, end)
            if flag != 1 and start:
                # Degenerate: the locked bands (1e-9 wide) meet the box at a vertex and DAQP
                # cannot tell them from infeasible. Widen the bands to the solver's own
                # tolerance (the higher levels move by at most that) and solve once more.
                self.relaxed_retries += 1
                ws.lo_rows[:start] -= self._relax
                ws.hi_rows[:start] += self._relax
                w, flag = self._solve_with_slacks(ws, start, end)
            if flag != 1 or not math.isfinite(w @ ws.zeros_w[:n + m]):
                slacks.extend(np.full(lv.A.shape[0], np.nan) for lv in levels[i:])
                if qdot is None:
                    qdot = np.minimum(np.maximum(0.0, bl[:n]), bu[:n])
                return CascadeResult(qdot, slacks, 'hold' if i == 0 else 'fallback', i)
            # lock: [lower + s*, upper + s*] (A qdot* for equality rows), widened by the band
            if nat is not None:
                qdot, s = nat.accept_slack(w, bl, bu, ws.A_unit[sl], norm[sl], orig_lo[sl],
                                           orig_hi[sl], band[sl], lo_rows[sl], hi_rows[sl])
            else:
                qdot, a_unit = _accept(ws, w[:n], start, end)
                a = a_unit * norm[sl]
                s = w[n:]
                eq = orig_lo[sl] == orig_hi[sl]
                lo = np.where(eq, a, np.minimum(orig_lo[sl] + s, a))
                hi = np.where(eq, a, np.maximum(orig_hi[sl] + s, a))
                lo_rows[sl] = lo / norm[sl] - band[sl]
                hi_rows[sl] = hi / norm[sl] + band[sl]
            slacks.append(s)
            start = end
        return CascadeResult(qdot, slacks, 'ok', -1)

    def _solve_slack_level(self, ws, i, start, end):
        """Inequality level ``start:end`` as (4.45)-(4.48) over [qdot_v; s], with this level
        index's persistent DAQP model (warm started); return ``(x, exitflag)``.
        """
        n = self.n
        if (ws.orig_lo[start:end] == ws.orig_hi[start:end]).any():
            return self._solve_with_slacks(ws, start, end)  # equal rows: flagged, cold
        C, bu, bl, cold, model = ws.slack_level(i, start, end, self.rho)
        if self._native is not None:
            self._native.slack_setup(ws.A_unit, ws.A, start, end, ws.bl, ws.bu, ws.orig_lo,
                                     ws.orig_hi, C, bl, bu)
        else:
            m = end - start
            C[:start, :n] = ws.A_unit[:start]
            C[start:, :n] = ws.A[start:end]
            bu[:n] = ws.bu[:n]
            bl[:n] = ws.bl[:n]
            bu[n + m:n + m + start] = ws.hi_rows[:start]
            bl[n + m:n + m + start] = ws.lo_rows[:start]
            bu[n + m + start:] = ws.orig_hi[start:end]
            bl[n + m + start:] = ws.orig_lo[start:end]
        model.update(A=C, blower=bl)
        x, _, flag, _ = self._solve_model(model)
        if flag != 1:
            model.update(sense=cold)  # forget the working set
        return x, flag

    def _solve_with_slacks(self, ws, start, end):
        """Level ``start:end`` as (4.45)-(4.48) over [qdot_v; s]; return ``(x, exitflag)``."""
        n, m = self.n, end - start
        C = np.zeros((end, n + m))
        C[:start, :n] = ws.A_unit[:start]
        C[start:, :n] = ws.A[start:end]
        C[start:, n:] = -_eye(m)
        bu = np.concatenate([ws.bu[:n], np.full(m, _BIG), ws.hi_rows[:start],
                             ws.orig_hi[start:end]])
        bl = np.concatenate([ws.bl[:n], np.full(m, -_BIG), ws.lo_rows[:start],
                             ws.orig_lo[start:end]])
        sense = np.zeros(n + m + end, dtype=np.int32)
        sense[n + m + start:] = np.where(ws.orig_lo[start:end] == ws.orig_hi[start:end], _EQ, 0)
        H = np.diag(np.concatenate([np.full(n, self.rho), np.ones(m)]))
        x, _, flag, _ = self._solve(H, np.zeros(n + m), C, bu, bl, sense, **self._settings)
        return x, flag


class _Workspace:
    """Preallocated rows and bounds of a cascade with R task rows over n joints, and one
    DAQP model per level index that points at them (so updates only say what changed).
    """

    def __init__(self, n, R, rho, settings):
        self.n = n
        self.A = np.zeros((R, n))  # rows as the levels give them
        self.A_unit = np.zeros((R, n))  # the same rows scaled to unit norm (the models')
        self.norm = np.zeros(R)
        self.band = np.zeros(R)  # half-width of each row's lock, in unit-row coordinates
        self.orig_lo = np.zeros(R)
        self.orig_hi = np.zeros(R)
        self.bu = np.full(n + R, np.inf)
        self.bl = np.full(n + R, -np.inf)
        self.lo_rows = self.bl[n:]
        self.hi_rows = self.bu[n:]
        self.cold_sense = np.zeros(n + R, dtype=np.int32)
        self.zeros_w = np.zeros(n + R)
        self.settings = settings
        self._levels = {}

    def slack_level(self, i, start, end, rho):
        """``(C, bu, bl, cold sense, model)`` of inequality level index i (rows
        ``start:end``): over w = [qdot_v; s], C = [[A_higher, 0], [A_i, -I]], bounds [box;
        free; rows]; the model points at C, bu and bl and keeps its working set from tick to
        tick.
        """
        key = ('slack', i, start, end)
        hit = self._levels.get(key)
        if hit is None:
            hit = self._levels[key] = _slack_model(self.n, start, end, rho, self.settings)
        return hit

    def level(self, i, start):
        """``(H, diagonal view of H, f, model)`` of level index i, whose higher levels have
        ``start`` rows.

        The model sees the box and the first ``start`` rows (views of the shared arrays),
        and keeps its working set from tick to tick: a warm start.
        """
        key = (i, start)
        hit = self._levels.get(key)
        if hit is None:
            n = self.n
            H, f = np.eye(n), np.zeros(n)
            model = _daqp_model(H, f, self.A_unit[:start], self.bu[:n + start],
                                self.bl[:n + start], self.settings)
            hit = self._levels[key] = (H, H.reshape(-1)[::n + 1], f, model)
        return hit


def _slack_model(n, start, end, rho, settings):
    """Arrays and DAQP model of an inequality level with slacks (see ``slack_level``)."""
    m = end - start
    C = np.zeros((end, n + m))
    C[start:, n:] = -np.eye(m)
    bu = np.full(n + m + end, np.inf)
    bl = np.full(n + m + end, -np.inf)
    H = np.diag(np.concatenate([np.full(n, rho), np.ones(m)]))
    cold = np.zeros(n + m + end, dtype=np.int32)  # sense flags of a cold start
    return C, bu, bl, cold, _daqp_model(H, np.zeros(n + m), C, bu, bl, settings)


def _daqp_model(H, f, A, bu, bl, settings):
    """A DAQP model pointing at these arrays (no copies: later in-place changes plus an
    ``update`` naming them are seen), with its own all-inequality sense flags and
    ``settings`` applied over DAQP's defaults.
    """
    import daqp
    model = daqp.Model()
    model.setup(H, f, A, bu, bl, np.zeros(bu.shape[0], dtype=np.int32))
    merged = dict(model.settings)
    merged.update(settings)
    model.settings = merged
    return model


def _stack_rows(levels, ms, ws, lock_tolerance):
    """Stack the levels' rows and bounds into the workspace, with each row's norm, unit row
    and lock band (``_native.stack_rows`` in numpy).
    """
    A_all, norm = ws.A, ws.norm
    row = 0
    for lev, m in zip(levels, ms):
        A_all[row:row + m] = lev.A
        ws.orig_lo[row:row + m] = lev.lower
        ws.orig_hi[row:row + m] = lev.upper
        row += m
    np.einsum('ij,ij->i', A_all, A_all, out=norm)
    np.sqrt(norm, out=norm)
    np.maximum(norm, _TINY, out=norm)
    np.divide(A_all, norm[:, None], out=ws.A_unit)
    band = ws.band
    np.abs(A_all).sum(axis=1, out=band)
    band += 1.0
    band *= lock_tolerance
    band /= norm


def _lock_if_satisfied(ws, qdot, start, end):
    """If ``qdot`` satisfies the rows ``start:end``, lock them at their own bounds and return
    True (``_native.lock_if_satisfied`` in numpy).
    """
    sl = slice(start, end)
    a = ws.A[sl] @ qdot
    if not _satisfied(a, ws.orig_lo[sl], ws.orig_hi[sl]):
        return False
    lo, hi = ws.lo_rows[sl], ws.hi_rows[sl]
    np.divide(ws.orig_lo[sl], ws.norm[sl], out=lo)
    lo -= ws.band[sl]
    np.divide(ws.orig_hi[sl], ws.norm[sl], out=hi)
    hi += ws.band[sl]
    return True


def _accept(ws, x, start, end):
    """Take the solution ``x`` of the level of rows ``start:end``, clipped into the box
    (DAQP meets constraints to its 1e-6 tolerance); return ``(qdot_v, A_i qdot_v)``, the
    latter in unit-row coordinates.
    """
    n = x.shape[0]
    qdot = np.minimum(np.maximum(x, ws.bl[:n]), ws.bu[:n])
    return qdot, ws.A_unit[start:end] @ qdot


def _widen(ws, qdot, start):
    """Widen the locked bands of rows ``:start`` to contain ``qdot`` (the higher levels'
    solution, inside the box): the locked set then surely contains a point, and a level
    that DAQP called infeasible can be retried. Bands are 1e-9 wide and DAQP's tolerance is
    1e-6, so a solution may lie just outside them.
    """
    if qdot is None or not start:
        return
    a = ws.A_unit[:start] @ qdot
    np.minimum(ws.lo_rows[:start], a, out=ws.lo_rows[:start])
    np.maximum(ws.hi_rows[:start], a, out=ws.hi_rows[:start])


def _satisfied(a, lo, hi):
    """True if lo <= a <= hi everywhere."""
    return np.maximum(lo - a, a - hi).max() <= 0.0


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
