"""What every cascade solver shares.

What every cascade solver shares: the result, the level violation, and the generic level-by-level
loop of docs/SPEC.md §3 (Alg. C.3) over a per-level QP.

Variables w = [qdot_v; s] with s the slack of the current level. For i = 1..k::

    min 1/2 w^T diag(rho I_n, I_m) w
    s.t. beta_m,i <= A_i qdot_v - s <= beta_M,i          (current level, soft via s)
         b_m <= A_bar qdot_v <= b_M                      (all higher levels, hard)
         lower <= qdot_v <= upper                        (joint limits and PSPM, hard)

then the level is locked: its rows join A_bar with bounds [beta_m + s*, beta_M + s*]
(A_i qdot_v* for equality rows), widened by a band of 1e-9 per unit row norm. A level
whose solve fails keeps the previous level's solution.
"""

from collections.abc import Sequence
from typing import NamedTuple, Protocol

import numpy as np

from ifc_spg.errors import SolverError
from ifc_spg.limits.joint_limits import VelocityBox
from ifc_spg.tasks.task import Level

__all__ = ['Cascade', 'CascadeResult', 'CascadeSolver', 'level_violation']


class CascadeResult(NamedTuple):
    """Outcome of one cascade solve.

    Attributes:
        qdot_v: Virtual joint velocity in [rad/s] (n,), always finite and inside the box.
        slacks: Optimal slack s* of each level (list of (m_i,) arrays).
        status: 'ok', 'fallback' (a level failed; the previous level's solution is used)
            or 'hold' (the first level failed, or no finite solution; zero velocity clipped
            into the box).
        failed_level: Index of the failed level, or -1.
    """

    qdot_v: np.ndarray
    slacks: list
    status: str
    failed_level: int


class Cascade(Protocol):
    """What the set-point generator asks of a solver (``daqp``, ``proxsuite``, ``nullspace``).

    Attributes:
        name: The solver's name (``SetPointGenerator(solver=...)``).
        supports_inequalities: False if the solver takes equality levels only (the nullspace
            baseline): a stack with an inequality task is refused when it is set.
        supports_torque_limits: False if the solver cannot take the implicit torque-limit
            level (4.3) on top, folded into the box it respects as hard bounds: asking for
            torque limits with it is refused at construction.
        lock_tolerance: Half-width of a locked row's band per unit of its 1-norm (the
            torque-limit level locks with the same band).
    """

    name: str
    supports_inequalities: bool
    supports_torque_limits: bool
    lock_tolerance: float

    def prepare(self, dims: Sequence[int], equalities: Sequence[bool]) -> None:
        """Build what a stack's levels need before it is active.

        Build, before a stack is active, whatever its levels (sizes ``dims``, kinds
        ``equalities``) need, so that its first tick does no setup.
        """

    def solve(self, levels: Sequence[Level], box: VelocityBox,
              q_v: np.ndarray | None = None) -> CascadeResult:
        """Solve the levels within the velocity box.

        Solve the levels (highest first) within the velocity ``box`` at the virtual
        configuration ``q_v`` [rad] (used by solvers that clamp joints near their limits);
        the result's qdot_v is finite and inside the box.
        """


def level_violation(level: Level, qdot_v: np.ndarray) -> np.ndarray:
    """Return the per-row violation of a level's bounds by ``qdot_v`` (>= 0), shape (m,)."""
    a = level.A @ qdot_v
    return np.maximum(np.maximum(level.lower - a, a - level.upper), 0.0)


class CascadeSolver:
    """The cascade level by level over :meth:`solve_level` (a subclass's QP).

    Args:
        n: Number of joints.
        rho: Regularization weight of qdot_v in the level cost (4.45), > 0.
    """

    name = 'base'
    supports_inequalities = True
    supports_torque_limits = True
    lock_tolerance = 1e-9  # half-width of a locked row's band, per unit of its 1-norm

    def __init__(self, n: int, rho: float = 0.01):
        if not (np.isfinite(rho) and rho > 0):
            raise SolverError(f'rho must be a finite number > 0, got {rho!r}')
        self.n = int(n)
        self.rho = float(rho)

    def prepare(self, dims: Sequence[int], equalities: Sequence[bool]) -> None:
        """Nothing to build ahead of a stack (solvers with per-stack models override this)."""

    def solve_level(self, A: np.ndarray, lower: np.ndarray, upper: np.ndarray,
                    A_bar: np.ndarray, b_lo: np.ndarray, b_hi: np.ndarray,
                    box_lo: np.ndarray, box_hi: np.ndarray, eq_rows: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray, bool]:
        """Solve one level; return ``(qdot_v, s, ok)``.

        ``eq_rows`` is a bool mask over the rows [A; A_bar] that are equalities.
        """
        raise NotImplementedError

    def solve(self, levels: Sequence[Level], box: VelocityBox,
              q_v: np.ndarray | None = None) -> CascadeResult:
        """Solve the cascade; return a :class:`CascadeResult`.

        Args:
            levels: Levels, highest priority first.
            box: :class:`~ifc_spg.limits.VelocityBox` on qdot_v.
            q_v: The virtual configuration (unused here; see :class:`~ifc_spg.cascade.Cascade`).
        """
        n = self.n
        box_lo = np.asarray(box.lower, dtype=float)
        box_hi = np.asarray(box.upper, dtype=float)
        qdot = np.clip(np.zeros(n), box_lo, box_hi)
        A_bar = np.zeros((0, n))
        b_lo = np.zeros(0)
        b_hi = np.zeros(0)
        eq_bar = np.zeros(0, dtype=bool)
        slacks: list = []
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
