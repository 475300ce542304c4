"""Task-specification strategy (thesis 5.5, Table 5.1): constrained manipulation as tasks.

The exploration becomes the level-1 wrench task on the force part of the static wrench
(S = [I3; 0], 5.14)::

    alpha = f_s,   alpha_d = P_hat f_s   (5.12),   ff = kappa d_hat   (5.13)

with the velocity compensation cancelled (``compensate_velocity=False``; the
``- S^T J^{+T} K qdot`` of 5.13), so the force along d_hat grows at kappa until the
motion it causes levels it off, and the force orthogonal to d_hat is regulated to zero
with gain Lambda. The direction estimator is updated once per tick from the measured state
(``kin.q``, ``kin.qdot``) inside :meth:`ConstrainedWrenchTask.level`; the orientation
tasks read the same estimator.

Orientation (5.15-5.20): ``fixed`` (o_init, a Cartesian pose task on rx ry rz), ``align_z``
(rotation about z_ee held, then z_ee aligned with -d_hat, "pulling"), ``release_y``
(rotation about z_ee held, x_ee aligned, rotation about y_ee left to lower levels),
``free`` (none). Then the posture level (joint position).

:func:`build_tasks` is what a task stack's ``constrained_manipulation`` entry expands to.
"""

import math

import numpy as np

from ifc_spg.constrained.direction_estimator import DirectionEstimator, FixedDirection
from ifc_spg.constrained.params import ORIENTATIONS, EstimatorParams
from ifc_spg.errors import IfcSpgError, ParameterError, did_you_mean
from ifc_spg.tasks import CartesianPoseTask, JointPositionTask, Level, Task, WrenchTask
from ifc_spg.tasks.static_interaction import static_wrench

__all__ = ['SPEC_KEYS', 'AxisAlignTask', 'ConstrainedWrenchTask', 'build_tasks']

FORCE_MODES = ('measured', 0)


class ConstrainedWrenchTask(WrenchTask):
    """Level 1 of Table 5.1: explore along d_hat, cancel the force orthogonal to it.

    Args:
        robot: The :class:`~ifc_spg.model.RobotModel`.
        frame: Chain id of the interaction point (e.g. ``'tool'``).
        estimator: A :class:`~ifc_spg.constrained.direction_estimator.DirectionEstimator`
            (updated by this task once per tick).
        kappa: Exploration rate kappa in [N/s].
        gain: Lambda in [1/s] of the regulation of f_s towards P_hat f_s.
        force: 'measured' (alpha_d = P_hat f_s, Table 5.1) or 0 (alpha_d = 0: the force is
            regulated to zero and only the feed-forward explores).
        max_force: The feed-forward stops while d_hat . f_s >= max_force [N].
        compensate_velocity: False (default, Table 5.1) cancels the velocity compensation.
        name: Task name.
    """

    kind = 'constrained_wrench'

    def __init__(self, robot, *, frame, estimator, kappa=9.0, gain=50.0, force='measured',
                 max_force=math.inf, compensate_velocity=False, name='exploration'):
        super().__init__(robot, frame=frame, axes=('fx', 'fy', 'fz'), equal=[0.0, 0.0, 0.0],
                         gain=gain, feedforward=None, compensate_velocity=compensate_velocity,
                         name=name)
        if force not in FORCE_MODES:
            raise ParameterError(f"task '{name}': force must be 'measured' (alpha_d = P_hat "
                                 f"f_s, Table 5.1) or 0, got {force!r}")
        if not (math.isfinite(kappa) and kappa >= 0):
            raise ParameterError(f"task '{name}': kappa must be a finite rate >= 0 [N/s], got "
                                 f'{kappa!r}')
        if math.isnan(max_force) or max_force <= 0:
            raise ParameterError(f"task '{name}': max_force must be > 0 [N], got {max_force!r}")
        self.estimator = estimator
        self.kappa = float(kappa)
        self.measured = force == 'measured'
        self.max_force = float(max_force)
        self.frame_id = robot.frame_id(frame)
        self.force = np.zeros(3)

    def level(self, kin, t):
        """Update the estimator from the measured state, then build the level."""
        _, _, J = kin.frame(self.frame_id, virtual=False)
        d = self.estimator.update(J[:3] @ kin.qdot, stamp=t)
        h, A, g, _ = static_wrench(self.robot, kin, self.frame)
        f = h[:3]
        self.force[:] = f
        along = float(d @ f)
        target = along * d if self.measured else 0.0
        ff = self.kappa * d if along < self.max_force else 0.0
        beta = self.gain * (target - f) + ff
        if self.compensate_velocity:
            beta = beta + g[:3]
        return Level(self.name, A[:3], beta, beta, True)


class AxisAlignTask(Task):
    """Align z_ee with -d_hat (5.19/5.20): angular velocity about chosen end-effector axes.

    The level asks ``S^T omega_v = k_o S^T (-z_ee x d_hat)`` with S the chosen axes of the
    virtual end-effector frame (x and y for ``align_z``, x for ``release_y``) and omega_v
    the angular velocity of the frame at q_v (A = S^T J_v,ang).

    Args:
        robot: The :class:`~ifc_spg.model.RobotModel`.
        frame: Chain id.
        estimator: The shared direction estimator (read only).
        axes: End-effector axes, a subset of ``('x', 'y')``.
        gain: k_o in [1/s].
        pull: True: z_ee turns towards -d_hat (pulling, as in the thesis); False: +d_hat.
        name: Task name.
    """

    kind = 'axis_align'

    def __init__(self, robot, *, frame, estimator, axes=('x', 'y'), gain=2.0, pull=True,
                 name='align_z'):
        axes = tuple(axes)
        for a in axes:
            if a not in ('x', 'y'):
                raise ParameterError(f"task '{name}': axes must be a subset of x, y, got {a!r}")
        super().__init__(robot, dim=len(axes), name=name, equal=np.zeros(len(axes)),
                         gain=gain)
        self.frame = frame
        self.frame_id = robot.frame_id(frame)
        self.estimator = estimator
        self.columns = np.array(['xyz'.index(a) for a in axes])
        self.k_o = float(gain)
        self.sign = -1.0 if pull else 1.0

    def level(self, kin, t):
        """The alignment level: ``S^T J_ang qdot_v = k_o S^T (sign z_ee x d_hat)``."""
        _, R, J = kin.frame(self.frame_id, virtual=True)
        S = R[:, self.columns]  # 3 x m, base frame
        omega = (self.sign * self.k_o) * np.cross(R[:, 2], self.estimator.direction)
        beta = S.T @ omega
        return Level(self.name, S.T @ J[3:], beta, beta, True)

    def compute_value(self, kin):
        """Zero: the alignment is a velocity task (its level holds the error term)."""
        return np.zeros(self.dim)

    def compute_jacobian(self, kin):
        """A = S^T J_v,ang with S the chosen axes of the virtual end-effector frame."""
        _, R, J = kin.frame(self.frame_id, virtual=True)
        return R[:, self.columns].T @ J[3:]


#: Keys of a ``constrained_manipulation`` task-stack entry.
SPEC_KEYS = ('type', 'name', 'frame', 'kappa', 'force', 'max_force', 'gain', 'estimator',
             'direction', 'orientation', 'posture')
_ORIENTATION_KEYS = ('mode', 'gain')
_POSTURE_KEYS = ('gain', 'equal')
_ESTIMATOR_KEYS = ('window', 'v_threshold', 'w0', 'initial_direction')


def _err(msg):
    return ParameterError(f'constrained_manipulation: {msg}')


def _check_keys(d, allowed, where):
    if not isinstance(d, dict):
        raise _err(f'{where} must be a mapping with keys {", ".join(allowed)}, got '
                   f'{type(d).__name__} {d!r}')
    for key in d:
        if key not in allowed:
            name = f'{where}.{key}' if where else key
            raise _err(f"unknown key '{name}'{did_you_mean(key, allowed)}; valid keys: "
                       f"{', '.join(allowed)}")


def _number(value, key, minimum=0.0, allow_inf=False):
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise _err(f"'{key}' must be a number, got {value!r}")
    v = float(value)
    if math.isnan(v) or (math.isinf(v) and not allow_inf) or v < minimum:
        raise _err(f"'{key}' must be a finite number >= {minimum:g}, got {value!r}")
    return v


def _make_estimator(spec):
    direction = spec.get('direction')
    est = spec.get('estimator', {})
    if direction is not None:
        if est:
            raise _err("give either 'direction' (a fixed d_hat) or 'estimator', not both")
        try:
            return FixedDirection(direction)
        except IfcSpgError as exc:
            raise _err(f"'direction' must be 3 numbers, not all zero, got {direction!r}") \
                from exc
    _check_keys(est, _ESTIMATOR_KEYS, 'estimator')
    try:
        return DirectionEstimator(EstimatorParams(**est))
    except (TypeError, IfcSpgError) as exc:
        raise _err(f'estimator: {exc}') from exc


def build_tasks(robot, spec):
    """Expand a ``constrained_manipulation`` task-stack entry into its levels (Table 5.1).

    Args:
        robot: The :class:`~ifc_spg.model.RobotModel`.
        spec: Mapping with the keys

            - ``frame``: chain id of the interaction point (default: ``tool`` if the model
              has it, else required),
            - ``kappa``: exploration rate [N/s] (default 9),
            - ``force``: ``measured`` (default, alpha_d = P_hat f_s) or 0,
            - ``max_force``: stop exploring above this force along d_hat [N] (default none),
            - ``gain``: Lambda of the wrench level [1/s] (default 50),
            - ``estimator``: ``{window: N, v_threshold: [m/s], w0: [m/s],
              initial_direction: [x, y, z]}`` (thesis defaults 500, 0.01, 0.01, +z), or
            - ``direction``: a fixed d_hat instead of the estimator,
            - ``orientation``: ``fixed`` (default) | ``align_z`` | ``release_y`` | ``free``,
              or ``{mode: ..., gain: k_o [1/s]}``,
            - ``posture``: ``{gain: [1/s], equal: init | [q...]}`` (default gain 1, init) or
              ``false`` for none,
            - ``name``: prefix of the task names (default ``constrained``).

    Returns:
        The tasks, highest priority first. ``tasks[0].estimator`` is the direction
        estimator shared by all of them.

    Raises:
        ParameterError: An unknown key (named, with the valid keys) or a bad value.
        UnknownFrame: ``frame`` is not a chain of the robot.
    """
    _check_keys(spec, SPEC_KEYS, '')
    if spec.get('type', 'constrained_manipulation') != 'constrained_manipulation':
        raise _err(f"type must be 'constrained_manipulation', got {spec['type']!r}")
    prefix = str(spec.get('name', 'constrained'))
    frame = _frame(robot, spec)
    kappa = _number(spec.get('kappa', 9.0), 'kappa')
    gain = _number(spec.get('gain', 50.0), 'gain')
    max_force = spec.get('max_force')
    max_force = math.inf if max_force is None else _number(max_force, 'max_force', 1e-9,
                                                           allow_inf=True)
    force = spec.get('force', 'measured')
    if force not in FORCE_MODES or isinstance(force, bool):
        raise _err(f"'force' must be 'measured' (alpha_d = P_hat f_s, Table 5.1) or 0, got "
                   f'{force!r}')
    estimator = _make_estimator(spec)
    orientation, k_o = _orientation(spec)
    tasks = [ConstrainedWrenchTask(robot, frame=frame, estimator=estimator, kappa=kappa,
                                   gain=gain, force=force, max_force=max_force,
                                   name=f'{prefix}.exploration')]
    tasks.extend(_orientation_tasks(robot, frame, estimator, orientation, k_o, prefix))
    tasks.extend(_posture_tasks(robot, spec.get('posture', {}), prefix))
    return tasks


def _frame(robot, spec):
    """The interaction chain: ``frame``, else ``tool`` where the model has it."""
    if 'frame' in spec:
        frame = spec['frame']
    elif 'tool' in robot.chains:
        frame = 'tool'
    else:
        raise _err(f"'frame' is required for robot '{robot.name}' (it has no 'tool'); "
                   f"chains: {', '.join(robot.chains)}")
    robot.frame_id(frame)
    return frame


def _orientation(spec):
    """``(mode, k_o)`` of the ``orientation`` entry (a mode name or ``{mode, gain}``)."""
    orientation = spec.get('orientation', 'fixed')
    k_o = 2.0
    if isinstance(orientation, dict):
        _check_keys(orientation, _ORIENTATION_KEYS, 'orientation')
        k_o = _number(orientation.get('gain', k_o), 'orientation.gain')
        orientation = orientation.get('mode', 'fixed')
    if orientation not in ORIENTATIONS:
        raise _err(f"orientation '{orientation}' unknown{did_you_mean(orientation, ORIENTATIONS)}"
                   f"; choose one of {', '.join(ORIENTATIONS)}")
    return orientation, k_o


def _orientation_tasks(robot, frame, estimator, orientation, k_o, prefix):
    """The orientation levels of 5.15-5.20 (none for ``free``)."""
    if orientation == 'fixed':
        return [CartesianPoseTask(robot, frame=frame, axes=('rx', 'ry', 'rz'), equal='init',
                                  gain=k_o, name=f'{prefix}.orientation')]
    if orientation not in ('align_z', 'release_y'):
        return []
    z_axis = np.zeros((6, 1))
    z_axis[5, 0] = 1.0
    axes = ('x', 'y') if orientation == 'align_z' else ('x',)
    return [CartesianPoseTask(robot, frame=frame, subspace=z_axis,
                              subspace_frame='ee_orientation', equal=0.0, gain=k_o,
                              name=f'{prefix}.hold_z'),
            AxisAlignTask(robot, frame=frame, estimator=estimator, axes=axes, gain=k_o,
                          name=f'{prefix}.{orientation}')]


def _posture_tasks(robot, posture, prefix):
    """The posture level (joint position), or none for ``posture: false``."""
    if posture is False or posture is None:
        return []
    _check_keys(posture, _POSTURE_KEYS, 'posture')
    p_gain = _number(posture.get('gain', 1.0), 'posture.gain')
    equal = posture.get('equal', 'init')
    try:
        return [JointPositionTask(robot, equal=equal, gain=p_gain, name=f'{prefix}.posture')]
    except IfcSpgError as exc:
        raise _err(f'posture.equal: {exc}') from exc
