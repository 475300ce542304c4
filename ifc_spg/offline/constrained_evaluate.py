"""Scenario evaluation of constrained manipulation.

    python -m ifc_spg.cli.constrained_evaluate

Runs the strategies in the lockstep simulator and prints a JSON report:

- ``comparison``: task-specification vs joint-compliance strategy, overall RMS |f_perp|
  on the 1.2 kg vertical drawer lifted 0.29 m, nine runs per strategy over the thesis grid
  K x kappa = {40, 100, 200} Nm/rad x {5, 10, 15} N/s (5.5.3; thesis 0.58 -> 0.17 N with
  a fixed true direction, 11.17 -> 1.54 N with the SMA estimator).
- ``mechanisms``: each strategy on the vertical drawer, the crank (quarter turn) and the
  microwave door (0.4 rad) from a 45 deg initial direction error.
- ``accrea``: the Cartesian-admittance strategy (5.3) on the ACCREA emulation (position
  based Cartesian admittance, wrist F/T) on the same three mechanisms, from a 45 deg
  initial error, each from its start pose of
  :func:`~ifc_spg.offline.constrained.initial_pose_deg`; success needs |f| <= 40 N.

Examples::

    python -m ifc_spg.cli.constrained_evaluate --only comparison
    python -m ifc_spg.cli.constrained_evaluate --only accrea
    python -m ifc_spg.cli.constrained_evaluate --quick      # shorter runs (CI smoke)
"""

from dataclasses import replace
import math

from ifc_spg.constrained.metrics import pooled_rms
from ifc_spg.constrained.params import EstimatorParams, StrategyParams
from ifc_spg.errors import ParameterError, did_you_mean
from ifc_spg.offline.constrained import Scenario, robot_with_stiffness, run
from ifc_spg.offline.sweep import map_unordered

__all__ = ['ACCREA_SCENES', 'KAPPAS', 'QUICK_COMPARISON', 'STIFFNESSES', 'THESIS_5_5_3',
           'accrea', 'comparison', 'mechanisms', 'reduction']

#: Estimator settings for the crank: the task-spec strategy moves the handle at ~1-2 cm/s,
#: close to the thesis dead band of 1 cm/s, so the dead band and window are reduced.
CRANK_ESTIMATOR = EstimatorParams(window=250, v_threshold=0.003, w0=0.003)


def reduction(before, after):
    """Relative reduction (before - after) / before in [%]."""
    return 100.0 * (before - after) / before if before > 0 else float('nan')


#: The thesis' parameter grid of 5.5.3 (Figs. 5.16/5.17): each strategy runs once per
#: (K [Nm/rad], kappa [N/s]) pair, nine runs.
STIFFNESSES = (40.0, 100.0, 200.0)
KAPPAS = (5.0, 10.0, 15.0)
#: The thesis' "overall RMS" result, (joint compliance [N], task specification [N],
#: reduction [%]).
THESIS_5_5_3 = {'fixed_direction': (0.58, 0.17, 70.0), 'sma_estimator': (11.17, 1.54, 86.0)}
#: Short comparison for the tests and ``--quick``: one (K, kappa) pair of the grid (the
#: fastest lift), the full travel.
QUICK_COMPARISON = {'stiffnesses': (40.0,), 'kappas': (15.0,), 'travel': 0.29, 'duration': 25.0}
_KEEP = ('rms_f_perp', 'rms_fs_perp', 'rms_fd_perp', 'max_f_perp', 'travel', 'time_to_open',
         'rms_error_angle_deg', 'samples')


def _grid_run(job):
    """One run of the grid (a worker task): the metrics of :data:`_KEEP`."""
    (strategy, k, kappa, fixed, initial_error_deg, travel, duration, estimator,
     damping_scale) = job
    params = StrategyParams(stiffness=k, kappa=kappa, estimator=estimator or EstimatorParams())
    scenario = Scenario(strategy=strategy, scene='drawer_vertical', params=params,
                        fixed_direction=fixed, initial_error_deg=initial_error_deg,
                        target=travel, duration=duration)
    if damping_scale != 1.0:    # the plant's IFC damping at this K, scaled
        damping = robot_with_stiffness(scenario.robot, k).damping * damping_scale
        scenario = replace(scenario, sim={**scenario.sim, 'damping': damping.tolist()})
    log = run(scenario)
    return {key: log.metrics.get(key) for key in _KEEP}


def _grid_runs(stiffnesses, kappas, fixed, initial_error_deg, travel, duration, workers=1,
               estimator=None, damping_scale=1.0):
    """Both strategies once per (K, kappa) on the vertical drawer: one row each.

    With ``workers`` > 1 the runs go to a local Dask cluster of as many worker processes
    (:func:`ifc_spg.offline.sweep.map_unordered`; each run is deterministic, so the rows
    are the same).
    """
    jobs = [(strategy, float(k), float(kappa), fixed, initial_error_deg, travel, duration,
             estimator, float(damping_scale))
            for k in stiffnesses for kappa in kappas
            for strategy in ('joint_compliance', 'task_specification')]
    results = [None] * len(jobs)
    for i, res in map_unordered(_grid_run, jobs,
                                workers=workers if workers > 1 and len(jobs) > 1 else 1):
        results[i] = res
    rows = []
    for i in range(0, len(jobs), 2):
        _, k, kappa, *_ = jobs[i]
        rows.append({'stiffness': k, 'kappa': kappa, 'joint_compliance': results[i],
                     'task_specification': results[i + 1]})
    return rows


def comparison(stiffnesses=STIFFNESSES, kappas=KAPPAS, travel=0.29, duration=80.0,
               sma_initial_error_deg=0.0, cases=('fixed_direction', 'sma_estimator'),
               workers=1, estimator=None, damping_scale=1.0):
    """The thesis comparison (5.5.3) on the 1.2 kg vertical drawer; a dict of metrics.

    Both strategies lift the drawer ``travel`` (the thesis: 0.3 m) once per (K, kappa) of the
    grid, with a fixed d_hat = the true initial direction (``fixed_direction``) and with the
    SMA estimator (``sma_estimator``) seeded ``sma_initial_error_deg`` from it (5.5.3 names
    no initial error; its induced d_hat "corresponds basically to the real direction").
    |f_perp| is the measured interaction force (ground truth at the grasp) orthogonal to the
    true motion direction from 10 ms after the start until the drawer is open (or
    ``duration`` ends); the static force f_s of the set-point deflection is reported too.

    Args:
        stiffnesses: Joint stiffnesses K [Nm/rad] of the grid.
        kappas: Exploration rates kappa [N/s] of the grid.
        travel: Lift [m] that ends a run.
        duration: Longest run [s] (the task-specification strategy is slow at high K).
        sma_initial_error_deg: Initial error of the SMA estimator [deg].
        cases: Subset of ``('fixed_direction', 'sma_estimator')``.
        workers: Processes for the runs (1: in this process; the results do not depend
            on it).
        estimator: The :class:`~ifc_spg.constrained.params.EstimatorParams` of every run
            (None: the defaults, Sec. 5.4.3's N = 500 and v_th = 0.01 m/s).
        damping_scale: Factor on the plant's IFC joint damping D (the robot's, scaled to
            each run's K by :func:`~ifc_spg.offline.constrained.robot_with_stiffness`);
            1: the robot's own. The thesis gives no D (a cause ablation, not the setup).

    Returns:
        Per case: ``runs`` (one row per (K, kappa): both strategies' metrics),
        ``rms_f_perp_jc_to_ts`` (overall RMS, :func:`~ifc_spg.constrained.metrics.
        pooled_rms`, [N]), ``reduction_percent``, the same for f_s (``rms_fs_perp_jc_to_ts``,
        ``static_reduction_percent``), ``opened`` (runs that reached ``travel``); and
        ``thesis``.
    """
    if not damping_scale > 0:
        raise ParameterError(f'damping_scale must be > 0, got {damping_scale!r}')
    out = {}
    for label in cases:
        if label not in THESIS_5_5_3:
            raise ParameterError(f"unknown comparison case '{label}'"
                                 f"{did_you_mean(label, THESIS_5_5_3)}; cases: "
                                 f"{', '.join(THESIS_5_5_3)}")
        fixed = label == 'fixed_direction'
        rows = _grid_runs(stiffnesses, kappas, fixed, sma_initial_error_deg, travel, duration,
                          workers, estimator, damping_scale)
        res = {'runs': rows, 'travel_target': travel, 'duration': duration,
               'damping_scale': damping_scale}
        if not fixed:
            res['initial_error_deg'] = sma_initial_error_deg
        for key, name, red in (('rms_f_perp', 'rms_f_perp_jc_to_ts', 'reduction_percent'),
                               ('rms_fs_perp', 'rms_fs_perp_jc_to_ts',
                                'static_reduction_percent')):
            jc = pooled_rms([r['joint_compliance'] for r in rows], key)
            ts = pooled_rms([r['task_specification'] for r in rows], key)
            res[name] = [jc, ts]
            res[red] = reduction(jc, ts)
        # the plant's damping force -D qdot through J^{+T}, orthogonal to the motion: the
        # part of the measured force the static models of both strategies do not see
        res['rms_fd_perp_jc_to_ts'] = [
            pooled_rms([r[strategy] for r in rows], 'rms_fd_perp')
            for strategy in ('joint_compliance', 'task_specification')]
        res['opened'] = {s: sum(r[s]['time_to_open'] is not None for r in rows)
                         for s in ('joint_compliance', 'task_specification')}
        out[label] = res
    out['thesis'] = {k: list(v) for k, v in THESIS_5_5_3.items()}
    return out


def mechanisms(duration=30.0):
    """Each joint-level strategy (and the admittance strategy on the LBR) on three scenes."""
    out = {}
    scenes: tuple[tuple[str, float, dict[str, str], EstimatorParams | None], ...] = (
              ('drawer_vertical', 0.29, {}, None),
              ('crank', math.pi / 2, {'grasp': 'connect'}, CRANK_ESTIMATOR),
              ('microwave_door', 0.4, {'grasp': 'connect'}, None))
    for scene, target, options, est in scenes:
        for strategy in ('admittance', 'joint_compliance', 'task_specification'):
            params = StrategyParams(orientation='free' if scene == 'crank' else 'fixed')
            if est is not None:
                params = StrategyParams(orientation=params.orientation, estimator=est)
            log = run(Scenario(strategy=strategy, scene=scene, params=params, target=target,
                               duration=duration, scene_options=options))
            out[f'{scene}/{strategy}'] = log.metrics
    return out


#: ACCREA cases: (scene, target travel [m or rad], scene options).
ACCREA_SCENES: tuple[tuple[str, float, dict[str, str]], ...] = (('drawer_vertical', 0.29, {}),
                 ('crank', math.pi / 2, {'grasp': 'connect'}),
                 ('microwave_door', 0.4, {'grasp': 'connect'}))


def accrea(duration=20.0, force_limit=40.0):
    """The admittance strategy on the ACCREA on :data:`ACCREA_SCENES`; dict of metrics."""
    out = {}
    for scene, target, options in ACCREA_SCENES:
        log = run(Scenario(strategy='admittance', robot='accrea_dual_arm', scene=scene,
                           target=target, duration=duration, scene_options=options,
                           force_limit=force_limit))
        m = dict(log.metrics)
        m['max_ik_residual'] = float(max(log.ik_residual))
        out[scene] = m
    return out
