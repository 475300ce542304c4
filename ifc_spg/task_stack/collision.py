"""The task-stack language of collision avoidance: ``obstacles:`` and ``collision_avoidance``.

::

    obstacles:                       # top level, optional
      - name: post
        shape: cylinder              # box | sphere | capsule | cylinder | plane
        radius: 0.05                 # sphere, capsule, cylinder [m]
        length: 0.8                  # capsule, cylinder: along the local z axis [m]
        # size: [0.2, 0.1, 0.3]      # box: full edge lengths [m]
        frame: base                  # or a chain id of the robot (default base)
        position: [0.55, 0.0, 0.4]   # of the shape's center in frame [m]
        rpy: [0, 0, 0]               # roll pitch yaw in frame [rad] (default 0)
    tasks:
      - name: avoid
        type: collision_avoidance
        pairs: [self, {links: [link5, link6, link7], obstacles: [post]}]
        margin: 0.01                 # d_s [m], never closer (default 0.01)
        influence: 0.10              # d_i [m], rows only closer than this (default 0.10)
        gain: 0.5                    # xi [m/s] approach speed allowed at d_i (default 0.5)
        max_rows: 24                 # rows of the level: the closest pairs within d_i

A plane is the half-space below the plane z = 0 of its pose (the robot stays on the +z
side). ``links`` are MJCF body names (every shape of the body) or shape names, or ``all``.
The spec side (:func:`parse_obstacles`, :func:`parse_options`) checks what needs no
robot; :func:`build` checks names against the robot and its obstacles.
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass
from types import MappingProxyType
from typing import TYPE_CHECKING, Any

from ifc_spg.errors import IfcSpgError, did_you_mean
from ifc_spg.geometry.collision import OBSTACLE_SHAPES, CollisionGeometry, Obstacle, rpy_matrix
from ifc_spg.task_stack.errors import TaskStackError
from ifc_spg.tasks.collision_avoidance import (
    DEFAULT_GAIN,
    DEFAULT_INFLUENCE,
    DEFAULT_MARGIN,
    DEFAULT_MAX_ROWS,
    CollisionAvoidanceTask,
)

if TYPE_CHECKING:
    from ifc_spg.model.robot_model import RobotModel
    from ifc_spg.task_stack.task_stack import TaskStack

__all__ = ['COLLISION_FIELDS', 'MAX_OBSTACLES', 'OBSTACLE_FIELDS', 'PAIR_FIELDS',
           'ObstacleSpec', 'build', 'obstacle_to_data', 'parse_obstacles', 'parse_options']

COLLISION_FIELDS = ('name', 'type', 'description', 'pairs', 'margin', 'influence', 'gain',
                    'max_rows')
MAX_ROWS = 1000
OBSTACLE_FIELDS = ('name', 'shape', 'size', 'radius', 'length', 'frame', 'position', 'rpy',
                   'description')
PAIR_FIELDS = ('name', 'links', 'obstacles')
MAX_OBSTACLES = 64
_MAX_SIZE = 1e3  # [m]
_SIZE_FIELDS = {'box': ('size',), 'sphere': ('radius',), 'capsule': ('radius', 'length'),
                'cylinder': ('radius', 'length'), 'plane': ()}


@dataclass(frozen=True)
class ObstacleSpec:
    """An obstacle as written: name, shape, sizes [m], frame, position [m], rpy [rad]."""

    name: str
    shape: str
    size: tuple
    frame: str = 'base'
    position: tuple = (0.0, 0.0, 0.0)
    rpy: tuple = (0.0, 0.0, 0.0)

    def obstacle(self) -> Obstacle:
        """The :class:`~ifc_spg.geometry.Obstacle`."""
        return Obstacle(self.name, self.shape, self.size, self.frame, self.position,
                        tuple(map(tuple, rpy_matrix(self.rpy))))


def obstacle_to_data(o: ObstacleSpec) -> dict[str, Any]:
    """Plain data of an :class:`ObstacleSpec` (every field explicit)."""
    out: dict[str, Any] = {'name': o.name, 'shape': o.shape}
    if o.shape == 'box':
        out['size'] = list(o.size)
    else:
        out.update(zip(_SIZE_FIELDS[o.shape], o.size))
    out.update({'frame': o.frame, 'position': list(o.position), 'rpy': list(o.rpy)})
    return out


# -- parsing (no robot) --------------------------------------------------------------------
def _triple(p: Any, path: tuple, x: Any, what: str) -> tuple:
    if not isinstance(x, list) or len(x) != 3:
        raise p.err(path, f'{what}: expected 3 numbers [x, y, z], got {x!r}'[:200])
    return tuple(p.number(path + (i,), v, f'a number for {what}') for i, v in enumerate(x))


def _size(p: Any, path: tuple, x: Any, what: str) -> float:
    v = p.number(path, x, f'a size in m for {what}')
    if not 0.0 < v <= _MAX_SIZE:
        raise p.err(path, f'{what} must be > 0 m (and <= {_MAX_SIZE:g} m), got {v:g}')
    return v


def _obstacle(p: Any, path: tuple, x: Any) -> ObstacleSpec:
    p.mapping(path, x, 'an obstacle')
    p.fields(path, x, OBSTACLE_FIELDS, 'an obstacle')
    if 'name' not in x:
        raise p.err(path, 'missing field name (the name pairs use to list the obstacle)')
    name = p.string(path + ('name',), x['name'], 'an obstacle name')
    if 'shape' not in x:
        raise p.err(path, f"missing field shape; one of {', '.join(OBSTACLE_SHAPES)}")
    shape = p.choice(path + ('shape',), x['shape'], tuple(OBSTACLE_SHAPES), 'obstacle shape')
    need = _SIZE_FIELDS[shape]
    for k in ('size', 'radius', 'length'):
        if k in x and k not in need:
            raise p.err(path + (k,), f"a {shape} has no {k}; give {', '.join(need) or 'no size'}")
    for k in need:
        if k not in x:
            raise p.err(path, f"missing field {k} of the {shape} (give {', '.join(need)})")
    if shape == 'box':
        size = tuple(_size(p, path + ('size', i), v, f'size[{i}]')
                     for i, v in enumerate(_triple(p, path + ('size',), x['size'], 'size')))
    else:
        size = tuple(_size(p, path + (k,), x[k], k) for k in need)
    frame = p.string(path + ('frame',), x['frame'], 'a frame (base or a chain id)') \
        if 'frame' in x else 'base'
    position = _triple(p, path + ('position',), x['position'], 'position') \
        if 'position' in x else (0.0, 0.0, 0.0)
    rpy = _triple(p, path + ('rpy',), x['rpy'], 'rpy') if 'rpy' in x else (0.0, 0.0, 0.0)
    return ObstacleSpec(name, shape, size, frame, position, rpy)


def parse_obstacles(p: Any, x: Any) -> tuple:
    """The stack's ``obstacles:`` list (``p`` is the spec parser); unique names."""
    path = ('obstacles',)
    if x is None:
        return ()
    if not isinstance(x, list):
        raise p.err(path, 'expected a list of obstacles (name, shape, sizes, pose)')
    if len(x) > MAX_OBSTACLES:
        raise p.err(path, f'{len(x)} obstacles, more than the limit {MAX_OBSTACLES}')
    out = tuple(_obstacle(p, path + (i,), o) for i, o in enumerate(x))
    seen: dict[str, int] = {}
    for i, o in enumerate(out):
        if o.name in seen:
            raise p.err(path + (i, 'name'), f"obstacle name '{o.name}' is used twice (also "
                                            f'obstacles[{seen[o.name]}]); names must be unique')
        seen[o.name] = i
    return out


def _names(p: Any, path: tuple, x: Any, what: str, allow_all: bool) -> Any:
    if allow_all and x == 'all':
        return 'all'
    if isinstance(x, str):
        x = [x]
    if not isinstance(x, list) or not x:
        raise p.err(path, f'expected a list of {what} names'
                          + (" or 'all'" if allow_all else '') + f', got {x!r}'[:200])
    return tuple(p.string(path + (i,), v, f'a {what} name') for i, v in enumerate(x))


def _group(p: Any, path: tuple, x: Any, index: int) -> MappingProxyType:
    if x == 'self':
        return MappingProxyType({'name': 'self', 'self': True})
    if isinstance(x, str):
        raise p.err(path, f"unknown pair group {x!r}{did_you_mean(x, ('self',))}; give 'self' "
                          'or {links: [...], obstacles: [...]}')
    p.mapping(path, x, "a pair group ('self' or {links: [...], obstacles: [...]})")
    p.fields(path, x, PAIR_FIELDS, 'a pair group')
    for k in ('links', 'obstacles'):
        if k not in x:
            raise p.err(path, f'missing field {k}; a pair group lists links and the obstacles '
                              'to keep them from')
    name = p.string(path + ('name',), x['name'], 'a group name') if 'name' in x \
        else f'pairs[{index}]'
    return MappingProxyType({
        'name': name, 'links': _names(p, path + ('links',), x['links'], 'link', True),
        'obstacles': _names(p, path + ('obstacles',), x['obstacles'], 'obstacle', False)})


def _max_rows(p: Any, path: tuple, x: dict[str, Any]) -> int:
    if 'max_rows' not in x:
        return DEFAULT_MAX_ROWS
    v = x['max_rows']
    if isinstance(v, bool) or not isinstance(v, int) or not 1 <= v <= MAX_ROWS:
        raise p.err(path + ('max_rows',), f'max_rows must be an integer in [1, {MAX_ROWS}] '
                                          f'(rows of the level), got {v!r}'[:200])
    return v


def parse_options(p: Any, path: tuple, x: dict[str, Any]) -> MappingProxyType:
    """``pairs``, ``margin``, ``influence`` and ``gain`` of a collision_avoidance task."""
    p.fields(path, x, COLLISION_FIELDS, 'a collision_avoidance task')
    if 'pairs' not in x:
        raise p.err(path, "missing field pairs; list 'self' and/or {links: [...], "
                          'obstacles: [...]}')
    pairs = x['pairs']
    if isinstance(pairs, (str, dict)):
        pairs = [pairs]
    if not isinstance(pairs, list) or not pairs:
        raise p.err(path + ('pairs',), "expected a list of pair groups ('self' or {links: "
                                       f'[...], obstacles: [...]}}), got {pairs!r}'[:200])
    groups = tuple(_group(p, path + ('pairs', i), g, i) for i, g in enumerate(pairs))
    vals = {}
    for k, default, lo in (('margin', DEFAULT_MARGIN, 0.0), ('influence', DEFAULT_INFLUENCE,
                                                             None),
                           ('gain', DEFAULT_GAIN, None)):
        v = p.number(path + (k,), x[k], f'a number for {k}') if k in x else default
        if lo is not None and v < lo:
            raise p.err(path + (k,), f'{k} must be >= {lo:g} m, got {v:g}')
        if lo is None and v <= 0:
            raise p.err(path + (k,), f'{k} must be > 0, got {v:g}')
        vals[k] = v
    vals['max_rows'] = _max_rows(p, path, x)
    if vals['influence'] <= vals['margin']:
        raise p.err(path + ('influence',), f"influence ({vals['influence']:g} m) must be "
                                           f"greater than margin ({vals['margin']:g} m): rows "
                                           'start at the influence distance and stop at the '
                                           'margin')
    return MappingProxyType({'pairs': groups, **vals})


def options_to_data(options: Any) -> dict[str, Any]:
    """Plain data of a collision_avoidance task's options."""
    groups: list[Any] = []
    for g in options['pairs']:
        if g.get('self'):
            groups.append('self')
        else:
            links = g['links']
            groups.append({'name': g['name'],
                           'links': links if isinstance(links, str) else list(links),
                           'obstacles': list(g['obstacles'])})
    return {'pairs': groups, 'margin': options['margin'], 'influence': options['influence'],
            'gain': options['gain'], 'max_rows': options['max_rows']}


# -- building (with the robot) -------------------------------------------------------------
_CACHE: OrderedDict = OrderedDict()


def geometry_for(robot: RobotModel, obstacles: tuple) -> CollisionGeometry:
    """The :class:`CollisionGeometry` of ``robot`` with ``obstacles`` (cached, immutable)."""
    key = (id(robot.model), robot.model_file, tuple(robot.q_home), obstacles)
    hit = _CACHE.get(key)
    if hit is None or hit[0] is not robot.model:
        hit = _CACHE[key] = (robot.model, CollisionGeometry(
            robot, [o.obstacle() for o in obstacles]))
        while len(_CACHE) > 8:
            _CACHE.popitem(last=False)
    return hit[1]


def _stack_geometry(stack: TaskStack, robot: RobotModel, path: tuple) -> CollisionGeometry:
    for i, o in enumerate(stack.obstacles):
        if o.frame != 'base' and o.frame not in robot.chains:
            raise stack.error(('obstacles', i, 'frame'),
                              f"frame '{o.frame}' not in model '{robot.name}'"
                              f"{did_you_mean(o.frame, ('base',) + robot.chains)}; frames: "
                              f"base, {', '.join(robot.chains)}")
    try:
        return geometry_for(robot, tuple(stack.obstacles))
    except IfcSpgError as exc:
        raise stack.error(path, str(exc)) from None


def _group_pairs(stack: TaskStack, geometry: CollisionGeometry, gpath: tuple,
                 g: Any) -> list[tuple[int, int]]:
    if g.get('self'):
        return geometry.self_pairs()
    links = list(geometry.bodies) if g['links'] == 'all' else g['links']
    shapes: list[int] = []
    for i, link in enumerate(links):
        try:
            shapes += geometry.link_shapes(link)
        except IfcSpgError as exc:
            raise stack.error(gpath + ('links', i), str(exc)) from None
    pairs = []
    for i, name in enumerate(g['obstacles']):
        try:
            b = geometry.obstacle_shape(name)
        except IfcSpgError as exc:
            hint = '' if geometry.obstacles else ' (declare it under the top-level obstacles:)'
            raise stack.error(gpath + ('obstacles', i), str(exc) + hint) from None
        pairs += [(a, b) for a in shapes]
    return pairs


def build(stack: TaskStack, robot: RobotModel, spec: Any,
          construct: bool | str) -> list[CollisionAvoidanceTask]:
    """Check a collision_avoidance spec against ``robot``; return its task (if built)."""
    path = ('tasks', spec.index)
    opts = spec.options
    geometry = _stack_geometry(stack, robot, path)
    groups = [(g['name'], _group_pairs(stack, geometry, path + ('pairs', i), g))
              for i, g in enumerate(opts['pairs'])]
    if not any(pairs for _, pairs in groups):
        raise stack.error(path + ('pairs',), 'these groups hold no pairs (the robot has no '
                                             'self-collision pairs left); list links and '
                                             'obstacles')
    if not construct:
        return []
    try:
        return [CollisionAvoidanceTask(robot, geometry=geometry, groups=groups,
                                       margin=opts['margin'], influence=opts['influence'],
                                       gain=opts['gain'], max_rows=opts['max_rows'],
                                       name=spec.name)]
    except TaskStackError:
        raise
    except IfcSpgError as exc:
        raise stack.error(path, str(exc)) from None
