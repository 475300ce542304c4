"""Metrics of a constrained-manipulation run, from plain time series (thesis 5.4.3, 5.5.3).

All functions take arrays sampled at the run's ticks; none needs the simulator, so they
apply to recorded runs as well.
"""

import numpy as np

__all__ = [
    'error_angles',
    'perpendicular_force',
    'pooled_rms',
    'rms',
    'summarize',
    'time_to_open',
    'travel',
]


def _unit_rows(d):
    d = np.asarray(d, dtype=float)
    n = np.linalg.norm(d, axis=-1, keepdims=True)
    return np.divide(d, n, out=np.zeros_like(d), where=n > 1e-12)


def perpendicular_force(force, direction):
    """|f_perp| per sample: the force orthogonal to the (true) motion direction, in [N].

    Args:
        force: Forces (T, 3) in [N] (either sign convention; only the magnitude counts).
        direction: Motion directions (T, 3) or (3,) (normalized here).
    """
    f = np.asarray(force, dtype=float)
    d = np.broadcast_to(_unit_rows(direction), f.shape)
    f_par = np.sum(f * d, axis=-1, keepdims=True) * d
    return np.linalg.norm(f - f_par, axis=-1)


def rms(x):
    """Root mean square of a series (0 for an empty one)."""
    x = np.asarray(x, dtype=float)
    return float(np.sqrt(np.mean(x * x))) if x.size else 0.0


def pooled_rms(runs, key='rms_f_perp'):
    """Overall RMS of several runs: the RMS of all their samples together, in [N].

    The thesis' "overall RMS of |f_perp|" over a set of runs (5.5.3). From each run's RMS and
    sample count, sqrt(sum_i n_i rms_i^2 / sum_i n_i), which equals the RMS of the
    concatenated series.

    Args:
        runs: :func:`summarize` dicts (with ``samples`` and ``key``).
        key: The per-run RMS to pool (``rms_f_perp`` or ``rms_fs_perp``).
    """
    n = sum(int(m['samples']) for m in runs)
    if n == 0:
        return 0.0
    return float(np.sqrt(sum(m['samples'] * m[key] ** 2 for m in runs) / n))


def error_angles(estimate, truth):
    """Angle between estimated and true directions per sample in [rad] (T,)."""
    a, b = _unit_rows(estimate), _unit_rows(truth)
    b = np.broadcast_to(b, a.shape)
    cross = np.linalg.norm(np.cross(a, b), axis=-1)
    return np.arctan2(cross, np.sum(a * b, axis=-1))


def travel(env_q):
    """Largest displacement |q_env - q_env[0]| of the mechanism (m or rad)."""
    q = np.asarray(env_q, dtype=float).reshape(len(env_q), -1)[:, 0]
    return float(np.max(np.abs(q - q[0]))) if q.size else 0.0


def time_to_open(t, env_q, target):
    """First time in [s] (from t[0]) the mechanism moved by ``target``; None if never."""
    q = np.asarray(env_q, dtype=float).reshape(len(env_q), -1)[:, 0]
    hit = np.flatnonzero(np.abs(q - q[0]) >= target)
    return None if hit.size == 0 else float(t[hit[0]] - t[0])


def summarize(t, env_q, force, true_direction, estimate=None, static_force=None, target=None,
              force_limit=np.inf, until_open=True, skip=0.0, damping_force=None):
    """Metrics of one run as a JSON-friendly dict.

    Args:
        t: Time stamps in [s] (T,).
        env_q: Mechanism joint position (T,) in [m] or [rad].
        force: Interaction force the robot applies (or its negative) (T, 3) in [N].
        true_direction: True motion direction of the handle (T, 3).
        estimate: Estimated direction d_hat (T, 3), optional.
        static_force: Static force f_s (T, 3) in [N], optional.
        target: Travel that counts as "open" (m or rad); None: no success criterion.
        force_limit: Success also needs max |force| <= force_limit [N].
        until_open: Evaluate the force metrics up to the opening time only (the rest of a
            run may push against the end stop).
        skip: Leave out the first ``skip`` seconds of the force and angle metrics.
        damping_force: The IFC's damping force (T, 3) in [N], optional.

    Returns:
        Dict with ``rms_f_perp``, ``max_f_perp``, ``max_force``, ``travel``,
        ``time_to_open``, ``success``, ``samples`` (samples in the evaluated window, for
        :func:`pooled_rms`) and, when given, ``rms_error_angle_deg``,
        ``final_error_angle_deg``, ``rms_fs_perp``, ``rms_fd_perp``.
    """
    t = np.asarray(t, dtype=float)
    topen = None if target is None else time_to_open(t, env_q, target)
    end = len(t)
    if until_open and topen is not None:
        end = int(np.searchsorted(t, t[0] + topen, side='right'))
    start = min(int(np.searchsorted(t, t[0] + skip, side='left')), max(end - 1, 0))
    sl = slice(start, max(end, start + 1))
    td = np.asarray(true_direction, dtype=float)
    td = td[sl] if td.ndim == 2 else td
    f_perp = perpendicular_force(np.asarray(force)[sl], td)
    fmax = float(np.max(np.linalg.norm(np.asarray(force)[sl], axis=-1)))
    out = {
        'rms_f_perp': rms(f_perp),
        'max_f_perp': float(np.max(f_perp)),
        'max_force': fmax,
        'travel': travel(env_q),
        'time_to_open': topen,
        'success': None if target is None else bool(topen is not None and fmax <= force_limit),
        'samples': int(len(f_perp)),
    }
    if estimate is not None:
        ang = np.degrees(error_angles(np.asarray(estimate)[sl], td))
        out['rms_error_angle_deg'] = rms(ang)
        out['final_error_angle_deg'] = float(ang[-1])
    if static_force is not None:
        out['rms_fs_perp'] = rms(perpendicular_force(np.asarray(static_force)[sl], td))
    if damping_force is not None:
        out['rms_fd_perp'] = rms(perpendicular_force(np.asarray(damping_force)[sl], td))
    return out
