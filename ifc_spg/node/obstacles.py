"""``spg/obstacles``: moving the running stack's obstacles with visualization_msgs/MarkerArray.

Each marker of the array moves one obstacle the running (or pending) stack declares, so RViz
and Foxglove draw the same message the SPG takes (:func:`obstacle_marker` builds one;
``spg/markers`` draws the obstacles where the SPG has them with the same markers,
:func:`obstacle_markers`):

- ``ns`` is the obstacle's name (``id`` is free); ``action`` ADD/MODIFY (0) moves it,
  DELETE and DELETEALL are ignored (counted in ``ignored``: an obstacle leaves with a new
  stack only);
- ``header.frame_id`` is the frame the obstacle was declared in: for one in the base
  frame, empty, ``world``, the robot's root link or the ``markers.frame`` parameter; for
  one fixed to a chain of the robot (``frame: tool``), that chain id: the marker moves it
  relative to the frame it moves with (a held object shifted in the gripper). Not farther
  from the frame than the collision cull's bound allows (``out_of_reach``);
- ``pose``: the shape's center and orientation in that frame (as ``position`` / ``rpy``
  of the stack), the quaternion of norm 1 within 1e-3 (then normalized);
- ``type`` fits the shape: box CUBE, sphere SPHERE, cylinder CYLINDER, capsule CYLINDER
  (drawn as its bounding cylinder), plane CUBE;
- ``scale`` does not resize: sizes come from the stack. It is either zero (0, 0, 0) or
  the drawing of the declared size within 1e-6 m (:func:`marker_scale`: box (x, y, z)
  edge lengths; sphere 2r in x, y and z; cylinder (2r, 2r, length); capsule (2r, 2r,
  length + 2r); a plane takes any scale).

A marker that breaks a rule is rejected and counted by reason (:data:`REJECT_REASONS`) with
the reason in ``spg/status`` → ``obstacles`` and ``errors``; the others of the array still
apply. Accepted poses wait for the next tick boundary (:meth:`ObstacleInput.apply`), never
mid-tick; the last one per obstacle wins. ``spg/state`` records the pose of every obstacle
each tick used (``obstacle:<name>``: x, y, z, qx, qy, qz, qw), from which a replay takes them.
"""

import math

import numpy as np

__all__ = ['MARKER_TYPES', 'OBSTACLE_MARKER_ID', 'REJECT_REASONS', 'ObstacleInput',
           'marker_scale', 'obstacle_marker', 'obstacle_markers', 'obstacle_poses',
           'obstacle_tasks']

REJECT_REASONS = ('unknown_obstacle', 'unknown_frame', 'attached', 'non_finite',
                  'not_unit_quaternion', 'wrong_shape', 'size_change', 'out_of_reach')
#: visualization_msgs/Marker type per obstacle shape (CUBE 1, SPHERE 2, CYLINDER 3)
MARKER_TYPES = {'box': 1, 'sphere': 2, 'cylinder': 3, 'capsule': 3, 'plane': 1}
_TYPE_NAMES = {1: 'CUBE', 2: 'SPHERE', 3: 'CYLINDER'}
QUATERNION_TOLERANCE = 1e-3   # | |q| - 1 | accepted (then normalized)
SCALE_TOLERANCE = 1e-6        # [m]
PLANE_SCALE = (2.0, 2.0, 0.002)   # [m] how the SPG draws a plane (a thin square)
_ADD = 0


def marker_scale(obstacle):
    """The marker ``scale`` (x, y, z) [m] that draws ``obstacle`` (a declared Obstacle)."""
    s = [float(v) for v in obstacle.size]
    if obstacle.shape == 'box':
        return tuple(s)
    if obstacle.shape == 'sphere':
        return (2 * s[0],) * 3
    if obstacle.shape == 'cylinder':
        return (2 * s[0], 2 * s[0], s[1])
    if obstacle.shape == 'capsule':
        return (2 * s[0], 2 * s[0], s[1] + 2 * s[0])
    return PLANE_SCALE


def obstacle_marker(classes, obstacle, position, quaternion, frame='world', stamp_ns=0,
                    rgba=(0.6, 0.6, 0.65, 0.8), marker_id=0):
    """A Marker that moves ``obstacle`` to ``position`` [m], ``quaternion`` (x, y, z, w).

    Args:
        classes: ``ifc_spg.ros.msg`` or ``ifc_spg.ros.messages`` (``Marker``).
        obstacle: The declared :class:`~ifc_spg.geometry.Obstacle` (name, shape, sizes).
        position: Center of the shape [m] in ``frame``.
        quaternion: Orientation (x, y, z, w) in ``frame``.
        frame: Header frame id (the base frame).
        stamp_ns: Header stamp [ns].
        rgba: Colour.
        marker_id: The marker's ``id`` (any: the SPG matches ``ns``).
    """
    from ifc_spg.ros.stamps import set_stamp

    mk = classes.Marker()
    set_stamp(mk.header.stamp, stamp_ns)
    mk.header.frame_id = frame
    mk.ns, mk.id = obstacle.name, int(marker_id)
    mk.type, mk.action = MARKER_TYPES[obstacle.shape], _ADD
    p, o = mk.pose.position, mk.pose.orientation
    p.x, p.y, p.z = (float(v) for v in position)
    o.x, o.y, o.z, o.w = (float(v) for v in quaternion)
    mk.scale.x, mk.scale.y, mk.scale.z = marker_scale(obstacle)
    mk.color.r, mk.color.g, mk.color.b, mk.color.a = (float(v) for v in rgba)
    return mk


#: ``id`` of the obstacle markers in ``spg/markers`` (clear of a task's markers 0-3, 10, 11
#: should a task share the obstacle's name)
OBSTACLE_MARKER_ID = 20


def obstacle_markers(classes, tasks, frame='world', stamp_ns=0):
    """Markers of the base-frame obstacles of ``tasks`` where the SPG has them now.

    ``spg/markers`` draws them; sent to ``spg/obstacles`` they are accepted as they are.
    """
    declared = _declared(tasks)
    return [obstacle_marker(classes, declared[name], pose[:3], pose[3:], frame, stamp_ns,
                            marker_id=OBSTACLE_MARKER_ID)
            for name, pose in obstacle_poses(tasks).items() if declared[name].frame == 'base']


def obstacle_tasks(tasks):
    """The tasks of ``tasks`` whose obstacles can move (``collision_avoidance``)."""
    return [t for t in tasks if hasattr(t, 'move_obstacle')]


def obstacle_poses(tasks):
    """Obstacle name -> pose (7,) the collision tasks of ``tasks`` use (the first task's)."""
    out: dict[str, np.ndarray] = {}
    for task in obstacle_tasks(tasks):
        for name, pose in task.obstacle_poses.items():
            out.setdefault(name, pose)
    return out


def _declared(tasks):
    """Obstacle name -> its declared Obstacle, over the collision tasks of ``tasks``."""
    out = {}
    for task in obstacle_tasks(tasks):
        out.update(task.geometry.declared)
    return out


class ObstacleInput:
    """Checks ``spg/obstacles`` markers and applies the accepted poses at tick boundaries.

    Args:
        base_frames: Frame ids that mean the robot's base frame.

    Attributes:
        received: Markers handled; accepted; ignored (DELETE, DELETEALL);
        rejected: Reason -> count (:data:`REJECT_REASONS`).
        moved: Poses applied at tick boundaries that moved an obstacle.
    """

    def __init__(self, base_frames=('', 'world')):
        self.base_frames = tuple(dict.fromkeys(base_frames))
        self.received = self.accepted = self.ignored = self.moved = 0
        self.rejected = dict.fromkeys(REJECT_REASONS, 0)
        self._pending = {}   # name -> pose (7,), for the next tick boundary

    def handle(self, markers, tasks):
        """Check ``markers`` against the obstacles of ``tasks`` (running and pending).

        Returns:
            ``[(reason, message)]`` of the rejected markers (the accepted ones wait for
            :meth:`apply`).
        """
        declared = _declared(tasks)
        geometries = {name: task.geometry for task in obstacle_tasks(tasks)
                      for name in task.geometry.declared}
        errors = []
        for mk in markers:
            self.received += 1
            if int(mk.action) != _ADD:
                self.ignored += 1
                continue
            pose, error = self._check(mk, declared, geometries)
            if error is not None:
                self.rejected[error[0]] += 1
                errors.append(error)
                continue
            self.accepted += 1
            self._pending[str(mk.ns)] = pose
        return errors

    def _check(self, mk, declared, geometries):
        """(pose (7,), None) or (None, (reason, message)) for one ADD marker."""
        name = str(mk.ns)
        obs = declared.get(name)
        if obs is None:
            from ifc_spg.errors import did_you_mean
            listed = (', '.join(declared) if declared else
                      '(none: no collision_avoidance task of the running stack lists one)')
            return None, ('unknown_obstacle', f"marker ns '{name}' names no obstacle of the "
                          f'running stack{did_you_mean(name, declared)}; obstacles: {listed}')
        error = self._frame_error(name, obs, str(mk.header.frame_id))
        if error is not None:
            return None, error
        p, o, s = mk.pose.position, mk.pose.orientation, mk.scale
        try:
            vals = np.array([float(v) for v in (p.x, p.y, p.z, o.x, o.y, o.z, o.w)])
            scale = np.array([float(s.x), float(s.y), float(s.z)])
        except (TypeError, ValueError):
            return None, ('non_finite', f"obstacle '{name}': pose or scale not numbers")
        if not (np.all(np.isfinite(vals)) and np.all(np.isfinite(scale))):
            return None, ('non_finite', f"obstacle '{name}': non-finite pose or scale "
                          f'{vals.tolist()} {scale.tolist()}')
        norm = math.sqrt(float(vals[3:] @ vals[3:]))
        if abs(norm - 1.0) > QUATERNION_TOLERANCE:
            return None, ('not_unit_quaternion', f"obstacle '{name}': orientation quaternion "
                          f'of norm {norm:.6g}; give a unit quaternion (within '
                          f'{QUATERNION_TOLERANCE:g})')
        want = MARKER_TYPES[obs.shape]
        if int(mk.type) != want:
            return None, ('wrong_shape', f"obstacle '{name}' is a {obs.shape}: marker type "
                          f'{want} ({_TYPE_NAMES[want]}), got {int(mk.type)}')
        drawn = np.array(marker_scale(obs))
        if obs.shape != 'plane' and np.any(scale) and \
                np.abs(scale - drawn).max() > SCALE_TOLERANCE:
            return None, ('size_change', f"obstacle '{name}': scale {scale.tolist()} is not "
                          f'its declared size drawn ({drawn.tolist()}) nor zero; sizes come '
                          'from the stack (send a new stack to resize)')
        vals[3:] /= norm
        return self._reach(name, obs, vals, geometries[name])

    def _frame_error(self, name, obs, frame):
        """(reason, message) if ``frame`` is not the frame ``obs`` was declared in, else None."""
        if obs.frame != 'base':
            if frame != obs.frame:
                return ('attached', f"obstacle '{name}' is fixed to frame '{obs.frame}' and "
                        f"moves with it: give its pose in frame_id '{obs.frame}', not '{frame}'")
        elif frame not in self.base_frames:
            return ('unknown_frame', f"obstacle '{name}': frame_id '{frame}'; give the pose in "
                    f"the base frame ({' or '.join(map(repr, self.base_frames))})")
        return None

    @staticmethod
    def _reach(name, obs, pose, geometry):
        """(pose, None), or (None, ('out_of_reach', message)) beyond the cull's bound."""
        if obs.frame != 'base':
            from ifc_spg.errors import ParameterError
            try:
                geometry.obstacle_placement(name, pose)
            except ParameterError as exc:
                return None, ('out_of_reach', str(exc))
        return pose, None

    @property
    def due(self):
        """Whether poses were accepted since the last :meth:`apply`."""
        return bool(self._pending)

    def apply(self, tasks):
        """Move the obstacles of ``tasks`` to the poses accepted since the last call.

        Call at a tick boundary (before the tick), with the running and pending tasks.
        """
        if not self._pending:
            return
        pending, self._pending = self._pending, {}
        movable = obstacle_tasks(tasks)
        from ifc_spg.errors import ParameterError
        for name, pose in pending.items():
            moved = False
            for task in movable:
                try:
                    moved = task.move_obstacle(name, pose) or moved
                except ParameterError:  # (another stack's cull bound than the one checked)
                    self.rejected['out_of_reach'] += 1
            self.moved += moved

    def status(self):
        """The ``obstacles`` entry of ``spg/status``."""
        return {'received': self.received, 'accepted': self.accepted,
                'ignored': self.ignored, 'moved': self.moved, 'rejected': dict(self.rejected)}
