"""Offline lockstep runs of a scenario: bridge + SPG in one process, no DDS (``ifc-spg run``).

    ifc-spg run config/scenarios/demo_lbr.yaml -o out/demo [--duration S] [--quiet]

Each SPG tick: the simulation's state at the period's start becomes the ``joint_states``
message (stamp = sim time), the SPG (:class:`~ifc_spg.node.core.SpgRunner`, the live node's
logic) answers with ``command/joint_position`` (same stamp), the simulation holds that q_v
for one command period — from this period on, or with ``sim: {fri_delay: n}`` (the LBR FRI
emulation's loop delay, :mod:`sim_bridge.simulation`) from n periods later. The bag in
``DIR/bag`` has the topics a live run records, with the same types, QoS and header stamps
(log time = sim time): ``joint_states``, ``command/joint_position``, ``spg/task_stack``,
``spg/status``, ``sim/contact_wrench``, ``ft_sensor/wrench`` (robots with wrist sensors),
``sim/env_joint_states`` (scenes with mechanisms) and ``sim/apply_wrench`` (the scenario's
pushes), and what Foxglove draws the robot from:
``robot_description``, ``tf_static``, ``tf`` (measured q and, as ``virtual/...``, q_v, every
10 ms) and ``spg/markers`` (the Cartesian task targets and force arrows, at the SPG
configuration's ``markers.rate`` as the live node publishes them, 30 Hz by default), see
:mod:`ifc_spg.offline.foxglove`. Everything that sets the SPG's output besides
the recorded joint states and task stacks is stored in the bag, each as JSON in the
metadata's ``custom_data`` (``metadata.yaml``) and in the first ``spg/status`` message: the
SPG configuration (``ifc_spg.node.config`` / ``config``: dt, solver, rho, torque_limits, PSPM,
watchdog) and the robot parameters the SPG ran with (``ifc_spg.robot_params`` /
``robot_params``: K and D after the scenario's ``sim: {stiffness, damping}``, and the limits),
so ``ifc-spg replay`` recomputes every command. ``DIR/metrics.json`` holds the metrics.

A scenario file (YAML)::

    name: surface_tracking_short
    robot: lbr_iiwa14            # RobotModel.from_config name
    interface: lbr_fri           # optional (implied by the robot)
    scene: table                 # sim_bridge scene, options in scene_options
    scene_options: {gap: 0.01}
    q0_deg: [0, 30, 0, -60, 0, 90, 0]     # or q0 [rad]; default: home
    dt: 0.002                    # SPG / command period [s]
    timestep: 0.001              # physics step [s]
    spg: {solver: daqp, pspm: true, status_decimation: 1}   # SpgConfig fields, or
                                 #  {params_file: lbr_iiwa14.yaml, ...}: a spg_node params
                                 #  file (in config/), then the overrides given next to it
    duration: 5.0                # [s] of sim time
    stacks:                      # task-stack sequence: file (relative to this file or
      - {at: 0.0, file: surface_tracking.yaml}          #  config/tasks/) or inline stack
      - {at: 3.0, stack: {version: 1, name: hold, tasks: [...]}}
    pushes:
      - {at: 2.0, target: tool, wrench: [0, 0, -10, 0, 0, 0], duration: 0.2}
    metrics:                     # names, or {name: options}; default: the basic set
      - final_task_errors
      - force_error_rms: {axis: fz, target: 8.0, after: 2.0}
      - task_error_rms: {task: circle, after: 2.0}
    progress: 10                 # print a progress line every N % (0: none)
    sim: {joint_damping: 0.1}    # bridge overrides: joint_damping, frictionloss, armature,
                                 #  contact_chain; stiffness K / damping D of the IFC
                                 #  (scalar or per joint; used by the bridge AND the SPG);
                                 #  fri_delay: FRI loop delay in whole periods (int >= 0,
                                 #  lbr_fri only; 0, the default: the command acts in the
                                 #  period it answers, n: n periods later)

Metrics: ``final_task_errors`` (per task of the last stack: distance of the value at the
measured q, and of the virtual value, to the bounds), ``max_contact_force`` [N],
``tank_energy_min`` [J], ``limit_violations`` (ticks x joints with q_v outside the
position limits or |qdot_v| above the velocity limit), ``tick_time`` (p50/p99/max [ms]),
``missed_ticks`` (command periods without a command), ``force_error_rms`` [N] (force the
robot exerts along a base axis, from ``sim/contact_wrench``, vs a target; with ``window``
[s] also after a moving average), ``task_error_rms`` (a task's measured and virtual
distance to its bounds, over ``components`` (indices) if given), ``geom_contact``
(``{geoms: [...], with: [...], after: s, series: false}``: MuJoCo contacts between two sets
of geoms of the simulation, per tick at the state the SPG reads: ticks in contact, contacts,
max and mean normal force [N], impulse [Ns], smallest signed distance [m]
(``mj_geomDistance``, capped at 0.2 m); with ``series`` the per-tick values).
"""

from collections.abc import Mapping
import dataclasses
import json
import math
import os
from pathlib import Path
import signal
import sys
import threading
import time
from typing import Any, TextIO

import numpy as np
import yaml

from ifc_spg.errors import IfcSpgError, ParameterError, did_you_mean
from ifc_spg.kinematics import Kinematics
from ifc_spg.model import RobotModel
from ifc_spg.node.config import PARAMETERS, SpgConfig, config_from_parameters
from ifc_spg.node.core import SpgRunner, parse_task_stack, robot_params, status_json
from ifc_spg.node.markers import wrench_arrows
from ifc_spg.offline.bag import TOPICS, BagWriter
from ifc_spg.offline.foxglove import FoxgloveTopics, cartesian_targets
from ifc_spg.offline.metrics import MetricsRecorder, band_error
from ifc_spg.ros import messages as m
from ifc_spg.tasks.subspace import subspace_in_base
from sim_bridge.interface import check_fri_delay

__all__ = [
    'CONFIG_KEY',
    'ROBOT_PARAMS_KEY',
    'STACK_SINCE_KEY',
    'RunResult',
    'Scenario',
    'StopRequest',
    'band_error',
    'find_config_dir',
    'load_scenario',
    'robot_with_ifc',
    'run_scenario',
]

CONFIG_KEY = 'ifc_spg.node.config'
ROBOT_PARAMS_KEY = 'ifc_spg.robot_params'
SCENARIO_KEY = 'ifc_spg.scenario'
STACK_SINCE_KEY = 'since'
_SCENARIO_KEYS = ('name', 'description', 'robot', 'interface', 'scene', 'scene_options', 'q0',
                  'q0_deg', 'dt', 'timestep', 'spg', 'duration', 'stacks', 'pushes', 'metrics',
                  'progress', 'sim')
_DEFAULT_METRICS = ('final_task_errors', 'max_contact_force', 'tank_energy_min',
                    'limit_violations', 'tick_time', 'missed_ticks')
_METRICS = _DEFAULT_METRICS + ('force_error_rms', 'task_error_rms', 'geom_contact')
_SIM_KEYS = ('joint_damping', 'frictionloss', 'armature', 'contact_chain', 'stiffness',
             'damping', 'fri_delay')


def find_config_dir() -> Path:
    """The ``config/`` directory: the source tree's, else the installed share dir."""
    here = Path(__file__).resolve().parents[2] / 'config'
    if here.is_dir():
        return here
    return Path(sys.prefix) / 'share' / 'ifc_spg' / 'config'


@dataclasses.dataclass(frozen=True)
class StackEntry:
    """One task stack of the sequence: its text, from when [s], and where it came from."""

    at: float
    text: str
    source: str


@dataclasses.dataclass(frozen=True)
class Push:
    """A person-like push: ``wrench`` [N, Nm] (base frame) on ``target`` from ``at`` [s]."""

    at: float
    target: str
    wrench: tuple[float, ...]
    duration: float


@dataclasses.dataclass(frozen=True)
class Scenario:
    """A validated scenario (see the module docstring for the file format)."""

    name: str
    robot: str
    interface: str | None  # None: the robot's own
    scene: str
    scene_options: dict[str, Any]  # YAML options of the scene
    q0: tuple[float, ...] | None
    dt: float
    timestep: float
    spg: SpgConfig
    duration: float
    stacks: tuple[StackEntry, ...]
    pushes: tuple[Push, ...]
    metrics: dict[str, dict[str, Any]]  # metric name -> its YAML options
    progress: float
    sim: dict[str, Any]  # YAML overrides of the simulation
    description: str = ''
    path: str = ''


def _err(where, message):
    return ParameterError(f'{where}: {message}')


def _number(value, what, where, low=None, positive=False):
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise _err(where, f'{what} must be a number, got {value!r}')
    if positive and not value > 0:
        raise _err(where, f'{what} must be > 0, got {value!r}')
    if low is not None and value < low:
        raise _err(where, f'{what} must be >= {low}, got {value!r}')
    return float(value)


def _stack_text(entry, i, base, where):
    item = f'{where}: stacks[{i}]'
    if not isinstance(entry, dict):
        raise ParameterError(f'{item}: expected a mapping {{at: SECONDS, file: PATH}} or '
                             f'{{at: SECONDS, stack: {{...}}}}, got {entry!r}')
    unknown = [k for k in entry if k not in ('at', 'file', 'stack')]
    if unknown:
        raise ParameterError(f"{item}: unknown key '{unknown[0]}'"
                             f"{did_you_mean(unknown[0], ('at', 'file', 'stack'))}; keys: at, "
                             'file, stack')
    at = _number(entry.get('at', 0.0), 'at', item, low=0.0)
    if ('file' in entry) == ('stack' in entry):
        raise ParameterError(f"{item}: give exactly one of 'file' (a task-stack file) or "
                             "'stack' (an inline stack)")
    if 'file' in entry:
        name = str(entry['file'])
        candidates = [Path(name)] if os.path.isabs(name) else [
            base / name, find_config_dir() / 'tasks' / name]
        path = next((p for p in candidates if p.is_file()), None)
        if path is None:
            raise ParameterError(f"{item}: task-stack file '{name}' not found; looked in "
                                 f"{', '.join(str(p) for p in candidates)}")
        text, source = path.read_text(encoding='utf8'), str(path)
    else:
        text, source = json.dumps(entry['stack']), f'{where}:stacks[{i}]'
    parse_task_stack(text, source=source)  # validate now: errors name the file and field
    return StackEntry(at, text, source)


def params_file_values(path):
    """``{ROS parameter name: value}`` of a ``spg_node`` params file.

    The file is ``config/<robot>.yaml``: ``/**: ros__parameters:`` with nested groups. The
    result has no robot, dt and watchdog.timeout (a scenario sets those; offline there is no
    wall-clock watchdog).

    Args:
        path: The params file (relative ones are also looked for in ``config/``).

    Raises:
        ParameterError: The file is missing or not a params file.
    """
    path = Path(path)
    if not path.is_absolute() and not path.is_file():
        path = find_config_dir() / path
    try:
        doc = yaml.safe_load(path.read_text(encoding='utf8'))
        params = next(iter(doc.values()))['ros__parameters']
    except (OSError, yaml.YAMLError, AttributeError, KeyError, TypeError,
            StopIteration) as exc:
        raise ParameterError(f"params file '{path}': not a spg_node params file ({exc}); "
                             'expected /**: {ros__parameters: {...}}') from None
    out = {}

    def flat(prefix, d):
        for k, v in d.items():
            if isinstance(v, dict):
                flat(f'{prefix}{k}.', v)
            else:
                out[prefix + k] = v
    flat('', params)
    for key in ('robot', 'dt', 'watchdog.timeout'):
        out.pop(key, None)
    return out


def _spg_config(spec: Mapping[str, Any] | None, robot: str, dt: float,
                where: str) -> SpgConfig:
    spec = dict(spec or {})
    fields = {p.field: p.name for p in PARAMETERS}
    values = {'robot': robot, 'dt': dt}
    if 'params_file' in spec:  # the shipped node parameters, then the scenario's overrides
        values.update(params_file_values(spec.pop('params_file')))
    for key, value in spec.items():
        name = fields.get(key, key)
        if key == 'pspm' and isinstance(value, dict):
            for k, v in value.items():
                values[f'pspm.{k}'] = v
            continue
        if key == 'pspm':
            name = 'pspm.enabled'
        values[name] = value
    values.setdefault('status.decimation', 1)
    values.setdefault('watchdog.timeout', 0.0)  # offline: no wall clock, no watchdog
    try:
        return config_from_parameters(values)
    except ParameterError as exc:
        raise _err(f'{where}: spg', str(exc)) from None


def _metrics(spec, where):
    if spec is None:
        return {m: {} for m in _DEFAULT_METRICS}
    out = {}
    for item in spec:
        name, opts = (item, {}) if isinstance(item, str) else (
            next(iter(item)), item[next(iter(item))] or {}) if isinstance(item, dict) and \
            len(item) == 1 else (None, None)
        if name not in _METRICS:
            raise _err(where, f"unknown metric {name!r}{did_you_mean(str(name), _METRICS)}; "
                       f"metrics: {', '.join(_METRICS)}")
        out[name] = dict(opts or {})  # (a None opts raised above)
    gc = out.get('geom_contact')
    if gc is not None:
        for key in ('geoms', 'with'):
            names = gc.get(key)
            if not (isinstance(names, list) and names and
                    all(isinstance(x, str) for x in names)):
                raise _err(where, f'metric geom_contact: {key} must be a list of geom names, '
                           f'got {names!r}')
    return out


def load_scenario(path: str | Path, overrides: Mapping[str, Any] | None = None) -> Scenario:
    """Read and validate a scenario file.

    Args:
        path: YAML file.
        overrides: Keys replacing the file's (e.g. ``{'duration': 2.0}``).

    Raises:
        ParameterError: A bad key or value (naming the file, the key and the fix);
            ``TaskStackError`` for a bad stack.
    """
    path = Path(path)
    if not path.is_file():
        alt = find_config_dir() / 'scenarios' / path.name
        if alt.is_file():
            path = alt
        else:
            raise ParameterError(f"scenario file '{path}' not found (also looked for {alt})")
    try:
        data = yaml.safe_load(path.read_text(encoding='utf8'))
    except yaml.YAMLError as exc:
        raise ParameterError(f"scenario '{path}': not valid YAML: {exc}") from None
    if not isinstance(data, dict):
        raise ParameterError(f"scenario '{path}': expected a mapping of keys, got "
                             f'{type(data).__name__}')
    data.update(overrides or {})
    return scenario_from_dict(data, where=str(path), base=path.parent)


def _q0(data, robot, where):
    """The initial configuration [rad] of ``q0`` or ``q0_deg`` (None: the robot's home)."""
    if 'q0' in data and 'q0_deg' in data:
        raise _err(where, "give 'q0' [rad] or 'q0_deg' [deg], not both")
    if data.get('q0') is None and data.get('q0_deg') is None:
        return None
    raw = data.get('q0') if data.get('q0') is not None else data['q0_deg']
    q0 = np.asarray(raw, dtype=float).reshape(-1)
    if 'q0_deg' in data:
        q0 = np.deg2rad(q0)
    if q0.shape != (robot.n,):
        raise _err(where, f'q0 needs {robot.n} values ({", ".join(robot.joint_names)}), '
                   f'got {q0.size}')
    return tuple(float(x) for x in q0)


def _push(p, item):
    """One validated ``pushes`` entry; ``item`` names it in errors."""
    if not isinstance(p, dict) or 'wrench' not in p:
        raise ParameterError(f'{item}: expected {{at, target, wrench: [fx, fy, fz, tx, ty, '
                             f'tz], duration}}, got {p!r}')
    bad = [k for k in p if k not in ('at', 'target', 'wrench', 'duration')]
    if bad:
        raise ParameterError(f"{item}: unknown key '{bad[0]}'; keys: at, target, wrench, "
                             'duration')
    w = np.asarray(p['wrench'], dtype=float).reshape(-1)
    if w.shape != (6,) or not np.all(np.isfinite(w)):
        raise ParameterError(f'{item}: wrench needs 6 finite numbers [N, Nm], got '
                             f"{p['wrench']!r}")
    return Push(_number(p.get('at', 0.0), 'at', item, low=0.0), str(p.get('target', '')),
                tuple(w.tolist()), _number(p.get('duration', 0.5), 'duration', item,
                                           positive=True))


def scenario_from_dict(data: Mapping[str, Any], where: str = 'scenario',
                       base: Path = Path('.')) -> Scenario:
    """Validate a scenario mapping (the parsed file); see :func:`load_scenario`."""
    unknown = [k for k in data if k not in _SCENARIO_KEYS]
    if unknown:
        raise _err(where, f"unknown key '{unknown[0]}'{did_you_mean(unknown[0], _SCENARIO_KEYS)}"
                   f"; keys: {', '.join(_SCENARIO_KEYS)}")
    robot_name = data.get('robot', 'lbr_iiwa14')
    robot = RobotModel.from_config(robot_name)
    dt = _number(data.get('dt', 0.002), 'dt', where, positive=True)
    timestep = _number(data.get('timestep', 0.001), 'timestep', where, positive=True)
    duration = _number(data.get('duration', 5.0), 'duration', where, positive=True)
    q0 = _q0(data, robot, where)
    stacks = data.get('stacks') or []
    if not isinstance(stacks, list):
        raise _err(where, "'stacks' must be a list of {at, file|stack} entries")
    entries = tuple(sorted((_stack_text(e, i, base, where) for i, e in enumerate(stacks)),
                           key=lambda e: e.at))
    pushes = [_push(p, f'{where}: pushes[{i}]') for i, p in enumerate(data.get('pushes') or [])]
    sim = dict(data.get('sim') or {})
    bad = [k for k in sim if k not in _SIM_KEYS]
    if bad:
        raise _err(where, f"sim: unknown key '{bad[0]}'{did_you_mean(bad[0], _SIM_KEYS)}; keys: "
                   f"{', '.join(_SIM_KEYS)}")
    if 'fri_delay' in sim:
        sim['fri_delay'] = check_fri_delay(sim['fri_delay'], f'{where}: sim.fri_delay')
    return Scenario(
        name=str(data.get('name') or Path(where).stem), robot=robot_name,
        interface=data.get('interface'), scene=str(data.get('scene', 'free')),
        scene_options=dict(data.get('scene_options') or {}), q0=q0, dt=dt, timestep=timestep,
        spg=_spg_config(data.get('spg'), robot_name, dt, where), duration=duration,
        stacks=entries, pushes=tuple(sorted(pushes, key=lambda p: p.at)),
        metrics=_metrics(data.get('metrics'), where),
        progress=_number(data.get('progress', 10), 'progress', where, low=0.0), sim=sim,
        description=str(data.get('description') or ''), path=where)


# -- the run ------------------------------------------------------------------------------

def _stamp(t):
    """Sim time [s] -> (sec, nanosec) as the bridge stamps it."""
    sec = math.floor(t)
    nsec = round((t - sec) * 1e9)
    if nsec >= 1_000_000_000:
        sec, nsec = sec + 1, nsec - 1_000_000_000
    return sec, nsec


class _TaskProbe:
    """Task values at the virtual and the measured configuration, for status and metrics."""

    def __init__(self, robot):
        self.robot = robot
        self.kin_v = Kinematics(robot)
        self.kin_m = Kinematics(robot)

    def evaluate(self, tasks, q, qdot, q_v, task_time, contact_wrench, contact_chain):
        self.kin_v.update(q, qdot, q_v)
        self.kin_m.update(q, qdot, q)
        out = []
        for task in tasks:
            if not task.active:
                continue
            value = np.asarray(task.compute_value(self.kin_v), dtype=float)
            physical = None
            if task.kind in ('cartesian_pose', 'joint_position'):
                physical = np.asarray(task.compute_value(self.kin_m), dtype=float)
            elif task.kind == 'wrench' and task.frame == contact_chain:
                _, R, _ = self.kin_m.frame(self.robot.frame_id(task.frame), virtual=True)
                S = subspace_in_base(task.S, task.subspace_frame, R)
                physical = S.T @ (-np.asarray(contact_wrench))  # robot on environment
            lower, upper = task.bounds_at(task_time)
            out.append({'name': task.name, 'type': task.kind, 'value': value.tolist(),
                        'physical': None if physical is None else physical.tolist(),
                        'lower': np.asarray(lower, float).tolist(),
                        'upper': np.asarray(upper, float).tolist()})
        return out


@dataclasses.dataclass
class RunResult:
    """What :func:`run_scenario` produced: paths and the metrics dict."""

    out_dir: Path
    bag: Path
    metrics_path: Path
    metrics: dict


def run_scenario(scenario: Scenario | str | Path, out_dir: str | Path,
                 duration: float | None = None, quiet: bool = False,
                 stream: TextIO | None = None) -> 'RunResult':
    """Run ``scenario`` (a :class:`Scenario` or a path) and write ``out_dir/bag`` + metrics.

    Args:
        scenario: :class:`Scenario` or scenario file path.
        out_dir: Output directory (created; an existing ``bag`` inside is an error).
        duration: Override the scenario duration [s].
        quiet: No progress lines.
        stream: Where progress goes (default stdout).
    """
    if not isinstance(scenario, Scenario):
        scenario = load_scenario(scenario)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    bag_path = out_dir / 'bag'
    if bag_path.exists():
        raise ParameterError(f"'{bag_path}' exists; choose another -o directory or remove it")
    duration = scenario.duration if duration is None else float(duration)
    run = _LockstepRun(scenario, bag_path, duration, quiet, stream or sys.stdout)
    wall0 = time.perf_counter()
    try:
        done = run.loop(wall0)
    finally:
        missed, warnings = run.close()
    wall = time.perf_counter() - wall0
    metrics = run.metrics.report(done, wall, missed, warnings, run.runner)
    if done < run.n_ticks:
        metrics['interrupted'] = {'by': stop_request.requested, 'ticks_done': done,
                                  'ticks_planned': run.n_ticks}
    metrics_path = out_dir / 'metrics.json'
    metrics_path.write_text(json.dumps(metrics, indent=2, allow_nan=False) + '\n')
    return RunResult(out_dir, bag_path, metrics_path, metrics)


class _LockstepRun:
    """One offline run: the simulation, the SPG (:class:`SpgRunner`) and the bag, tick by tick.

    Args:
        scenario: The :class:`Scenario`.
        bag_path: Bag directory to create.
        duration: Sim time to run [s].
        quiet: No progress or stall lines.
        stream: Where progress goes.
    """

    def __init__(self, scenario, bag_path, duration, quiet, stream):
        from sim_bridge.simulation import SimConfig, Simulation  # MuJoCo: only when running

        self.scenario, self.quiet, self.stream = scenario, quiet, stream
        self.config = scenario.spg
        sim_opts = {k: v for k, v in scenario.sim.items() if k not in ('stiffness', 'damping')}
        self.sim = Simulation(SimConfig(
            robot=robot_with_ifc(scenario), interface=scenario.interface, scene=scenario.scene,
            scene_options=scenario.scene_options, q0=scenario.q0, timestep=scenario.timestep,
            command_period=scenario.dt, **sim_opts))
        self.runner = SpgRunner(self.config, robot=self.sim.robot)
        self.probe = _TaskProbe(self.sim.robot)
        self.steps = round(scenario.dt / scenario.timestep)
        self.n_ticks = round(duration / scenario.dt)
        self.contact_chain = self.sim.contact_chain
        self.names = list(self.sim.joint_names)
        self.stacks, self.pushes = list(scenario.stacks), list(scenario.pushes)
        self.since = {}
        self.writer = BagWriter(bag_path)
        self._write_header(duration)
        self.metrics = MetricsRecorder(scenario, self.sim.robot)
        gc = scenario.metrics.get('geom_contact')
        self.geom_sets = None if gc is None else (self.sim.geom_ids(gc['geoms']),
                                                  self.sim.geom_ids(gc['with']))
        self.progress_every = max(1, int(self.n_ticks * scenario.progress / 100)) \
            if scenario.progress and not quiet else 0

    def _write_header(self, duration):
        """Custom data (config, robot parameters, scenario), the topics, the first status."""
        scenario, sim, writer = self.scenario, self.sim, self.writer
        config_doc = dataclasses.asdict(self.config)
        robot_doc = robot_params(self.runner.robot)
        writer.set_custom_data(CONFIG_KEY, json.dumps(config_doc, sort_keys=True))
        writer.set_custom_data(ROBOT_PARAMS_KEY, json.dumps(robot_doc))
        writer.set_custom_data(SCENARIO_KEY, json.dumps({
            'name': scenario.name, 'path': scenario.path, 'scene': scenario.scene,
            'interface': sim.interface, 'duration': duration,
            # ifc-spg render rebuilds the scene: it is anchored at the tool pose of q0
            'scene_options': scenario.scene_options or {},
            'q0': [float(x) for x in sim.q0],
            # the FRI loop delay [periods], when there is one (absent: 0, as before it existed)
            **({'fri_delay': sim.fri_delay} if sim.fri_delay else {})}))
        topics = ['joint_states', 'command/joint_position', 'spg/task_stack', 'spg/status',
                  'sim/contact_wrench']
        if sim.read_state().ft_wrench:
            topics.append('ft_sensor/wrench')
        if sim.env_joint_names:
            topics.append('sim/env_joint_states')
        if scenario.pushes:
            topics.append('sim/apply_wrench')
        for topic in topics:
            writer.add_topic('/' + topic, *TOPICS[topic])
        rate = self.config.markers_rate  # as the live node publishes them (0: none)
        self.foxglove = FoxgloveTopics(writer, sim.robot,
                                       markers_period=1.0 / rate if rate > 0 else None)
        self.foxglove.write_static(0)
        writer.write_msg('/spg/status', 0, m.String(data=status_json(
            {'event': {'type': 'started', 'message': f'offline run of {scenario.name}'},
             'config': config_doc, 'robot_params': robot_doc, 'robot': sim.robot.name,
             'tick': 0})))

    def loop(self, wall0):
        """Run every tick (or until a stop is requested); the number of ticks done."""
        for k in range(self.n_ticks):
            if stop_request.requested:
                print(f'[{self.scenario.name}] stopped by {stop_request.requested} after {k} '
                      'ticks; closing the bag and writing the metrics', file=self.stream,
                      flush=True)
                return k
            self.tick(k)
            if self.progress_every and ((k + 1) % self.progress_every == 0 or
                                        k + 1 == self.n_ticks):
                self._progress(k + 1, time.perf_counter() - wall0)
        return self.n_ticks

    def tick(self, k):
        """Tick ``k``: inputs due, the state into the bag and the SPG, its command out."""
        s = self.sim.read_state()
        sec, nsec = _stamp(s.t)
        t_ns = sec * 1_000_000_000 + nsec
        stamp = m.Time(sec=sec, nanosec=nsec)
        self._stacks_due(s.t, t_ns)
        self._pushes_due(s.t, t_ns, stamp)
        js = self._write_state(s, t_ns, stamp)
        if self.geom_sets is not None:
            self.metrics.on_geom_contact(s.t, *self.sim.geom_contact(*self.geom_sets))
        # the SPG sees exactly what the bag holds
        runner = self.runner
        cmd, events = runner.tick(js.name, js.position, js.velocity, t_ns)
        if cmd is None:
            raise IfcSpgError(f'the SPG rejected the joint state at t = {s.t:.3f} s: '
                              f'{runner.last_error}')
        out = m.JointState(name=self.names, position=cmd.position, velocity=cmd.velocity)
        out.header.stamp = stamp
        self.writer.write_msg('/command/joint_position', t_ns, out)
        self.foxglove.joint_state(t_ns, t_ns, js.name, js.position)
        self.foxglove.joint_state(t_ns, t_ns, self.names, cmd.position, virtual=True)
        if runner.stack_id and runner.stack_id not in self.since:
            self.since[runner.stack_id] = t_ns * 1e-9
        info = runner.spg.info
        task_time = info.task_time if info.task_time is not None else 0.0
        tasks = self.probe.evaluate(runner.spg.tasks, np.asarray(js.position),
                                    np.asarray(js.velocity), cmd.position, task_time,
                                    s.contact_wrench, self.contact_chain)
        if self.foxglove.markers_due(t_ns):  # self.probe.kin_v is at this tick's q_v
            force = -np.asarray(s.contact_wrench[:3], dtype=float)  # robot on environment
            self.foxglove.markers(t_ns, t_ns, cartesian_targets(
                runner.spg.tasks, self.probe.kin_v, task_time), wrench_arrows(
                runner.spg.tasks, self.probe.kin_v, task_time,
                (self.contact_chain, force)))
        event = None
        for kind, text in events:
            if kind == 'pspm_stall':  # once per episode, as spg_node reports it
                event = (kind, text)
                if not self.quiet:
                    print(f'[{self.scenario.name}] t = {s.t:.3f} s: {text}',
                          file=self.stream, flush=True)
        if event or k % self.config.status_decimation == 0 or k == self.n_ticks - 1:
            self._write_status(event, tasks, t_ns)
        self.metrics.on_tick(s.t, s.contact_wrench, cmd, info, tasks)
        self.sim.write_command(cmd.position)
        self.sim.step(self.steps)

    def _stacks_due(self, t, t_ns):
        """Send the task stacks due at sim time ``t`` [s] to the SPG (and the bag)."""
        while self.stacks and self.stacks[0].at <= t + 1e-9:
            entry = self.stacks.pop(0)
            self.writer.write_msg('/spg/task_stack', t_ns, m.String(data=entry.text))
            event = self.runner.handle_task_stack(entry.text, source=entry.source)
            if not event.accepted:
                raise IfcSpgError(event.message)

    def _pushes_due(self, t, t_ns, stamp):
        """Apply the pushes due at sim time ``t`` [s] (and record them)."""
        while self.pushes and self.pushes[0].at <= t + 1e-9:
            p = self.pushes.pop(0)
            target = p.target or self.contact_chain
            self.sim.apply_wrench(target, p.wrench, p.duration)
            ws = m.WrenchStamped()
            ws.header.stamp = stamp
            ws.header.frame_id = f'{target};duration={p.duration:g}'
            (ws.wrench.force.x, ws.wrench.force.y, ws.wrench.force.z, ws.wrench.torque.x,
             ws.wrench.torque.y, ws.wrench.torque.z) = p.wrench
            self.writer.write_msg('/sim/apply_wrench', t_ns, ws)

    def _write_state(self, s, t_ns, stamp):
        """Record the simulation state ``s``; the joint state message the SPG gets."""
        writer = self.writer
        js = m.JointState(name=self.names, position=s.q, velocity=s.qd, effort=s.tau_measured)
        js.header.stamp = stamp
        writer.write_msg('/joint_states', t_ns, js)
        for chain, w in s.ft_external.items():
            writer.write_msg('/ft_sensor/wrench', t_ns, _wrench(stamp, chain, w))
        writer.write_msg('/sim/contact_wrench', t_ns,
                         _wrench(stamp, self.contact_chain, s.contact_wrench))
        if s.env_joint_names:
            env = m.JointState(name=list(s.env_joint_names), position=s.env_q,
                               velocity=s.env_qd)
            env.header.stamp = stamp
            writer.write_msg('/sim/env_joint_states', t_ns, env)
        return js

    def _write_status(self, event, tasks, t_ns):
        doc = self.runner.status(event)
        if doc.get('stack'):
            doc['stack'][STACK_SINCE_KEY] = self.since.get(self.runner.stack_id)
        doc['tasks'] = tasks
        self.writer.write_msg('/spg/status', t_ns, m.String(data=status_json(doc)))

    def _progress(self, done, wall):
        t_sim = done * self.scenario.dt
        print(f'[{self.scenario.name}] {100 * done / self.n_ticks:5.1f} %  sim {t_sim:7.3f} s  '
              f'wall {wall:6.2f} s  real-time factor {t_sim / max(wall, 1e-9):5.2f}',
              file=self.stream, flush=True)

    def close(self):
        """Close the bag and the simulation; ``(missed commands, MuJoCo warnings)``."""
        try:
            self.writer.close()
        finally:
            missed = self.sim.missed_commands
            warnings = self.sim.warnings()
            self.sim.close()
        return missed, warnings


def robot_with_ifc(scenario):
    """The scenario's robot with its IFC gains: ``sim: {stiffness, damping}``.

    The overrides (K [Nm/rad] and D [Nms/rad], scalar or per joint) hold for the simulated
    controller AND the SPG.

    Args:
        scenario: The :class:`Scenario`.

    Raises:
        ParameterError: A gain that is not a positive number (or one per joint).
    """
    return RobotModel.from_config(scenario.robot).with_gains(
        stiffness=scenario.sim.get('stiffness'), damping=scenario.sim.get('damping'),
        where=f"scenario '{scenario.path}': sim.")


def _wrench(stamp, frame, w):
    msg = m.WrenchStamped()
    msg.header.stamp = stamp
    msg.header.frame_id = frame
    f, t = msg.wrench.force, msg.wrench.torque
    f.x, f.y, f.z, t.x, t.y, t.z = (float(x) for x in w)
    return msg


class StopRequest:
    """SIGINT/SIGTERM set :attr:`requested` (the signal's name) instead of killing the run.

    So an interrupted run still closes its bag and writes its metrics.
    """

    def __init__(self):
        self.requested = None

    def install(self):
        """Catch SIGINT and SIGTERM (main thread only); the handlers to restore."""
        if threading.current_thread() is not threading.main_thread():
            return {}

        def handler(signum, frame):
            self.requested = signal.Signals(signum).name
        return {s: signal.signal(s, handler) for s in (signal.SIGINT, signal.SIGTERM)}

    @staticmethod
    def restore(old):
        """Put back the handlers :meth:`install` returned."""
        for sig, h in old.items():
            signal.signal(sig, h)


#: The run's stop request: ``ifc-spg run`` installs it, the lockstep loop polls it.
stop_request = StopRequest()
