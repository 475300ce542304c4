"""Scenes built programmatically with ``mujoco.MjSpec``, selectable by name.

Every scene is placed relative to the robot's tool frame at the initial configuration
(the :class:`Anchor`): mechanisms put their handle exactly at the tool, so the robot starts
"in front of the device" with the handle in hand. Directions: ``u`` is the horizontal
direction from the robot base to the tool ("forward"), ``v = z × u`` ("left"), ``z`` up.

========================  ==============================================================
scene                     what
========================  ==============================================================
``free``                  free space
``table``                 a table whose top is ``gap`` below the tool frame (centre
                          ``offset`` (x, y) from the tool); contact stiffness via
                          ``solref = (timeconst [s], dampratio)``, tool friction
                          ``friction`` (0.3) and ``solref_friction``; optionally an
                          obstacle box on it, ``obstacle_offset`` (x, y) [m] from the
                          tool start, half sizes ``obstacle_size`` [m]; optionally a
                          fixed ball at ``ball`` (x, y, z) [m] in the base frame, radius
                          ``ball_radius`` [m], with a contact pair against every robot
                          geom (an obstacle for the arm, not the tool)
``obstacle``              a box ``offset`` [m] (world frame) from the tool
``post``                  a vertical cylinder (``radius``, ``height`` [m]) on the floor at
                          ``position`` (x, y) [m] in the base frame; every robot geom has
                          a contact pair with it (collision avoidance)
``obstacles``             the obstacles of a task stack (``obstacles``: its list, the
                          stack's own fields: name, shape, size / radius / length,
                          position, rpy; base frame only), fixed, each with a contact
                          pair against every robot geom (collision avoidance)
``drawer_horizontal``     1.2 kg drawer pulled towards the robot (−u), 0.3 m travel;
                          optional break-away latch ``breakaway`` [N] (default 0: none)
``drawer_vertical``       1.2 kg drawer (sash) pulled up (+z), 0.3 m travel;
                          ``breakaway`` as above
``crank``                 crank, radius 0.17 m, axis along u, handle at the tool
``cupboard_door``         vertical hinge, 20 N break-away latch at the handle
``microwave_door``        vertical hinge on the other side, 15 N break-away latch
========================  ==============================================================

Mechanism scenes grasp the handle with ``grasp='weld'`` (default; tool and handle frames
welded), ``'connect'`` (ball joint at the tool frame) or ``'none'``. Tool/mechanism
contacts are excluded (the grasp carries the load). Scene geoms collide with the robot only
(``contype=1, conaffinity=2``), never with each other.

Tool contacts with the table and the obstacle are explicit contact pairs (every geom of the
tool subtree against the scene geom; their body-level dynamic contacts are excluded) with
Coulomb friction ``friction`` (sliding, default 0.3: a plastic or metal pen tip on a
varnished table), a separate, slow friction reference ``solref_friction`` (1 s; MuJoCo
``solreffriction``, effective with the elliptic cones the simulation uses) and impedance
:data:`TOOL_SOLIMP`. Why: MuJoCo's convex soft-contact model lets a sliding contact
"hydroplane" — by the elliptic cone's complementarity conditions the normal acceleration
gains about ``mu * b * |v_t|``, ``b ~ 2 / timeconst`` the friction reference damping —
and with the normal ``solref`` (10 ms) also used for friction, a pen sliding at 6 cm/s
lifted off by ~20 µm, dropped back and chattered at ~70 Hz: the ground-truth normal force
alternated between 0 and twice its mean (even for mu = 0.05). With the slow friction
reference and d = 0.7 the hover term stays below the normal constraint's preload term
``(1 - d)/d f_n / m`` down to ~1 N of normal force. The price: below ~1 cm/s of slip the
friction is viscous rather than Coulomb (about 0.05 f_n at 2 mm/s, the full mu f_n from
~2 cm/s; ``impratio`` 10 keeps this creep small), and the normal stiffness is ~0.1 mm of
penetration at 8 N.

Break-away doors use a *latch*: a joint equality holding the door closed until the torque
it carries reaches ``force × lever``; then it releases and the door swings with only a
small hinge friction. It re-engages once the door was opened past 0.05 rad and comes back
within 2 mrad of closed. Drawers with ``breakaway`` > 0 get the same latch on their slide
joint (lever 1, so the constraint force is compared with ``breakaway`` in [N]; re-engaged
after 5 cm out and back within 2 mm).
"""

from dataclasses import dataclass, field
import inspect
import math
from typing import Any

import mujoco
import numpy as np

from ifc_spg.errors import ParameterError, did_you_mean

__all__ = ['SCENES', 'Anchor', 'Latch', 'SceneInfo', 'build_scene', 'scene_names']

SCENE_CONTYPE = 1
SCENE_CONAFFINITY = 2
_GRASPS = ('weld', 'connect', 'none')
#: Impedance (d0, dwidth, width [m], midpoint, power) of the tool/table and tool/obstacle
#: contacts: d = 0.7 instead of MuJoCo's 0.9-0.95 (about 0.1 mm penetration at 8 N), which
#: makes the normal constraint's own preload term (1 - d)/d f_n/m large enough that a
#: sliding tool does not hover (see the module doc).
TOOL_SOLIMP = (0.7, 0.7, 0.001, 0.5, 2.0)
#: Friction reference (timeconst [s], dampratio) of the tool contacts (``solreffriction``).
TOOL_SOLREF_FRICTION = (1.0, 1.0)
#: Distance [m] from the handle to the mechanism's front (drawer front, door, crank plane)
#: along u, so that a wrist above a downward-pointing tool clears the mechanism.
STANDOFF = 0.1


@dataclass(frozen=True)
class Anchor:
    """Where the robot's tool is at the initial configuration (world frame).

    Attributes:
        tool_pos: Tool frame position in [m].
        tool_rot: Tool frame rotation matrix (3x3).
        base_pos: Robot base position in [m].
        tool_site: MuJoCo site of the tool frame (the grasp attaches here).
        tool_body: Body whose subtree is the tool (excluded from handle contacts).
    """

    tool_pos: np.ndarray
    tool_rot: np.ndarray
    base_pos: np.ndarray
    tool_site: str
    tool_body: str

    def frame(self):
        """Return the unit vectors (u forward, v left, z up) of the scene frame."""
        u = np.array(self.tool_pos - self.base_pos, dtype=float)
        u[2] = 0.0
        if np.linalg.norm(u) < 1e-6:
            u = np.array([1.0, 0.0, 0.0])
        u /= np.linalg.norm(u)
        z = np.array([0.0, 0.0, 1.0])
        return u, np.cross(z, u), z


@dataclass(frozen=True)
class Latch:
    """A break-away latch on a mechanism hinge.

    Attributes:
        joint: The hinge joint name.
        equality: The joint-equality constraint holding it closed.
        force: Break-away force at the handle in [N].
        lever: Handle distance from the hinge axis in [m].
    """

    joint: str
    equality: str
    force: float
    lever: float

    @property
    def torque(self):
        """Break-away torque in [Nm]."""
        return self.force * self.lever


@dataclass(frozen=True)
class SceneInfo:
    """What the simulation needs to know about a built scene.

    Attributes:
        name: Scene name.
        env_joints: Mechanism joint names, reported as environment joint states.
        latches: Break-away latches.
        handle_site: Site on the handle (a push target), or ``None``.
        grasp: Name of the grasp equality, or ``None``.
        options: The options used (defaults filled in).
    """

    name: str
    env_joints: tuple[str, ...] = ()
    latches: tuple[Latch, ...] = ()
    handle_site: str | None = None
    grasp: str | None = None
    options: dict[str, Any] = field(default_factory=dict)  # scene options, from JSON


def _scene_geom(body, **kw):
    kw.setdefault('contype', SCENE_CONTYPE)
    kw.setdefault('conaffinity', SCENE_CONAFFINITY)
    return body.add_geom(**kw)


def _box(body, pos, half, mass=0.0, rgba=(0.6, 0.5, 0.4, 1.0), name=''):
    kw = {'type': mujoco.mjtGeom.mjGEOM_BOX, 'pos': np.asarray(pos, float),
              'size': np.asarray(half, float), 'rgba': list(rgba), 'name': name}
    if mass > 0:
        kw['mass'] = mass
    else:
        kw['density'] = 0.0
    return _scene_geom(body, **kw)


def _rot_columns(a, b, c):
    """Quaternion of the rotation whose columns are a, b, c."""
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, np.column_stack([a, b, c]).reshape(-1))
    return quat


def _mechanism_body(spec, anchor, name, pos):
    """A body at ``pos`` whose frame is the scene frame (x forward, y left, z up)."""
    u, v, z = anchor.frame()
    return spec.worldbody.add_body(name=name, pos=np.asarray(pos, float),
                                   quat=_rot_columns(u, v, z))


def _add_handle(spec, body, anchor, grasp, axis):
    """Handle bar at the tool, a site aligned with the tool frame, and the grasp.

    Args:
        spec: The MjSpec being built.
        body: The scene body the handle bar belongs to.
        anchor: The tool frame (:class:`Anchor`).
        grasp: 'weld', 'connect' (an equality between the tool site and the handle) or
            'none'.
        axis: Direction of the handle bar in the body frame.
    """
    u, v, z = anchor.frame()
    r_world_body = np.column_stack([u, v, z])
    rel = r_world_body.T @ (anchor.tool_pos - np.asarray(body.pos, float))
    a = np.asarray(axis, float)
    b = np.cross([0.0, 0.0, 1.0], a) if abs(a[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    b /= np.linalg.norm(b)
    _scene_geom(body, type=mujoco.mjtGeom.mjGEOM_CAPSULE, pos=rel, quat=_rot_columns(
        b, np.cross(a, b), a), size=[0.012, 0.05, 0.0], mass=0.05, rgba=[0.2, 0.2, 0.2, 1],
        name='handle')
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, (r_world_body.T @ np.asarray(anchor.tool_rot, float)).reshape(-1))
    body.add_site(name='handle', pos=rel, quat=quat, size=[0.01, 0, 0])
    spec.add_exclude(bodyname1=anchor.tool_body, bodyname2=body.name)
    if grasp == 'none':
        return None
    eq_type = mujoco.mjtEq.mjEQ_WELD if grasp == 'weld' else mujoco.mjtEq.mjEQ_CONNECT
    spec.add_equality(name='grasp', type=eq_type, objtype=mujoco.mjtObj.mjOBJ_SITE,
                      name1=anchor.tool_site, name2='handle')
    return 'grasp'


def _free(spec, anchor):
    return {}


def _subtree(body):
    yield body
    for child in body.bodies:
        yield from _subtree(child)


def _tool_contact_pairs(spec, anchor, scene_body, scene_geom, friction, solref,
                        solref_friction):
    """Explicit contact pairs between every tool geom and ``scene_geom`` (see the module doc).

    Args:
        spec: The MjSpec being built.
        anchor: The tool frame (:class:`Anchor`).
        scene_body: The body ``scene_geom`` belongs to.
        scene_geom: The scene's geom the tool touches.
        friction: Sliding friction coefficient mu (>= 0).
        solref: Normal contact reference (timeconst [s], dampratio).
        solref_friction: Friction reference (timeconst [s], dampratio); slow on purpose.
    """
    mu = float(friction)
    if not np.isfinite(mu) or mu < 0:
        raise ParameterError(f'friction must be a number >= 0, got {friction!r}')
    for name, ref in (('solref', solref), ('solref_friction', solref_friction)):
        ref = np.asarray(ref, dtype=float).reshape(-1)
        if ref.shape != (2,) or not np.all(ref > 0):
            raise ParameterError(f'{name} must be (timeconst [s] > 0, dampratio > 0), got '
                                 f'{list(ref)}')
    for body in _subtree(spec.body(anchor.tool_body)):
        spec.add_exclude(bodyname1=body.name, bodyname2=scene_body)
        for i, geom in enumerate(body.geoms):
            if not geom.name:
                geom.name = f'{body.name}_geom{i}'
            spec.add_pair(name=f'{geom.name}_{scene_geom}', geomname1=geom.name,
                          geomname2=scene_geom, condim=3,
                          friction=[mu, mu, 0.005, 1e-4, 1e-4], solref=list(solref),
                          solimp=list(TOOL_SOLIMP), solreffriction=list(solref_friction))


def _xy(value, name):
    v = np.asarray(value, dtype=float).reshape(-1)
    if v.shape != (2,) or not np.all(np.isfinite(v)):
        raise ParameterError(f'{name} must be (x, y) [m], got {value!r}')
    return v


def _table(spec, anchor, solref=(0.01, 1.0), gap=0.002, size=(0.4, 0.4), friction=0.3,
           solref_friction=TOOL_SOLREF_FRICTION, offset=(0.0, 0.0), obstacle_offset=None,
           obstacle_size=(0.05, 0.02, 0.02), ball=None, ball_radius=0.05):
    """Table top ``gap`` [m] below the tool frame.

    Centred ``offset`` (x, y) [m] (world) from the tool; with ``obstacle_offset`` (x, y) [m]
    (world, from the tool) a box of half sizes ``obstacle_size`` [m] stands on it (same
    contact parameters as the top). With ``ball`` (x, y, z) [m] (base frame) a fixed sphere
    of radius ``ball_radius`` [m] (geom ``ball``) with a contact pair against every robot
    geom, as the ``post`` scene's (``friction``, ``solref``).
    """
    if ball is not None:
        _ball(spec, ball, ball_radius, friction, solref)
    off = _xy(offset, 'table offset')
    top = anchor.tool_pos[2] - gap
    table = spec.worldbody.add_body(name='table', pos=[anchor.tool_pos[0] + off[0],
                                                      anchor.tool_pos[1] + off[1], top - 0.02])
    g = _box(table, [0, 0, 0], [size[0], size[1], 0.02], name='table_top')
    g.solref = list(solref)
    _tool_contact_pairs(spec, anchor, 'table', 'table_top', friction, solref, solref_friction)
    if obstacle_offset is None:
        return {}
    ob = _xy(obstacle_offset, 'obstacle_offset')
    half = np.asarray(obstacle_size, dtype=float).reshape(-1)
    if half.shape != (3,) or not np.all(half > 0):
        raise ParameterError(f'obstacle_size must be 3 half sizes [m] > 0, got '
                             f'{obstacle_size!r}')
    if np.all(np.abs(ob) < half[:2]) and 2 * half[2] > gap:
        raise ParameterError(f'obstacle_offset {ob.tolist()} m puts the tool start inside the '
                             f'box (half sizes {half.tolist()} m); move it by more than the '
                             'half size along x or y')
    body = spec.worldbody.add_body(name='table_obstacle', pos=[
        anchor.tool_pos[0] + ob[0], anchor.tool_pos[1] + ob[1], top + half[2]])
    g = _box(body, [0, 0, 0], half, name='table_obstacle', rgba=(0.8, 0.2, 0.2, 1))
    g.solref = list(solref)
    _tool_contact_pairs(spec, anchor, 'table_obstacle', 'table_obstacle', friction, solref,
                        solref_friction)
    return {}


def _obstacle(spec, anchor, offset=(0.0, 0.15, 0.0), half_size=(0.04, 0.04, 0.1),
              friction=0.3, solref=(0.01, 1.0), solref_friction=TOOL_SOLREF_FRICTION):
    body = spec.worldbody.add_body(name='obstacle', pos=anchor.tool_pos + np.asarray(offset))
    g = _box(body, [0, 0, 0], half_size, name='obstacle', rgba=(0.8, 0.2, 0.2, 1))
    g.solref = list(solref)
    _tool_contact_pairs(spec, anchor, 'obstacle', 'obstacle', friction, solref,
                        solref_friction)
    return {}


def _post(spec, anchor, position=(0.45, 0.3), radius=0.04, height=1.2, friction=0.3,
          solref=(0.01, 1.0)):
    """A vertical post (cylinder) on the floor at ``position`` (x, y) [m] of the base frame.

    Every robot geom gets an explicit contact pair with it, so MuJoCo reports (and
    resolves) any contact of the robot with the post.
    """
    xy = _xy(position, 'position')
    for name, v in (('radius', radius), ('height', height)):
        if not (np.isfinite(v) and v > 0):
            raise ParameterError(f"scene 'post': {name} must be > 0 m, got {v!r}")
    robot_bodies = [b for top in spec.worldbody.bodies for b in _subtree(top)]
    body = spec.worldbody.add_body(name='post', pos=[xy[0], xy[1], height / 2])
    _scene_geom(body, name='post', type=mujoco.mjtGeom.mjGEOM_CYLINDER,
                size=[radius, height / 2, 0.0], rgba=(0.8, 0.2, 0.2, 1))
    _robot_pairs(spec, robot_bodies, 'post', friction, solref)
    return {}


#: size fields [m] per obstacle shape, as in a task stack's ``obstacles:``
_OBSTACLE_SIZES = {'box': ('size',), 'sphere': ('radius',), 'capsule': ('radius', 'length'),
                   'cylinder': ('radius', 'length'), 'plane': ()}


def _obstacles(spec, anchor, obstacles=(), friction=0.3, solref=(0.01, 1.0)):
    """The obstacles a task stack declares (its ``obstacles:`` list), fixed in the world.

    The stack's fields (name, shape, size / radius / length, position, rpy), checked here
    (sim_bridge does not import the stack parser: ARCHITECTURE.md); obstacles fixed to a
    chain of the robot are refused (the world holds base-frame ones). Each becomes a geom
    named after it (box: ``size`` edge lengths; capsule and cylinder along their z,
    ``length`` of the cylinder part; plane: the half-space below its xy plane) with a contact
    pair against every robot geom, as the post's.
    """
    if not isinstance(obstacles, (list, tuple)) or not obstacles:
        raise ParameterError("scene 'obstacles': obstacles must be a non-empty list of the "
                             "stack's obstacles (name, shape, sizes, position, rpy)")
    robot_bodies = [b for top in spec.worldbody.bodies for b in _subtree(top)]
    seen = set()
    for i, o in enumerate(obstacles):
        name, shape, size, position, rpy = _obstacle_fields(i, o)
        if name in seen:
            raise ParameterError(f"scene 'obstacles': obstacles[{i}].name '{name}' is used twice")
        seen.add(name)
        body = spec.worldbody.add_body(name=f'obstacle_{name}', pos=list(position))
        quat = np.empty(4)
        mujoco.mju_euler2Quat(quat, np.asarray(rpy, dtype=float), 'XYZ')  # Rz Ry Rx, as rpy
        body.quat = quat
        if shape == 'box':
            kind, size = mujoco.mjtGeom.mjGEOM_BOX, [v / 2 for v in size]
        elif shape == 'sphere':
            kind, size = mujoco.mjtGeom.mjGEOM_SPHERE, [size[0], 0.0, 0.0]
        elif shape == 'capsule':
            kind, size = mujoco.mjtGeom.mjGEOM_CAPSULE, [size[0], size[1] / 2, 0.0]
        elif shape == 'cylinder':
            kind, size = mujoco.mjtGeom.mjGEOM_CYLINDER, [size[0], size[1] / 2, 0.0]
        else:
            kind, size = mujoco.mjtGeom.mjGEOM_PLANE, [0.0, 0.0, 0.05]
        _scene_geom(body, name=name, type=kind, size=size, rgba=(0.8, 0.2, 0.2, 0.6))
        _robot_pairs(spec, robot_bodies, name, friction, solref)
    return {}


def _obstacle_fields(i, o):
    """(name, shape, sizes, position, rpy) of ``obstacles[i]``, or ParameterError."""
    where = f"scene 'obstacles': obstacles[{i}]"
    if not isinstance(o, dict):
        raise ParameterError(f'{where}: expected an obstacle (name, shape, sizes, position, rpy)')
    allowed = ('name', 'shape', 'size', 'radius', 'length', 'frame', 'position', 'rpy')
    for key in o:
        if key not in allowed:
            raise ParameterError(f'{where}.{key}: no such field{did_you_mean(key, allowed)}')
    name, shape = o.get('name'), o.get('shape')
    if not isinstance(name, str) or not name:
        raise ParameterError(f'{where}.name: a non-empty string is required')
    if shape not in _OBSTACLE_SIZES:
        raise ParameterError(f'{where}.shape: one of {", ".join(_OBSTACLE_SIZES)}, got '
                             f'{shape!r}{did_you_mean(str(shape), _OBSTACLE_SIZES)}')
    if o.get('frame', 'base') != 'base':
        raise ParameterError(f"{where}: obstacle '{name}' is fixed to frame '{o['frame']}'; "
                             'the scene holds obstacles in the base frame')
    need = _OBSTACLE_SIZES[shape]
    for key in ('size', 'radius', 'length'):
        if key in o and key not in need:
            raise ParameterError(f"{where}.{key}: a {shape} has no {key}; give "
                                 f"{', '.join(need) or 'no size'}")
        if key in need and key not in o:
            raise ParameterError(f'{where}: missing field {key} of the {shape}')
    size = _numbers(where, o, 'size', 3, True) if shape == 'box' else \
        [_numbers(where, o, k, 1, True)[0] for k in need]
    position = _numbers(where, o, 'position', 3, False) if 'position' in o else [0.0] * 3
    rpy = _numbers(where, o, 'rpy', 3, False) if 'rpy' in o else [0.0] * 3
    return name, shape, size, position, rpy


def _numbers(where, o, key, count, positive):
    """``count`` finite numbers (> 0 where ``positive``) of field ``key``, or ParameterError."""
    v = o[key] if count > 1 else [o[key]]
    if not isinstance(v, (list, tuple)) or len(v) != count:
        raise ParameterError(f'{where}.{key}: expected {count} numbers, got {o[key]!r}')
    if not all(not isinstance(x, bool) and isinstance(x, (int, float)) and math.isfinite(x)
               and (x > 0 or not positive) for x in v):
        raise ParameterError(f'{where}.{key}: ' + ('sizes must be finite and > 0 m' if positive
                                                   else 'finite numbers') + f', got {o[key]!r}')
    return [float(x) for x in v]


def _robot_pairs(spec, robot_bodies, scene_geom, friction, solref):
    """A contact pair between every geom of ``robot_bodies`` and ``scene_geom``."""
    mu = float(friction)
    for b in robot_bodies:
        for i, geom in enumerate(b.geoms):
            if not geom.name:
                geom.name = f'{b.name}_geom{i}'
            spec.add_pair(name=f'{geom.name}_{scene_geom}', geomname1=geom.name,
                          geomname2=scene_geom, condim=3,
                          friction=[mu, mu, 0.005, 1e-4, 1e-4], solref=list(solref))


def _ball(spec, position, radius, friction, solref):
    """A fixed sphere ``ball`` at ``position`` (x, y, z) [m] (base frame), pairs as the post's.

    Call it before adding other scene bodies (the robot's bodies are the world's then).
    """
    c = np.asarray(position, dtype=float).reshape(-1)
    if c.shape != (3,) or not np.all(np.isfinite(c)):
        raise ParameterError(f'ball must be (x, y, z) [m] in the base frame, got {position!r}')
    if not (isinstance(radius, (int, float)) and np.isfinite(radius) and radius > 0):
        raise ParameterError(f'ball_radius must be > 0 m, got {radius!r}')
    robot_bodies = [b for top in spec.worldbody.bodies for b in _subtree(top)]
    body = spec.worldbody.add_body(name='ball', pos=c)
    _scene_geom(body, name='ball', type=mujoco.mjtGeom.mjGEOM_SPHERE,
                size=[float(radius), 0.0, 0.0], rgba=(0.8, 0.2, 0.2, 1))
    _robot_pairs(spec, robot_bodies, 'ball', friction, solref)


def _latch(spec, joint, force, lever):
    """A joint equality ``latch`` holding ``joint`` at 0 (see the module doc); its Latch."""
    eq = spec.add_equality(name='latch', type=mujoco.mjtEq.mjEQ_JOINT, name1=joint,
                           objtype=mujoco.mjtObj.mjOBJ_JOINT)
    eq.solref = [0.004, 1.0]
    return Latch(joint=joint, equality='latch', force=float(force), lever=float(lever))


def _drawer(spec, anchor, vertical, mass=1.2, travel=0.3, damping=1.0, grasp='weld',
            breakaway=0.0):
    if not (isinstance(breakaway, (int, float)) and np.isfinite(breakaway)
            and breakaway >= 0):
        raise ParameterError(f'drawer breakaway must be a force >= 0 N (0: no latch), got '
                             f'{breakaway!r}')
    u, _, _ = anchor.frame()
    body = _mechanism_body(spec, anchor, 'drawer', anchor.tool_pos + STANDOFF * u)
    body.add_joint(name='drawer', type=mujoco.mjtJoint.mjJNT_SLIDE,
                   axis=[0, 0, 1] if vertical else [-1, 0, 0], range=[0.0, travel],
                   damping=[damping, 0, 0])
    depth, box_mass = 0.3, mass - 0.05
    # Front panel facing the robot plus the drawer box behind it.
    _box(body, [0.01, 0, 0], [0.01, 0.2, 0.08], mass=0.4 * box_mass, name='drawer_front')
    _box(body, [0.02 + depth / 2, 0, -0.02], [depth / 2, 0.18, 0.05], mass=0.6 * box_mass,
         name='drawer_box', rgba=(0.5, 0.4, 0.3, 1))
    grasp_eq = _add_handle(spec, body, anchor, grasp, [0, 1, 0])
    latches: tuple[Latch, ...] = ()
    if breakaway > 0:
        # Slide joint: the constraint carries a force, lever 1 makes torque == force.
        latches = (_latch(spec, 'drawer', breakaway, 1.0),)
    return {'env_joints': ('drawer',), 'handle_site': 'handle', 'grasp': grasp_eq,
            'latches': latches}


def _drawer_horizontal(spec, anchor, **kw):
    return _drawer(spec, anchor, vertical=False, **kw)


def _drawer_vertical(spec, anchor, **kw):
    return _drawer(spec, anchor, vertical=True, **kw)


def _crank(spec, anchor, radius=0.17, mass=0.5, damping=0.05, grasp='weld'):
    u, _, z = anchor.frame()
    body = _mechanism_body(spec, anchor, 'crank', anchor.tool_pos - radius * z + STANDOFF * u)
    body.add_joint(name='crank', type=mujoco.mjtJoint.mjJNT_HINGE, axis=[-1, 0, 0],
                   damping=[damping, 0, 0])
    # Balanced crank: its centre of mass lies on the axis, so gravity exerts no torque.
    body.explicitinertial = True
    body.mass = mass
    body.ipos = [0.0, 0.0, 0.0]
    body.inertia = [mass * radius ** 2 / 3.0] * 3
    _scene_geom(body, type=mujoco.mjtGeom.mjGEOM_CAPSULE, fromto=[0, 0, 0, 0, 0, radius],
                size=[0.01, 0, 0], density=0.0, rgba=[0.4, 0.4, 0.5, 1], name='crank_arm')
    _scene_geom(body, type=mujoco.mjtGeom.mjGEOM_CYLINDER, fromto=[0.02, 0, 0, 0.04, 0, 0],
                size=[0.03, 0, 0], density=0.0, rgba=[0.3, 0.3, 0.3, 1], name='crank_hub')
    grasp_eq = _add_handle(spec, body, anchor, grasp, [1, 0, 0])
    return {'env_joints': ('crank',), 'handle_site': 'handle', 'grasp': grasp_eq}


def _door(spec, anchor, side, force, lever, mass, damping=0.05, friction=0.05, grasp='weld',
          latch=True):
    u, v, _ = anchor.frame()
    body = _mechanism_body(spec, anchor, 'door', anchor.tool_pos + STANDOFF * u + side * lever * v)
    # A positive angle swings the handle towards the robot (-u).
    body.add_joint(name='door', type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0, 0, -side],
                   range=[0.0, 1.9], damping=[damping, 0, 0], frictionloss=friction)
    width = lever + 0.06
    _box(body, [0.01, -side * width / 2, 0], [0.01, width / 2, 0.25], mass=mass,
         name='door_panel', rgba=(0.7, 0.7, 0.75, 1))
    grasp_eq = _add_handle(spec, body, anchor, grasp, [0, 0, 1])
    latches = (_latch(spec, 'door', force, lever),) if latch else ()
    return {'env_joints': ('door',), 'handle_site': 'handle', 'grasp': grasp_eq,
            'latches': latches}


def _cupboard_door(spec, anchor, force=20.0, lever=0.35, mass=1.5, **kw):
    return _door(spec, anchor, side=-1.0, force=force, lever=lever, mass=mass, **kw)


def _microwave_door(spec, anchor, force=15.0, lever=0.30, mass=1.0, **kw):
    return _door(spec, anchor, side=1.0, force=force, lever=lever, mass=mass, **kw)


#: Scene name -> builder ``f(spec, anchor, **options) -> dict`` (SceneInfo fields).
SCENES = {
    'free': _free,
    'table': _table,
    'obstacle': _obstacle,
    'post': _post,
    'obstacles': _obstacles,
    'drawer_horizontal': _drawer_horizontal,
    'drawer_vertical': _drawer_vertical,
    'crank': _crank,
    'cupboard_door': _cupboard_door,
    'microwave_door': _microwave_door,
}


def scene_names():
    """Return the scene names."""
    return tuple(SCENES)


def _check_options(name, builder, options):
    """Raise ParameterError for an option the scene builder does not take."""
    params = inspect.signature(builder).parameters
    allowed = [p for p in params if p not in ('spec', 'anchor')]
    if name in ('drawer_horizontal', 'drawer_vertical'):
        allowed = [p for p in inspect.signature(_drawer).parameters
                   if p not in ('spec', 'anchor', 'vertical')]
    if name in ('cupboard_door', 'microwave_door'):
        allowed = [p for p in inspect.signature(_door).parameters
                   if p not in ('spec', 'anchor', 'side')]
    for key in options:
        if key not in allowed:
            raise ParameterError(f"scene '{name}' has no option '{key}'"
                                 f"{did_you_mean(key, allowed)}; options: "
                                 f"{', '.join(allowed) or '(none)'}")
    grasp = options.get('grasp', 'weld')
    if grasp not in _GRASPS:
        raise ParameterError(f"scene '{name}': grasp must be one of {', '.join(_GRASPS)}, "
                             f"got '{grasp}'")


def build_scene(spec, name, anchor, options=None):
    """Add scene ``name`` to ``spec`` around ``anchor`` and describe it.

    Args:
        spec: The robot's ``MjSpec`` (modified in place).
        name: A scene name (see :data:`SCENES`).
        anchor: The :class:`Anchor` of the tool at the initial configuration.
        options: Builder keyword options (e.g. ``{'solref': (0.005, 1)}`` for ``table``).

    Raises:
        ParameterError: Unknown scene or option.
    """
    if name not in SCENES:
        raise ParameterError(f"unknown scene '{name}'{did_you_mean(name, SCENES)}; "
                             f"available: {', '.join(SCENES)}")
    options = dict(options or {})
    builder = SCENES[name]
    _check_options(name, builder, options)
    # Robot bodies carry explicit inertials; scene bodies take theirs from their geoms.
    spec.compiler.inertiafromgeom = mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_AUTO
    spec.worldbody.add_light(name='scene_light', pos=[0, 0, 3], dir=[0, 0, -1])
    info = builder(spec, anchor, **options)
    return SceneInfo(name=name, options=options, **info)
