"""The metrics of an offline lockstep run (``DIR/metrics.json`` of ``ifc-spg run``).

:class:`MetricsRecorder` is fed once per SPG tick (:meth:`MetricsRecorder.on_tick`) and
writes the report at the end (:meth:`MetricsRecorder.report`); the metric names and their
options are those of the scenario file (see :mod:`ifc_spg.offline.runner`).
"""

import numpy as np

from ifc_spg.errors import ParameterError

__all__ = ['FORCE_AXES', 'MetricsRecorder', 'band_error']

#: The components of a wrench, as ``force_error_rms: {axis: ...}`` names them.
FORCE_AXES = ('fx', 'fy', 'fz', 'tx', 'ty', 'tz')


def band_error(value, lower, upper):
    """Distance of ``value`` to the band [lower, upper] per component (0 inside)."""
    v, lo, hi = (np.asarray(x, dtype=float) for x in (value, lower, upper))
    with np.errstate(invalid='ignore'):
        return np.where(v < lo, lo - v, np.where(v > hi, v - hi, 0.0))


def _rms(x):
    return float(np.sqrt(np.mean(np.square(x)))) if len(x) else None


def _norm_or_none(value, lower, upper, comps=slice(None)):
    """The norm of the band error over ``comps``; None for a missing ``value``."""
    if value is None:
        return None
    return float(np.linalg.norm(band_error(value, lower, upper)[comps]))


class MetricsRecorder:
    """Collects a run's samples tick by tick and turns them into the metrics report.

    Args:
        scenario: The :class:`~ifc_spg.offline.runner.Scenario` (its ``metrics`` options,
            name, robot, scene and dt go into the report).
        robot: The RobotModel the SPG runs with (position and velocity limits).

    Raises:
        ParameterError: ``force_error_rms`` names an axis that is not one of
            :data:`FORCE_AXES`.
    """

    def __init__(self, scenario, robot):
        self.scenario = scenario
        self.robot = robot
        self.force_norms, self.tank_minima, self.tick_times = [], [], []
        self.violations = 0
        self.force_errors, self.task_errors = [], {}
        self.last_tasks = []
        self.geom_contacts = []  # (t, count, normal force, distance) per tick (geom_contact)
        self._force_opt = scenario.metrics.get('force_error_rms')
        self._task_opt = scenario.metrics.get('task_error_rms')
        self._axis = None
        if self._force_opt is not None:
            axis = self._force_opt.get('axis', 'fz')
            if axis not in FORCE_AXES:
                raise ParameterError(f"metric force_error_rms: axis '{axis}' not one of "
                                     f"{', '.join(FORCE_AXES)}")
            self._axis = FORCE_AXES.index(axis)
        topt = self._task_opt
        self._comps = slice(None) if topt is None or topt.get('components') is None else \
            np.asarray(topt['components'], dtype=int)

    def on_tick(self, t, contact_wrench, command, info, tasks):
        """Record one tick.

        Args:
            t: Sim time of the joint state [s].
            contact_wrench: The simulated contact wrench (6,) [N, Nm] on the robot.
            command: The SPG's command (``position``, ``velocity``).
            info: The SPG's ``SpgInfo`` of the tick (tank energy, tick time).
            tasks: The task values of the tick (``_TaskProbe.evaluate``).
        """
        robot = self.robot
        self.last_tasks = tasks
        self.force_norms.append(float(np.linalg.norm(contact_wrench[:3])))
        if info.tank_energy is not None:
            self.tank_minima.append(float(np.min(info.tank_energy)))
        self.violations += int(np.sum(
            (command.position < robot.q_min - 1e-9) | (command.position > robot.q_max + 1e-9) |
            (np.abs(command.velocity) > robot.v_max * (1 + 1e-6) + 1e-12)))
        self.tick_times.append(info.tick_time or 0.0)
        fopt = self._force_opt
        if fopt is not None and t >= fopt.get('after', 0.0) - 1e-9:
            f = -contact_wrench[self._axis]
            self.force_errors.append(f - float(fopt.get('target', 0.0)))
        topt = self._task_opt
        if topt is not None and t >= topt.get('after', 0.0) - 1e-9:
            for task in tasks:
                if task['name'] == topt.get('task'):
                    self._task_error(task)

    def on_geom_contact(self, t, count, force, distance):
        """Record one tick's contacts of the ``geom_contact`` metric.

        Args:
            t: Sim time of the joint state [s].
            count: MuJoCo contacts between the two geom sets.
            force: The sum of their normal forces [N].
            distance: The smallest signed distance between the sets [m] (capped).
        """
        self.geom_contacts.append((float(t), int(count), float(force), float(distance)))

    def _task_error(self, task):
        lower, upper = task['lower'], task['upper']
        self.task_errors.setdefault('virtual', []).append(
            _norm_or_none(task['value'], lower, upper, self._comps))
        physical = _norm_or_none(task['physical'], lower, upper, self._comps)
        if physical is not None:
            self.task_errors.setdefault('physical', []).append(physical)

    def report(self, ticks, wall, missed, warnings, runner):
        """The metrics dict (``metrics.json``), keys in a fixed order.

        Args:
            ticks: SPG ticks run.
            wall: Wall-clock time of the run [s].
            missed: Command periods the simulation had no command for.
            warnings: MuJoCo's warnings ``{name: count}``.
            runner: The :class:`~ifc_spg.node.core.SpgRunner` (PSPM tanks, rejections).
        """
        sc = self.scenario
        duration = ticks * sc.dt
        out = {'scenario': sc.name, 'robot': sc.robot, 'scene': sc.scene,
               'duration_s': duration, 'ticks': ticks, 'wall_time_s': wall,
               'real_time_factor': duration / wall if wall > 0 else None,
               'mujoco_warnings': warnings}
        self._basic(out, missed)
        if 'force_error_rms' in sc.metrics:
            self._force_report(out)
        if 'task_error_rms' in sc.metrics:
            out['task_error_rms'] = {k: _rms(v) for k, v in self.task_errors.items()}
            out['task_error_rms_options'] = sc.metrics['task_error_rms']
        if 'geom_contact' in sc.metrics:
            out['geom_contact'] = self._geom_contact_report(sc.metrics['geom_contact'])
        if runner.spg.tanks is not None:
            out['pspm'] = _pspm_report(runner, duration)
        out['spg'] = {'rejected': dict(runner.rejected), 'errors': list(runner.errors)}
        return out

    def _basic(self, out, missed):
        """The default metrics the scenario asks for, into ``out``."""
        metrics = self.scenario.metrics
        if 'final_task_errors' in metrics:
            out['final_task_errors'] = {
                t['name']: {'virtual': _norm_or_none(t['value'], t['lower'], t['upper']),
                            'physical': _norm_or_none(t['physical'], t['lower'], t['upper'])}
                for t in self.last_tasks}
        if 'max_contact_force' in metrics:
            out['max_contact_force_n'] = max(self.force_norms) if self.force_norms else 0.0
        if 'tank_energy_min' in metrics:
            out['tank_energy_min_j'] = min(self.tank_minima) if self.tank_minima else None
        if 'limit_violations' in metrics:
            out['limit_violations'] = self.violations
        if 'tick_time' in metrics:
            tt = np.array(self.tick_times) * 1e3
            out['tick_time_ms'] = {'p50': float(np.percentile(tt, 50)),
                                   'p99': float(np.percentile(tt, 99)), 'max': float(tt.max())}
        if 'missed_ticks' in metrics:
            out['missed_ticks'] = int(missed)

    def _force_report(self, out):
        opt = self.scenario.metrics['force_error_rms']
        errors = self.force_errors
        out['force_error_rms_n'] = _rms(errors)
        window = round(float(opt.get('window', 0.0)) / self.scenario.dt)
        if window > 1 and len(errors) >= window:
            smooth = np.convolve(errors, np.ones(window) / window, mode='valid')
            out['force_error_rms_filtered_n'] = _rms(smooth)
        out['force_error_rms_options'] = opt


    def _geom_contact_report(self, opt):
        """The ``geom_contact`` metric over the ticks from ``after`` [s] on."""
        rows = np.array(self.geom_contacts, dtype=float).reshape(-1, 4)
        rows = rows[rows[:, 0] >= float(opt.get('after', 0.0)) - 1e-9]
        t, count, force, dist = rows.T
        out = {'geoms': list(opt['geoms']), 'with': list(opt['with']),
               'after': float(opt.get('after', 0.0)), 'ticks': len(rows),
               'ticks_in_contact': int(np.count_nonzero(count)),
               'contacts': int(count.sum()),
               'max_normal_force_n': float(force.max()) if len(rows) else 0.0,
               'mean_normal_force_n': float(force.mean()) if len(rows) else 0.0,
               'impulse_ns': float(force.sum() * self.scenario.dt),
               'min_distance_m': float(dist.min()) if len(rows) else None}
        if opt.get('series'):
            out['series'] = {'t': t.round(6).tolist(), 'normal_force_n': force.round(4).tolist(),
                             'distance_m': dist.round(6).tolist()}
        return out


def _pspm_report(runner, duration):
    """Energy the power budget put into the tanks (this session), and the stalls."""
    tanks = runner.spg.tanks
    refilled = float(tanks.refilled.sum())
    return {'power_budget_w': tanks.power, 'max_power_w': tanks.config.max_power,
            'refilled_j': refilled,
            'refilled_per_minute_j': refilled * 60.0 / duration if duration > 0 else None,
            'tank_energy_start_j': float(tanks.config.initial_energy *
                                         np.count_nonzero(tanks.mask)),
            'tank_energy_end_j': float(tanks.energy.sum()),
            'stalls': runner.pspm_stalls,
            'stall': runner.spg.info.pspm['stall'],
            'last_stall_message': runner.last_stall or None}
