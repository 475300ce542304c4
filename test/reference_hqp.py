"""A slow, obviously-correct reference for the strict-priority cascade (docs/SPEC.md §3).

Level by level, a fresh QP in (qdot, s) is written down exactly as (4.45)-(4.48): the
current level's rows with their slack, every higher level's rows at their locked bounds,
the variable box. Locked bounds follow the cascade's definition: [lower + s*, upper + s*]
(A qdot* for equality rows), widened by ``LOCK_TOLERANCE * (1 + |row|_1)``. Each QP is
solved cold and its optimum accepted only if the KKT conditions (stationarity, primal
feasibility, dual signs, complementarity) hold to 1e-8, so the reference rests on no
solver's word. It shares no code with :mod:`ifc_spg.cascade.daqp`.
"""

import daqp
import numpy as np

LOCK_TOLERANCE = 1e-9
PRIMAL_TOL = 1e-9  # feasibility tolerance of the reference QPs (DAQP's default is 1e-6)
INF = 1e30


def solve_qp_certified(H, g, M, lo, hi, eq):
    """min 1/2 x^T H x + g^T x  s.t.  lo <= M x <= hi (rows ``eq`` with lo == hi)."""
    sense = np.where(eq, 5, 0).astype(np.int32)
    x, _, flag, info = daqp.solve(H, g, M, np.clip(hi, -INF, INF), np.clip(lo, -INF, INF),
                                  sense, primal_tol=PRIMAL_TOL)
    if flag != 1:
        raise RuntimeError(f'reference QP not solved (exitflag {flag})')
    lam = np.asarray(info['lam'])
    Mx = M @ x
    scale = 1.0 + np.abs(x).max() + np.abs(lam).max()
    stationarity = np.abs(H @ x + g + M.T @ lam).max()
    infeasible = max(np.max(lo - Mx, initial=0.0), np.max(Mx - hi, initial=0.0))
    tol = PRIMAL_TOL * (1.0 + np.abs(Mx))
    wrong_sign = max(np.max(np.where(~eq & (Mx > lo + tol), -lam, 0.0), initial=0.0),
                     np.max(np.where(~eq & (Mx < hi - tol), lam, 0.0), initial=0.0))
    if stationarity > 1e-8 * scale or infeasible > 10 * PRIMAL_TOL or \
            wrong_sign > 1e-8 * scale:
        raise RuntimeError(f'KKT not certified: stationarity {stationarity:.1e}, infeasibility '
                           f'{infeasible:.1e}, complementarity {wrong_sign:.1e}')
    return x


def reference_cascade(levels, box_lo, box_hi, rho):
    """Return ``(qdot, slacks)`` of the cascade, computed the slow way."""
    n = levels[0].A.shape[1]
    locked_A = np.zeros((0, n))
    locked_lo = np.zeros(0)
    locked_hi = np.zeros(0)
    qdot = np.zeros(n)
    slacks = []
    for lev in levels:
        m = lev.A.shape[0]
        H = np.diag(np.r_[np.full(n, rho), np.ones(m)])
        # rows: variables (box / free slack), current level [A -I], locked rows [A_bar 0]
        M = np.vstack([np.eye(n + m), np.hstack([lev.A, -np.eye(m)]),
                       np.hstack([locked_A, np.zeros((locked_A.shape[0], m))])])
        lo = np.r_[box_lo, np.full(m, -np.inf), lev.lower, locked_lo]
        hi = np.r_[box_hi, np.full(m, np.inf), lev.upper, locked_hi]
        eq = np.zeros(M.shape[0], dtype=bool)
        eq[n + m:n + 2 * m] = lev.lower == lev.upper
        x = solve_qp_certified(H, np.zeros(n + m), M, lo, hi, eq)
        qdot, s = x[:n], x[n:]
        slacks.append(s)
        a = lev.A @ qdot
        band = LOCK_TOLERANCE * (1.0 + np.abs(lev.A).sum(axis=1))
        is_eq = lev.lower == lev.upper
        locked_A = np.vstack([locked_A, lev.A])
        locked_lo = np.r_[locked_lo, np.where(is_eq, a, np.minimum(lev.lower + s, a)) - band]
        locked_hi = np.r_[locked_hi, np.where(is_eq, a, np.maximum(lev.upper + s, a)) + band]
    return qdot, slacks
