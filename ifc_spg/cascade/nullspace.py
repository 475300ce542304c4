"""Baseline: hierarchical nullspace mapping (docs/SPEC.md §5, Sec. 3.2.6, Alg. C.1/C.2).

Kept for comparisons, not the default. Equality tasks only::

    qdot = 0 (with a box: its point nearest 0), N = I
    for each level: A <- A with clamped-joint columns zeroed
                    b <- beta - A qdot;  A <- A N
                    qdot <- qdot + A^{+lambda} b;  N <- N - A^+ A

checklimits (C.2) clamps joints within dl_crit of a limit that move towards it; the loop
repeats with the union of clamped joints until no new joint is clamped.

**The velocity box.** The thesis' Ch. 3 mapping knows the position limits only (C.2); the
SPG's velocity box (joint limits 4.31-4.33, PSPM) enters each level by the saturation in
the null space (SNS) of Flacco, De Luca and Khatib (IROS 2012, Alg. 3): per level, the most
critical joint that leaves the box is saturated at its bound, the increment that takes it
there is realised in the null space of the levels above (they keep their solution), the
level is solved again with the remaining joints, and when they cannot solve it any more
the level is scaled down (its correction x - A qdot_above times s in [0, 1], the largest
s seen that keeps every joint inside; SNS scales the task velocity, which is the same for
the first level, and s = 0 leaves the levels above as they are, inside the box). Clipping
the result per joint afterwards (the baseline before issue 21) instead changes every
level's solution, the first one's included. Every rank decision takes its singular values
against the level's |A| (rcond |A|), never against those of the projected A N, which are
all rounding when the levels above already span the level: the saturated result is inside
the box by construction (the saturated joints sit on their bounds, the free ones are
scaled), not by a rank decision on round-off. The result is still clipped into the box as
a last guard. The implicit torque-limit level, whose lock the cascades take as hard bounds,
is not available. With the SPG's ``velocity_box`` off (the thesis' Ch. 3 setups) the box is
the position limits one step ahead only, as Alg. C.1/C.2 have it.
"""

from collections.abc import Sequence
import math

import numpy as np

from ifc_spg.cascade.base import CascadeResult
from ifc_spg.errors import SolverError
from ifc_spg.limits.joint_limits import VelocityBox
from ifc_spg.tasks.task import Level

__all__ = ['CRITICAL_DISTANCE', 'NullspaceCascade']

#: dl_crit [rad] of checklimits (Alg. C.2): a joint this close to a limit, moving towards it,
#: is clamped (the default of :class:`NullspaceCascade`)
CRITICAL_DISTANCE = 0.02


def _svd_cut(M: np.ndarray, cutoff: float
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """SVD of M with the singular values at or below the absolute ``cutoff`` marked dropped.

    The cut-off is absolute (the caller scales it by a norm fixed for the level), not
    relative to M's own largest singular value: a matrix that is all rounding (A P_bar or
    A N of a level that the levels above and the saturated or clamped joints leave nothing
    to move: singular values around 1e-14 |A|) then has rank 0 on every BLAS, where a
    relative cut-off keeps its largest rounding value as rank 1 and inverts noise.
    """
    U, sv, Vt = np.linalg.svd(M, full_matrices=False)
    return U, sv, Vt, sv > cutoff


def _pinv(M: np.ndarray, cutoff: float) -> np.ndarray:
    """Moore-Penrose inverse of M, singular values at or below the absolute ``cutoff`` zero."""
    U, sv, Vt, keep = _svd_cut(M, cutoff)
    return (Vt.T * np.where(keep, 1.0 / np.where(keep, sv, 1.0), 0.0)) @ U.T


def _damped_pinv_rank(A: np.ndarray, damping: float, cutoff: float
                      ) -> tuple[np.ndarray, int]:
    """A^T (A A^T + lambda^2 I)^-1 by the SVD and the rank, singular values <= cutoff dropped.

    Where saturated or clamped joints leave a level without the columns to span it, its
    singular values sit at rounding level (1e-14 |A|), which the damped gain s / (s^2 +
    lambda^2) would amplify by up to 1 / (2 lambda); they count as zero, as in the
    undamped inverse of the projectors. ``cutoff`` is absolute (see :func:`_svd_cut`).
    """
    U, sv, Vt, keep = _svd_cut(A, cutoff)
    return ((Vt.T * np.where(keep, sv / (sv ** 2 + damping ** 2), 0.0)) @ U.T,
            int(np.count_nonzero(keep)))


def _norm2(A: np.ndarray) -> float:
    """The spectral norm of A (0 for an empty A)."""
    return float(np.linalg.norm(A, 2)) if A.size else 0.0


def _scaling(a: np.ndarray, b: np.ndarray, lower: np.ndarray, upper: np.ndarray,
             free: np.ndarray) -> tuple[float, int]:
    """SNS Alg. 2: the largest s in [0, 1] with lower <= s a + b <= upper.

    Over the ``free`` joints (the saturated ones do not move with s). Returns s and the
    joint that limits it, or (0, -1) when no s in [0, 1] fits.
    """
    moving = free & (np.abs(a) > 1e-12 * max(float(np.max(np.abs(a))), 1e-300))
    still = free & ~moving
    if np.any(still & ((b < lower - 1e-12) | (b > upper + 1e-12))):
        return 0.0, -1  # a joint no s moves is outside already
    with np.errstate(divide='ignore', invalid='ignore'):
        lo = np.where(moving, (lower - b) / a, -np.inf)
        hi = np.where(moving, (upper - b) / a, np.inf)
    lo, hi = np.minimum(lo, hi), np.maximum(lo, hi)
    j = int(np.argmin(hi))
    s_max, s_min = float(hi[j]), float(np.max(lo))
    if s_min > s_max or s_max < 0.0 or s_min > 1.0:
        return 0.0, -1
    return min(s_max, 1.0), j


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
        rcond: Cut-off of the singular values, relative to the level's |A| (the damped
            inverse, its rank, the undamped inverse used for N (3.48)) or to 1 (the rows of
            the projector N of the saturated joints).
    """

    name = 'nullspace'
    supports_inequalities = False
    supports_torque_limits = False
    lock_tolerance = 1e-9

    def __init__(self, n: int, rho: float = 0.01, *, q_min: np.ndarray | None = None,
                 q_max: np.ndarray | None = None, damping: float = 1e-3,
                 critical_distance: float = CRITICAL_DISTANCE, rcond: float = 1e-10):
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
        """Solve the levels by the nullspace mapping with the box saturated in it (SNS).

        The mapping at the virtual configuration ``q_v`` (None: no joint is clamped); a
        non-finite solution holds (zero velocity clipped into the box, status 'hold').
        """
        qdot, _ = self.mapping(levels, q_v, box)
        status = 'ok'
        if not math.isfinite(qdot @ self._zeros):
            qdot, status = np.zeros(self.n), 'hold'
        return CascadeResult(np.clip(qdot, box.lower, box.upper), [], status, -1)

    def mapping(self, levels: Sequence[Level], q_v: np.ndarray | None,
                box: VelocityBox | None = None) -> tuple[np.ndarray, np.ndarray]:
        """The nullspace mapping with joint clamping (C.2) and, with ``box``, SNS.

        Return ``(qdot_v, clamped_joints)`` for equality ``levels`` at virtual q_v (None:
        no joint is clamped).
        """
        for lev in levels:
            if not lev.equality:
                raise SolverError(f"the nullspace baseline handles equality tasks only; task "
                                  f"'{lev.name}' is an inequality (use solver 'daqp')")
        n = self.n
        if box is None:  # no joint leaves an unbounded box: the plain steps of Alg. C.1
            box = VelocityBox(np.full(n, -np.inf), np.full(n, np.inf))
        clamped = np.zeros(n, dtype=bool)
        # The start is the box point nearest zero (zero itself whenever the box holds it):
        # the first level's s = 0, inside the box.
        start = np.minimum(np.maximum(0.0, box.lower), box.upper)
        for _ in range(n + 1):
            qdot = start
            N = np.eye(n)
            for lev in levels:
                A = lev.A * ~clamped
                cutoff = self.rcond * _norm2(A)  # rank decisions against |A|, not |A N|
                qdot = self._sns_level(A, lev.lower, qdot, N, box, cutoff)
                AN = A @ N
                N = N - _pinv(AN, cutoff) @ AN
            if q_v is None:
                break
            near_hi = (self.q_max - q_v < self.critical_distance) & (qdot > 0)
            near_lo = (q_v - self.q_min < self.critical_distance) & (qdot < 0)
            new = (near_hi | near_lo) & ~clamped
            if not np.any(new):
                break
            clamped |= new
        return qdot, np.flatnonzero(clamped)

    def _sns_level(self, A: np.ndarray, x: np.ndarray, qdot_prev: np.ndarray, P: np.ndarray,
                   box: VelocityBox, cutoff: float) -> np.ndarray:
        """One level of SNS (Alg. 3): qdot inside ``box`` solving the level, scaled if need be.

        ``qdot_prev`` is the solution of the levels above (inside the box) and ``P`` the
        projector onto their null space; the increments that take saturated joints to
        their bounds go through P, so those levels keep their solution. ``cutoff`` is the
        absolute singular-value cut-off of the level's rank decisions.

        Every candidate returned is inside the box: the unscaled solution when it is, else
        s a + b with s from :func:`_scaling` over the free joints, the saturated ones
        sitting exactly on their bounds (a = 0 there), or s = 0 of the first step, which
        is ``qdot_prev``.
        """
        lower, upper, tol = box.lower, box.upper, self.lock_tolerance
        free = np.ones(self.n, dtype=bool)
        qdot_n = np.zeros(self.n)  # increments that take the saturated joints to their bounds
        a, b, rank0 = self._sns_terms(A, x, qdot_prev, P, free, qdot_n, cutoff)
        best = (0.0, np.zeros(self.n), qdot_prev)  # (s, a, b): best scaled so far
        for _ in range(self.n):
            qdot = a + b
            out = free & ((qdot < lower - tol) | (qdot > upper + tol))
            if not np.any(out):
                return qdot
            scale, j = _scaling(a, b, lower, upper, free)
            if scale > best[0]:
                best = (scale, a, b)
            if j < 0:  # no scale fits: saturate the joint farthest outside
                j = int(np.argmax(np.where(free, np.maximum(qdot - upper, lower - qdot),
                                           -np.inf)))
            free[j] = False
            qdot_n[j] = (upper[j] if qdot[j] > upper[j] else lower[j]) - qdot_prev[j]
            a, b, rank = self._sns_terms(A, x, qdot_prev, P, free, qdot_n, cutoff)
            target = (qdot_prev + qdot_n)[~free]
            reached = np.abs(b[~free] - target) <= 1e-9 * (1.0 + np.abs(qdot_n[~free]))
            if rank < rank0 or not np.any(free) or not np.all(reached):
                # The free joints cannot solve the level, or the levels above leave no
                # motion that takes the saturated joints to their bounds: the best scaled
                # solution so far.
                break
            # The saturated joints sit on their bounds and do not move with s (their
            # columns are out of A P_bar): rounding removed, so the scaling over the free
            # joints keeps every joint inside.
            a[~free], b[~free] = 0.0, target
        s, a, b = best
        return s * a + b

    def _sns_terms(self, A: np.ndarray, x: np.ndarray, qdot_prev: np.ndarray, P: np.ndarray,
                   free: np.ndarray, qdot_n: np.ndarray, cutoff: float
                   ) -> tuple[np.ndarray, np.ndarray, int]:
        """(a, b, rank of A P_bar) of SNS: the level's solution is s a + b.

        s scales the level's correction x - A qdot_prev (for the first level, x itself as
        in SNS): s = 0 leaves the levels above as they are, inside the box.
        """
        if free.all():  # nothing saturated: the plain step of Alg. C.1
            P_bar, sat = P, np.zeros(self.n)
        else:  # ((I - W) P)^+, P's norm is 1 (an orthogonal projector): cut-off rcond
            S_pinv = _pinv(P * ~free[:, None], self.rcond)
            P_bar = P - S_pinv @ P
            sat = S_pinv @ qdot_n
        JP_pinv, rank = _damped_pinv_rank(A @ P_bar, self.damping, cutoff)
        return JP_pinv @ (x - A @ qdot_prev), qdot_prev + sat - JP_pinv @ (A @ sat), rank
