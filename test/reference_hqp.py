"""A slow, obviously-correct reference for the strict-priority cascade (SPEC 3).

Level by level, the locked equality rows of the higher levels are eliminated exactly
(q = q_p + Z y with Z an SVD nullspace basis, so redundant rows are harmless), and the
remaining small QP in (y, s) is solved and its optimality certified by the KKT conditions
(so no solver is trusted). Locking follows
the cascade's definition: equality rows keep A q*, inequality rows keep
[lower + s*, upper + s*] (widened to contain A q*).
"""

import numpy as np
import daqp

RELAX = 1e-10


def _solve_qp(H, g, E, e, C, lo, hi):
    """min 1/2 x^T H x + g^T x  s.t.  E x = e,  lo <= C x <= hi, certified by its KKT conditions.

    The solve itself uses DAQP; the answer is only accepted if stationarity, primal
    feasibility, dual sign and complementarity hold to 1e-8, so the reference does not
    rest on trusting any solver.
    """
    # rows that vanish after the elimination constrain nothing; they must hold at 0
    zero = np.abs(C).max(axis=1) < 1e-12
    if np.any(lo[zero] > 1e-8) or np.any(hi[zero] < -1e-8):
        raise RuntimeError('a fully determined row is violated: the elimination is wrong')
    C, lo, hi = C[~zero], lo[~zero], hi[~zero]
    M = np.vstack([E, C])
    # the inequalities are relaxed by 1e-10: the previous level's solution lies on some of
    # them, and the elimination's round-off would otherwise make them infeasible
    bl = np.concatenate([e, lo - RELAX])
    bu = np.concatenate([e, hi + RELAX])
    sense = np.zeros(M.shape[0], dtype=np.int32)
    sense[:E.shape[0]] = 5
    x, _, flag, info = daqp.solve(H, g, M, np.clip(bu, -1e30, 1e30), np.clip(bl, -1e30, 1e30),
                                  sense)
    if flag != 1:
        raise RuntimeError(f'reference QP not solved (exitflag {flag})')
    lam = np.asarray(info['lam'])
    Mx = M @ x
    scale = 1.0 + np.abs(x).max() + np.abs(lam).max()
    stationarity = np.abs(H @ x + g + M.T @ lam).max()
    infeasible = max(np.max(bl - Mx, initial=0.0), np.max(Mx - bu, initial=0.0))
    ineq = slice(E.shape[0], None)
    wrong_sign = max(np.max(lam[ineq][Mx[ineq] > bl[ineq] + 1e-7].clip(max=0) ** 2, initial=0),
                     np.max(lam[ineq][Mx[ineq] < bu[ineq] - 1e-7].clip(min=0) ** 2, initial=0))
    if stationarity > 1e-8 * scale or infeasible > 1e-8 or wrong_sign > 1e-16:
        raise RuntimeError(f'KKT not certified: stationarity {stationarity:.1e}, infeasibility '
                           f'{infeasible:.1e}, complementarity {wrong_sign:.1e}')
    return x


def _nullspace(E, tol=1e-9):
    if E.shape[0] == 0:
        return np.eye(E.shape[1])
    _, sv, Vt = np.linalg.svd(E)
    rank = int(np.sum(sv > tol * max(1.0, sv[0])))
    return Vt[rank:].T


def reference_cascade(levels, box_lo, box_hi, rho):
    """Return ``(qdot, slacks)`` of the cascade, computed the slow way."""
    n = levels[0].A.shape[1]
    E = np.zeros((0, n))
    e = np.zeros(0)
    I = np.zeros((0, n))
    il = np.zeros(0)
    iu = np.zeros(0)
    q = np.zeros(n)
    slacks = []
    for lev in levels:
        m = lev.A.shape[0]
        q_p = np.linalg.lstsq(E, e, rcond=None)[0] if E.shape[0] else np.zeros(n)
        Z = _nullspace(E)
        k = Z.shape[1]
        eq = lev.lower == lev.upper
        # variables x = [y (k); s (m)]
        H = np.diag(np.r_[np.full(k, rho), np.ones(m)])
        g = np.r_[rho * Z.T @ q_p, np.zeros(m)]
        AZ = np.hstack([lev.A @ Z, -np.eye(m)])
        rows_eq = AZ[eq]
        b_eq = (lev.lower - lev.A @ q_p)[eq]
        C = np.vstack([AZ[~eq], np.hstack([I @ Z, np.zeros((I.shape[0], m))]),
                       np.hstack([Z, np.zeros((n, m))])])
        lo = np.r_[(lev.lower - lev.A @ q_p)[~eq], il - I @ q_p, box_lo - q_p]
        hi = np.r_[(lev.upper - lev.A @ q_p)[~eq], iu - I @ q_p, box_hi - q_p]
        x = _solve_qp(H, g, rows_eq, b_eq, C, lo, hi)
        q = q_p + Z @ x[:k]
        s = x[k:]
        slacks.append(s)
        a = lev.A @ q
        E = np.vstack([E, lev.A[eq]])
        e = np.r_[e, a[eq]]
        I = np.vstack([I, lev.A[~eq]])
        il = np.r_[il, np.minimum(lev.lower + s, a)[~eq]]
        iu = np.r_[iu, np.maximum(lev.upper + s, a)[~eq]]
    return q, slacks
