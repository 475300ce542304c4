"""Offline lockstep runs of a scenario: bridge + SPG in one process, no DDS (``ifc-spg run``).

    ifc-spg run config/scenarios/demo_lbr.yaml -o out/demo [--duration S] [--quiet]

Each SPG tick: the simulation's state becomes the ``joint_states`` message (stamp = sim
time), the SPG (:class:`~ifc_spg.node.core.SpgRunner`, the live node's logic) answers with
``command/joint_position`` (same stamp), the simulation holds that q_v for one command
period. The bag in ``DIR/bag`` has the topics a live run records, with the same types,
QoS and header stamps (log time = sim time): ``joint_states``, ``command/joint_position``,
``spg/task_stack``, ``spg/status``, ``sim/contact_wrench``, ``ft_sensor/wrench`` (robots
with wrist sensors), ``sim/env_joint_states`` (scenes with mechanisms) and
``sim/apply_wrench`` (the scenario's pushes). Everything that sets the SPG's output besides
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
                                 #  (scalar or per joint; used by the bridge AND the SPG)

Metrics: ``final_task_errors`` (per task of the last stack: distance of the value at the
measured q, and of the virtual value, to the bounds), ``max_contact_force`` [N],
``tank_energy_min`` [J], ``limit_violations`` (ticks x joints with q_v outside the
position limits or |qdot_v| above the velocity limit), ``tick_time`` (p50/p99/max [ms]),
``missed_ticks`` (command periods without a command), ``force_error_rms`` [N] (force the
robot exerts along a base axis, from ``sim/contact_wrench``, vs a target; with ``window``
[s] also after a moving average), ``task_error_rms`` (a task's measured and virtual
distance to its bounds, over ``components`` (indices) if given).
"""

import argparse
import dataclasses
import json
import math
import os
from pathlib import Path
import sys
import time

import numpy as np

from ifc_spg.errors import IfcSpgError, ParameterError, did_you_mean

__all__ = [
    'CONFIG_KEY',
    'ROBOT_PARAMS_KEY',
    'STACK_SINCE_KEY',
    'RunResult',
    'Scenario',
    'find_config_dir',
    'load_scenario',
    'main',
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
_METRICS = _DEFAULT_METRICS + ('force_error_rms', 'task_error_rms')
_SIM_KEYS = ('joint_damping', 'frictionloss', 'armature', 'contact_chain', 'stiffness',
             'damping')


def find_config_dir():
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
    wrench: tuple
    duration: float


@dataclasses.dataclass(frozen=True)
class Scenario:
    """A validated scenario (see the module docstring for the file format)."""

    name: str
    robot: str
    interface: str
    scene: str
    scene_options: dict
    q0: tuple
    dt: float
    timestep: float
    spg: object
    duration: float
    stacks: tuple
    pushes: tuple
    metrics: dict
    progress: float
    sim: dict
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
    from ifc_spg.node.core import parse_task_stack

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
    """``{ROS parameter name: value}`` of a ``spg_node`` params file (``config/<robot>.yaml``:
    ``/**: ros__parameters:`` with nested groups), without robot, dt and watchdog.timeout
    (a scenario sets those; offline there is no wall-clock watchdog).

    Raises:
        ParameterError: The file is missing or not a params file.
    """
    import yaml

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


def _spg_config(spec, robot, dt, where):
    from ifc_spg.node.config import PARAMETERS, config_from_parameters

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
        out[name] = dict(opts)
    return out


def load_scenario(path, overrides=None):
    """Read and validate a scenario file.

    Args:
        path: YAML file.
        overrides: Keys replacing the file's (e.g. ``{'duration': 2.0}``).

    Raises:
        ParameterError: A bad key or value (naming the file, the key and the fix);
            ``TaskStackError`` for a bad stack.
    """
    import yaml

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


def scenario_from_dict(data, where='scenario', base=Path('.')):
    """Validate a scenario mapping (the parsed file); see :func:`load_scenario`."""
    from ifc_spg.model import RobotModel

    unknown = [k for k in data if k not in _SCENARIO_KEYS]
    if unknown:
        raise _err(where, f"unknown key '{unknown[0]}'{did_you_mean(unknown[0], _SCENARIO_KEYS)}"
                   f"; keys: {', '.join(_SCENARIO_KEYS)}")
    robot_name = data.get('robot', 'lbr_iiwa14')
    robot = RobotModel.from_config(robot_name)
    dt = _number(data.get('dt', 0.002), 'dt', where, positive=True)
    timestep = _number(data.get('timestep', 0.001), 'timestep', where, positive=True)
    duration = _number(data.get('duration', 5.0), 'duration', where, positive=True)
    if 'q0' in data and 'q0_deg' in data:
        raise _err(where, "give 'q0' [rad] or 'q0_deg' [deg], not both")
    q0 = None
    if data.get('q0') is not None or data.get('q0_deg') is not None:
        raw = data.get('q0') if data.get('q0') is not None else data['q0_deg']
        q0 = np.asarray(raw, dtype=float).reshape(-1)
        if 'q0_deg' in data:
            q0 = np.deg2rad(q0)
        if q0.shape != (robot.n,):
            raise _err(where, f'q0 needs {robot.n} values ({", ".join(robot.joint_names)}), '
                       f'got {q0.size}')
        q0 = tuple(float(x) for x in q0)
    stacks = data.get('stacks') or []
    if not isinstance(stacks, list):
        raise _err(where, "'stacks' must be a list of {at, file|stack} entries")
    entries = tuple(sorted((_stack_text(e, i, base, where) for i, e in enumerate(stacks)),
                           key=lambda e: e.at))
    pushes = []
    for i, p in enumerate(data.get('pushes') or []):
        item = f'{where}: pushes[{i}]'
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
        pushes.append(Push(_number(p.get('at', 0.0), 'at', item, low=0.0),
                           str(p.get('target', '')), tuple(w.tolist()),
                           _number(p.get('duration', 0.5), 'duration', item, positive=True)))
    sim = dict(data.get('sim') or {})
    bad = [k for k in sim if k not in _SIM_KEYS]
    if bad:
        raise _err(where, f"sim: unknown key '{bad[0]}'{did_you_mean(bad[0], _SIM_KEYS)}; keys: "
                   f"{', '.join(_SIM_KEYS)}")
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
        from ifc_spg.kinematics import Kinematics

        self.robot = robot
        self.kin_v = Kinematics(robot)
        self.kin_m = Kinematics(robot)

    def evaluate(self, tasks, q, qdot, q_v, task_time, contact_wrench, contact_chain):
        from ifc_spg.tasks.subspace import subspace_in_base

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


def band_error(value, lower, upper):
    """Distance of ``value`` to the band [lower, upper] per component (0 inside)."""
    v, lo, hi = (np.asarray(x, dtype=float) for x in (value, lower, upper))
    with np.errstate(invalid='ignore'):
        return np.where(v < lo, lo - v, np.where(v > hi, v - hi, 0.0))


@dataclasses.dataclass
class RunResult:
    """What :func:`run_scenario` produced: paths and the metrics dict."""

    out_dir: Path
    bag: Path
    metrics_path: Path
    metrics: dict


def run_scenario(scenario, out_dir, duration=None, quiet=False, stream=None):
    """Run ``scenario`` (a :class:`Scenario` or a path) and write ``out_dir/bag`` + metrics.

    Args:
        scenario: :class:`Scenario` or scenario file path.
        out_dir: Output directory (created; an existing ``bag`` inside is an error).
        duration: Override the scenario duration [s].
        quiet: No progress lines.
        stream: Where progress goes (default stdout).
    """
    from ifc_spg.node.core import SpgRunner, robot_params, status_json
    from ifc_spg.offline.bag import TOPICS, BagWriter
    from ifc_spg.ros import messages as m
    from sim_bridge.simulation import SimConfig, Simulation

    if not isinstance(scenario, Scenario):
        scenario = load_scenario(scenario)
    stream = stream or sys.stdout
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    bag_path = out_dir / 'bag'
    if bag_path.exists():
        raise ParameterError(f"'{bag_path}' exists; choose another -o directory or remove it")
    duration = scenario.duration if duration is None else float(duration)
    config = scenario.spg
    sim_opts = {k: v for k, v in scenario.sim.items() if k not in ('stiffness', 'damping')}
    sim = Simulation(SimConfig(robot=_robot_with_ifc(scenario), interface=scenario.interface,
                               scene=scenario.scene, scene_options=scenario.scene_options,
                               q0=scenario.q0, timestep=scenario.timestep,
                               command_period=scenario.dt, **sim_opts))
    runner = SpgRunner(config, robot=sim.robot)
    probe = _TaskProbe(sim.robot)
    robot = sim.robot
    steps = round(scenario.dt / scenario.timestep)
    n_ticks = round(duration / scenario.dt)
    contact_chain = sim.contact_chain
    writer = BagWriter(bag_path)
    config_doc = dataclasses.asdict(config)
    robot_doc = robot_params(runner.robot)
    writer.set_custom_data(CONFIG_KEY, json.dumps(config_doc, sort_keys=True))
    writer.set_custom_data(ROBOT_PARAMS_KEY, json.dumps(robot_doc))
    writer.set_custom_data(SCENARIO_KEY, json.dumps({
        'name': scenario.name, 'path': scenario.path, 'scene': scenario.scene,
        'interface': sim.interface, 'duration': duration,
        # ifc-spg render rebuilds the scene: it is anchored at the tool pose of q0
        'scene_options': scenario.scene_options or {}, 'q0': [float(x) for x in sim.q0]}))
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
    writer.write_msg('/spg/status', 0, m.String(data=status_json(
        {'event': {'type': 'started', 'message': f'offline run of {scenario.name}'},
         'config': config_doc, 'robot_params': robot_doc, 'robot': robot.name, 'tick': 0})))

    stacks = list(scenario.stacks)
    pushes = list(scenario.pushes)
    names = list(sim.joint_names)
    since = {}
    m_force, m_tank, m_viol, m_tick, m_forcerr, m_taskerr = [], [], 0, [], [], {}
    fopt = scenario.metrics.get('force_error_rms')
    topt = scenario.metrics.get('task_error_rms')
    axis_idx = None
    if fopt is not None:
        axes = ('fx', 'fy', 'fz', 'tx', 'ty', 'tz')
        axis = fopt.get('axis', 'fz')
        if axis not in axes:
            raise ParameterError(f"metric force_error_rms: axis '{axis}' not one of "
                                 f"{', '.join(axes)}")
        axis_idx = axes.index(axis)
    comps = slice(None) if topt is None or topt.get('components') is None else \
        np.asarray(topt['components'], dtype=int)
    last_tasks = []
    progress_every = max(1, int(n_ticks * scenario.progress / 100)) if scenario.progress \
        and not quiet else 0
    wall0 = time.perf_counter()
    done = 0
    try:
        for k in range(n_ticks):
            if _stop.requested:
                print(f'[{scenario.name}] stopped by {_stop.requested} after {k} ticks; '
                      'closing the bag and writing the metrics', file=stream, flush=True)
                break
            s = sim.read_state()
            sec, nsec = _stamp(s.t)
            t_ns = sec * 1_000_000_000 + nsec
            stamp = m.Time(sec=sec, nanosec=nsec)
            while stacks and stacks[0].at <= s.t + 1e-9:
                entry = stacks.pop(0)
                writer.write_msg('/spg/task_stack', t_ns, m.String(data=entry.text))
                event = runner.handle_task_stack(entry.text, source=entry.source)
                if not event.accepted:
                    raise IfcSpgError(event.message)
            while pushes and pushes[0].at <= s.t + 1e-9:
                p = pushes.pop(0)
                target = p.target or contact_chain
                sim.apply_wrench(target, p.wrench, p.duration)
                ws = m.WrenchStamped()
                ws.header.stamp = stamp
                ws.header.frame_id = f'{target};duration={p.duration:g}'
                (ws.wrench.force.x, ws.wrench.force.y, ws.wrench.force.z, ws.wrench.torque.x,
                 ws.wrench.torque.y, ws.wrench.torque.z) = p.wrench
                writer.write_msg('/sim/apply_wrench', t_ns, ws)
            js = m.JointState(name=names, position=s.q, velocity=s.qd, effort=s.tau_measured)
            js.header.stamp = stamp
            writer.write_msg('/joint_states', t_ns, js)
            for chain, w in s.ft_external.items():
                writer.write_msg('/ft_sensor/wrench', t_ns, _wrench(m, stamp, chain, w))
            writer.write_msg('/sim/contact_wrench', t_ns,
                             _wrench(m, stamp, contact_chain, s.contact_wrench))
            if s.env_joint_names:
                env = m.JointState(name=list(s.env_joint_names), position=s.env_q,
                                   velocity=s.env_qd)
                env.header.stamp = stamp
                writer.write_msg('/sim/env_joint_states', t_ns, env)
            # the SPG sees exactly what the bag holds
            stalls = runner.pspm_stalls
            cmd = runner.handle_joint_state(js.name, js.position, js.velocity, t_ns)
            if cmd is None:
                raise IfcSpgError(f'the SPG rejected the joint state at t = {s.t:.3f} s: '
                                  f'{runner.last_error}')
            out = m.JointState(name=names, position=cmd.position, velocity=cmd.velocity)
            out.header.stamp = stamp
            writer.write_msg('/command/joint_position', t_ns, out)
            if runner.stack_id and runner.stack_id not in since:
                since[runner.stack_id] = t_ns * 1e-9
            info = runner.spg.info
            task_time = info.task_time if info.task_time is not None else 0.0
            tasks = probe.evaluate(runner.spg.tasks, np.asarray(js.position),
                                   np.asarray(js.velocity), cmd.position, task_time,
                                   s.contact_wrench, contact_chain)
            last_tasks = tasks
            event = None
            if runner.pspm_stalls != stalls:  # once per episode, as spg_node logs it
                event = ('pspm_stall', runner.last_stall)
                if not quiet:
                    print(f'[{scenario.name}] t = {s.t:.3f} s: {runner.last_stall}',
                          file=stream, flush=True)
            if event or k % config.status_decimation == 0 or k == n_ticks - 1:
                doc = runner.status(event)
                if doc.get('stack'):
                    doc['stack'][STACK_SINCE_KEY] = since.get(runner.stack_id)
                doc['tasks'] = tasks
                writer.write_msg('/spg/status', t_ns, m.String(data=status_json(doc)))
            # metrics
            m_force.append(float(np.linalg.norm(s.contact_wrench[:3])))
            if info.tank_energy is not None:
                m_tank.append(float(np.min(info.tank_energy)))
            m_viol += int(np.sum((cmd.position < robot.q_min - 1e-9) |
                                 (cmd.position > robot.q_max + 1e-9) |
                                 (np.abs(cmd.velocity) > robot.v_max * (1 + 1e-6) + 1e-12)))
            m_tick.append(info.tick_time or 0.0)
            if fopt is not None and s.t >= fopt.get('after', 0.0) - 1e-9:
                f = -s.contact_wrench[axis_idx]
                m_forcerr.append(f - float(fopt.get('target', 0.0)))
            if topt is not None and s.t >= topt.get('after', 0.0) - 1e-9:
                for task in tasks:
                    if task['name'] == topt.get('task'):
                        ev = band_error(task['value'], task['lower'], task['upper'])[comps]
                        ep = None if task['physical'] is None else band_error(
                            task['physical'], task['lower'], task['upper'])[comps]
                        m_taskerr.setdefault('virtual', []).append(float(np.linalg.norm(ev)))
                        if ep is not None:
                            m_taskerr.setdefault('physical', []).append(
                                float(np.linalg.norm(ep)))
            sim.write_command(cmd.position)
            sim.step(steps)
            done = k + 1
            if progress_every and ((k + 1) % progress_every == 0 or k + 1 == n_ticks):
                wall = time.perf_counter() - wall0
                t_sim = (k + 1) * scenario.dt
                print(f'[{scenario.name}] {100 * (k + 1) / n_ticks:5.1f} %  sim {t_sim:7.3f} s  '
                      f'wall {wall:6.2f} s  real-time factor {t_sim / max(wall, 1e-9):5.2f}',
                      file=stream, flush=True)
    finally:
        writer.close()
        missed = sim.missed_commands
        warnings = sim.warnings()
        sim.close()
    wall = time.perf_counter() - wall0
    metrics = _report(scenario, done * scenario.dt, wall, done, missed, warnings, last_tasks,
                      m_force,
                      m_tank, m_viol, m_tick, m_forcerr, m_taskerr, runner)
    if done < n_ticks:
        metrics['interrupted'] = {'by': _stop.requested, 'ticks_done': done,
                                  'ticks_planned': n_ticks}
    metrics_path = out_dir / 'metrics.json'
    metrics_path.write_text(json.dumps(metrics, indent=2, allow_nan=False) + '\n')
    return RunResult(out_dir, bag_path, metrics_path, metrics)


def _robot_with_ifc(scenario):
    """The scenario's robot; ``sim: {stiffness, damping}`` override its IFC gains K [Nm/rad]
    and D [Nms/rad] (scalar or per joint) for the simulated controller AND the SPG.
    """
    from ifc_spg.model import RobotModel

    return RobotModel.from_config(scenario.robot).with_gains(
        stiffness=scenario.sim.get('stiffness'), damping=scenario.sim.get('damping'),
        where=f"scenario '{scenario.path}': sim.")
    robot = copy.copy(robot)
    for key, raw in (('stiffness', stiffness), ('damping', damping)):
        if raw is None:
            continue
        try:
            value = np.asarray(raw, dtype=float).reshape(-1)
        except (TypeError, ValueError):
            value = np.array([np.nan])
        if value.size == 1:
            value = np.full(robot.n, value[0])
        if value.shape != (robot.n,) or not np.all(np.isfinite(value)) or np.any(
                value < 0) or (key == 'stiffness' and np.any(value <= 0)):
            raise ParameterError(f'{where}{key} must be '
                                 f'{"> 0" if key == "stiffness" else ">= 0"} '
                                 f'(scalar or {robot.n} values for '
                                 f"{', '.join(robot.joint_names)}), got {raw!r}")
        value = value.copy()
        value.setflags(write=False)
        setattr(robot, key, value)
    return robot


def _wrench(m, stamp, frame, w):
    msg = m.WrenchStamped()
    msg.header.stamp = stamp
    msg.header.frame_id = frame
    f, t = msg.wrench.force, msg.wrench.torque
    f.x, f.y, f.z, t.x, t.y, t.z = (float(x) for x in w)
    return msg


def _rms(x):
    return float(np.sqrt(np.mean(np.square(x)))) if len(x) else None


def _report(sc, duration, wall, n_ticks, missed, warnings, last_tasks, m_force, m_tank, m_viol,
            m_tick, m_forcerr, m_taskerr, runner):
    out = {'scenario': sc.name, 'robot': sc.robot, 'scene': sc.scene, 'duration_s': duration,
           'ticks': n_ticks, 'wall_time_s': wall,
           'real_time_factor': duration / wall if wall > 0 else None,
           'spg_status_counts': None, 'mujoco_warnings': warnings}
    metrics = sc.metrics
    if 'final_task_errors' in metrics:
        out['final_task_errors'] = {
            t['name']: {'virtual': float(np.linalg.norm(band_error(t['value'], t['lower'],
                                                                   t['upper']))),
                        'physical': None if t['physical'] is None else float(np.linalg.norm(
                            band_error(t['physical'], t['lower'], t['upper'])))}
            for t in last_tasks}
    if 'max_contact_force' in metrics:
        out['max_contact_force_n'] = max(m_force) if m_force else 0.0
    if 'tank_energy_min' in metrics:
        out['tank_energy_min_j'] = min(m_tank) if m_tank else None
    if 'limit_violations' in metrics:
        out['limit_violations'] = m_viol
    if 'tick_time' in metrics:
        tt = np.array(m_tick) * 1e3
        out['tick_time_ms'] = {'p50': float(np.percentile(tt, 50)),
                               'p99': float(np.percentile(tt, 99)), 'max': float(tt.max())}
    if 'missed_ticks' in metrics:
        out['missed_ticks'] = int(missed)
    if 'force_error_rms' in metrics:
        opt = metrics['force_error_rms']
        out['force_error_rms_n'] = _rms(m_forcerr)
        window = round(float(opt.get('window', 0.0)) / sc.dt)
        if window > 1 and len(m_forcerr) >= window:
            smooth = np.convolve(m_forcerr, np.ones(window) / window, mode='valid')
            out['force_error_rms_filtered_n'] = _rms(smooth)
        out['force_error_rms_options'] = opt
    if 'task_error_rms' in metrics:
        opt = metrics['task_error_rms']
        out['task_error_rms'] = {k: _rms(v) for k, v in m_taskerr.items()}
        out['task_error_rms_options'] = opt
    tanks = runner.spg.tanks
    if tanks is not None:
        # energy the power budget put into the tanks (this session), and the stalls
        out['pspm'] = {'power_budget_w': tanks.power, 'max_power_w': tanks.config.max_power,
                       'refilled_j': float(tanks.refilled.sum()),
                       'refilled_per_minute_j': float(tanks.refilled.sum()) * 60.0 /
                       duration if duration > 0 else None,
                       'tank_energy_start_j': float(tanks.config.initial_energy *
                                                    np.count_nonzero(tanks.mask)),
                       'tank_energy_end_j': float(tanks.energy.sum()),
                       'stalls': runner.pspm_stalls,
                       'stall': runner.spg.info.pspm['stall'],
                       'last_stall_message': runner.last_stall or None}
    out['spg'] = {'rejected': dict(runner.rejected), 'errors': list(runner.errors)}
    del out['spg_status_counts']
    return out


class _StopRequest:
    """SIGINT/SIGTERM set :attr:`requested` (the signal's name) instead of killing the run,
    so that an interrupted run still closes its bag and writes its metrics.
    """

    def __init__(self):
        self.requested = None

    def install(self):
        import signal
        import threading
        if threading.current_thread() is not threading.main_thread():
            return {}

        def handler(signum, frame):
            self.requested = signal.Signals(signum).name
        return {s: signal.signal(s, handler) for s in (signal.SIGINT, signal.SIGTERM)}

    @staticmethod
    def restore(old):
        import signal
        for sig, h in old.items():
            signal.signal(sig, h)


_stop = _StopRequest()


def main(argv=None):
    """``ifc-spg run SCENARIO.yaml -o DIR``."""
    parser = argparse.ArgumentParser(prog='ifc-spg run', description=__doc__.split('\n')[0])
    parser.add_argument('scenario', help='scenario YAML file (or a name in config/scenarios)')
    parser.add_argument('-o', '--output', required=True, help='output directory')
    parser.add_argument('--duration', type=float, default=None, help='override [s]')
    parser.add_argument('-q', '--quiet', action='store_true', help='no progress output')
    opts = parser.parse_args(sys.argv[1:] if argv is None else argv)
    old = _stop.install()
    try:
        result = run_scenario(opts.scenario, opts.output, opts.duration, opts.quiet)
    except IfcSpgError as exc:
        print(f'ifc-spg run: {exc}', file=sys.stderr)
        return 2
    finally:
        _StopRequest.restore(old)
    print(f'bag: {result.bag}\nmetrics: {result.metrics_path}')
    print(json.dumps({k: v for k, v in result.metrics.items() if k not in ('spg',)}, indent=1))
    return 130 if _stop.requested else 0


if __name__ == '__main__':
    sys.exit(main())
