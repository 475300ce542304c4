"""Sweep files: a base scenario, the axes to vary, the metrics to collect (``ifc-spg sweep``).

A sweep file (YAML)::

    version: 1
    name: free_push_gains          # default: the file name
    scenario: free_push.yaml       # base scenario: relative to this file or config/scenarios/
    set: {duration: 1.0}           # fixed changes to the base scenario (dotted paths)
    axes:                          # dotted path into the scenario -> how it varies
      sim.stiffness: {values: [200, 400, 800]}          # grid
      pushes.0.wrench.1: {uniform: [5.0, 20.0]}          # random draws
      stacks.0.stack.tasks.0.gain: {normal: [5.0, 1.0]}  # mean, std
      spg.solver: {choice: [daqp, proxsuite]}
    samples: 4                     # draws of the random axes (needed when there are any)
    seed: 7                        # sample s is drawn by numpy.random.default_rng([seed, s])
    metrics:                       # dotted paths into the run's metrics.json
      - task_error_rms.physical
      - tank_energy_min_j
    keep_bags: false               # true: keep each run's bag in DIR/runs/KEY/

A path names a key of the scenario file (``sim.stiffness``), a list entry by its index
(``pushes.0.wrench.1``: the push's fy); stacks given as ``file:`` are read into the
scenario first, so their fields are paths too (``stacks.0.stack.tasks.1.gain``). The
points are the grid (every combination of the ``values`` axes, first axis slowest) times
the samples; every grid point gets the same draws (common random numbers), so a gain
comparison is paired.

Errors name the file, line, field and the fix, like ``ifc-spg check`` does for task stacks
(the same safe loader: :mod:`ifc_spg.task_stack.loader`).
"""

import copy
import dataclasses
import hashlib
import itertools
import json
import os
from pathlib import Path
import subprocess

import numpy as np
import yaml

import ifc_spg
from ifc_spg.errors import IfcSpgError, did_you_mean
from ifc_spg.offline.runner import _SCENARIO_KEYS, find_config_dir, scenario_from_dict
from ifc_spg.task_stack.errors import TaskStackError
from ifc_spg.task_stack.loader import load

__all__ = ['AXIS_KINDS', 'Point', 'SweepError', 'SweepSpec', 'code_version', 'load_sweep',
           'scenario_for', 'set_path']

VERSION = 1
TOP_FIELDS = ('version', 'name', 'description', 'scenario', 'set', 'axes', 'samples', 'seed',
              'metrics', 'keep_bags')
AXIS_KINDS = ('values', 'uniform', 'normal', 'choice')
RANDOM_KINDS = ('uniform', 'normal', 'choice')
MAX_POINTS = 1_000_000
# metrics.json keys -> the scenario metric that produces them (None: always there)
_METRIC_KEYS = {
    'scenario': None, 'robot': None, 'scene': None, 'duration_s': None, 'ticks': None,
    'wall_time_s': None, 'real_time_factor': None, 'mujoco_warnings': None, 'pspm': None,
    'spg': None, 'final_task_errors': 'final_task_errors',
    'max_contact_force_n': 'max_contact_force', 'tank_energy_min_j': 'tank_energy_min',
    'limit_violations': 'limit_violations', 'tick_time_ms': 'tick_time',
    'missed_ticks': 'missed_ticks', 'force_error_rms_n': 'force_error_rms',
    'force_error_rms_filtered_n': 'force_error_rms', 'task_error_rms': 'task_error_rms',
}
_DEFAULT_SCENARIO_METRICS = ('final_task_errors', 'max_contact_force', 'tank_energy_min',
                             'limit_violations', 'tick_time', 'missed_ticks')


class SweepError(TaskStackError):
    """A sweep file is malformed: ``FILE (line L, column C): FIELD: REASON AND FIX``."""


@dataclasses.dataclass(frozen=True)
class Axis:
    """One axis: a dotted path into the scenario and how it varies."""

    path: str
    kind: str
    spec: object

    @property
    def random(self):
        """True for random draws (uniform, normal, choice)."""
        return self.kind in RANDOM_KINDS


@dataclasses.dataclass(frozen=True)
class Point:
    """One run of a sweep: its index, parameters ``{path: value}``, sample and key."""

    index: int
    params: dict
    sample: int
    key: str
    scenario: dict


@dataclasses.dataclass(frozen=True)
class SweepSpec:
    """A validated sweep file (see the module docstring)."""

    name: str
    path: str
    scenario_path: str
    base: dict
    set: dict
    axes: tuple
    samples: int
    seed: int
    metrics: tuple
    keep_bags: bool
    description: str = ''

    def points(self, version=None):
        """Every point, in order: the grid (first axis slowest) times the samples."""
        version = code_version() if version is None else version
        grid = [a for a in self.axes if not a.random]
        rand = [a for a in self.axes if a.random]
        draws = [_draw(rand, self.seed, s) for s in range(self.samples)] if rand else [{}]
        out: list[Point] = []
        for combo in itertools.product(*(a.spec for a in grid)):
            for s, drawn in enumerate(draws):
                values = dict(zip((a.path for a in grid), combo))
                values.update(drawn)
                params = {a.path: values[a.path] for a in self.axes}
                data = scenario_for(self.base, params, self.scenario_dir)
                sample = s if rand else 0
                key = point_key(data, version, sample)
                out.append(Point(len(out), params, sample, key, data))
        return out

    @property
    def scenario_dir(self):
        """The base scenario's directory (its stack files are relative to it)."""
        return str(Path(self.scenario_path).parent)

    def count(self):
        """The number of points."""
        n = self.samples if any(a.random for a in self.axes) else 1
        for a in self.axes:
            if not a.random:
                n *= len(a.spec)
        return n


def _draw(axes, seed, sample):
    """The random axes' values of sample ``sample`` (plain Python values)."""
    rng = np.random.default_rng([seed, sample])
    out = {}
    for a in axes:
        if a.kind == 'uniform':
            out[a.path] = float(rng.uniform(*a.spec))
        elif a.kind == 'normal':
            out[a.path] = float(rng.normal(*a.spec))
        else:
            out[a.path] = copy.deepcopy(a.spec[int(rng.integers(len(a.spec)))])
    return out


def point_key(scenario, version, sample=0):
    """Hash of a point's full scenario (base, set, parameters), sample and code version.

    The sample index keeps two draws apart that happen to be equal (``choice`` axes).
    """
    text = json.dumps({'scenario': scenario, 'code': version, 'sample': sample},
                      sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


_VERSION_CACHE: dict[str, str] = {}


def code_version():
    """``ifc_spg`` version and, in a git checkout, its commit (``0.1.0+g1234abcd``)."""
    if 'v' not in _VERSION_CACHE:
        version = ifc_spg.__version__
        root = Path(ifc_spg.__file__).resolve().parents[1]
        try:
            head = subprocess.run(['git', '-C', str(root), 'rev-parse', '--short=12', 'HEAD'],
                                  capture_output=True, text=True, timeout=10, check=False)
            if head.returncode == 0 and head.stdout.strip():
                version += '+g' + head.stdout.strip()
        except (OSError, subprocess.SubprocessError):
            pass
        _VERSION_CACHE['v'] = version
    return _VERSION_CACHE['v']


# -- paths into the scenario ------------------------------------------------------------

def _walk_error(path, i, reason):
    return ValueError(f"'{'.'.join(path[:i + 1])}': {reason}")


def _step(node, parts, i):
    """The key or index of ``parts[i]`` in ``node`` (a missing mapping on the way is made)."""
    part, last = parts[i], i == len(parts) - 1
    if isinstance(node, list):
        if not part.isdigit():
            raise _walk_error(parts, i, f'is a list here ({len(node)} entries); use an '
                              f'index 0..{len(node) - 1}')
        if int(part) >= len(node):
            raise _walk_error(parts, i, f'index {part} is out of range: the list has '
                              f'{len(node)} entries (0..{len(node) - 1})')
        return int(part)
    if not isinstance(node, dict):
        raise _walk_error(parts, i - 1, f'is a {type(node).__name__} ({node!r}), not a '
                          'mapping or list; shorten the path')
    if not last and node.get(part) is None:
        if parts[i + 1].isdigit():
            whole = '.'.join(parts[:i + 1])
            raise _walk_error(parts, i, f'is not in the scenario, so it has no entry '
                              f"{parts[i + 1]}; vary the whole value ('{whole}') or give it "
                              'in the scenario (or in set:)')
        node[part] = {}
    return part


def set_path(data, path, value):
    """Set ``value`` at the dotted ``path`` of the scenario mapping ``data`` (in place).

    Missing mapping keys on the way are created; list entries must exist.

    Raises:
        ValueError: The path does not fit the scenario (says which part and why).
    """
    parts = path.split('.')
    if not all(parts):
        raise ValueError(f"'{path}': empty part; write keys and list indices joined by '.', "
                         "e.g. 'pushes.0.wrench.1'")
    if parts[0] not in _SCENARIO_KEYS:
        hint = did_you_mean(parts[0], _SCENARIO_KEYS)
        raise ValueError(f"'{parts[0]}' is not a scenario key{hint}; keys: "
                         f"{', '.join(_SCENARIO_KEYS)}")
    node = data
    for i in range(len(parts)):
        k = _step(node, parts, i)
        if i == len(parts) - 1:
            node[k] = copy.deepcopy(value)
        else:
            node = node[k]
    return data


def _inline_stack_files(data, base_dir):
    """Read ``stacks: [{file: ...}]`` entries into ``stack:`` (same text the runner reads)."""
    stacks = data.get('stacks')
    if not isinstance(stacks, list):
        return data
    for entry in stacks:
        if not isinstance(entry, dict) or 'file' not in entry:
            continue
        name = str(entry['file'])
        candidates = [Path(name)] if os.path.isabs(name) else [
            Path(base_dir) / name, find_config_dir() / 'tasks' / name]
        path = next((p for p in candidates if p.is_file()), None)
        if path is None:
            continue  # the runner names the missing file
        entry.pop('file')
        entry.pop('stack', None)
        entry['stack'] = load(path.read_text(encoding='utf8'), source=str(path)).data
    return data


def scenario_for(base, params, base_dir):
    """The scenario mapping of one point: ``base`` with ``params`` set, stack files read."""
    data = _inline_stack_files(copy.deepcopy(base), base_dir)
    for path, value in params.items():
        set_path(data, path, value)
        if path.endswith('.file'):
            parent = data
            for part in path.split('.')[:-1]:
                parent = parent[int(part)] if isinstance(parent, list) else parent[part]
            parent.pop('stack', None)
    return _inline_stack_files(data, base_dir)


# -- the file ---------------------------------------------------------------------------

class _Doc:
    """The loaded file and its positions; errors carry file, line, field and fix."""

    def __init__(self, doc):
        self.doc = doc

    def error(self, path, reason):
        line, column = self.doc.mark(path)
        return SweepError(reason, path, line, column, self.doc.source)


def _is_number(x):
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def _list_axis(d, at, kind, value):
    """The entries of a ``values`` or ``choice`` axis (a grid value only once)."""
    if not isinstance(value, list) or not value:
        raise d.error(at, f'{kind} needs a non-empty list, e.g. {kind}: [1, 2, 3]; got '
                      f'{value!r}')
    seen = [json.dumps(v, sort_keys=True) for v in value]
    twice = next((v for i, v in enumerate(value) if seen[i] in seen[:i]), None)
    if kind == 'values' and twice is not None:
        raise d.error(at, f'values lists {twice!r} twice; remove one (each grid point runs '
                      'once)')
    return tuple(value)


def _axis(d, path, spec):
    """Validate one axis entry ``axes: {PATH: SPEC}``."""
    where = ('axes', path)
    example = ('{values: [1, 2, 3]}, {uniform: [LOW, HIGH]}, {normal: [MEAN, STD]} or '
               '{choice: [A, B]}')
    if not isinstance(spec, dict) or len(spec) != 1:
        raise d.error(where, f'expected one of {example}, got {spec!r}')
    kind, value = next(iter(spec.items()))
    if kind not in AXIS_KINDS:
        raise d.error(where + (kind,), f"unknown axis kind '{kind}'"
                      f"{did_you_mean(kind, AXIS_KINDS)}; use {example}")
    at = where + (kind,)
    if kind in ('values', 'choice'):
        return Axis(path, kind, _list_axis(d, at, kind, value))
    if kind == 'normal' and isinstance(value, dict):
        bad = [k for k in value if k not in ('mean', 'std')]
        if bad:
            raise d.error(at + (bad[0],), f"unknown key '{bad[0]}'; normal takes "
                          '{mean: M, std: S} or [M, S]')
        value = [value.get('mean'), value.get('std')]
    names = ('low', 'high') if kind == 'uniform' else ('mean', 'std')
    if not isinstance(value, list) or len(value) != 2 or not all(map(_is_number, value)):
        raise d.error(at, f'{kind} needs two numbers [{names[0].upper()}, '
                      f'{names[1].upper()}], got {value!r}')
    a, b = (float(x) for x in value)
    if kind == 'uniform' and not a < b:
        raise d.error(at, f'uniform needs LOW < HIGH, got [{a:g}, {b:g}]; swap them or use '
                      f'values: [{a:g}] for a fixed value')
    if kind == 'normal' and not b > 0:
        raise d.error(at, f'normal needs STD > 0, got {b:g}; use values: [{a:g}] for a fixed '
                      'value')
    return Axis(path, kind, (a, b))


def _check_top(d, data):
    if not isinstance(data, dict):
        raise d.error((), 'a sweep file is a mapping with keys '
                      f"{', '.join(TOP_FIELDS)}; got {type(data).__name__}")
    for key in data:
        if key not in TOP_FIELDS:
            raise d.error((key,), f"unknown key '{key}'{did_you_mean(key, TOP_FIELDS)}; keys: "
                          f"{', '.join(TOP_FIELDS)}")
    if data.get('version', VERSION) != VERSION:
        raise d.error(('version',), f"version {data['version']!r} is not supported; write "
                      f'version: {VERSION}')
    for key, fix in (('scenario', 'scenario: free_push.yaml (a file in config/scenarios/ '
                                  'or relative to this file)'),
                     ('axes', 'axes: {sim.stiffness: {values: [200, 400]}}'),
                     ('metrics', 'metrics: [tank_energy_min_j] (keys of the metrics.json '
                                 'of ifc-spg run)')):
        if data.get(key) is None:
            raise d.error((key,) if key in data else (), f"missing '{key}'; add {fix}")


def _scenario_file(d, name, here):
    if not isinstance(name, str) or not name:
        raise d.error(('scenario',), f'expected a scenario file name, got {name!r}')
    candidates = [Path(name)] if os.path.isabs(name) else [
        here / name, find_config_dir() / 'scenarios' / name]
    path = next((p for p in candidates if p.is_file()), None)
    if path is None:
        raise d.error(('scenario',), f"scenario file '{name}' not found; looked in "
                      f"{', '.join(str(p) for p in candidates)}")
    try:
        base = yaml.safe_load(path.read_text(encoding='utf8'))
    except yaml.YAMLError as exc:
        raise d.error(('scenario',), f"scenario '{path}' is not valid YAML: {exc}") from None
    if not isinstance(base, dict):
        raise d.error(('scenario',), f"scenario '{path}' is not a mapping of keys")
    return path, base


def _int(d, data, key, low, default):
    value = data.get(key, default)
    if value is None:
        return default
    if not isinstance(value, int) or isinstance(value, bool) or value < low:
        raise d.error((key,), f'{key} must be an integer >= {low}, got {value!r}')
    return value


def _metrics(d, metrics, scenario_metrics, scenario_path):
    if not isinstance(metrics, list) or not metrics:
        raise d.error(('metrics',), 'metrics needs a non-empty list of dotted paths into '
                      'metrics.json, e.g. [tank_energy_min_j, task_error_rms.physical]')
    seen = set()
    for i, m in enumerate(metrics):
        if not isinstance(m, str) or not m or not all(m.split('.')):
            raise d.error(('metrics', i), f'expected a dotted path like '
                          f"'task_error_rms.physical', got {m!r}")
        head = m.split('.')[0]
        if head not in _METRIC_KEYS:
            raise d.error(('metrics', i), f"'{head}' is not a key of metrics.json"
                          f'{did_you_mean(head, _METRIC_KEYS)}; keys: '
                          f"{', '.join(_METRIC_KEYS)}")
        need = _METRIC_KEYS[head]
        if need is not None and need not in scenario_metrics:
            raise d.error(('metrics', i), f"'{head}' needs the scenario metric '{need}', "
                          f"which {scenario_path.name} does not compute; add it to the "
                          "scenario's metrics (or set: {metrics: [...]} here)")
        if m in seen:
            raise d.error(('metrics', i), f"'{m}' is listed twice; remove one")
        seen.add(m)
    return tuple(metrics)


def _scenario_metric_names(data):
    spec = data.get('metrics')
    if spec is None:
        return set(_DEFAULT_SCENARIO_METRICS)
    out = set()
    for item in spec if isinstance(spec, list) else []:
        out.add(item if isinstance(item, str) else next(iter(item)) if isinstance(item, dict)
                and item else None)
    return out


def _axes(d, axes, base):
    if not isinstance(axes, dict) or not axes:
        raise d.error(('axes',), 'axes needs a mapping {PATH: SPEC}, e.g. '
                      '{sim.stiffness: {values: [200, 400]}}')
    out = []
    for path, spec in axes.items():
        if not isinstance(path, str):
            raise d.error(('axes', path), f'an axis is a dotted path into the scenario, e.g. '
                          f"'sim.stiffness', got {path!r}")
        axis = _axis(d, path, spec)
        try:
            set_path(copy.deepcopy(base), path, axis.spec[0])
        except ValueError as exc:
            raise d.error(('axes', path), f'{exc}') from None
        out.append(axis)
    return tuple(out)


def _set(d, values, base):
    if values is None:
        return {}
    if not isinstance(values, dict):
        raise d.error(('set',), 'set needs a mapping {PATH: VALUE}, e.g. {duration: 1.0}')
    for path, value in values.items():
        try:
            set_path(base, str(path), value)
        except ValueError as exc:
            raise d.error(('set', path), str(exc)) from None
    return dict(values)


def load_sweep(path, text=None):
    """Read and validate a sweep file.

    Args:
        path: The YAML file (its name is used in errors; stacks and the base scenario are
            found relative to it).
        text: The file's text (default: read it).

    Raises:
        SweepError: A bad field: the message names the file, line, field and the fix.
    """
    path = Path(path)
    if text is None:
        try:
            text = path.read_text(encoding='utf8')
        except OSError as exc:
            raise SweepError(f'cannot read the sweep file: {exc.strerror}',
                             source=str(path)) from None
    d = _Doc(load(text, fmt='yaml', source=str(path)))
    data = d.doc.data
    _check_top(d, data)
    scenario_path, base = _scenario_file(d, data['scenario'], path.parent)
    base = _inline_stack_files(base, scenario_path.parent)  # their fields become paths
    fixed = _set(d, data.get('set'), base)
    axes = _axes(d, data['axes'], base)
    randoms = [a.path for a in axes if a.random]
    if randoms and data.get('samples') is None:
        raise d.error(('axes', randoms[0]), f"'{randoms[0]}' is drawn at random: add "
                      'samples: N (the number of draws) and seed: S')
    if not randoms and data.get('samples') is not None:
        raise d.error(('samples',), 'samples needs a random axis (uniform, normal or choice); '
                      'remove samples or make an axis random')
    spec = SweepSpec(
        name=str(data.get('name') or path.stem), path=str(path),
        scenario_path=str(scenario_path), base=base, set=fixed, axes=axes,
        samples=_int(d, data, 'samples', 1, 1), seed=_int(d, data, 'seed', 0, 0),
        metrics=_metrics(d, data['metrics'], _scenario_metric_names(base), scenario_path),
        keep_bags=_keep_bags(d, data), description=str(data.get('description') or ''))
    if spec.count() > MAX_POINTS:
        raise d.error(('axes',), f'{spec.count()} points is more than {MAX_POINTS}; use fewer '
                      'values or samples')
    _check_first_point(d, spec)
    return spec


def _keep_bags(d, data):
    value = data.get('keep_bags', False)
    if not isinstance(value, bool):
        raise d.error(('keep_bags',), f'keep_bags must be true or false, got {value!r}')
    return value


def _check_first_point(d, spec):
    """The first point must make a valid scenario (else every point would fail alike).

    Each axis is tried alone first (its first value on the base scenario), so an error
    names the axis that causes it.
    """
    params = {a.path: a.spec[0] for a in spec.axes if not a.random}
    params.update(_draw([a for a in spec.axes if a.random], spec.seed, 0))
    params = {a.path: params[a.path] for a in spec.axes}
    for where, values in [(('axes', p), {p: v}) for p, v in params.items()] + [
            (('axes',), params)]:
        try:
            data = scenario_for(spec.base, values, spec.scenario_dir)
            scenario_from_dict(data, where=spec.scenario_path, base=Path(spec.scenario_dir))
        except (IfcSpgError, ValueError, TypeError) as exc:
            shown = ', '.join(f'{k}={v!r}' for k, v in values.items())
            raise d.error(where, f'{shown} does not make a valid scenario: {exc}; fix the '
                          'path or the values') from None
