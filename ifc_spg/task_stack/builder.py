"""Validate task specs against a robot model and build the task objects (ifc_spg.tasks).

Everything that needs the robot is checked here: frames (chain ids), joint names, the
task dimension m and the sizes of bounds, gains and trajectory parameters, component
names, lower <= upper, joint targets inside the joint limits. Then the tasks are
constructed; any error from a task constructor is reported at the task's path, so a stack
that validates also builds.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
import importlib
from types import ModuleType
from typing import TYPE_CHECKING, Any

import numpy as np

from ifc_spg.errors import IfcSpgError, did_you_mean
from ifc_spg.task_stack.errors import TaskStackError
from ifc_spg.task_stack.spec import ByName, task_to_data
from ifc_spg.task_stack.trajectories import Anchor, Circle, Ramp, Sine, SquareWave
from ifc_spg.tasks import (
    CartesianPoseTask,
    Constant,
    Init,
    JointPositionTask,
    JointTorqueTask,
    WrenchTask,
)
from ifc_spg.tasks.stream import StreamBound, base_frames
from ifc_spg.tasks.subspace import AXES, WRENCH_AXES

if TYPE_CHECKING:
    from ifc_spg.model.robot_model import RobotModel
    from ifc_spg.task_stack.spec import BoundSpec, TaskSpec
    from ifc_spg.task_stack.task_stack import TaskStack
    from ifc_spg.tasks.bounds import Bound
    from ifc_spg.tasks.task import Task

#: A field's path in the document, e.g. ``('tasks', 2, 'subspace')``.
Path = tuple[str | int, ...]

__all__ = ['CONSTRAINED_MODULE', 'bound_list', 'build_tasks']

CONSTRAINED_MODULE = 'ifc_spg.constrained'

_CLASSES = {
    'joint_position': JointPositionTask,
    'joint_torque': JointTorqueTask,
    'cartesian_pose': CartesianPoseTask,
    'wrench': WrenchTask,
}


class _Components:
    """Dimension and names of a task's components (for sizes and name lookups)."""

    def __init__(self, dim: int, names: Sequence[str] | None, describe: str) -> None:
        self.dim = dim
        self.names = tuple(names) if names is not None else None
        self.describe = describe  # e.g. 'subspace directions y z rx ry rz'


def _constrained_module() -> ModuleType | None:
    try:
        return importlib.import_module(CONSTRAINED_MODULE)
    except ModuleNotFoundError as exc:
        if exc.name and CONSTRAINED_MODULE.startswith(exc.name):
            return None
        raise


class _Builder:
    def __init__(self, stack: TaskStack, robot: RobotModel) -> None:
        self.stack = stack
        self.robot = robot

    def err(self, path: Path, reason: str) -> TaskStackError:
        return self.stack.error(path, reason)

    # -- components ------------------------------------------------------------------------
    def components(self, spec: TaskSpec, path: Path) -> _Components:
        robot = self.robot
        if spec.type in ('cartesian_pose', 'wrench'):
            names = AXES if spec.type == 'cartesian_pose' else WRENCH_AXES
            sub = spec.subspace
            if sub is None:
                axes = names
            elif sub.axes is not None:
                axes = sub.axes
            else:
                return _Components(sub.dim, None, f'{sub.dim} subspace columns')
            return _Components(len(axes), axes, f"subspace directions {' '.join(axes)}")
        if spec.joints is not None:
            for i, j in enumerate(spec.joints):
                if j not in robot.joint_names:
                    raise self.err(path + ('joints', i),
                                   f"joint '{j}' not in model '{robot.name}'"
                                   f'{did_you_mean(j, robot.joint_names)}; joints: '
                                   f"{', '.join(robot.joint_names)}")
            joints: Sequence[str] = spec.joints
            if spec.type == 'joint_torque':
                stiff = [j for j in joints if robot.stiff_mask[robot.joint_index(j)]]
                if stiff:
                    raise self.err(path + ('joints',),
                                   f"joint(s) {', '.join(stiff)} are stiff (position "
                                   'controlled) and have no static torque; remove them from '
                                   'the joint_torque task')
        else:
            joints = [j for i, j in enumerate(robot.joint_names)
                      if not (spec.type == 'joint_torque' and robot.stiff_mask[i])]
        return _Components(len(joints), joints, f"joints {' '.join(joints)}")

    def frame(self, spec: TaskSpec, path: Path) -> None:
        if spec.frame not in self.robot.chains:
            raise self.err(path + ('frame',),
                           f"'{spec.frame}' not in model '{self.robot.name}'"
                           f'{did_you_mean(spec.frame, self.robot.chains)}; frames (chain '
                           f"ids): {', '.join(self.robot.chains)}")

    def vector(self, path: Path, v: Any, comp: _Components, *, what: str, fill: float = 0.0,
               allow_init: bool = False,
               allow_open: float | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Resolve a component vector to ``(values (m,), init_mask (m,))``."""
        m = comp.dim
        if isinstance(v, ByName):
            if comp.names is None:
                raise self.err(path, f'{what}: components by name need named components; '
                                     f'this task has {comp.describe}, give a list of {m}')
            values = np.full(m, fill)
            mask = np.zeros(m, bool)
            for k, x in v.items:
                if k not in comp.names:
                    raise self.err(path + (k,),
                                   f"'{k}' is not a component of this task"
                                   f'{did_you_mean(k, comp.names)}; components: '
                                   f"{', '.join(comp.names)}")
                i = comp.names.index(k)
                mask[i] = x == 'init'
                values[i] = 0.0 if x == 'init' else (
                    allow_open if x is None else x)
            return values, mask
        if isinstance(v, tuple):
            if len(v) != m:
                raise self.err(path, f'{what}: expected {m} values (one per component: '
                                     f'{comp.describe}), got {len(v)}: {bound_list(v)}')
            mask = np.array([x == 'init' for x in v], bool)
            values = np.array([0.0 if x == 'init' else (allow_open if x is None else x)
                               for x in v], float)
            return values, mask
        if v == 'init':
            return np.zeros(m), np.ones(m, bool)
        return np.full(m, float(v)), np.zeros(m, bool)

    def index(self, path: Path, c: str | int, comp: _Components) -> int:
        if isinstance(c, int):
            if not 0 <= c < comp.dim:
                raise self.err(path, f'component index {c} out of range 0..{comp.dim - 1} '
                                     f'({comp.describe})')
            return c
        if comp.names is None or c not in comp.names:
            choices = comp.names or ()
            raise self.err(path, f"'{c}' is not a component of this task"
                                 f'{did_you_mean(c, choices)}; components: '
                                 + (', '.join(choices) if choices else
                                    f'indices 0..{comp.dim - 1}'))
        return comp.names.index(c)

    # -- bounds ----------------------------------------------------------------------------
    def bound(self, path: Path, b: BoundSpec, comp: _Components, which: str) -> Bound:
        """Return a :class:`~ifc_spg.tasks.bounds.Bound` of dimension m."""
        if b.kind == 'init':
            return Init()
        if b.kind == 'stream':
            return StreamBound(b.get('stream'), b.get('stale_after'))
        if b.kind == 'constant':
            open_fill = np.inf if which == 'upper' else -np.inf
            values, mask = self.vector(path, b.get('value'), comp, what=which,
                                       allow_open=open_fill)
            if mask.any():
                return Init(mask=mask, other=Constant(values)) if not mask.all() else Init()
            return Constant(values)
        p = dict(b.params)
        if b.kind == 'circle':
            return self._circle(path, p, comp)
        if b.kind == 'sine':
            return Sine(comp.dim, amplitude=self._values(path, p, 'amplitude', comp),
                        frequency=self._values(path, p, 'frequency', comp),
                        phase=self._values(path, p, 'phase', comp),
                        offset=self._values(path, p, 'offset', comp),
                        center=self._anchor(path, p, 'center', comp))
        if b.kind == 'square':
            offs = [self.vector(path + ('offsets', i), o, comp, what='offset')[0]
                    for i, o in enumerate(p['offsets'])]
            return SquareWave(comp.dim, offsets=np.array(offs), period=p['period'],
                              duty=p['duty'], transition=p['transition'],
                              center=self._anchor(path, p, 'center', comp))
        return self._ramp(path, p, comp, 'linear' if b.kind == 'ramp' else 'min_jerk')

    def _values(self, path: Path, p: dict[str, Any], name: str,
                comp: _Components) -> np.ndarray:
        """Trajectory parameter ``name`` as m numbers."""
        return self.vector(path + (name,), p[name], comp, what=name)[0]

    def _anchor(self, path: Path, p: dict[str, Any], name: str, comp: _Components) -> Anchor:
        """Trajectory parameter ``name`` as an :class:`Anchor` of m (``init`` allowed)."""
        values, mask = self.vector(path + (name,), p[name], comp, what=name, allow_init=True)
        return Anchor(values, mask)

    def _circle(self, path: Path, p: dict[str, Any], comp: _Components) -> Circle:
        i, j = (self.index(path + ('plane', k), c, comp) for k, c in enumerate(p['plane']))
        if i == j:
            raise self.err(path + ('plane',), 'plane: the two components must differ')
        two = _Components(2, None, 'the 2 plane components')
        anchors: dict[str, Anchor | None] = {'center': None, 'start': None}
        for name in anchors:
            if p[name] is not None:
                values, mask = self.vector(path + (name,), p[name], two, what=name)
                anchors[name] = Anchor(values, mask)
        return Circle(comp.dim, plane=(i, j), radius=p['radius'], frequency=p['frequency'],
                      phase=p['phase'], center=anchors['center'], start=anchors['start'])

    def _ramp(self, path: Path, p: dict[str, Any], comp: _Components, profile: str) -> Ramp:
        start = self._anchor(path, p, 'from', comp)
        to = p['to']
        if to is None:
            return Ramp(comp.dim, duration=p['duration'], delay=p['delay'], start=start,
                        profile=profile, delta=self._values(path, p, 'by', comp))
        values, mask = self.vector(path + ('to',), to, comp, what='to', allow_init=True)
        same = np.zeros(comp.dim, bool)
        if isinstance(to, ByName):  # unnamed components stay where they start
            named = {k for k, _ in to.items}
            same = np.array([n not in named for n in comp.names or ()], bool)
        return Ramp(comp.dim, duration=p['duration'], delay=p['delay'], start=start,
                    profile=profile, end=Anchor(values, mask), end_same=same)

    def check_order(self, path: Path, spec: TaskSpec, lower: Bound, upper: Bound) -> None:
        if not (isinstance(lower, Constant) and isinstance(upper, Constant)):
            return
        bad = np.flatnonzero(lower.value > upper.value)
        if bad.size:
            i = int(bad[0])
            raise self.err(path + ('lower',),
                           f'lower > upper in component {i}: {lower.value[i]:g} > '
                           f'{upper.value[i]:g} (lower {bound_list(lower.value)}, upper '
                           f'{bound_list(upper.value)}); swap them or use equal')

    def check_joint_targets(self, path: Path, spec: TaskSpec, comp: _Components,
                            bound: Bound) -> None:
        if spec.type != 'joint_position' or not isinstance(bound, Constant):
            return
        robot = self.robot
        for k, name in enumerate(comp.names or ()):
            j = robot.joint_index(name)
            v = bound.value[k]
            if not robot.q_min[j] <= v <= robot.q_max[j]:
                raise self.err(path + ('equal',),
                               f'target {v:g} rad for joint {name} is outside its limits '
                               f'[{robot.q_min[j]:.4g}, {robot.q_max[j]:.4g}] rad')

    # -- tasks -----------------------------------------------------------------------------
    def task(self, spec: TaskSpec, construct: bool | str) -> list[Task]:
        """Check ``spec`` against the robot; return its task objects (``[]`` unless built)."""
        path = ('tasks', spec.index)
        if spec.type == 'constrained_manipulation':
            return self._constrained(spec, path, construct)
        if spec.type == 'collision_avoidance':
            from ifc_spg.task_stack import collision
            return list(collision.build(self.stack, self.robot, spec, construct))
        if spec.type in ('cartesian_pose', 'wrench'):
            self.frame(spec, path)
        comp = self.components(spec, path)
        kw: dict[str, Any] = {'name': spec.name}
        kw.update(self._bounds(spec, path, comp))
        kw.update(self._regulation(spec, path, comp))
        kw.update(self._geometry(spec, comp))
        if not construct:
            return []
        try:
            task = _CLASSES[spec.type](self.robot, **kw)
            if isinstance(kw.get('equal'), StreamBound):
                kw['equal'].bind(task, base_frames(self.robot))
            return [task]
        except TaskStackError:
            raise
        except IfcSpgError as exc:
            raise self.err(path, str(exc)) from None

    def _constrained(self, spec: TaskSpec, path: Path, construct: bool | str) -> list[Task]:
        """Expand a ``constrained_manipulation`` entry through its module's build_tasks."""
        self.frame(spec, path)
        mod = _constrained_module()
        if mod is None or not hasattr(mod, 'build_tasks'):
            if construct is True:
                raise self.err(path + ('type',),
                               "task type 'constrained_manipulation' is not available: "
                               f"module '{CONSTRAINED_MODULE}' (build_tasks) is not "
                               'installed in this ifc_spg')
            return []
        try:
            data = task_to_data(spec)
            data.pop('description', None)
            return list(mod.build_tasks(self.robot, data))
        except TaskStackError:
            raise
        except IfcSpgError as exc:
            raise self.err(path, str(exc)) from None
        except (TypeError, ValueError, KeyError, IndexError, AttributeError) as exc:
            # the module got a value of the wrong shape/type it did not check itself
            raise self.err(path, f'invalid constrained_manipulation fields: '
                                 f'{type(exc).__name__}: {exc}') from None

    def _bounds(self, spec: TaskSpec, path: Path, comp: _Components) -> dict[str, Bound]:
        """The task's bounds (``equal`` or ``lower``/``upper``), checked against each other."""
        bounds: dict[str, Bound] = {}
        for which in ('equal', 'lower', 'upper'):
            b = getattr(spec, which)
            if b is None:
                continue
            if b.kind == 'constant' and which == 'equal':
                self._check_no_open_entries(path + (which,), b.get('value'))
            bounds[which] = self.bound(path + (which,), b, comp, which)
        if 'lower' in bounds and 'upper' in bounds:
            self.check_order(path, spec, bounds['lower'], bounds['upper'])
        if 'equal' in bounds:
            self.check_joint_targets(path, spec, comp, bounds['equal'])
        return bounds

    def _check_no_open_entries(self, path: Path, v: Any) -> None:
        items = v.items if isinstance(v, ByName) else (
            enumerate(v) if isinstance(v, tuple) else ())
        for k, x in items:
            if x is None:
                raise self.err(path + (k,), 'equal: null (open) entries are only allowed in '
                                            'lower/upper')

    def _regulation(self, spec: TaskSpec, path: Path, comp: _Components) -> dict[str, Any]:
        """Gain, feed-forward and velocity options of the task's constructor."""
        kw: dict[str, Any] = {}
        kw['gain'] = self.vector(path + ('gain',), spec.gain, comp, what='gain')[0]
        ff = spec.feedforward
        if ff is None or ff == 'trajectory':
            kw['feedforward'] = ff
        else:
            kw['feedforward'] = self.vector(path + ('feedforward',), ff, comp,
                                            what='feedforward')[0]
        kw['velocity_gain'] = spec.velocity_gain
        kw['compensate_velocity'] = spec.compensate_velocity
        if spec.type in ('wrench', 'joint_torque'):
            kw['include_damping'] = spec.include_damping
        return kw

    def _geometry(self, spec: TaskSpec, comp: _Components) -> dict[str, Any]:
        """Frame, subspace and orientation (Cartesian tasks) or joints of the constructor."""
        if spec.type not in ('cartesian_pose', 'wrench'):
            return {'joints': list(comp.names or ())}
        kw: dict[str, Any] = {'frame': spec.frame}
        sub = spec.subspace
        if sub is not None:
            kw['subspace_frame'] = sub.frame
            if sub.axes is not None:
                kw['axes'] = list(sub.axes)
            else:
                kw['subspace'] = sub.matrix()
        if spec.type == 'cartesian_pose':
            kw['orientation'] = spec.orientation if isinstance(spec.orientation, str) \
                else np.array(spec.orientation)
            kw['relative'] = spec.relative
        return kw


def bound_list(v: Iterable[Any]) -> str:
    """Short text of a list of bound entries."""
    return '[' + ', '.join(x if isinstance(x, str) else ('null' if x is None else f'{x:g}')
                           for x in v) + ']'


def build_tasks(stack: TaskStack, robot: RobotModel,
                construct: bool | str = True) -> list[Task]:
    """Validate ``stack`` against ``robot`` and build its tasks.

    Args:
        stack: The :class:`~ifc_spg.task_stack.TaskStack`.
        robot: The :class:`~ifc_spg.model.RobotModel`.
        construct: True: build every task (a missing ``constrained_manipulation`` module
            is an error); 'available': build what can be built (skip that type when the
            module is missing); False: check only.

    Returns:
        The task objects, highest priority first.

    Raises:
        TaskStackError: With the path, line and column of the offending field.
    """
    b = _Builder(stack, robot)
    tasks: list[Task] = []
    for spec in stack.tasks:
        tasks.extend(b.task(spec, construct))
    return tasks

