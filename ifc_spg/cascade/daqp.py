"""The strict-priority cascade with DAQP (docs/SPEC.md §3, Alg. C.3), the default solver.

The level QPs are those of :mod:`ifc_spg.cascade.base`; this solver stacks the rows of all
levels once per tick, keeps one warm-started DAQP model per level index, skips the QP of
an inequality level the current solution satisfies, and solves equality levels without
slack variables (see :class:`DaqpCascade`). The warm start is explicit state: each model's
working set is kept as sense flags, given to DAQP with every solve, and can be read and
restored (:meth:`DaqpCascade.warm_start`), so a replay that starts mid-run solves exactly
as the live run did.
"""

from collections.abc import Sequence
import importlib
import importlib.metadata
import math
import os
from types import ModuleType
from typing import Any

import numpy as np

from ifc_spg import kernels as _kernels
from ifc_spg.cascade.base import CascadeResult, CascadeSolver, level_violation
from ifc_spg.errors import IfcSpgError
from ifc_spg.limits.joint_limits import VelocityBox
from ifc_spg.tasks.task import Level

__all__ = ['CascadeResult', 'DaqpCascade', 'describe', 'level_violation', 'native']

_BIG = 1e30  # what the solvers take as infinity
_EQ = 5  # DAQP sense flag: equality constraint (ACTIVE | IMMUTABLE)
_ACTIVE, _LOWER = 1, 2  # DAQP sense flags: in the working set; at its lower bound
_ABI = 2  # the interface of ifc_spg.cascade._daqp_native this module is written for

#: Why the C module is not used where it was built ('' where it is, or was not built).
stale = ''


def _load_native() -> ModuleType | None:
    """The level solves from C (``_daqp_native.c``), or None.

    The module calls DAQP's C functions in the installed ``daqp`` module's binary. None
    where it was not built (no compiler, or setup could not fetch DAQP's headers), and where
    it is stale: built for another interface or another DAQP version than the ``daqp``
    module installed, or that module does not export DAQP's functions.
    """
    global stale
    try:
        module = importlib.import_module('ifc_spg.cascade._daqp_native')
    except ImportError:
        return None
    try:
        installed = importlib.metadata.version('daqp')
    except importlib.metadata.PackageNotFoundError:
        installed = '?'
    if getattr(module, 'UNBOUND', 'unknown'):  # DAQP's C functions not found
        stale = f'DAQP not bound: {getattr(module, "UNBOUND", "unknown")}'
    elif getattr(module, 'ABI', None) != _ABI:
        stale = f'built for interface {getattr(module, "ABI", None)}, not {_ABI}'
    elif getattr(module, 'DAQP_VERSION', None) != installed:
        stale = f'built with DAQP {getattr(module, "DAQP_VERSION", None)}, not {installed}'
    return None if stale else module


#: The C level solves (:mod:`ifc_spg.cascade._daqp_native`), or None where not built or stale.
native: ModuleType | None = _load_native()
_disabled = os.environ.get('IFC_SPG_NATIVE', '1').strip() == '0'
_UPDATE_H, _UPDATE_A, _UPDATE_BOUNDS = 1, 2, 8  # DAQP_UPDATE_Rinv, _M, _d


def describe() -> str:
    """Which DAQP layer a cascade with the C kernels uses, and why."""
    if native is not None and not _disabled:
        return 'DAQP from C (ifc_spg.cascade._daqp_native)'
    if _disabled:
        return 'DAQP through its Python module (IFC_SPG_NATIVE=0)'
    if stale:
        return (f'DAQP through its Python module (ifc_spg.cascade._daqp_native is stale, '
                f'{stale}: rebuild it with ./run setup or pip install -e .)')
    return ('DAQP through its Python module (ifc_spg.cascade._daqp_native was not built: '
            "reinstall with a C compiler and DAQP's headers, see setup.py)")


class DaqpCascade(CascadeSolver):
    """The cascade with DAQP (exact dual active-set QP, PyPI ``daqp``).

    The rows of all levels are stacked once per tick in priority order. An equality level
    needs no slack variables: with s = A_i qdot_v - beta_i free, (4.45)-(4.48) is exactly

        min 1/2 qdot_v^T (rho I + A_i^T A_i) qdot_v - (A_i^T beta_i)^T qdot_v

    under the locked higher rows and the box (n variables). An inequality level the current
    solution already satisfies is locked without a QP; one that it violates is solved with
    its slacks, (4.45)-(4.48) as written.

    Each level index has its own DAQP model over views of the stacked workspace (the box
    and the higher levels' rows, scaled to unit norm); every level starts from its own
    active set of the last tick (a warm start). That working set is explicit state, not
    DAQP's: after each solve it is read from the multipliers (a constraint is in it if its
    multiplier is not zero, at its lower bound if negative) and handed back as the sense
    flags of the next solve, so a solve depends only on its data and that working set, and
    :meth:`warm_start` / :meth:`set_warm_start` carry it to another solver (a replay that
    starts mid-run: with a different working set DAQP may stop at a different point of a
    degenerate level's optimal set within its tolerance, 1.5e-2 rad/s apart on a stalled
    stack). A failed solve retries cold with the locked bands widened to contain the current
    solution, then in the slack form, then with the bands widened by the solver's
    tolerance (degenerate vertices), before the level is given up.

    The cost's condition number grows like |A_i|^2 / rho; below rho = 1e-6 (only used to
    compare with pseudo-inverses) equality levels also take the slack form.

    The warm-started level solves call DAQP from C (:data:`native`, one call per solve
    over the same arrays, the same DAQP calls and working-set rule) where that module was
    built and the cascade uses the C kernels; ``daqp_native=False`` (or the numpy kernels)
    keeps them on DAQP's Python module. The two give the same numbers.
    """

    name = 'daqp'

    def __init__(self, n: int, rho: float = 0.01, primal_tol: float = 1e-6, *,
                 kernels: ModuleType | None = None, daqp_native: bool | None = None):
        super().__init__(n, rho)
        import daqp
        #: The two DAQP calls, ``solve_model(model)`` (a persistent model) and
        #: ``solve_qp(H, f, A, bu, bl, sense, **settings)`` (a one-off QP), both returning
        #: ``(x, fval, exitflag, info)``; attributes so that a test can inject failures.
        self.solve_model = _solve_model
        self.solve_qp = daqp.solve
        #: The C solve of a level model (where :attr:`native_daqp` is set and
        #: ``solve_model`` is DAQP's own), ``solve_native(model, mask) -> exitflag`` (see
        #: ``_daqp_native.c``); an attribute for the same reason.
        self.solve_native = _solve_native
        self._settings = {'primal_tol': float(primal_tol)}
        self._ws: dict = {}
        self._plans: dict = {}  # level layout -> [_LevelPlan] (see _plan)
        self._cold = True  # every working set is empty (no solve since forget_warm_start)
        self._normal_form = self.rho >= 1e-6
        #: Level solves retried cold (a warm start ended in a false 'infeasible').
        self.cold_retries = 0
        #: Level solves retried with the locked bands widened to DAQP's tolerance.
        self.relaxed_retries = 0
        self._relax = float(primal_tol)
        self._kernels = _kernels.resolve(kernels)
        self._zeros_n = np.zeros(n)
        self._zeros_n.setflags(write=False)
        if daqp_native is None:
            daqp_native = self._kernels is not _kernels.reference and not _disabled
        #: The C level solves (:data:`native`) this cascade makes, or None (DAQP's Python
        #: module); built with them, a cascade can be switched to None and back.
        self.native_daqp: ModuleType | None = native if daqp_native else None

    @property
    def model_count(self) -> int:
        """DAQP models built so far (workspaces and per-level models are kept for reuse)."""
        return sum(len(ws.models) for ws in self._ws.values())

    def prepare(self, dims: Sequence[int], equalities: Sequence[bool]) -> None:
        """Build the workspace and models of a stack before it is active.

        Build, before a stack is active, the workspace and the DAQP model of each level a
        stack with these level sizes and kinds will solve (normal-form models of equality
        levels, warm-started slack models of inequality levels), so that its first tick
        does no setup (issue: a first or stack-switch tick of 1-1.8 ms against a 0.1 ms
        median), and the per-level views of its layout (:meth:`_plan`).
        """
        self._warm_sets(dims, equalities)
        layout = tuple([(int(m), bool(e)) for m, e in zip(dims, equalities)])
        if layout and sum(dims) and layout not in self._plans:
            self._plan(layout)

    def _warm_sets(self, dims: Sequence[int], equalities: Sequence[bool]) -> list:
        """The working sets (sense arrays) of a stack's level models, built if new."""
        R = int(sum(dims))
        if not R:
            return []
        ws = self._workspace(R)
        start, sets = 0, []
        for i, (m, equality) in enumerate(zip(dims, equalities)):
            end = start + int(m)
            if equality and self._normal_form:
                ws.level(i, start)
                sets.append(ws.warm[(i, start)])
            elif not equality:
                ws.slack_level(i, start, end, self.rho)
                sets.append(ws.warm[('slack', i, start, end)])
            start = end
        return sets

    def warm_start(self, dims: Sequence[int], equalities: Sequence[bool]) -> np.ndarray:
        """The working sets a stack's next solve starts from, as one float vector.

        For the stack with level sizes ``dims`` and kinds ``equalities``: per level model
        (equality levels in their normal form, inequality levels with slacks), in level
        order, DAQP's sense flag of each constraint (0 free, 1 active at its upper bound, 3
        at its lower bound). :meth:`set_warm_start` of another solver of the same size and
        rho continues from it exactly.
        """
        sets = self._warm_sets(dims, equalities)
        return np.concatenate(sets).astype(float) if sets else np.zeros(0)

    def set_warm_start(self, dims: Sequence[int], equalities: Sequence[bool],
                       values: np.ndarray) -> bool:
        """Start the next solves from a :meth:`warm_start` vector.

        Returns False (and leaves the working sets as they are) when ``values`` does not
        fit the stack: a wrong size, or entries that are not sense flags 0, 1 or 3.
        """
        sets = self._warm_sets(dims, equalities)
        values = np.asarray(values, dtype=float).reshape(-1)
        if values.size != sum(s.size for s in sets) or not np.isin(values, (0, 1, 3)).all():
            return False
        start = 0
        for s in sets:
            s[:] = values[start:start + s.size]
            start += s.size
        self._cold = False
        return True

    def forget_warm_start(self) -> None:
        """Start every level model cold at its next solve (a new stack, a restart)."""
        if self._cold:  # (a new stack's first tick after a reset asks twice)
            return
        for ws in self._ws.values():
            for warm in ws.warm.values():
                warm[:] = 0
        self._cold = True

    def _workspace(self, R: int) -> '_Workspace':
        ws = self._ws.get(R)
        if ws is None:
            ws = self._ws[R] = _Workspace(self.n, R, self.rho, self._settings,
                                          self.native_daqp)
        return ws

    def solve(self, levels: Sequence[Level], box: VelocityBox,
              q_v: np.ndarray | None = None) -> CascadeResult:
        """Solve the cascade; return a :class:`CascadeResult` (see the class docstring).

        ``q_v`` is not used (the box carries the joint limits).
        """
        if not levels:
            return super().solve(levels, box)
        self._cold = False  # the solves below keep working sets
        layout = tuple([(lev.A.shape[0], lev.equality) for lev in levels])
        plan = self._plans.get(layout)
        if plan is None:
            plan = self._plan(layout)
        ws = plan[0].ws
        # The models see the rows scaled to unit norm (the same constraints; DAQP's
        # tolerances are absolute, and a wrench row of norm ~400 next to pose rows of
        # norm ~1 otherwise made levels falsely infeasible).
        # Lock band of every row: lock_tolerance (1 + |row|_1), in unit-row coordinates.
        # Locked equality rows of several levels are often redundant (higher levels may fix
        # qdot_v completely); exact equalities would then be inconsistent by round-off.
        self._kernels.stack_rows(levels, ws.A, ws.orig_lo, ws.orig_hi, ws.norm, ws.A_unit,
                                 ws.band, self.lock_tolerance)
        ws.bl_box[:] = box.lower  # (DAQP takes +-inf as unbounded)
        ws.bu_box[:] = box.upper
        qdot = None  # no level solved yet: the point of the box nearest zero (made on demand)
        slacks: list = []
        for lp in plan:
            if lp.normal:
                done = self._equality_level(lp, qdot)
            else:
                if qdot is None:
                    qdot = self._box_point(ws)
                done = self._inequality_level(lp, qdot) if not lp.equality \
                    else self._accept_slack(ws, *self._solve_with_slacks(ws, lp.start, lp.end),
                                            lp.start, lp.end)
            if done is None:
                i = lp.i
                slacks.extend(np.full(lv.A.shape[0], np.nan) for lv in levels[i:])
                if qdot is None:
                    qdot = self._box_point(ws)
                return CascadeResult(qdot, slacks, 'hold' if i == 0 else 'fallback', i)
            qdot, s = done
            slacks.append(s)
        if qdot is None:  # solve() returns early on empty levels
            raise IfcSpgError('internal: cascade solved no level')
        return CascadeResult(qdot, slacks, 'ok', -1)

    def _box_point(self, ws: '_Workspace') -> np.ndarray:
        """The point of the box nearest zero, min(max(0, lower), upper) (a new array)."""
        zeros = self._zeros_n  # (the integrate kernel from zero: ~1.3 us less than numpy's)
        return self._kernels.integrate(zeros, 0.0, zeros, ws.bl_box, ws.bu_box)

    def _plan(self, layout: tuple) -> list['_LevelPlan']:
        """The per-level views and models of a stack with this layout.

        ``layout`` is ``((rows, equality), ...)`` per level. Built once per layout (level
        sizes and kinds), so that a tick slices no arrays and looks up no models.
        """
        ws = self._workspace(sum(m for m, _ in layout))
        plan, start = [], 0
        for i, (m, equality) in enumerate(layout):
            plan.append(_LevelPlan(self, ws, i, start, start + m, equality))
            start += m
        self._plans[layout] = plan
        return plan

    def _equality_level(self, lp: '_LevelPlan', qdot: np.ndarray | None
                        ) -> tuple[np.ndarray, np.ndarray] | None:
        """Solve an equality level in its normal form.

        An equality level without slacks (its normal form, n variables), with this level
        index's warm-started model; ``(qdot_v, s*)``, or None if it failed every retry.
        """
        ws, start, end = lp.ws, lp.start, lp.end
        H, f, model, warm = lp.H, lp.f, lp.model, lp.warm
        self._kernels.normal_form(lp.A, lp.lo, self.rho, H, f)
        if lp.native is not None and self.native_daqp is not None \
                and self.solve_model is _solve_model:
            # the same solves from C: x into lp.x, the working set kept in warm
            solve = self.solve_native
            flag = lp.native.solve(_UPDATE_H) if solve is _solve_native \
                else solve(lp.native, _UPDATE_H)
            if flag != 1:
                self.cold_retries += 1
                _widen(ws, qdot, start)
                warm[:] = 0
                flag = self.solve_native(lp.native, _UPDATE_BOUNDS)
            x = lp.x
            if flag == 1 and lp.native.finite():  # (math.isfinite(x @ f), without numpy)
                return self._kernels.accept(x, ws.bl, ws.bu, lp.A_unit, lp.norm, lp.lo,
                                            lp.band, lp.lock_lo, lp.lock_hi)
            return self._accept_slack(ws, *self._solve_with_slacks(ws, start, end), start,
                                      end)
        # Each level index has its own DAQP model and working set: the solve starts from
        # this level's active bounds and rows of the last tick (the sense flags ``warm``).
        # The model points at H, f and the workspace's rows and bounds (all written in
        # place), and a new H makes DAQP recompute everything from them (update_ldp: a new
        # Rinv implies M, v and d), so only H and the working set are handed over.
        model.update(H=H, sense=warm)
        solve_model = self.solve_model
        x, _, flag, info = model.solve() if solve_model is _solve_model else solve_model(model)
        if flag != 1:
            # a warm start can end in a false 'infeasible' on degenerate levels (a higher
            # level locked at a vertex of the box); retry cold, with the locked bands
            # widened to contain the current solution
            self.cold_retries += 1
            _widen(ws, qdot, start)
            warm[:] = 0
            model.update(blower=lp.bl_higher, sense=warm)
            x, _, flag, info = self.solve_model(model)
        if flag != 1 or type(info) is not dict or info.get('iterations') != 1:
            _keep_working_set(warm, flag, info)  # (one iteration: the set is kept as it is)
        # x @ f is finite for any finite x and NaN otherwise (cheaper than isfinite)
        if flag == 1 and math.isfinite(x @ f):
            # lock (4.60)-(4.62) at A_i qdot_v +- band; the last level needs no lock
            return self._kernels.accept(x, ws.bl, ws.bu, lp.A_unit, lp.norm, lp.lo, lp.band,
                                        lp.lock_lo, lp.lock_hi)
        # retry in the slack form (better conditioned)
        return self._accept_slack(ws, *self._solve_with_slacks(ws, start, end), start, end)

    def _inequality_level(self, lp: '_LevelPlan', qdot: np.ndarray
                          ) -> tuple[np.ndarray, np.ndarray] | None:
        """Solve an inequality level (or lock it without a QP).

        An inequality level: locked without a QP if ``qdot`` satisfies it, else solved with
        its slacks (warm started, then cold); ``(qdot_v, s*)`` or None.
        """
        ws, start, end = lp.ws, lp.start, lp.end
        # If the current solution satisfies this level with zero slack, it minimizes
        # rho |qdot|^2 over everything the higher levels allow, so it is this level's
        # optimum too: no QP needed (typical for inactive inequalities: obstacles, boxes,
        # torque bands). Its lock [lower + s*, upper + s*] is its own bounds (s* = 0; they
        # contain the solution), in unit-row coordinates.
        if self._kernels.lock_if_satisfied(lp.A, qdot, lp.lo, lp.hi, lp.norm, lp.band,
                                           lp.lo_rows, lp.hi_rows):
            return qdot, np.zeros(end - start)
        w, flag = self._solve_slack_level(ws, lp.i, start, end)  # warm started
        if flag != 1:
            self.cold_retries += 1
            _widen(ws, qdot, start)
            w, flag = self._solve_with_slacks(ws, start, end)
        return self._accept_slack(ws, w, flag, start, end)

    def _accept_slack(self, ws: '_Workspace', w: np.ndarray, flag: int, start: int,
                      end: int) -> tuple[np.ndarray, np.ndarray] | None:
        """Take a slack-form solution and lock its level.

        Take a slack-form solution ``w`` (retried once with relaxed locks if it failed);
        return ``(qdot_v, s*)`` with the level locked, or None if it failed.
        """
        n, sl = self.n, slice(start, end)
        if flag != 1 and start:
            # Degenerate: the locked bands (1e-9 wide) meet the box at a vertex and DAQP
            # cannot tell them from infeasible. Widen the bands to the solver's own
            # tolerance (the higher levels move by at most that) and solve once more.
            self.relaxed_retries += 1
            ws.lo_rows[:start] -= self._relax
            ws.hi_rows[:start] += self._relax
            w, flag = self._solve_with_slacks(ws, start, end)
        if flag != 1 or not math.isfinite(w @ ws.zeros_w[:n + end - start]):
            return None
        # lock: [lower + s*, upper + s*] (A qdot* for equality rows), widened by the band
        return self._kernels.accept_slack(w, ws.bl, ws.bu, ws.A_unit[sl], ws.norm[sl],
                                          ws.orig_lo[sl], ws.orig_hi[sl], ws.band[sl],
                                          ws.lo_rows[sl], ws.hi_rows[sl])

    def _solve_slack_level(self, ws: '_Workspace', i: int, start: int, end: int
                           ) -> tuple[np.ndarray, int]:
        """Solve an inequality level with slacks, warm started.

        Inequality level ``start:end`` as (4.45)-(4.48) over [qdot_v; s], with this level
        index's persistent DAQP model (warm started); return ``(x, exitflag)``.
        """
        if (ws.orig_lo[start:end] == ws.orig_hi[start:end]).any():
            return self._solve_with_slacks(ws, start, end)  # equal rows: flagged, cold
        C, bu, bl, _, model, cmodel, w = ws.slack_level(i, start, end, self.rho)
        warm = ws.warm[('slack', i, start, end)]
        self._kernels.slack_setup(ws.A_unit, ws.A, start, end, ws.bl, ws.bu, ws.orig_lo,
                                  ws.orig_hi, C, bl, bu)
        if cmodel is not None and self.native_daqp is not None \
                and self.solve_model is _solve_model:
            flag = self.solve_native(cmodel, _UPDATE_A | _UPDATE_BOUNDS)  # w, warm kept, in C
            if flag != 1:
                warm[:] = 0  # (as the C solve does: a failed solve forgets it)
            return w.copy(), flag  # (the slacks returned may be views of it)
        model.update(A=C, blower=bl, sense=warm)
        x, _, flag, info = self.solve_model(model)
        _keep_working_set(warm, flag, info)  # a failed solve forgets it
        return x, flag

    def _solve_with_slacks(self, ws: '_Workspace', start: int, end: int
                           ) -> tuple[np.ndarray, int]:
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
        x, _, flag, _ = self.solve_qp(H, np.zeros(n + m), C, bu, bl, sense, **self._settings)
        return x, flag


class _Workspace:
    """Preallocated rows, bounds and DAQP models of a cascade.

    Preallocated rows and bounds of a cascade with R task rows over n joints, and one DAQP
    model per level index that points at them (so updates only say what changed).
    """

    def __init__(self, n: int, R: int, rho: float, settings: dict,
                 native: ModuleType | None = None):
        self.n = n
        self.native = native  # the C level solves, or None
        self.R = R
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
        self.bl_box = self.bl[:n]
        self.bu_box = self.bu[:n]
        self.cold_sense = np.zeros(n + R, dtype=np.int32)
        self.zeros_w = np.zeros(n + R)
        self.settings = settings
        self.models: dict = {}  # the per-level arrays and DAQP models, by level key
        self.warm: dict = {}  # each model's working set (DAQP sense flags), by level key

    def slack_level(self, i: int, start: int, end: int, rho: float) -> tuple:
        """The arrays and model of an inequality level with slacks.

        ``(C, bu, bl, cold sense, model, C model, w)`` of inequality level index i (rows
        ``start:end``): over w = [qdot_v; s], C = [[A_higher, 0], [A_i, -I]], bounds [box;
        free; rows]; the model points at C, bu and bl and keeps its working set from tick
        to tick. The C model (None without :data:`native`) solves the same over the same
        arrays into ``w``.
        """
        key = ('slack', i, start, end)
        hit = self.models.get(key)
        if hit is None:
            C, bu, bl, cold, model, H, f = _slack_model(self.n, start, end, rho,
                                                         self.settings)
            warm = self.warm[key] = np.zeros(self.n + 2 * end - start, dtype=np.int32)
            w = np.zeros(self.n + end - start)
            cmodel = None if self.native is None else self.native.Model(
                H, f, C, bu, bl, warm, w, self.settings['primal_tol'])
            hit = self.models[key] = (C, bu, bl, cold, model, cmodel, w)
        return hit

    def level(self, i: int, start: int) -> tuple:
        """``(H, f, model, C model, x)`` of level index i, whose higher levels have ``start`` rows.

        The model sees the box and the first ``start`` rows (views of the shared arrays),
        and keeps its working set from tick to tick: a warm start. The C model (None
        without :data:`native`) solves the same over the same arrays into ``x``.
        """
        key = (i, start)
        hit = self.models.get(key)
        if hit is None:
            n = self.n
            H, f = np.eye(n), np.zeros(n)
            A, bu, bl = self.A_unit[:start], self.bu[:n + start], self.bl[:n + start]
            model = _daqp_model(H, f, A, bu, bl, self.settings)
            warm = self.warm[key] = np.zeros(n + start, dtype=np.int32)
            x = np.zeros(n)
            cmodel = None if self.native is None else self.native.Model(
                H, f, A, bu, bl, warm, x, self.settings['primal_tol'])
            hit = self.models[key] = (H, f, model, cmodel, x)
        return hit


class _LevelPlan:
    """One level of a stack's layout: its rows' views of the workspace and its model.

    Attributes are views of the :class:`_Workspace` arrays (rows ``start:end``), so that the
    tick slices nothing; ``normal``: an equality level solved in its normal form, whose
    ``H``, ``f``, ``model``, ``warm``, ``native`` (its C model) and ``x`` are built here
    (inequality levels get their slack models from the workspace as they are solved).
    """

    __slots__ = ('ws', 'i', 'start', 'end', 'equality', 'normal', 'A', 'lo', 'hi', 'A_unit',
                 'norm', 'band', 'lo_rows', 'hi_rows', 'lock_lo', 'lock_hi', 'A_higher',
                 'bl_higher', 'H', 'f', 'model', 'warm', 'native', 'x')

    def __init__(self, cascade: 'DaqpCascade', ws: _Workspace, i: int, start: int, end: int,
                 equality: bool):
        sl = slice(start, end)
        self.ws, self.i, self.start, self.end, self.equality = ws, i, start, end, equality
        self.normal = equality and cascade._normal_form
        self.A, self.lo, self.hi = ws.A[sl], ws.orig_lo[sl], ws.orig_hi[sl]
        self.A_unit, self.norm, self.band = ws.A_unit[sl], ws.norm[sl], ws.band[sl]
        self.lo_rows, self.hi_rows = ws.lo_rows[sl], ws.hi_rows[sl]
        lock = end < ws.R  # the last level needs no lock
        self.lock_lo = self.lo_rows if lock else None
        self.lock_hi = self.hi_rows if lock else None
        self.A_higher = ws.A_unit[:start]
        self.bl_higher = ws.bl[:ws.n + start]
        self.H: Any = None
        self.f: Any = None
        self.model: Any = None
        self.warm: Any = None
        self.native: Any = None
        self.x: Any = None
        if self.normal:
            self.H, self.f, self.model, self.native, self.x = ws.level(i, start)
            self.warm = ws.warm[(i, start)]


def _solve_model(model):
    """Solve a DAQP model (``model.solve()``)."""
    return model.solve()


def _solve_native(model, mask):
    """Update (``mask``) and solve a C level model (``model.solve(mask)``)."""
    return model.solve(mask)


def _keep_working_set(warm, flag, info):
    """Set ``warm`` to the working set a solve that started from it ended with.

    Cold (all 0) after a failure. A solve of one iteration found its starting set optimal
    and kept it (the usual tick: nothing to do). Otherwise a constraint is in the working
    set if its multiplier is not zero, at its lower bound if the multiplier is negative
    (DAQP's sign convention).
    """
    if flag != 1 or not isinstance(info, dict):
        warm[:] = 0
        return
    if info.get('iterations') == 1:
        return
    lam = info.get('lam')
    if lam is None or np.shape(lam) != warm.shape:
        warm[:] = 0
        return
    np.not_equal(lam, 0.0, out=warm, casting='unsafe')  # _ACTIVE
    np.putmask(warm, lam < 0.0, _ACTIVE | _LOWER)


def _slack_model(n, start, end, rho, settings):
    """Arrays and DAQP model of an inequality level with slacks, then its H and f.

    ``(C, bu, bl, cold sense, model, H, f)`` (see ``slack_level``).
    """
    m = end - start
    C = np.zeros((end, n + m))
    C[start:, n:] = -np.eye(m)
    bu = np.full(n + m + end, np.inf)
    bl = np.full(n + m + end, -np.inf)
    H = np.diag(np.concatenate([np.full(n, rho), np.ones(m)]))
    f = np.zeros(n + m)
    cold = np.zeros(n + m + end, dtype=np.int32)  # sense flags of a cold start
    return C, bu, bl, cold, _daqp_model(H, f, C, bu, bl, settings), H, f


def _daqp_model(H, f, A, bu, bl, settings):
    """A DAQP model pointing at these arrays.

    A DAQP model pointing at these arrays (no copies: later in-place changes plus an ``update``
    naming them are seen), with its own all-inequality sense flags and ``settings`` applied
    over DAQP's defaults.
    """
    import daqp
    model = daqp.Model()
    model.setup(H, f, A, bu, bl, np.zeros(bu.shape[0], dtype=np.int32))
    merged = dict(model.settings)
    merged.update(settings)
    model.settings = merged
    return model


def _widen(ws, qdot, start):
    """Widen the locked bands of rows ``:start`` to contain ``qdot``.

    Widen the locked bands of rows ``:start`` to contain ``qdot`` (the higher levels' solution,
    inside the box): the locked set then surely contains a point, and a level that DAQP called
    infeasible can be retried. Bands are 1e-9 wide and DAQP's tolerance is 1e-6, so a solution
    may lie just outside them.
    """
    if qdot is None or not start:
        return
    a = ws.A_unit[:start] @ qdot
    np.minimum(ws.lo_rows[:start], a, out=ws.lo_rows[:start])
    np.maximum(ws.hi_rows[:start], a, out=ws.hi_rows[:start])


_EYES: dict[int, np.ndarray] = {}


def _eye(m):
    e = _EYES.get(m)
    if e is None:
        e = _EYES[m] = np.eye(m)
    return e
