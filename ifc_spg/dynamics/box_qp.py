"""The box QP of static friction: argmin ½ xᵀ G x + gᵀ x  s.t.  −f ≤ x ≤ f, G ⪰ 0.

A primal active-set method, exact in a finite number of steps: from x = 0 (feasible) a
Newton step on the free coordinates, cut at the first bound it crosses (that coordinate
joins the active set); at the minimum of a face the bound with the most violated
multiplier leaves it. The free block is solved with Cholesky of G_FF + ε I,
ε = 1e-14 max(1, max diag G): along a singular direction of G this is a long step that
ends on a bound. This is the numpy reference of ``box_qp`` in ``_native_dynamics.c``
(same steps, same tolerances); the tests compare both with proxsuite.
"""

import numpy as np

__all__ = ['box_qp']


def box_qp(G, g, f):
    """Solve the box QP.

    Args:
        G: (k, k) symmetric positive semidefinite matrix.
        g: (k,) linear term.
        f: (k,) half-widths of the box, ≥ 0.

    Returns:
        ``(x, ok)``: the minimizer and whether it satisfies the KKT conditions (to
        1e-9 max(1, |g|_max, |G|_max |f|_max)); when ``ok`` is False use a general QP solver.
    """
    G = np.asarray(G, dtype=float)
    g = np.asarray(g, dtype=float)
    f = np.asarray(f, dtype=float)
    k = g.size
    x = np.zeros(k)
    state = np.zeros(k, dtype=int)           # 0 free, +1 at f, -1 at -f
    if k == 0:
        return x, True
    eps = 1e-14 * max(1.0, float(np.max(np.diag(G))))
    tol = 1e-9 * max(1.0, float(np.max(np.abs(g))), float(np.max(np.abs(G)) * np.max(f)))
    newton = True
    for _ in range(20 * k + 20):
        grad = G @ x + g
        if newton:
            newton = _newton_step(G, grad, f, x, state, eps)
            if newton is None:
                return x, False
            continue
        viol = np.where(state == 1, grad, np.where(state == -1, -grad, 0.0))
        worst = int(np.argmax(viol))
        if not viol[worst] > tol:
            break
        state[worst] = 0
        newton = True
    return x, _kkt_holds(G, g, f, x, state, tol)


def _newton_step(G, grad, f, x, state, eps):
    """A Newton step on the free coordinates, cut at the first bound it crosses.

    Updates ``x`` and ``state`` in place.

    Returns:
        True if a bound was hit (that coordinate joined the active set: step again), False
        at the minimum of the face, None if the free block is not positive definite.
    """
    fi = np.flatnonzero(state == 0)
    if fi.size:
        H = G[np.ix_(fi, fi)] + eps * np.eye(fi.size)
        try:
            c = np.linalg.cholesky(H)
        except np.linalg.LinAlgError:
            return None
        p = -np.linalg.solve(c.T, np.linalg.solve(c, grad[fi]))
    else:
        p = np.zeros(0)
    alpha, block, side = _ratio_test(fi, p, x, f)
    x[fi] += max(alpha, 0.0) * p
    if block >= 0:
        state[block] = side
        x[block] = side * f[block]
        return True
    return False


def _ratio_test(fi, p, x, f):
    """``(alpha, block, side)``: the step length along ``p`` to the first bound crossed."""
    alpha, block, side = 1.0, -1, 0
    for a, i in enumerate(fi):
        if p[a] > 0 and x[i] + p[a] > f[i]:
            t = (f[i] - x[i]) / p[a]
            if t < alpha:
                alpha, block, side = t, i, 1
        elif p[a] < 0 and x[i] + p[a] < -f[i]:
            t = (-f[i] - x[i]) / p[a]
            if t < alpha:
                alpha, block, side = t, i, -1
    return alpha, block, side


def _kkt_holds(G, g, f, x, state, tol):
    """Whether ``x`` with the active set ``state`` satisfies the KKT conditions to ``tol``."""
    grad = G @ x + g
    free = state == 0
    return bool(np.all(np.abs(grad[free]) <= tol) and np.all(np.abs(x[free]) <= f[free])
                and np.all(grad[state == 1] <= tol) and np.all(grad[state == -1] >= -tol))
