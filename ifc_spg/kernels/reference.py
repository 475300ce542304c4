"""The numpy reference of the C kernels.

The numpy reference of the C kernels (``ifc_spg.kernels._native``): the same functions, arguments
and results, computed with numpy exactly as the C loops do (NaN included).

This module runs wherever the C module is missing or ``IFC_SPG_NATIVE=0``, and the tests
compare the two on random inputs. Arrays are float64; the arguments documented as written
are the caller's preallocated outputs (the C module requires them C-contiguous), every other
argument is only read.
"""

import math

import numpy as np
import pinocchio as pin

__all__ = ['accept', 'accept_slack', 'collision_cull', 'collision_level', 'collision_rows',
           'integrate', 'limits_box', 'lock_if_satisfied', 'normal_form', 'pose_error',
           'pspm_bounds', 'pspm_update', 'slack_setup', 'stack_rows', 'task_bounds',
           'torque_limit', 'velocity_box']

_TINY = 1e-300  # floor of a row norm (an all-zero row stays zero when scaled)

Array = np.ndarray


# ---- the cascade (ifc_spg.cascade.daqp.DaqpCascade) ------------------------------------

def stack_rows(levels: list, A: Array, lower: Array, upper: Array, norm: Array,
               A_unit: Array, band: Array, lock_tolerance: float) -> None:
    """Stack the levels' rows and bounds, with norms and lock bands.

    Stack the levels' rows and bounds into A (R, n), lower, upper (R,); then per row norm =
    max(|row|_2, 1e-300), A_unit = row / norm and band = lock_tolerance (1 + |row|_1) / norm.
    Writes A, lower, upper, norm, A_unit, band.
    """
    row = 0
    for lev in levels:
        m = lev.A.shape[0]
        A[row:row + m] = lev.A
        lower[row:row + m] = lev.lower
        upper[row:row + m] = lev.upper
        row += m
    np.einsum('ij,ij->i', A, A, out=norm)
    np.sqrt(norm, out=norm)
    np.maximum(norm, _TINY, out=norm)
    np.divide(A, norm[:, None], out=A_unit)
    np.abs(A).sum(axis=1, out=band)
    band += 1.0
    band *= lock_tolerance
    band /= norm


def normal_form(A: Array, beta: Array, rho: float, H: Array, f: Array) -> None:
    """The cost of an equality level without slacks.

    The cost of an equality level without slacks: writes H = rho I + A^T A (n, n) and f = -A^T
    beta (n,).
    """
    n = H.shape[0]
    np.dot(A.T, A, out=H)
    H.reshape(-1)[::n + 1] += rho
    np.dot(beta, A, out=f)
    np.negative(f, out=f)


def accept(x: Array, bl: Array, bu: Array, A_unit: Array, norm: Array, beta: Array,
           band: Array, lock_lo: Array | None, lock_hi: Array | None) -> tuple[Array, Array]:
    """Take an equality level's solution; return ``(qdot, slack)``.

    qdot = x clipped into [bl[:n], bu[:n]], a = A_unit qdot (unit-row coordinates),
    slack = a norm - beta; unless lock_lo is None, writes the lock band lock_lo = a - band,
    lock_hi = a + band (m rows each).
    """
    n = x.shape[0]
    qdot = np.minimum(np.maximum(x, bl[:n]), bu[:n])
    a_unit = A_unit @ qdot
    slack = a_unit * norm - beta
    if lock_lo is not None and lock_hi is not None:
        np.subtract(a_unit, band, out=lock_lo)
        np.add(a_unit, band, out=lock_hi)
    return qdot, slack


def lock_if_satisfied(A: Array, qdot: Array, lower: Array, upper: Array, norm: Array,
                      band: Array, lock_lo: Array, lock_hi: Array) -> bool:
    """Lock a level its solution already satisfies.

    If lower <= A qdot <= upper holds on every row (NaN fails), lock the level at its own
    bounds in unit-row coordinates (writes lock_lo = lower / norm - band and lock_hi = upper /
    norm + band) and return True; otherwise write nothing, return False.
    """
    a = A @ qdot
    if not np.maximum(lower - a, a - upper).max() <= 0.0:
        return False
    np.divide(lower, norm, out=lock_lo)
    lock_lo -= band
    np.divide(upper, norm, out=lock_hi)
    lock_hi += band
    return True


def slack_setup(A_unit: Array, A: Array, start: int, end: int, ws_bl: Array, ws_bu: Array,
                lower: Array, upper: Array, C: Array, bl: Array, bu: Array) -> None:
    """The rows and bounds of an inequality level's slack QP over w = [qdot_v; s].

    Writes the first n columns of C (end, n + m): the higher levels' unit rows
    A_unit[:start] and this level's rows A[start:end]; and bl/bu (n + m + end): the box
    ws_bl/ws_bu[:n], the locks ws_bl/ws_bu[n:n + start] and the level's
    lower/upper[start:end]. The slack columns and entries n..n+m of bl/bu are left as they
    are.
    """
    n = A.shape[1]
    m = end - start
    C[:start, :n] = A_unit[:start]
    C[start:, :n] = A[start:end]
    bu[:n] = ws_bu[:n]
    bl[:n] = ws_bl[:n]
    bu[n + m:n + m + start] = ws_bu[n:n + start]
    bl[n + m:n + m + start] = ws_bl[n:n + start]
    bu[n + m + start:] = upper[start:end]
    bl[n + m + start:] = lower[start:end]


def accept_slack(w: Array, bl: Array, bu: Array, A_unit: Array, norm: Array, lower: Array,
                 upper: Array, band: Array, lock_lo: Array, lock_hi: Array
                 ) -> tuple[Array, Array]:
    """Take a slack QP's solution w = [x; s]; return ``(qdot, s)``.

    qdot = x clipped into [bl[:n], bu[:n]], a = (A_unit qdot) norm; writes the lock
    [lower + s, upper + s] widened to contain a (a itself on equal rows), in unit-row
    coordinates, widened by band, into lock_lo and lock_hi.
    """
    n = A_unit.shape[1]
    qdot = np.minimum(np.maximum(w[:n], bl[:n]), bu[:n])
    a = (A_unit @ qdot) * norm
    s = w[n:]
    eq = lower == upper
    lo = np.where(eq, a, np.minimum(lower + s, a))
    hi = np.where(eq, a, np.maximum(upper + s, a))
    lock_lo[:] = lo / norm - band
    lock_hi[:] = hi / norm + band
    return qdot, s


# ---- the torque-limit level (ifc_spg.limits.torque_limits) ------------------------------

def torque_limit(q: Array, qdot: Array, q_v: Array, idx: Array | None, K: Array, gain: float,
                 gain_tau: Array, K_over: Array, band: Array, lower: Array, upper: Array
                 ) -> tuple[Array, Array, Array, Array, Array]:
    """TorqueLimitLevel.apply on the joints idx (an intp array; None: all).

    Returns ``(beta_m, beta_M, s, lower', upper')``: the level's bounds
    K (qdot - gain (q_v - q)) -+ gain_tau (unbounded where not finite), the slack s of its
    closed-form solution projected onto the box (NaN -> 0) and the box narrowed by the lock
    (new arrays).
    """
    i = slice(None) if idx is None else idx
    comp = qdot[i] - gain * (q_v[i] - q[i])
    comp *= K                                           # K qdot - Lambda tau_s
    lo_b = comp - gain_tau                              # beta_m
    hi_b = comp + gain_tau                              # beta_M
    zeros = np.zeros(K.shape[0])
    if not math.isfinite(comp @ zeros):  # overflow on absurd measurements:
        bad = ~np.isfinite(comp)           # leave those joints to the box
        lo_b[bad], hi_b[bad] = -np.inf, np.inf
    lower = lower.copy()
    upper = upper.copy()
    lower_i, upper_i = lower[i], upper[i]  # (views when every joint is compliant)
    # minimizer of rho x^2 + dist(K x, [lo_b, hi_b])^2, projected onto the box
    x = np.minimum(np.maximum(0.0, lo_b), hi_b)
    x *= K_over
    np.minimum(np.maximum(x, lower_i), upper_i, out=x)
    Kx = K * x
    s = Kx - np.minimum(np.maximum(Kx, lo_b), hi_b)
    if not math.isfinite(s @ zeros):
        s[np.isnan(s)] = 0.0
    lower[i] = np.maximum(lower_i, np.minimum((lo_b + s) / K, x) - band)
    upper[i] = np.minimum(upper_i, np.maximum((hi_b + s) / K, x) + band)
    return lo_b, hi_b, s, lower, upper


# ---- joint limits (ifc_spg.limits.joint_limits) -----------------------------------------

def limits_box(q_v: Array, q_min: Array, q_max: Array, d_free: Array, k_scale: Array,
               half_c: Array, inv_dt: float, v: Array) -> tuple[Array, Array] | None:
    """The joint-limit box (JointVelocityLimits.box).

    JointVelocityLimits.box: None where every distance d = [q_v - q_min; q_max - q_v] is at
    least d_free (the constant free box applies), else the stopping-velocity box ``(lower,
    upper)`` (2n-vectors d_free, k_scale, half_c, v).
    """
    n = q_v.shape[0]
    d = np.empty(2 * n)
    np.subtract(q_v, q_min, out=d[:n])
    np.subtract(q_max, q_v, out=d[n:])
    if (d >= d_free).all():
        return None
    np.maximum(d, 0.0, out=d)
    k = d * k_scale
    k += 0.25
    np.sqrt(k, out=k)
    k -= 0.5
    np.floor(k, out=k)
    k1 = k + 1.0
    k *= k1
    k *= half_c
    stop = d * inv_dt
    stop += k
    stop /= k1
    np.minimum(stop, v, out=stop)
    return -stop[:n], stop[n:]


# ---- the tick (ifc_spg.spg.SetPointGenerator) -------------------------------------------

def velocity_box(lower: Array, upper: Array, pb_lower: Array | None, pb_upper: Array | None,
                 qdot_prev: Array, accel: Array) -> tuple[Array, Array]:
    """The tick's box on qdot_v.

    The tick's box on qdot_v: the joint-limit box intersected with the passivity box (None: no
    PSPM; a NaN bound becomes 0, stopping that joint), then softly with the acceleration box
    [qdot_prev - accel, qdot_prev + accel] (limits.intersect_soft).
    """
    if pb_lower is not None and pb_upper is not None:
        lower = np.maximum(lower, pb_lower)
        upper = np.minimum(upper, pb_upper)
        zeros = np.zeros(lower.shape[0])
        if not math.isfinite(lower @ zeros + upper @ zeros):  # NaN
            # an overflow in the passivity bounds (absurd measurements): stop that joint
            lower[np.isnan(lower)] = 0.0
            upper[np.isnan(upper)] = 0.0
    soft_lower = qdot_prev - accel
    soft_upper = qdot_prev + accel
    # limits.intersect_soft(hard, soft): both ends of soft clipped into hard
    return (np.minimum(np.maximum(soft_lower, lower), upper),
            np.maximum(np.minimum(soft_upper, upper), lower))


def integrate(q_v: Array, dt: float, qdot_v: Array, q_min: Array, q_max: Array) -> Array:
    """min(max(q_v + dt qdot_v, q_min), q_max) as a new array."""
    return np.minimum(np.maximum(q_v + dt * qdot_v, q_min), q_max)


# ---- the energy tanks (ifc_spg.pspm.EnergyTanks) ----------------------------------------

def pspm_bounds(q: Array, q_v: Array, q_prev: Array, energy: Array, shuffle: Array | None,
                D_over_dt: Array, two_over_K: Array, inv_dt: float, modulated: Array
                ) -> tuple[Array, Array, Array, Array]:
    """EnergyTanks.bounds; returns ``(lower, upper, dissipated_min, avail)``.

    E_Dmin = D/dT (q - q_prev)^2, E_avail = E_r + E_Dmin (+ shuffle unless None),
    r = sqrt(2 E_avail / K + dq^2) with dq = q_v - q, upper = (r - dq)/dT,
    lower = -(r + dq)/dT, unbounded where modulated is 0. modulated is a float array (1 or
    0). Writes nothing: the caller keeps q as the next tick's q_prev.
    """
    step = q - q_prev
    step *= step
    step *= D_over_dt
    if shuffle is not None:
        avail = energy + step + shuffle
    else:
        avail = energy + step
    dq = q_v - q
    r = avail * two_over_K
    r += dq * dq
    np.sqrt(r, out=r)
    upper = r - dq
    upper *= inv_dt
    r += dq
    r *= -inv_dt
    lower = r
    fixed = np.flatnonzero(modulated == 0.0)
    if fixed.size:
        lower[fixed] = -np.inf
        upper[fixed] = np.inf
    return lower, upper, step, avail


def pspm_update(q: Array, q_v: Array, qdot_v: Array, avail: Array, half_K: Array, dt: float,
                max_energy: float, modulated: Array, energy: Array
                ) -> tuple[Array, Array, float]:
    """The energy tanks' booking of a step (EnergyTanks.update).

    EnergyTanks.update before its NaN / round-off repair; returns ``(energy', dEk,
    min(energy'))``.

    dEk = K/2 ((dq + dt qdot_v)^2 - dq^2), energy' = min(avail - dEk, max_energy), the old
    energy where modulated is 0; the minimum is NaN if any entry is.
    """
    dq = q_v - q
    new = qdot_v * dt
    new += dq
    new *= new
    dq *= dq
    new -= dq
    dEk = new
    dEk *= half_K
    e = avail - dEk
    np.minimum(e, max_energy, out=e)
    fixed = np.flatnonzero(modulated == 0.0)
    if fixed.size:
        e[fixed] = energy[fixed]
    return e, dEk, float(e.min())


# ---- the tasks (ifc_spg.tasks.task.Task.level) -----------------------------------------

def task_bounds(gain: Array, alpha: Array, lower: Array, lower_ff: Array, upper: Array | None,
                upper_ff: Array | None, gamma: Array | None, kd: Array | None,
                zero_gain: bool) -> tuple[Array, Array]:
    """A task's velocity bounds (4.25-4.28); return ``(beta_lo, beta_hi)``.

    beta_lo = gain (lower - alpha) + ff_lo with ff_lo = lower_ff + gamma + kd (gamma, kd:
    None for none, added in that order), the same for beta_hi with upper and upper_ff;
    upper None: beta_hi is beta_lo (an equality task). zero_gain: where lower is -inf,
    beta_lo is -inf (where upper is +inf, beta_hi is +inf), whatever 0 * inf gave.
    """
    def side(bound, ff, inf):
        if gamma is not None:
            ff = ff + gamma
        if kd is not None:
            ff = ff + kd
        if not zero_gain:
            return gain * (bound - alpha) + ff
        with np.errstate(invalid='ignore'):
            beta = gain * (bound - alpha) + ff
        beta[bound == inf] = inf
        return beta

    beta_lo = side(lower, lower_ff, -np.inf)
    if upper is None or upper_ff is None:
        return beta_lo, beta_lo
    return beta_lo, side(upper, upper_ff, np.inf)

def pose_error(p: Array | None, p_ref: Array | None, R: Array, R_ref: Array,
               J: Array) -> tuple[Array, Array]:
    """A pose task's error and Jacobian (docs/SPEC.md, Orientation); return ``(x, Jx)``.

    With R_e = R R_ref^T: e = log3(R_e), J_rot = Jlog3(R_e) R_e^T J[3:] (pinocchio's log3 and
    Jlog3); x = (p - p_ref, e) (6,), Jx = (J[:3]; J_rot) (6, n). p and p_ref None: the
    rotation only, ``(e (3,), J_rot (3, n))``.
    """
    # (ndarray.dot: half the overhead of @ on 3 x 3 operands, ~0.8 against ~1.7 us)
    R_e = R.dot(R_ref.T)
    e, J_rot = pin.log3(R_e), pin.Jlog3(R_e).dot(R_e.T).dot(J[3:])
    if p is None or p_ref is None:
        return e, J_rot
    return np.concatenate((p - p_ref, e)), np.concatenate((J[:3], J_rot))

# ---- collision avoidance (ifc_spg.geometry.PairQuery) ----------------------------------

def collision_cull(last_bound: Array, lever: Array, q: Array, last_q: Array,
                   influence: float, distance: Array) -> Array:
    """The cull across calls: the bounds and the pairs left for coal.

    Writes ``distance = last_bound - lever @ |q - last_q|``; returns the indices
    (ascending) where ``distance <= influence``.
    """
    distance[:] = last_bound - lever @ np.abs(np.asarray(q, dtype=float) - last_q)
    return np.flatnonzero(distance <= influence)


def collision_level(rows: Array, distance: Array, pairs: Array, influence: float, gain: float,
                    margin: float, A: Array, lower: Array) -> Array:
    """The velocity damper level of a collision-avoidance task (writes ``A`` and ``lower``).

    Returns the pairs (in the order given) with ``distance < influence``; the first R of
    them (R = ``lower.size``) fill ``A[t] = rows[p]`` and
    ``lower[t] = -gain (distance[p] - margin)``; the other rows of A are zero and their
    lower bounds -inf.
    """
    pairs = np.asarray(pairs, dtype=np.intp).reshape(-1)
    within = pairs[distance[pairs] < influence]
    idx = within[:lower.size]
    k = idx.size
    A[:k] = rows[idx]
    A[k:] = 0.0
    lower[:k] = -gain * (distance[idx] - margin)
    lower[k:] = -np.inf
    return within


def collision_rows(J: Array, within: Array, found: list | None, point_a: Array, point_b: Array,
                   distance: Array, normal: Array, mask_a: Array, mask_b: Array, eps: float,
                   rows: Array) -> None:
    """Witness points and distance Jacobian rows of the pairs ``within``.

    ``found``: their witness points ``[p_a, p_b, p_a, p_b, ...]`` (coal's), written to
    ``point_a`` and ``point_b`` first; None where ``point_a`` and ``point_b`` hold them
    already. Then per pair i:
    ``normal[i] = (point_b[i] - point_a[i]) / distance[i]`` where ``distance[i] > eps``
    (else ``normal[i]`` is kept: coal's), and
    ``rows[i] = (n^T J_v) (mask_b[i] - mask_a[i]) + ((p_b x n)^T J_w) mask_b[i]
    - ((p_a x n)^T J_w) mask_a[i]`` with J (6, n) the joint Jacobian in the world frame.
    Writes ``point_a``, ``point_b``, ``normal`` and ``rows`` (of the pairs within only).
    """
    within = np.asarray(within, dtype=np.intp)
    if found is not None and len(found) != 2 * within.size:
        raise ValueError('found must be a list of 2 points per pair within, or None')
    if found is not None and within.size:
        point_a[within] = found[0::2]
        point_b[within] = found[1::2]
    a, b, d = point_a[within], point_b[within], distance[within]
    n = normal[within]
    far = d > eps
    n[far] = (b[far] - a[far]) / d[far, None]
    normal[within] = n
    Jw = J[3:]
    ma, mb = mask_a[within], mask_b[within]
    rows[within] = (n @ J[:3]) * (mb - ma) + (_cross(b, n) @ Jw) * mb - (_cross(a, n) @ Jw) * ma


def _cross(a: Array, b: Array) -> Array:
    """Row-wise cross product of (k, 3) arrays."""
    out = np.empty_like(a)
    out[:, 0] = a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1]
    out[:, 1] = a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2]
    out[:, 2] = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    return out
