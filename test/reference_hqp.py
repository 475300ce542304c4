"""A slow, obviously-correct reference for the strict-priority cascade (SPEC 3).

Level by level, the locked equality rows of the higher levels are eliminated exactly
(q = q_p + Z y with Z an SVD nullspace basis, so redundant rows are harmless), and the
remaining small QP in (y, s) is solved by proxsuite to high accuracy. Locking follows
the cascade's definition: equality rows keep A q*, inequality rows keep
[lower + s*, upper + s*] (widened to contain A q*).
"""

import numpy as np
from proxsuite import proxqp

BIG = 1e30


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
        qp = proxqp.dense.QP(k + m, rows_eq.shape[0], C.shape[0])
        qp.settings.eps_abs = 1e-12
        qp.settings.eps_rel = 0.0
        qp.settings.max_iter = 100000
        qp.init(H, g, rows_eq, b_eq, C, np.clip(lo, -BIG, BIG), np.clip(hi, -BIG, BIG))
        qp.solve()
        if qp.results.info.status != proxqp.QPSolverOutput.PROXQP_SOLVED:
            raise RuntimeError('reference QP not solved')
        x = qp.results.x
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
