"""Task specs: the frozen, robot-independent form of a task stack, parsed from plain data.

Parsing checks the structure (fields, types, names of types and trajectories, value
ranges that need no robot); :mod:`ifc_spg.task_stack.builder` checks the rest against a
robot model (frames, joints, dimensions) and builds the task objects.

Component vectors (bounds, gains, trajectory parameters) are written as one number
(every component), a list (one entry per component) or a mapping from component names
(subspace axes ``x y z rx ry rz`` / ``fx ... tz``, or joint names) to numbers, e.g.
``amplitude: {y: 0.1, z: 0.05}`` (unnamed components: 0).
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math
import re
from types import MappingProxyType
from typing import TYPE_CHECKING, Any

import numpy as np

from ifc_spg.errors import did_you_mean
from ifc_spg.task_stack.collision import (
    COLLISION_FIELDS,
    options_to_data,
    parse_obstacles,
    parse_options,
)
from ifc_spg.task_stack.errors import TaskStackError
from ifc_spg.tasks.subspace import AXES, SUBSPACE_FRAMES, WRENCH_AXES

if TYPE_CHECKING:
    from ifc_spg.task_stack.loader import Document, Path

__all__ = [
    'BOUND_FIELDS',
    'MAX_DIM',
    'MAX_TASKS',
    'TASK_FIELDS',
    'TASK_TYPES',
    'TRAJECTORIES',
    'VERSION',
    'BoundSpec',
    'ByName',
    'SubspaceSpec',
    'TaskSpec',
    'bound_to_data',
    'parse_document',
    'task_to_data',
]

VERSION = 1
MAX_TASKS = 64
MAX_DIM = 64
MAX_NAME = 128

TASK_TYPES = ('joint_position', 'cartesian_pose', 'joint_torque', 'wrench',
              'constrained_manipulation', 'collision_avoidance')
TOP_FIELDS = ('version', 'name', 'robot', 'description', 'power_budget', 'obstacles', 'tasks')
#: Largest power_budget [W] a stack may declare (the node's pspm.max_power caps it further).
MAX_POWER_BUDGET = 1e4
BOUND_FIELDS = ('equal', 'lower', 'upper')
_COMMON = ('name', 'type', 'description', 'equal', 'lower', 'upper', 'gain', 'feedforward',
           'velocity_gain', 'compensate_velocity')
TASK_FIELDS = {
    'joint_position': _COMMON + ('joints',),
    'joint_torque': _COMMON + ('joints', 'include_damping'),
    'cartesian_pose': _COMMON + ('frame', 'subspace', 'orientation', 'relative'),
    'wrench': _COMMON + ('frame', 'subspace', 'include_damping'),
    'constrained_manipulation': ('name', 'type', 'description', 'frame'),  # + free options
    'collision_avoidance': COLLISION_FIELDS,
}
SUBSPACE_FIELDS = ('axes', 'columns', 'frame')

# Trajectory parameters: name -> (kind of value, default; REQUIRED if it must be given).
REQUIRED = object()
TRAJECTORIES = {
    'constant': {'value': ('vector', REQUIRED)},
    'init': {},
    'circle': {'plane': ('plane', REQUIRED), 'radius': ('positive', REQUIRED),
               'frequency': ('number', REQUIRED), 'phase': ('number', 0.0),
               'center': ('anchor2', None), 'start': ('anchor2', None)},
    'sine': {'amplitude': ('vector', REQUIRED), 'frequency': ('vector', REQUIRED),
             'phase': ('vector', 0.0), 'offset': ('vector', 0.0), 'center': ('anchor', 'init')},
    'square': {'offsets': ('offsets', REQUIRED), 'period': ('positive', REQUIRED),
               'duty': ('fraction', 0.5), 'transition': ('nonnegative', 0.0),
               'center': ('anchor', 'init')},
    'ramp': {'from': ('anchor', 'init'), 'to': ('anchor_to', None), 'by': ('vector', None),
             'duration': ('positive', REQUIRED), 'delay': ('nonnegative', 0.0)},
    'min_jerk': {'from': ('anchor', 'init'), 'to': ('anchor_to', None), 'by': ('vector', None),
                 'duration': ('positive', REQUIRED), 'delay': ('nonnegative', 0.0)},
}
#: Streamed bounds (``equal: {stream: TOPIC, stale_after: S}``): the task types that take
#: one, and the message each reads (see ifc_spg.tasks.stream).
STREAM_TYPES = {'cartesian_pose': 'geometry_msgs/msg/PoseStamped',
                'joint_position': 'sensor_msgs/msg/JointState',
                'wrench': 'geometry_msgs/msg/WrenchStamped'}
STREAM_STALE_AFTER = 0.2  # [s] default
#: A streamed bound's topic: a relative, private (~) or absolute ROS topic name.
TOPIC_PATTERN = r'^~?/?[A-Za-z_][A-Za-z0-9_]*(/[A-Za-z_][A-Za-z0-9_]*)*$'
_TOPIC_RE = re.compile(TOPIC_PATTERN)
TRAJECTORY_ALIASES = {'lissajous': 'sine', 'square_wave': 'square', 'minjerk': 'min_jerk',
                      'linear': 'ramp'}
_TIME_LIMIT = 1e6  # [s], bound on durations/periods; also on |frequency| [Hz]
_VALUE_LIMIT = 1e9  # bound on magnitudes of numbers in a stack


def _show(x, limit=60):
    s = repr(x)
    return s if len(s) <= limit else s[:limit - 3] + '...'


@dataclass(frozen=True)
class ByName:
    """A component vector given by component names, ``(('y', 0.1), ('z', 0.05))``."""

    items: tuple

    def to_data(self) -> dict[str, Any]:
        """Plain mapping."""
        return {k: v for k, v in self.items}


@dataclass(frozen=True)
class BoundSpec:
    """A bound as written: a constant, ``init`` or a trajectory with its parameters.

    Attributes:
        kind: 'constant', 'init' or a trajectory name (see :data:`TRAJECTORIES`).
        params: ``((name, value), ...)`` with defaults filled in; component vectors are a
            float, a tuple (entries float, 'init' or None = open) or a :class:`ByName`.
    """

    kind: str
    params: tuple = ()

    def get(self, name: str, default: Any = None) -> Any:
        """Parameter ``name`` (or ``default``)."""
        for k, v in self.params:
            if k == name:
                return v
        return default


@dataclass(frozen=True)
class SubspaceSpec:
    """A Cartesian subspace: named axes or explicit orthonormal columns, in a frame.

    Attributes:
        axes: Axis names (``x y z rx ry rz`` or ``fx fy fz tx ty tz``), or None.
        columns: The columns of S (each 6 numbers), or None.
        frame: 'base', 'ee' or 'ee_orientation'.
    """

    axes: tuple | None = None
    columns: tuple | None = None
    frame: str = 'base'

    @property
    def dim(self) -> int:
        """Number of task directions m."""
        if self.axes is not None:
            return len(self.axes)
        return 0 if self.columns is None else len(self.columns)

    def matrix(self) -> np.ndarray | None:
        """S as a 6 x m array (None when given by axes; the task builds it)."""
        return None if self.columns is None else np.array(self.columns, dtype=float).T


@dataclass(frozen=True)
class TaskSpec:
    """One task of the stack as written (robot-independent).

    Attributes:
        name: Task name (unique in the stack).
        type: One of :data:`TASK_TYPES`.
        index: Position in the stack (0 = highest priority).
        frame: Chain id (Cartesian tasks), or None.
        joints: Joint names (joint tasks), or None (all joints).
        subspace: :class:`SubspaceSpec` (Cartesian tasks), or None (all six directions).
        equal, lower, upper: :class:`BoundSpec` or None.
        gain: Lambda in [1/s]: float, tuple or :class:`ByName`.
        feedforward: 'trajectory', None (zero) or a component vector.
        velocity_gain: k_d (adds k_d times the measured task rate).
        compensate_velocity: Add the velocity compensation gamma.
        orientation: 'init' or a 3 x 3 rotation (rows) for ``cartesian_pose``.
        relative: Positions relative to the position at activation (``cartesian_pose``).
        include_damping: The static value includes -D qdot (``wrench``, ``joint_torque``).
        options: Further fields of ``constrained_manipulation`` (read-only mapping).
        description: Free text.
    """

    name: str
    type: str
    index: int = 0
    frame: str | None = None
    joints: tuple | None = None
    subspace: SubspaceSpec | None = None
    equal: BoundSpec | None = None
    lower: BoundSpec | None = None
    upper: BoundSpec | None = None
    gain: object = 1.0
    feedforward: object = 'trajectory'
    velocity_gain: float = 0.0
    compensate_velocity: bool = True
    orientation: object = 'init'
    relative: bool = False
    include_damping: bool = False
    options: MappingProxyType = field(default_factory=lambda: MappingProxyType({}))
    description: str | None = None


# -- to plain data (the normalized stack) -------------------------------------------------
def _vec_to_data(v):
    if isinstance(v, ByName):
        return v.to_data()
    if isinstance(v, tuple):
        return [_vec_to_data(x) for x in v]
    return v


def bound_to_data(b: BoundSpec) -> Any:
    """Plain data of a :class:`BoundSpec` (number, list, 'init' or a trajectory mapping)."""
    if b.kind == 'init':
        return 'init'
    if b.kind == 'constant':
        return _vec_to_data(b.get('value'))
    if b.kind == 'stream':
        return dict(b.params)
    out = {'trajectory': b.kind}
    for k, v in b.params:
        if v is not None:
            out[k] = _vec_to_data(v)
    return out


def _thaw(x):
    if isinstance(x, (MappingProxyType, dict)):
        return {k: _thaw(v) for k, v in x.items()}
    if isinstance(x, (tuple, list)):
        return [_thaw(v) for v in x]
    return x


def _options_to_data(t: TaskSpec, out: dict[str, Any]) -> dict[str, Any]:
    """Plain data of the task types that keep their fields in ``options``."""
    if t.type == 'collision_avoidance':
        out.update(options_to_data(t.options))
        return out
    out['frame'] = t.frame
    out.update(_thaw(t.options))
    return out


def task_to_data(t: TaskSpec) -> dict[str, Any]:
    """Plain data of a :class:`TaskSpec` (every field explicit, defaults filled in)."""
    out: dict[str, Any] = {'name': t.name, 'type': t.type}
    if t.description is not None:
        out['description'] = t.description
    if t.type in ('constrained_manipulation', 'collision_avoidance'):
        return _options_to_data(t, out)
    if t.type in ('cartesian_pose', 'wrench'):
        out['frame'] = t.frame
        sub = t.subspace
        if sub is None:
            out['subspace'] = {'axes': list(AXES if t.type == 'cartesian_pose' else WRENCH_AXES),
                               'frame': 'base'}
        elif sub.axes is not None:
            out['subspace'] = {'axes': list(sub.axes), 'frame': sub.frame}
        else:
            out['subspace'] = {'columns': [list(c) for c in sub.columns or ()],
                               'frame': sub.frame}
    else:
        out['joints'] = None if t.joints is None else list(t.joints)
    for k in BOUND_FIELDS:
        b = getattr(t, k)
        if b is not None:
            out[k] = bound_to_data(b)
    out['gain'] = _vec_to_data(t.gain)
    out['feedforward'] = _vec_to_data(t.feedforward)
    out['velocity_gain'] = t.velocity_gain
    out['compensate_velocity'] = t.compensate_velocity
    if t.type == 'cartesian_pose':
        orientation: Any = t.orientation  # 'init' or 3 rows of 3 numbers
        out['orientation'] = orientation if isinstance(orientation, str) \
            else [list(r) for r in orientation]
        out['relative'] = t.relative
    if t.type in ('wrench', 'joint_torque'):
        out['include_damping'] = t.include_damping
    return out


# -- parsing ---------------------------------------------------------------------------------
class _Parser:
    def __init__(self, doc):
        self.doc = doc

    def err(self, path, reason):
        return self.doc.error(path, reason)

    # primitives
    def number(self, path, x, what='a number'):
        if isinstance(x, bool) or not isinstance(x, (int, float)):
            raise self.err(path, f'expected {what}, got {_show(x)}')
        x = float(x)
        if not math.isfinite(x):
            raise self.err(path, f'{x} is not allowed: numbers must be finite')
        if abs(x) > _VALUE_LIMIT:
            raise self.err(path, f'{x:g} is out of range (|value| <= {_VALUE_LIMIT:g})')
        return x

    def string(self, path, x, what='a name'):
        if not isinstance(x, str) or not x:
            raise self.err(path, f'expected {what} (text), got {_show(x)}')
        if len(x) > MAX_NAME:
            raise self.err(path, f'{what} is {len(x)} characters long, more than {MAX_NAME}')
        return x

    def boolean(self, path, x):
        if not isinstance(x, bool):
            raise self.err(path, f'expected true or false, got {_show(x)}')
        return x

    def mapping(self, path, x, what):
        if not isinstance(x, dict):
            raise self.err(path, f'expected {what} (a mapping of fields), got {_show(x)}')
        return x

    def fields(self, path, x, allowed, what):
        for k in x:
            if k not in allowed:
                raise self.err(path + (k,), f"unknown field '{k}'{did_you_mean(k, allowed)}; "
                                            f"fields of {what}: {', '.join(allowed)}")

    def choice(self, path, x, choices, what):
        if not isinstance(x, str) or x not in choices:
            raise self.err(path, f'unknown {what} {_show(x)}'
                           f'{did_you_mean(x, choices) if isinstance(x, str) else ""}; '
                           f"valid: {', '.join(choices)}")
        return x

    # component vectors
    def vector(self, path: Path, x: Any, *, allow_init: bool = False, allow_open: bool = False,
               what: str = 'value') -> Any:
        """Number | list | mapping name -> number ('init' / None entries if allowed)."""
        def entry(p: Path, v: Any) -> Any:
            return self._entry(p, v, allow_init, allow_open, what)
        if isinstance(x, list):
            self._check_count(path, x, what, 'empty list; give one value per component',
                              'values')
            return tuple(entry(path + (i,), v) for i, v in enumerate(x))
        if isinstance(x, dict):
            self._check_count(path, x, what, 'empty mapping; give component: value pairs',
                              'entries')
            return ByName(tuple((k, entry(path + (k,), v)) for k, v in x.items()))
        if allow_init and x == 'init':
            return 'init'
        return entry(path, x)

    def _entry(self, path: Path, v: Any, allow_init: bool, allow_open: bool, what: str) -> Any:
        """One component: a number, or 'init' / None (open) where allowed."""
        if allow_init and v == 'init':
            return 'init'
        if allow_open and v is None:
            return None
        return self.number(path, v, f"a number{' or init' if allow_init else ''}"
                                    f"{' or null (open)' if allow_open else ''} for {what}")

    def _check_count(self, path: Path, x: list | dict, what: str, empty: str,
                     items: str) -> None:
        if not x:
            raise self.err(path, f'{what}: {empty}')
        if len(x) > MAX_DIM:
            raise self.err(path, f'{what}: {len(x)} {items}, more than the limit {MAX_DIM}')

    # the document
    def stack(self, data: Any) -> dict[str, Any]:
        """Parse the whole document into the keyword arguments of a TaskStack."""
        if data is None:
            raise self.err((), 'empty document; a task stack needs version: 1 and tasks')
        self.mapping((), data, 'a task stack')
        self.fields((), data, TOP_FIELDS, 'a task stack')
        self.version(data)
        name = self.string(('name',), data['name'], 'a stack name') if 'name' in data \
            else 'task_stack'
        robot = self.string(('robot',), data['robot'], 'a robot name') \
            if data.get('robot') is not None else None
        desc = data.get('description')
        if desc is not None and not isinstance(desc, str):
            raise self.err(('description',), f'expected text, got {_show(desc)}')
        budget = self.power_budget(data['power_budget']) if data.get('power_budget') \
            is not None else None
        return {'version': VERSION, 'name': name, 'robot': robot, 'description': desc,
                'power_budget': budget, 'obstacles': parse_obstacles(self, data.get('obstacles')),
                'tasks': self.tasks(data)}

    def version(self, data: dict[str, Any]) -> None:
        if 'version' not in data:
            raise self.err((), f'missing field version; add version: {VERSION}')
        v = data['version']
        if isinstance(v, bool) or v != VERSION:
            raise self.err(('version',), f'unsupported version {_show(v)}; this ifc_spg reads '
                                         f'version {VERSION}')

    def tasks(self, data: dict[str, Any]) -> tuple[TaskSpec, ...]:
        """The task list: at least one, at most MAX_TASKS, with unique names."""
        if 'tasks' not in data:
            raise self.err((), 'missing field tasks; list the tasks, highest priority first')
        tasks = data['tasks']
        if not isinstance(tasks, list):
            raise self.err(('tasks',), f'expected a list of tasks, got {_show(tasks)}')
        if not tasks:
            raise self.err(('tasks',), 'no tasks; list at least one task')
        if len(tasks) > MAX_TASKS:
            raise self.err(('tasks',), f'{len(tasks)} tasks, more than the limit {MAX_TASKS}')
        specs = tuple(self.task(('tasks', i), t, i) for i, t in enumerate(tasks))
        seen: dict[str, int] = {}
        for t in specs:
            if t.name in seen:
                raise self.err(('tasks', t.index, 'name'),
                               f"task name '{t.name}' is used twice (also tasks[{seen[t.name]}]);"
                               ' names must be unique')
            seen[t.name] = t.index
        return specs

    def power_budget(self, x):
        path = ('power_budget',)
        if isinstance(x, bool) or not isinstance(x, (int, float)):
            raise self.err(path, f'expected a power in watts (a number, e.g. power_budget: '
                                 f'2.0), got {_show(x)}')
        x = float(x)
        if not (math.isfinite(x) and 0.0 <= x <= MAX_POWER_BUDGET):
            raise self.err(path, f'{x:g} W is out of range: the refill rate of the energy '
                                 f'tanks must be in [0, {MAX_POWER_BUDGET:g}] W (0 or no '
                                 'power_budget: strictly passive)')
        return x

    def task(self, path: Path, x: Any, index: int) -> TaskSpec:
        """Parse one task entry (``tasks[index]``)."""
        self.mapping(path, x, 'a task')
        if 'type' not in x:
            raise self.err(path, f"missing field type; one of {', '.join(TASK_TYPES)}")
        ttype = self.choice(path + ('type',), x['type'], TASK_TYPES, 'task type')
        name = self.string(path + ('name',), x['name'], 'a task name') if 'name' in x \
            else f'{ttype}_{index}'
        desc = x.get('description')
        if desc is not None and not isinstance(desc, str):
            raise self.err(path + ('description',), f'expected text, got {_show(desc)}')
        kw: dict[str, Any] = {'name': name, 'type': ttype, 'index': index, 'description': desc}
        if ttype == 'constrained_manipulation':
            kw['frame'] = self.frame(path, x, 'missing field frame (the chain id that grasps '
                                              'the mechanism, e.g. tool)')
            kw['options'] = MappingProxyType({
                k: _freeze(v) for k, v in x.items() if k not in TASK_FIELDS[ttype]})
            return TaskSpec(**kw)
        if ttype == 'collision_avoidance':
            return TaskSpec(options=parse_options(self, path, x), **kw)
        self.fields(path, x, TASK_FIELDS[ttype], f'a {ttype} task')
        kw.update(self.task_geometry(path, x, ttype))
        kw.update(self.task_bounds(path, x))
        if getattr(kw.get('equal'), 'kind', None) == 'stream' and ttype not in STREAM_TYPES:
            raise self.err(path + ('equal',), f'a {ttype} task cannot follow a stream; '
                                              f"streamed tasks: {', '.join(STREAM_TYPES)}")
        kw.update(self.task_regulation(path, x))
        for key, parse in (('orientation', self.orientation), ('relative', self.boolean),
                           ('include_damping', self.boolean)):
            if key in x:
                kw[key] = parse(path + (key,), x[key])
        return TaskSpec(**kw)

    def frame(self, path: Path, x: dict[str, Any], missing: str) -> str:
        """The task's ``frame`` (a chain id); ``missing`` is the error without one."""
        if 'frame' not in x:
            raise self.err(path, missing)
        return self.string(path + ('frame',), x['frame'], 'a frame (chain id)')

    def task_geometry(self, path: Path, x: dict[str, Any], ttype: str) -> dict[str, Any]:
        """Frame and subspace (Cartesian tasks) or joints (joint tasks)."""
        if ttype not in ('cartesian_pose', 'wrench'):
            if x.get('joints') is not None:
                return {'joints': self.joints(path + ('joints',), x['joints'])}
            return {}
        frame = self.frame(path, x, f'missing field frame (the chain id) for the {ttype} task')
        if x.get('subspace') is not None:
            subspace = self.subspace(path + ('subspace',), x['subspace'], ttype)
        else:
            subspace = SubspaceSpec(axes=AXES if ttype == 'cartesian_pose' else WRENCH_AXES)
        return {'frame': frame, 'subspace': subspace}

    def task_bounds(self, path: Path, x: dict[str, Any]) -> dict[str, BoundSpec]:
        """``equal``, or ``lower`` and/or ``upper``."""
        if 'equal' in x and ('lower' in x or 'upper' in x):
            raise self.err(path + ('equal',), "give either 'equal' (equality task) or "
                                              "'lower'/'upper' (inequality task), not both")
        if not any(k in x for k in BOUND_FIELDS):
            raise self.err(path, "no bounds; give 'equal' (equality task) or 'lower' and/or "
                                 "'upper' (inequality task)")
        return {k: self.bound(path + (k,), x[k], k) for k in BOUND_FIELDS if k in x}

    def task_regulation(self, path: Path, x: dict[str, Any]) -> dict[str, Any]:
        """Gain, feed-forward, velocity gain and compensation."""
        kw: dict[str, Any] = {}
        if 'gain' in x:
            kw['gain'] = self.vector(path + ('gain',), x['gain'], what='gain')
            self.nonnegative_vector(path + ('gain',), kw['gain'], 'gain')
        if 'feedforward' in x:
            kw['feedforward'] = self.feedforward(path + ('feedforward',), x['feedforward'])
        if 'velocity_gain' in x:
            kw['velocity_gain'] = self.number(path + ('velocity_gain',), x['velocity_gain'])
        if 'compensate_velocity' in x:
            kw['compensate_velocity'] = self.boolean(path + ('compensate_velocity',),
                                                     x['compensate_velocity'])
        return kw

    def feedforward(self, path: Path, ff: Any) -> Any:
        """'trajectory', None (zero) or rates per component."""
        if ff in (None, 'none', 'zero'):
            return None
        if ff == 'trajectory':
            return 'trajectory'
        if isinstance(ff, str):
            raise self.err(path, f"feedforward {_show(ff)} unknown; use 'trajectory' (the "
                                 "bounds' rates, default), none, or rates per component"
                                 + did_you_mean(ff, ('trajectory', 'none')))
        return self.vector(path, ff, what='feedforward')

    def nonnegative_vector(self, path, v, what):
        vals = v.to_data().values() if isinstance(v, ByName) else \
            (v if isinstance(v, tuple) else (v,))
        for x in vals:
            if x < 0:
                raise self.err(path, f'{what} must be >= 0, got {x:g}')

    def joints(self, path, x):
        if isinstance(x, str):
            x = [x]
        if not isinstance(x, list) or not x:
            raise self.err(path, f'expected a list of joint names, got {_show(x)}')
        if len(x) > MAX_DIM:
            raise self.err(path, f'{len(x)} joints, more than the limit {MAX_DIM}')
        out = tuple(self.string(path + (i,), j, 'a joint name') for i, j in enumerate(x))
        for i, j in enumerate(out):
            if j in out[:i]:
                raise self.err(path + (i,), f"joint '{j}' listed twice")
        return out

    def subspace(self, path, x, ttype):
        names = AXES if ttype == 'cartesian_pose' else WRENCH_AXES
        frame = 'base'
        if isinstance(x, dict):
            self.fields(path, x, SUBSPACE_FIELDS, 'a subspace')
            if 'frame' in x:
                frame = self.choice(path + ('frame',), x['frame'], SUBSPACE_FRAMES,
                                    'subspace frame')
            if ('axes' in x) == ('columns' in x):
                raise self.err(path, "give either 'axes' (names) or 'columns' (explicit "
                                     'orthonormal columns of S, 6 numbers each)')
            if 'columns' in x:
                return SubspaceSpec(columns=self.columns(path + ('columns',), x['columns']),
                                    frame=frame)
            path, x = path + ('axes',), x['axes']
        return SubspaceSpec(axes=self.axes(path, x, names), frame=frame)

    def axes(self, path, x, names):
        alias = dict(zip(AXES, WRENCH_AXES)) if names is WRENCH_AXES \
            else dict(zip(WRENCH_AXES, AXES))
        if isinstance(x, str):
            x = x.replace(',', ' ').split()
        if not isinstance(x, list) or not x:
            raise self.err(path, f"expected axis names ({' '.join(names)}), got {_show(x)}")
        out = []
        for i, a in enumerate(x):
            if not isinstance(a, str):
                raise self.err(path + (i,), f"expected an axis name ({' '.join(names)}), got "
                                            f'{_show(a)}')
            a = alias.get(a, a)
            if a not in names:
                raise self.err(path + (i,), f"unknown axis '{a}'{did_you_mean(a, names)}; "
                                            f"valid axes: {' '.join(names)}")
            if a in out:
                raise self.err(path + (i,), f"axis '{a}' listed twice")
            out.append(a)
        return tuple(out)

    def columns(self, path, x):
        if not isinstance(x, list) or not x:
            raise self.err(path, 'expected a list of columns of S, each 6 numbers (x y z rx '
                                 f'ry rz), got {_show(x)}')
        if len(x) > 6:
            raise self.err(path, f'{len(x)} columns; a Cartesian subspace has at most 6')
        cols = []
        for i, c in enumerate(x):
            if not isinstance(c, list) or len(c) != 6:
                raise self.err(path + (i,), f'column {i} must be 6 numbers (x y z rx ry rz), '
                                            f'got {_show(c)}')
            cols.append(tuple(self.number(path + (i, k), v) for k, v in enumerate(c)))
        S = np.array(cols).T
        G = S.T @ S
        err = np.abs(G - np.eye(len(cols))).max()
        if err > 1e-6:
            norms = np.sqrt(np.diag(G))
            bad = [f'column {i} has norm {n:.3g}' for i, n in enumerate(norms)
                   if abs(n - 1.0) > 1e-6]
            iu = np.argwhere(np.triu(np.abs(G), 1) > 1e-6)
            bad += [f'columns {i} and {j} have dot product {G[i, j]:.3g}' for i, j in iu[:3]]
            raise self.err(path, 'columns are not orthonormal (' + '; '.join(bad) + '); '
                                 'normalize each column and make them perpendicular')
        return tuple(cols)

    def orientation(self, path, x):
        if x == 'init':
            return 'init'
        if not (isinstance(x, list) and len(x) == 3
                and all(isinstance(r, list) and len(r) == 3 for r in x)):
            raise self.err(path, "orientation must be 'init' or a 3 x 3 rotation matrix (3 "
                                 f'rows of 3 numbers), got {_show(x)}')
        R = np.array([[self.number(path + (i, k), v) for k, v in enumerate(r)]
                      for i, r in enumerate(x)])
        if np.abs(R.T @ R - np.eye(3)).max() > 1e-6 or np.linalg.det(R) < 0:
            raise self.err(path, 'orientation is not a rotation matrix (R^T R = I, det R = 1 '
                                 'within 1e-6)')
        return tuple(tuple(float(v) for v in r) for r in R)

    # bounds and trajectories
    def bound(self, path, x, which):
        allow_open = which != 'equal'
        if isinstance(x, dict) and 'stream' in x:
            return self.stream(path, x, which)
        if isinstance(x, dict):
            return self.trajectory(path, x)
        if isinstance(x, str):
            if x == 'init':
                return BoundSpec('init')
            raise self.err(path, f"expected a number, a list, 'init' or a trajectory "
                                 f'({{trajectory: circle, ...}}), got {_show(x)}'
                                 + did_you_mean(x, ('init',)))
        if x is None:
            raise self.err(path, f'{which} has no value; give a number, a list, init or a '
                                 'trajectory (omit lower/upper to leave that side open)')
        v = self.vector(path, x, allow_init=True, allow_open=allow_open, what=which)
        return BoundSpec('constant', (('value', v),))

    def stream(self, path, x, which):
        """A streamed target: ``{stream: TOPIC or null, stale_after: S}`` (equal only)."""
        if which != 'equal':
            raise self.err(path, f'{which}: a streamed bound is a target; write it as '
                                 'equal: {stream: TOPIC}')
        self.fields(path, x, ('stream', 'stale_after'), 'a streamed bound')
        topic = x['stream']
        if topic is not None and (not isinstance(topic, str) or
                                  not _TOPIC_RE.fullmatch(topic)):
            raise self.err(path + ('stream',), f'expected a topic name (e.g. spg/reference/'
                                               f'tool, or null for the default), got '
                                               f'{_show(topic)}')
        stale = x.get('stale_after', STREAM_STALE_AFTER)
        stale = self.number(path + ('stale_after',), stale, 'a time in seconds')
        if not 0.0 < stale <= _TIME_LIMIT:
            raise self.err(path + ('stale_after',), f'stale_after must be > 0 s, got '
                                                    f'{stale:g}')
        return BoundSpec('stream', (('stream', topic), ('stale_after', stale)))

    def trajectory(self, path, x):
        kinds = tuple(TRAJECTORIES) + tuple(TRAJECTORY_ALIASES)
        if 'trajectory' not in x:
            raise self.err(path, "a mapping bound needs 'trajectory: KIND' with KIND one of "
                                 f"{', '.join(TRAJECTORIES)}" + (
                                     ' (component values by name are only allowed in '
                                     'gains and trajectory parameters)' if x else ''))
        kind = self.choice(path + ('trajectory',), x['trajectory'], kinds, 'trajectory')
        kind = TRAJECTORY_ALIASES.get(kind, kind)
        table = TRAJECTORIES[kind]
        self.fields(path, x, ('trajectory',) + tuple(table), f'a {kind} trajectory')
        params = []
        for name, (vkind, default) in table.items():
            p = path + (name,)
            if name not in x:
                if default is REQUIRED:
                    raise self.err(path, f'{kind} trajectory: missing parameter {name}')
                params.append((name, default))
                continue
            params.append((name, self.param(p, x[name], vkind, name)))
        b = BoundSpec(kind, tuple(params))
        if kind == 'constant':
            return BoundSpec('constant', (('value', b.get('value')),))
        if kind == 'init':
            return BoundSpec('init')
        self.check_trajectory(path, x, b)
        return b

    def check_trajectory(self, path: Path, x: dict[str, Any], b: BoundSpec) -> None:
        """The checks across a trajectory's parameters."""
        kind = b.kind
        if kind == 'circle' and x.get('center') is not None and x.get('start') is not None:
            raise self.err(path + ('start',), "circle: give either 'center' or 'start' (the "
                                              'point at t = 0), not both')
        if kind in ('ramp', 'min_jerk') and (x.get('to') is None) == (x.get('by') is None):
            raise self.err(path, f"{kind}: give exactly one of 'to' (the end value) or 'by' "
                                 '(the displacement)')
        if kind == 'square' and b.get('transition') > 0:
            short = min(b.get('duty'), 1.0 - b.get('duty')) * b.get('period')
            if b.get('transition') > short:
                raise self.err(path + ('transition',),
                               f"square: transition {b.get('transition'):g} s is longer than "
                               f'the shorter phase ({short:g} s = period x min(duty, 1 - duty))')

    def param(self, path: Path, x: Any, vkind: str, name: str) -> Any:
        """One trajectory parameter of kind ``vkind`` (see :data:`TRAJECTORIES`)."""
        if vkind == 'vector':
            return self.vector(path, x, what=name)
        if vkind in ('anchor', 'anchor_to'):
            return self.vector(path, x, allow_init=True, what=name)
        if vkind == 'anchor2':
            return self.anchor2(path, x, name)
        if vkind == 'offsets':
            if not isinstance(x, list) or len(x) != 2:
                raise self.err(path, 'offsets: expected a list of two offsets (first and '
                                     f'second level), got {_show(x)}')
            return tuple(self.vector(path + (i,), v, what='offset') for i, v in enumerate(x))
        if vkind == 'plane':
            return self.plane(path, x)
        return self.scalar_param(path, x, vkind, name)

    def anchor2(self, path: Path, x: Any, name: str) -> Any:
        """Two values in plane order, or init (a circle's center or start)."""
        v = self.vector(path, x, allow_init=True, what=name)
        if isinstance(v, tuple) and len(v) != 2:
            raise self.err(path, f'{name}: expected 2 values (the two plane components) or '
                                 f'init, got {len(v)}')
        if isinstance(v, ByName):
            raise self.err(path, f'{name}: give 2 values (in plane order) or init')
        return v

    def scalar_param(self, path: Path, x: Any, vkind: str, name: str) -> float:
        """A number in the range its kind allows (positive, fraction, ...)."""
        v = self.number(path, x, f'a number for {name}')
        if vkind == 'positive' and not 0.0 < v <= _TIME_LIMIT:
            raise self.err(path, f'{name} must be > 0 (and <= {_TIME_LIMIT:g}), got {v:g}')
        if vkind == 'nonnegative' and not 0.0 <= v <= _TIME_LIMIT:
            raise self.err(path, f'{name} must be >= 0 (and <= {_TIME_LIMIT:g}), got {v:g}')
        if vkind == 'fraction' and not 0.0 < v < 1.0:
            raise self.err(path, f'{name} must be in (0, 1), got {v:g}')
        if vkind == 'number' and name == 'frequency' and abs(v) > _TIME_LIMIT:
            raise self.err(path, f'frequency {v:g} Hz is out of range')
        return v

    def plane(self, path, x):
        if isinstance(x, str):
            parts = x.replace(',', ' ').split()
            if len(parts) == 1:
                m = re.fullmatch(r'([ft]?[xyz]|r[xyz])([ft]?[xyz]|r[xyz])', x)
                parts = list(m.groups()) if m else parts
            x = parts
        if not isinstance(x, list) or len(x) != 2:
            raise self.err(path, 'plane: expected two components (e.g. xy, [y, z], or two '
                                 f'component indices), got {_show(x)}')
        out = []
        for i, c in enumerate(x):
            if isinstance(c, bool) or not isinstance(c, (str, int)):
                raise self.err(path + (i,), f'plane: expected a component name or index, got '
                                            f'{_show(c)}')
            out.append(c)
        if out[0] == out[1]:
            raise self.err(path, f'plane: the two components must differ, got {_show(out)}')
        return tuple(out)


def _freeze(x):
    if isinstance(x, dict):
        return MappingProxyType({k: _freeze(v) for k, v in x.items()})
    if isinstance(x, list):
        return tuple(_freeze(v) for v in x)
    return x


def parse_document(doc: Document) -> dict[str, Any]:
    """Parse a loaded :class:`~ifc_spg.task_stack.loader.Document`.

    Returns:
        dict with ``version``, ``name``, ``robot``, ``description``, ``tasks`` (tuple of
        :class:`TaskSpec`).

    Raises:
        TaskStackError: On any structural error (path, line and column in the message).
    """
    try:
        return _Parser(doc).stack(doc.data)
    except TaskStackError:
        raise
    except RecursionError:
        raise doc.error((), 'document nested too deeply') from None
