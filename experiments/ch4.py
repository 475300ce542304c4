"""Thesis Ch. 4 experiments (the QP cascade with constraints and PSPM): Tables 4.1-4.5.

Obstacle torque and force bands, the orientation box, pose and wrench limits, motion along
z_ee and the joint-5 stability regulator; run by :mod:`experiments.reproduce`.
"""

from typing import Any

import numpy as np

from experiments.harness import (
    _T_CIRCLE,
    Check,
    Experiment,
    RunSpec,
    _band_err,
    _fmt,
    _plt,
    _push_windows,
    _rms,
    _save,
    _scenario_doc,
    _shade_pushes,
    _smooth,
    _task_panel,
)

__all__ = ['CH4_EXPERIMENTS']

_K_LBR = 200.0


_V41 = ('1a_3a', '1b_3a', '1a_3b', '1b_3b')
#: Table 4.1's friction ablation (claims v10, the cause of the 1b claims): these variants again
#: with Coulomb friction mu = 1.0 and a 20 ms friction reference at the tool contacts (ours;
#: the scenarios' table scene: mu = 0.3 and a 1 s reference, viscous below ~1 cm/s of slip)
_V41_FRICTION = ('1a_3a', '1b_3a')
_FRICTION_41 = {'friction': 1.0, 'solref_friction': [0.02, 1.0]}
_T41_BAND = _T_CIRCLE + 1.0  # the approach leaves ~6 Nm; the 1b band is reached in ~0.5 s


def _static_wrench(run, chain='tool'):
    """h_s = J^{+T} K (q_v - q) [N, Nm] per joint-state sample.

    Least squares of J^T h = tau_s at the measured q (base frame), independent of the SPG's
    task code.
    """
    import pinocchio as pin

    from ifc_spg.model import RobotModel

    if run.robot is None:
        run.robot = RobotModel.from_config(run.metrics['robot'])
    robot = run.robot
    data = robot.create_data()
    fid = robot.frame_id(chain)
    k = np.where(robot.stiff_mask, 0.0, robot.stiffness)
    tau = run.static_torque(k)
    out = np.zeros((len(tau), 6))
    for i, q in enumerate(run.s.q[:len(tau)]):
        J = pin.computeFrameJacobian(robot.model, data, np.asarray(q), fid,
                                     pin.LOCAL_WORLD_ALIGNED) * (~robot.stiff_mask)
        out[i] = np.linalg.lstsq(J.T, tau[i], rcond=None)[0]
    return out


def _last_second_travel(run, y_v):
    """|y_v(end) - y_v(end - 1 s)| [m] of the commanded tool position."""
    t = run.s.t_cmd[:len(y_v)]
    i = int(np.searchsorted(t, t[-1] - 1.0))
    return float(abs(y_v[-1] - y_v[min(i, len(y_v) - 1)]))


def _friction_spec(variant):
    """The RunSpec of a Table 4.1 variant in the friction ablation (full run only).

    The scenario's scene options with :data:`_FRICTION_41`.
    """
    from ifc_spg.offline.runner import find_config_dir, load_scenario

    name = f'thesis_4_1_{variant}.yaml'
    scenario = load_scenario(find_config_dir() / 'scenarios' / name)
    return RunSpec(f'friction_{variant}', name,
                   overrides={'scene_options': {**scenario.scene_options, **_FRICTION_41}},
                   full_only=True)


def _longest_stall(run, pos, pos_v, face, window=0.5, still=1e-3):
    """The longest stall [s] of a run.

    A stall is a stretch of command samples at which the physical and the virtual tool each
    moved less than ``still`` [m] in the last ``window`` [s] while the virtual tool is beyond
    the obstacle face (``face`` [m] along y from the start). ``pos`` and ``pos_v``: the tool
    positions of the run at q and q_v (:meth:`~experiments.harness.Run.tool_positions`).
    """
    t = np.asarray(run.s.t_js[:len(pos)], dtype=float)
    t_v = np.asarray(run.s.t_cmd[:len(pos_v)], dtype=float)
    p = pos[np.clip(np.searchsorted(t, t_v, side='right') - 1, 0, len(t) - 1)]
    back = np.searchsorted(t_v, t_v - window)  # the sample `window` earlier
    moved = np.maximum(np.linalg.norm(p - p[back], axis=1),
                       np.linalg.norm(pos_v - pos_v[back], axis=1))
    stalled = (t_v - t_v[0] >= window) & (moved < still) & (pos_v[:, 1] - pos[0, 1] > face)
    best, start = 0.0, None
    for k, s in enumerate(np.append(stalled, False)):
        if s and start is None:
            start = k
        elif not s and start is not None:
            best, start = max(best, float(t_v[k - 1] - t_v[start])), None
    return best


def _obstacle_face(run):
    """The y of the obstacle face the tool meets, from the start [m] (None: no obstacle)."""
    opts = run.scenario.scene_options if run.scenario is not None else {}
    if opts.get('obstacle_offset') is None:
        return None
    return opts['obstacle_offset'][1] - opts.get('obstacle_size', (0, 0.02))[1]


def _check_4_1(runs, quick):
    out, txt = {}, []
    for v in _V41 + tuple(f'friction_{v}' for v in _V41_FRICTION):
        if v not in runs:  # the friction ablation: full runs only
            continue
        r = runs[v]
        tq = r.task('torque_limits')
        mt = tq['t'] >= _T41_BAND
        tau_v = float(np.max(np.abs(tq['value'][mt])))
        cf = r.task('contact_force', since=_T_CIRCLE)
        mc = cf['t'] >= _T41_BAND
        f_model = cf['value'][mc]
        tang_task = float(np.max(np.abs(f_model[:, 1:]))) if f_model.shape[1] > 1 else None
        h = _static_wrench(r)
        h = h[r.after(_T41_BAND)[:len(h)]]
        tang_static = float(np.max(np.abs(h[:, :2])))
        mf = r.after(_T41_BAND, r.s.t_cw)
        f = r.contact_force()[mf]
        f_y = _smooth(f[:, 1], 25)
        tang_meas = float(np.max(_smooth(np.linalg.norm(f[:, :2], axis=1), 25)))
        pos, _ = r.tool_positions()
        y_phys = float(np.max(pos[:, 1] - pos[0, 1]))
        pos_v, _ = r.tool_positions(virtual=True)
        face = _obstacle_face(r)
        hit = r.s.t_cw[mf][np.argmax(f_y > 3.0)] if np.any(f_y > 3.0) else None
        # where the tool touched the face (physical y at the largest force on it) and how far
        # short of that it stays in the last second, which the stall claim reads
        t_js = np.asarray(r.s.t_js[:len(pos)], dtype=float)
        y_rel = pos[:, 1] - pos[0, 1]
        t_peak = r.s.t_cw[mf][int(np.argmax(f_y))]
        y_touch = float(y_rel[min(int(np.searchsorted(t_js, t_peak)), len(y_rel) - 1)])
        gap_end = float(np.min(y_touch - y_rel[t_js >= t_js[-1] - 1.0]))
        tr = r.task('trajectory')
        ev, ep = _band_err(tr, comps=(0, 1))
        m = tr['t'] >= _T41_BAND
        out[v] = {'max_abs_static_torque_nm': tau_v,
                  'max_abs_static_tangential_force_n': tang_static,
                  'max_abs_task_tangential_force_n': tang_task,
                  'max_measured_tangential_force_n': tang_meas,
                  'max_obstacle_force_n': float(np.max(f_y)),
                  'obstacle_hit_s': None if hit is None else float(hit),
                  'max_virtual_y_m': float(np.max(pos_v[:, 1] - pos[0, 1])),
                  'max_virtual_penetration_m': None if face is None else
                  max(0.0, float(np.max(pos_v[:, 1] - pos[0, 1])) - face),
                  'virtual_y_travel_last_1s_m': _last_second_travel(r, pos_v[:, 1]),
                  'longest_stall_s': None if face is None else
                  _longest_stall(r, pos, pos_v, face),
                  'max_physical_y_m': y_phys,
                  'touch_y_m': y_touch,
                  'last_1s_short_of_touch_m': gap_end,
                  'trajectory_error_rms_m': _rms(ep[m])}
        pen = out[v]['max_virtual_penetration_m']
        if v.startswith('friction_'):
            txt.append(f'{v} (mu = {_FRICTION_41["friction"]:g}, 20 ms friction reference, '
                       f'ours): virtual tool at most {_fmt(None if pen is None else pen * 1e3)}'
                       f' mm beyond the obstacle face, longest stall '
                       f'{out[v]["longest_stall_s"]:.1f} s, virtual tool travel along y in '
                       f'the last second {out[v]["virtual_y_travel_last_1s_m"] * 1e3:.1f} mm')
            continue
        txt.append(f'{v}: max |tau_s| {tau_v:.1f} Nm, static tangential force max '
                   f'{tang_static:.1f} N, measured force on the obstacle max '
                   f'{np.max(f_y):.1f} N (25-tick mean), virtual tool at most '
                   f'{_fmt(None if pen is None else pen * 1e3)} mm beyond the obstacle face')
    return Check(out, '; '.join(txt) + f' (static torque and force maxima from '
                 f'{_T41_BAND - _T_CIRCLE:g} s after the switch)')


def _fig_4_1(runs, quick, path):
    plt = _plt()
    fig, axes = plt.subplots(3, 4, figsize=(10, 5.6), sharex=True)
    for col, v in enumerate(_V41):
        r = runs[v]
        tq = r.task('torque_limits')
        for j in range(tq['value'].shape[1]):
            axes[0, col].plot(tq['t'], tq['value'][:, j], lw=0.7)
        lim = 5.0 if v.startswith('1b') else 50.0
        for s in (-1, 1):
            axes[0, col].axhline(s * lim, color='k', ls='--', lw=0.8)
        if lim > 5.0:
            axes[0, col].set_ylim(-15, 15)
            for s in (-1, 1):
                axes[0, col].axhline(s * 5.0, color='0.6', ls=':', lw=0.8)
        axes[0, col].set_title(f'variant {v}')
        h = _static_wrench(r)
        t = r.s.t_js[:len(h)]
        for i, (lab, c) in enumerate(zip(('h_x', 'h_y', 'h_z'),
                                         ('#1f77b4', '#d62728', '#2ca02c'))):
            axes[1, col].plot(t, h[:, i], color=c, label=lab)
        for s in (-1, 1):
            axes[1, col].axhline(s * 10.0, color='k' if v.endswith('3b') else '0.6',
                                 ls='--' if v.endswith('3b') else ':', lw=0.8)
        pos, _ = r.tool_positions()
        pos_v, _ = r.tool_positions(virtual=True)
        y0 = pos[0, 1]
        axes[2, col].plot(r.s.t_js[:len(pos)], pos[:, 1] - y0, color='#d62728',
                          label='y physical')
        axes[2, col].plot(r.s.t_cmd[:len(pos_v)], pos_v[:, 1] - y0, color='#1f77b4',
                          label='y virtual')
        d = r.task('trajectory')
        axes[2, col].plot(d['t'], d['lower'][:, 1] - y0, 'k--', lw=0.8, label='p_d')
        face = _obstacle_face(r)
        if face is not None:
            axes[2, col].axhline(face, color='#8c564b', lw=0.8, label='obstacle face')
        axes[2, col].set_xlabel('time [s]')
    axes[0, 0].set_ylabel('static torques [Nm]')
    axes[1, 0].set_ylabel('static force J^+T tau_s [N]')
    axes[2, 0].set_ylabel('tool y - y_0 [m]')
    axes[1, 0].legend()
    axes[2, 0].legend()
    _save(fig, path)


_BOX_LO, _BOX_HI = np.array([0.2, 0.2, 0.4]), np.array([0.5, 0.5, 0.7])


def _check_4_2(runs, quick):
    out, txt = {}, []
    for v, k in (('high_k', 200.0), ('low_k', 50.0)):
        r = runs[v]
        pos, _ = r.tool_positions()
        pos_v, _ = r.tool_positions(virtual=True)
        out_p = np.maximum(pos - _BOX_HI, 0) + np.maximum(_BOX_LO - pos, 0)
        out_v = np.maximum(pos_v - _BOX_HI, 0) + np.maximum(_BOX_LO - pos_v, 0)
        moved = float(np.max(np.linalg.norm(pos - pos[0], axis=1)))
        out[v] = {'stiffness': k, 'max_virtual_outside_m': float(out_v.max()),
                  'max_physical_outside_m': float(out_p.max()), 'max_displacement_m': moved}
        txt.append(f'K = {k:g}: virtual tool at most {out_v.max() * 1e3:.2f} mm outside, '
                   f'physical up to {out_p.max() * 1e3:.1f} mm outside (moved '
                   f'{moved * 100:.1f} cm)')
    return Check(out, '; '.join(txt))


def _fig_4_2(runs, quick, path):
    plt = _plt()
    fig, axes = plt.subplots(1, 2, figsize=(8, 2.6), sharey=True)
    for ax, (v, k) in zip(axes, (('high_k', 200.0), ('low_k', 50.0))):
        r = runs[v]
        pos, _ = r.tool_positions()
        pos_v, _ = r.tool_positions(virtual=True)
        ax.plot(r.s.t_js[:len(pos)], pos[:, 0], color='#d62728', label='x physical')
        ax.plot(r.s.t_cmd[:len(pos_v)], pos_v[:, 0], color='#1f77b4', label='x virtual')
        ax.plot(r.s.t_js[:len(pos)], pos[:, 1], color='#d62728', ls=':', label='y physical')
        ax.plot(r.s.t_cmd[:len(pos_v)], pos_v[:, 1], color='#1f77b4', ls=':',
                label='y virtual')
        ax.axhline(_BOX_HI[0], color='k', ls='--', lw=0.8, label='box face x = 0.5')
        ax.axhline(_BOX_LO[1], color='0.5', ls='--', lw=0.8, label='box face y = 0.2')
        _shade_pushes(ax, r)
        ax.set_title(f'K = {k:g} Nm/rad')
        ax.set_xlabel('time [s]')
    axes[0].set_ylabel('tool position [m]')
    axes[0].legend(ncol=2)
    _save(fig, path)


def _windows(run, t):
    """Masks of (small push, large push, after the pushes + 1.5 s settling)."""
    (a1, b1), (a2, b2) = _push_windows(run)[:2]
    return ((t > a1 + 0.5) & (t < b1), (t > a2 + 0.5) & (t < b2), t > b2 + 1.5)


def _check_4_3(runs, quick):
    r = runs['pose']
    pos, _ = r.tool_positions()
    t = r.s.t_js[:len(pos)]
    err = np.linalg.norm(pos - pos[0], axis=1)
    small, large, after = _windows(r, t)
    fs = r.task('force_limits')
    tf = fs['t']
    sm_f, lg_f, _ = _windows(r, tf)
    fmax_small = float(np.max(np.abs(fs['value'][sm_f]))) if sm_f.any() else float('nan')
    fmax_large = float(np.max(np.abs(fs['value'][lg_f]))) if lg_f.any() else float('nan')
    out = {'error_small_push_m': float(err[small].max()),
           'error_large_push_m': float(err[large].max()),
           'error_after_m': float(err[after].max()) if after.any() else None,
           'error_end_m': float(err[-1]),
           'time_after_push_s': float(t[-1] - _push_windows(r)[1][1]),
           'static_force_small_push_n': fmax_small, 'static_force_large_push_n': fmax_large}
    return Check(out,
                 f'position error max: {err[small].max() * 1e3:.1f} mm during the 5 N push '
                 f'(static force {fmax_small:.1f} N), {err[large].max() * 1e3:.1f} mm during '
                 f'the 25 N push (static force {fmax_large:.1f} N), '
                 f'{_fmt(None if out["error_after_m"] is None else out["error_after_m"] * 1e3)} '
                 f'mm 1.5 s after it, {err[-1] * 1e3:.2f} mm {out["time_after_push_s"]:.1f} s '
                 'after it (the return runs along the -10 N bound)')


def _fig_4_3(runs, quick, path):
    plt = _plt()
    r = runs['pose']
    fig, axes = plt.subplots(1, 2, figsize=(8, 2.6))
    _task_panel(axes[0], r.task('force_limits'), 0, 'f_x', ylabel='static force f_x [N]')
    axes[0].legend()
    pos, _ = r.tool_positions()
    pos_v, _ = r.tool_positions(virtual=True)
    axes[1].plot(r.s.t_js[:len(pos)], (pos[:, 0] - pos[0, 0]) * 1e3, color='#d62728',
                 label='physical')
    axes[1].plot(r.s.t_cmd[:len(pos_v)], (pos_v[:, 0] - pos[0, 0]) * 1e3, color='#1f77b4',
                 label='virtual')
    axes[1].set_ylabel('x - x_init [mm]')
    axes[1].legend()
    for ax in axes:
        _shade_pushes(ax, r)
        ax.set_xlabel('time [s]')
    _save(fig, path)


def _check_4_4(runs, quick):
    r = runs['free_z']
    pos, rot = r.tool_positions()
    z_ee = rot[0][:, 2]
    d = pos - pos[0]
    along = d @ z_ee
    perp = np.linalg.norm(d - np.outer(along, z_ee), axis=1)
    t = r.s.t_js[:len(pos)]
    w = _push_windows(r)
    # displacement left after each push (0.5 s after it ends)
    left = []
    for _, b in w:
        i = int(np.searchsorted(t, min(b + 0.5, t[-1])))
        i = min(i, len(t) - 1)
        left.append((float(along[i]), float(perp[i])))
    out: dict[str, Any]
    out = {'max_along_z_ee_m': float(np.max(np.abs(along))),
           'max_perpendicular_m': float(perp.max()),
           'after_each_push_along_perp_m': left}
    return Check(out,
                 f'tool moved up to {out["max_along_z_ee_m"] * 100:.1f} cm along z_ee; '
                 f'perpendicular: {perp.max() * 1e3:.1f} mm at most while pushed, '
                 f'{max(abs(p) for _, p in left) * 1e3:.2f} mm left after the pushes; '
                 f'{abs(left[0][0]) * 100:.1f} cm left along z_ee after the first push')


def _fig_4_4(runs, quick, path):
    plt = _plt()
    r = runs['free_z']
    pos, rot = r.tool_positions()
    z_ee = rot[0][:, 2]
    d = pos - pos[0]
    along = d @ z_ee
    perp = d - np.outer(along, z_ee)
    t = r.s.t_js[:len(pos)]
    fig, ax = plt.subplots(1, 1, figsize=(5, 2.6))
    ax.plot(t, along * 100, color='#d62728', label='along z_ee')
    ax.plot(t, perp[:, 0] * 100, color='#1f77b4', label='perpendicular, x')
    ax.plot(t, perp[:, 1] * 100, color='#2ca02c', label='perpendicular, y')
    _shade_pushes(ax, r)
    ax.set_ylabel('tool displacement [cm]')
    ax.set_xlabel('time [s]')
    ax.legend()
    _save(fig, path)


_D5 = 2.5  # LBR-IV default IFC damping of A5 [Nms/rad] (v1 lowered it to 0.5)


def _energy_in(run, joint=4):
    """-int tau qdot dt of joint ``joint`` [J]: tau = K (q_v - q) - D qdot of the IFC."""
    k = _K_LBR
    damping = (run.scenario.sim or {}).get('damping') if run.scenario is not None else None
    d5 = _D5 if damping is None else float(damping[joint])
    s = run.s
    n = min(len(s.q), len(s.q_v))
    q_v = np.concatenate([s.q[:1, joint], s.q_v[:n - 1, joint]])
    q, qd = s.q[:n, joint], s.qd[:n, joint]
    q_prev = np.concatenate([q[:1], q[:-1]])
    tau = k * (q_v - 0.5 * (q + q_prev)) - d5 * qd  # spring at the midpoint of the step
    return s.t_js[:n], -np.cumsum(tau * (q - q_prev))


def _loop_radius(inertia, damping, delay, k=_K_LBR, kp=100.0, kd=0.8, dt=0.002, sub=2):
    """Spectral radius of the linearised joint-5 loop of (4.85) over one SPG tick.

    Plant I qdd = K (q_v - q) - D qd (semi-implicit Euler, ``sub`` steps per tick); the SPG
    integrates q_v += dt (-k_p q_v + k_d qd_meas) with qd measured ``delay`` ticks late.
    """
    n = 3 + delay

    def step(x):
        q, qd, qv, hist = x[0], x[1], x[2], list(x[3:])
        meas = hist[-1] if delay else qd
        qv = qv + dt * (-kp * qv + kd * meas)
        for _ in range(sub):
            qd = qd + dt / sub * (k * (qv - q) - damping * qd) / inertia
            q = q + dt / sub * qd
        return np.array([q, qd, qv] + ([qd] + hist[:-1] if delay else []))
    A = np.column_stack([step(e) for e in np.eye(n)])
    return float(np.max(np.abs(np.linalg.eigvals(A))))


def _stability_analysis(run):
    """Loop radius (> 1: unstable) at the run's D5 and at 0.5, for 0 / 5 / 20 ticks delay."""
    import pinocchio as pin

    from ifc_spg.model import RobotModel

    robot = RobotModel.from_config('lbr4')
    inertia = float(pin.crba(robot.model, robot.create_data(), np.zeros(robot.model.nq))[4, 4])
    damping = (run.scenario.sim or {}).get('damping') if run.scenario is not None else None
    d5 = _D5 if damping is None else float(damping[4])
    return {'inertia_5_kg_m2': inertia, 'damping_5': d5,
            'radius': {f'D{d:g}_delay{k}': _loop_radius(inertia, d, k)
                       for d in (d5, 0.5) for k in (0, 5, 20)}}


def _check_4_5(runs, quick):
    spg = runs['pspm'].scenario.spg
    c2 = spg.pspm_initial_energy + spg.pspm_shuffle_budget  # E_K(0) = 0 (q_v starts at q)
    out = {}
    for v in ('no_pspm', 'pspm'):
        r = runs[v]
        t, w = _energy_in(r)
        err = r.s.q[:, 4] - 0.0
        half = t[-1] / 2
        late = t > t[-1] - 1.0
        out[v] = {'energy_in_min_j': float(w.min()), 'energy_in_end_j': float(w[-1]),
                  'energy_in_mid_j': float(w[np.searchsorted(t, half)]),
                  'error_amplitude_last_1s_rad': float(np.max(np.abs(err[late]))),
                  'error_amplitude_max_rad': float(np.max(np.abs(err)))}
        if r.metrics.get('tank_energy_min_j') is not None:
            out[v]['tank_energy_min_j'] = r.metrics['tank_energy_min_j']
    off, on = out['no_pspm'], out['pspm']
    out['c2_j'] = c2
    out['linear_loop'] = lin = _stability_analysis(runs['pspm'])
    rad = ', '.join(f'{k} {v:.3f}' for k, v in lin['radius'].items())
    return Check(out,
                 f'-int tau_5 qdot_5 dt at the end: {off["energy_in_end_j"] * 1e3:.1f} mJ '
                 f'without PSPM (still falling: {off["energy_in_mid_j"] * 1e3:.1f} mJ at half '
                 f'time), {on["energy_in_end_j"] * 1e3:.2f} mJ with PSPM (min '
                 f'{on["energy_in_min_j"] * 1e3:.2f} mJ, '
                 f'bound -c^2 = {-c2 * 1e3:g} mJ); |q5 error| in the last second '
                 f'{off["error_amplitude_last_1s_rad"]:.4f} rad without, '
                 f'{on["error_amplitude_last_1s_rad"]:.5f} rad with PSPM; linearised loop '
                 f'(I5 = {lin["inertia_5_kg_m2"]:.4f} kg m^2), spectral radius per tick '
                 f'(> 1 unstable) by D5 and measurement delay [ticks]: {rad}')


def _fig_4_5(runs, quick, path):
    plt = _plt()
    fig, axes = plt.subplots(2, 2, figsize=(8, 4.2), sharex=True)
    for col, (v, title) in enumerate((('no_pspm', 'without PSPM'), ('pspm', 'with PSPM'))):
        r = runs[v]
        tank = [d.get('tank_energy') for d in r.s.status]
        tt = [t for t, d in zip(r.s.t_status, tank) if d]
        if tt:
            e5 = [d[4] for d in tank if d]
            axes[0, col].plot(tt, e5, color='#2ca02c', label='tank E_r,5')
        t, w = _energy_in(r)
        axes[0, col].plot(t, w, color='#d62728', label='-int tau_5 qdot_5 dt')
        axes[0, col].set_title(title)
        axes[0, col].legend()
        axes[1, col].plot(r.s.t_js, np.rad2deg(r.s.q[:, 4]), color='#1f77b4')
        axes[1, col].set_xlabel('time [s]')
    axes[0, 0].set_ylabel('energy [J]')
    axes[1, 0].set_ylabel('q5 - q5d [deg]')
    _save(fig, path)


#: Table 4.5 with a delayed FRI (issue 29): (FRI delay [periods], D5 [Nms/rad]) per run. D5
#: 2.5 is our estimate of the LBR-IV's A5 damping (the rules read it), 0.5 a plant the sweep
#: ``config/sweeps/table_4_5_fri_delay.yaml`` finds unstable (shown, read by no rule).
_DELAY_RUNS = ((0, 2.5), (1, 2.5), (0, 0.5), (1, 0.5))


def _delay_overrides(delay, d5):
    """Scenario overrides: the no-PSPM Table 4.5 scenario with ``fri_delay`` and D5."""
    sim = _scenario_doc('thesis_4_5_stability_no_pspm.yaml')['sim']
    sim['fri_delay'] = delay
    sim['damping'][4] = d5
    return {'sim': sim}


def _check_4_5_delay(runs, quick):
    from experiments.table_4_5_fri_delay import oscillation

    ratio, rows = {}, []
    for delay, d5 in _DELAY_RUNS:
        r = runs[f'fri{delay}_D{d5}']
        osc = oscillation(r.s.t_js, r.s.qd[:, 4])
        ratio[f'fri{delay}_D{d5}'] = osc['ratio']
        rows.append(f'FRI delay {delay} period(s), D5 {d5} Nms/rad: max |qdot_5| '
                    f'{osc["push"]:.3g} rad/s after the push, {osc["late"]:.3g} in the last '
                    f'second, ratio {osc["ratio"]:.3g}')
    return Check({'ratio': ratio}, '; '.join(rows))


#: The Ch. 4 experiments, in report order.
CH4_EXPERIMENTS = (
    Experiment('table_4_1', 'Table 4.1', 'Constrained trajectory tracking into an obstacle: '
               'with 1b the static joint torques stay within +-5 Nm, with 3b the static force '
               'components within +-10 N; with 1a_3a neither (Fig. 4.14)',
               tuple(RunSpec(v, f'thesis_4_1_{v}.yaml', quick=5.0) for v in _V41) +
               tuple(_friction_spec(v) for v in _V41_FRICTION),
               _check_4_1, _fig_4_1),
    Experiment('table_4_2', 'Table 4.2', 'The virtual tool stays inside the bounding box while '
               'pushed; the physical one is pushed out by an amount set by K (Fig. 4.16)',
               (RunSpec('high_k', 'thesis_4_2_orientation_box_high_k.yaml', quick=4.5),
                RunSpec('low_k', 'thesis_4_2_orientation_box_low_k.yaml', quick=4.5)),
               _check_4_2, _fig_4_2),
    Experiment('table_4_3', 'Table 4.3', 'Pose held until the wrench bound is reached, '
               'returns when the push ends (Fig. 4.17)',
               (RunSpec('pose', 'thesis_4_3_pose_wrench_limits.yaml', quick=7.6),),
               _check_4_3, _fig_4_3),
    Experiment('table_4_4', 'Table 4.4', 'Pushed, the tool moves only along z_ee',
               (RunSpec('free_z', 'thesis_4_4_free_ee_z.yaml', quick=4.5),), _check_4_4,
               _fig_4_4),
    Experiment('table_4_5', 'Table 4.5', 'Joint-5 regulator (K = 200, k_p = 100, k_d = 0.8): '
               'energy injected without bound without PSPM, bounded (and the oscillation '
               'decays) with it (Fig. 4.18)',
               (RunSpec('no_pspm', 'thesis_4_5_stability_no_pspm.yaml', quick=6.0),
                RunSpec('pspm', 'thesis_4_5_stability_pspm.yaml', quick=6.0)),
               _check_4_5, _fig_4_5),
    Experiment('table_4_5_delay', 'Table 4.5 (FRI delay)', 'The Table 4.5 regulator without '
               'PSPM with a delayed FRI (sim.fri_delay): is the loop delay what makes the '
               "thesis' regulator unstable at our D5? (the sweep over delay x D5: "
               'docs/TABLE_4_5_FRI_DELAY.md)',
               tuple(RunSpec(f'fri{delay}_D{d5}', 'thesis_4_5_stability_no_pspm.yaml',
                             _delay_overrides(delay, d5), duration=8.0, quick=4.0)
                     for delay, d5 in _DELAY_RUNS),
               _check_4_5_delay, ours=True),
)
