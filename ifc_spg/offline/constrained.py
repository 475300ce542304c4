"""Closed-loop constrained-manipulation runs in the lockstep simulator (no DDS).

One :class:`Scenario` names the robot, the scene, the strategy and its parameters; :func:`run`
steps :class:`~sim_bridge.simulation.Simulation` and the strategy in lockstep (one command
per joint-state sample, as the bridge's lockstep mode) and returns a :class:`RunLog` of time
series plus the metrics of :func:`~ifc_spg.constrained.metrics.summarize`.

The true motion direction of the mechanism is the direction of the handle's velocity per
unit mechanism motion (the handle site's Jacobian column of the mechanism joint), signed
with the direction the mechanism actually moved.
"""

from dataclasses import dataclass, field, replace
import math
from typing import Any

import mujoco
import numpy as np

from ifc_spg.constrained.admittance_strategy import CartesianAdmittanceStrategy
from ifc_spg.constrained.direction_estimator import FixedDirection
from ifc_spg.constrained.joint_compliance_strategy import JointComplianceStrategy
from ifc_spg.constrained.metrics import summarize
from ifc_spg.constrained.params import STRATEGIES, StrategyParams
from ifc_spg.constrained.task_specification import build_tasks
from ifc_spg.errors import ParameterError, did_you_mean
from ifc_spg.kinematics import Kinematics
from ifc_spg.model import RobotModel
from ifc_spg.spg import SetPointGenerator
from ifc_spg.tasks.static_interaction import static_wrench
from sim_bridge.simulation import Simulation

__all__ = [
    'DEFAULT_Q0_DEG',
    'RunLog',
    'Scenario',
    'TaskSpecificationStrategy',
    'initial_pose_deg',
    'make_strategy',
    'robot_with_stiffness',
    'run',
    'sim_frame',
]


def robot_with_stiffness(robot, stiffness=None):
    """Return ``robot`` (a model or a configuration name) with joint stiffness K [Nm/rad].

    The damping D is scaled by sqrt(K_new / K_old), which keeps the damping ratio.
    """
    if isinstance(robot, str):
        robot = RobotModel.from_config(robot)
    if stiffness is None:
        return robot
    k_new = np.broadcast_to(np.asarray(stiffness, dtype=float), (robot.n,))
    return robot.with_gains(stiffness=k_new,
                            damping=robot.damping * np.sqrt(k_new / robot.stiffness))


class TaskSpecificationStrategy:
    """The task-specification strategy (5.5) as a controller: the SPG with Table 5.1's tasks.

    Args:
        robot: The :class:`~ifc_spg.model.RobotModel`.
        params: :class:`~ifc_spg.constrained.params.StrategyParams`.
        frame: Chain id.
        direction: A fixed d_hat instead of the estimator (Sec. 5.5.3), or None.
        pspm: Passivity stabilizer of the SPG (default: ``params.pspm``).
        solver: QP solver of the SPG.
    """

    name = 'task_specification'

    def __init__(self, robot, params=None, *, frame='tool', direction=None, pspm=None,
                 solver='daqp'):
        p = params or StrategyParams()
        e = p.estimator
        spec = {'frame': frame, 'kappa': p.kappa, 'gain': p.force_gain,
                'orientation': {'mode': p.orientation, 'gain': p.orientation_gain},
                'posture': {'gain': p.posture_gain} if p.posture_gain > 0 else False}
        if math.isfinite(p.max_force):
            spec['max_force'] = p.max_force
        if direction is None:
            spec['estimator'] = {'window': e.window, 'v_threshold': e.v_threshold, 'w0': e.w0,
                                 'initial_direction': list(e.initial_direction)}
        else:
            spec['direction'] = list(direction)
        self.tasks = build_tasks(robot, spec)
        self.estimator = self.tasks[0].estimator
        self.spg = SetPointGenerator(robot, self.tasks, dt=p.dt,
                                     pspm=p.pspm if pspm is None else pspm, solver=solver)

    def step(self, q, qdot, t):
        """One SPG tick; returns q_v in [rad]."""
        return self.spg.step(q, qdot, t)


def make_strategy(name, robot, params=None, *, frame=None, direction=None, options=None):
    """Build a strategy controller (``step(q, qdot, t) -> q_v``, ``.estimator``).

    Args:
        name: 'admittance', 'joint_compliance' or 'task_specification'.
        robot: The :class:`~ifc_spg.model.RobotModel`.
        params: :class:`~ifc_spg.constrained.params.StrategyParams`.
        frame: Chain id (default: ``tool``, or the first admittance chain).
        direction: A fixed d_hat instead of the estimator, or None.
        options: Extra keyword options of the strategy class (``ik_iterations``,
            ``relax_time``, ``limit_margin``, ``projection`` of
            :class:`~ifc_spg.constrained.admittance_strategy.CartesianAdmittanceStrategy`).
    """
    params = params or StrategyParams()
    options = dict(options or {})
    if options and name != 'admittance':
        raise ParameterError(f"strategy options {sorted(options)} are options of the "
                             f"'admittance' strategy only, not '{name}'")
    if frame is None:
        frame = 'tool' if 'tool' in robot.chains else next(iter(robot.admittance), None)
    if name == 'task_specification':
        return TaskSpecificationStrategy(robot, params, frame=frame, direction=direction)
    estimator = None if direction is None else FixedDirection(direction)
    if name == 'joint_compliance':
        return JointComplianceStrategy(robot, params, frame=frame, estimator=estimator)
    if name == 'admittance':
        allowed = ('ik_iterations', 'relax_time', 'limit_margin', 'projection')
        for key in options:
            if key not in allowed:
                raise ParameterError(f"admittance strategy has no option '{key}'"
                                     f"{did_you_mean(key, allowed)}; options: "
                                     f"{', '.join(allowed)}")
        return CartesianAdmittanceStrategy(robot, params, frame=frame, estimator=estimator,
                                           **options)
    raise ParameterError(f"unknown strategy '{name}'{did_you_mean(name, STRATEGIES)}; choose "
                         f"one of {', '.join(STRATEGIES)}")


@dataclass(frozen=True)
class Scenario:
    """One constrained-manipulation run.

    Attributes:
        strategy: 'admittance', 'joint_compliance' or 'task_specification'.
        robot: Robot configuration name.
        scene: Mechanism scene (``drawer_vertical``, ``crank``, ...).
        params: :class:`~ifc_spg.constrained.params.StrategyParams`.
        initial_error_deg: Angle of d_p0 from the true initial direction in [deg]; d_p0 is
            the true direction turned by this angle about ``error_axis`` (ignored when
            ``params.estimator.initial_direction`` is to be used: set None).
        error_axis: 'scene_v' / 'scene_u' / 'scene_z', or a 3-vector of scene-frame
            components (u, v, z): the rotation axis of the error in the scene frame (u
            forward, v left, z up), made orthogonal to the true direction; None: the scene
            axis most orthogonal to the true direction.
        fixed_direction: Use the true initial direction as a constant d_hat (Sec. 5.5.3).
        duration: Run length in [s] (the run stops ``settle`` s after opening).
        target: Travel that counts as open (m or rad).
        settle: Seconds to keep running after the target is reached.
        force_limit: Success requires |f| <= force_limit [N].
        scene_options: Scene builder options (e.g. ``{'grasp': 'connect'}``).
        sim: Extra :class:`~sim_bridge.simulation.SimConfig` fields (e.g. admittance).
        q0_deg: Initial joint positions in [deg]; None: :func:`initial_pose_deg` of the
            robot and scene, or the robot's home pose. The scene is built at the tool pose
            of q0.
        strategy_options: Extra options of the strategy (see :func:`make_strategy`).
        pushes: Disturbances by hand, ``(at [s], [f; tau] in the base frame [N, Nm],
            duration [s])`` each, on the contact chain (its site origin).
    """

    strategy: str = 'task_specification'
    robot: str = 'lbr4'
    scene: str = 'drawer_vertical'
    params: StrategyParams = field(default_factory=StrategyParams)
    initial_error_deg: float = 45.0
    error_axis: str | tuple[float, float, float] | None = None
    fixed_direction: bool = False
    duration: float = 20.0
    target: float = 0.29
    settle: float = 0.0
    force_limit: float = 60.0
    scene_options: dict[str, Any] = field(default_factory=dict)  # options from YAML/JSON
    sim: dict[str, Any] = field(default_factory=dict)
    q0_deg: tuple[float, ...] | None = None
    strategy_options: dict[str, Any] = field(default_factory=dict)
    pushes: tuple[tuple[float, tuple[float, ...], float], ...] = ()


#: Right arm of the ACCREA in its home pose [deg] (it only holds still).
_ACCREA_RIGHT_HOME = (15.0, 90.0, 90.0, 45.0, 0.0, -60.0, 0.0)

#: Initial configurations [deg] per robot or per (robot, scene) (the pair wins). The
#: LBR-IV's home pose (tool down, A6 at 90 deg of +-105) leaves no room to lift a handle
#: 0.3 m with a fixed orientation; with the tool pointing forward at (0.80, 0, 0.48) m every
#: joint keeps >= 44 deg to its limits while the tool moves 0.3 m up, down or sideways.
#: The ACCREA's home pose puts the left tool (pointing down) at (0.45, 0.34, 0.95) m, where
#: a 0.3 m lift runs out of reach (the elbow stretches, the IK residual grows, A6 reaches
#: its limit after 0.22 m). The ACCREA poses below were found by a search over tool poses
#: (grid of positions, tool down/forward) scored by the smallest joint-limit margin and
#: Jacobian singular value along the scene's handle path, tracked with the strategy's own
#: IK (:func:`~ifc_spg.constrained.admittance_strategy.solve_ik`); margins along the path
#: are given per entry.
DEFAULT_Q0_DEG = {
    'lbr4': (0.0, 40.0, 0.0, -70.0, 0.0, -20.0, 0.0),
    # Tool down at (0.35, 0.40, 0.80) m; >= 32 deg margin, sigma_min >= 0.1 over a 0.31 m
    # lift.
    ('accrea_dual_arm', 'drawer_vertical'): (-2.7, 78.9, -90.7, 67.0, 2.7, -25.7, 8.6)
    + _ACCREA_RIGHT_HOME,
    # Tool pointing along +x at (0.50, 0.50, 1.25) m; >= 24 deg margin, sigma_min >= 0.07
    # over 1.15 quarter turns either way.
    ('accrea_dual_arm', 'crank'): (-53.2, 76.9, -62.9, 89.5, 40.0, 49.0, 53.9)
    + _ACCREA_RIGHT_HOME,
    # Tool down at (0.45, 0.30, 1.05) m; >= 24 deg margin while the door swings 0.4 rad.
    ('accrea_dual_arm', 'microwave_door'): (-26.4, 86.4, -111.4, 45.5, 21.6, -74.0, -13.0)
    + _ACCREA_RIGHT_HOME,
}


def initial_pose_deg(robot, scene):
    """The default initial configuration [deg] of ``robot`` in ``scene`` (or None)."""
    return DEFAULT_Q0_DEG.get((robot, scene), DEFAULT_Q0_DEG.get(robot))


#: Seconds left out of the force metrics at the start: the simulator's first samples carry
#: the grasp constraint's initial transient (up to 12 N for one sample), not the strategy.
SKIP = 0.01


@dataclass
class RunLog:
    """Time series of one run (row i = tick i) and its metrics.

    Attributes:
        t: Time [s] (T,). env_q: mechanism position (T,). force: force the robot applies
        at the tool, ground truth (T, 3) [N]. static_force: f_s (T, 3) [N]. damping_force:
        the plant's damping torque -D qdot through J^{+T} (T, 3) [N] (NaN without joint
        impedance). estimate:
        d_hat (T, 3). true_direction: (T, 3). metrics: :func:`summarize` output.
        q: measured joint positions (T, n) [rad]. ik_residual: the admittance strategy's
        IK residual |x_v - FK(q_v)| per tick (T,) (NaN for the other strategies).
    """

    t: np.ndarray
    env_q: np.ndarray
    force: np.ndarray
    static_force: np.ndarray
    damping_force: np.ndarray
    estimate: np.ndarray
    true_direction: np.ndarray
    metrics: dict[str, Any]
    warnings: dict[str, Any]
    q: np.ndarray | None = None
    ik_residual: np.ndarray | None = None


class _HandleDirection:
    """Direction of the handle's motion per unit of the mechanism joint (world frame)."""

    def __init__(self, sim):
        m = sim.model
        self.site = m.site('handle').id
        joint = m.joint(sim.env_joint_names[0]).id
        self.dof = int(m.jnt_dofadr[joint])
        self._jacp = np.zeros((3, m.nv))
        self._jacr = np.zeros((3, m.nv))

    def __call__(self, sim):
        mujoco.mj_jacSite(sim.model, sim.data, self._jacp, self._jacr, self.site)
        v = self._jacp[:, self.dof]
        return v / max(np.linalg.norm(v), 1e-12)


def _error_axis(sim, true_dir, error_axis):
    """The rotation axis of the initial error (world frame, not yet orthogonalized)."""
    u, v, z = sim_frame(sim)
    axes = {'scene_v': v, 'scene_u': u, 'scene_z': z}
    if error_axis is None:
        # The scene axis most orthogonal to the true direction (v first).
        return min(axes.values(), key=lambda a: abs(float(a @ true_dir)) - 1e-3 * (a is v))
    if isinstance(error_axis, str):
        if error_axis not in axes:
            raise ParameterError(f'error_axis must be None, scene_u, scene_v, scene_z or a '
                                 f'3-vector (u, v, z), got {error_axis!r}')
        return axes[error_axis]
    try:
        c = np.asarray(error_axis, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        c = np.zeros(0)
    if c.shape != (3,) or not np.all(np.isfinite(c)) or np.linalg.norm(c) < 1e-9:
        raise ParameterError(f'error_axis must be None, scene_u, scene_v, scene_z or a '
                             f'3-vector of finite scene-frame components (u, v, z), not all '
                             f'zero, got {error_axis!r}')
    return (c[0] * u + c[1] * v + c[2] * z) / np.linalg.norm(c)


def _initial_direction(sim, true_dir, scenario):
    axis = _error_axis(sim, true_dir, scenario.error_axis)
    a = math.radians(scenario.initial_error_deg)
    # Rodrigues rotation of true_dir about axis (axis made orthogonal to it).
    axis = axis - (axis @ true_dir) * true_dir
    if np.linalg.norm(axis) < 1e-6:
        raise ParameterError(f'error_axis {scenario.error_axis!r} is parallel to the true '
                             f'direction {np.round(true_dir, 3).tolist()} of '
                             f"'{scenario.scene}': a rotation about it changes nothing; use "
                             'another scene axis or None')
    axis = axis / np.linalg.norm(axis)
    return math.cos(a) * true_dir + math.sin(a) * np.cross(axis, true_dir)


def sim_frame(sim):
    """Scene frame (u forward, v left, z up) of a built simulation."""
    p, _ = sim.chain_pose(sim.contact_chain)
    u = np.array([p[0], p[1], 0.0])
    u = u / np.linalg.norm(u) if np.linalg.norm(u) > 1e-6 else np.array([1.0, 0.0, 0.0])
    z = np.array([0.0, 0.0, 1.0])
    return u, np.cross(z, u), z


def _simulation(scenario, robot, period):
    """The scenario's simulation, from its q0 (or the scene's initial pose)."""
    q0 = scenario.q0_deg if scenario.q0_deg is not None else initial_pose_deg(
        scenario.robot, scenario.scene)
    if q0 is not None:
        q0 = tuple(np.radians(np.asarray(q0, dtype=float)))
    return Simulation(robot=robot, scene=scenario.scene, scene_options=dict(
        scenario.scene_options), command_period=period, q0=q0, **scenario.sim)


def _record(rows, s, ctrl, h, h_damped, true_direction):
    """Append one tick's samples (state ``s``, static wrench ``h``) to ``rows``.

    ``h_damped``: the static wrench with the plant's damping torque -D qdot (None: the
    robot has no joint impedance); their difference is the damping force.
    """
    rows['t'].append(s.t)
    rows['env_q'].append(s.env_q[0])
    rows['force'].append(-s.contact_wrench[:3])
    rows['fs'].append(h[:3].copy())
    rows['fd'].append(np.full(3, math.nan) if h_damped is None else h_damped[:3] - h[:3])
    rows['est'].append(np.array(ctrl.estimator.direction))
    rows['true'].append(true_direction)
    rows['q'].append(s.q)
    rows['ik'].append(getattr(ctrl, 'ik_residual', math.nan))


def run(scenario):
    """Run one scenario in lockstep; returns a :class:`RunLog`."""
    p = scenario.params
    robot = RobotModel.from_config(scenario.robot)
    if robot.ifc == 'joint_impedance':
        robot = robot_with_stiffness(robot, p.stiffness)
    period = p.dt
    sim = _simulation(scenario, robot, period)
    try:
        handle = _HandleDirection(sim)
        d_true0 = handle(sim)
        if not scenario.fixed_direction and scenario.initial_error_deg is not None:
            d0 = _initial_direction(sim, d_true0, scenario)
            p = replace(p, estimator=replace(p.estimator, initial_direction=tuple(d0)))
        frame = sim.contact_chain
        ctrl = make_strategy(scenario.strategy, robot, p, frame=frame,
                             direction=d_true0 if scenario.fixed_direction else None,
                             options=scenario.strategy_options)
        kin = Kinematics(robot)
        # the damping the plant applies (sim.damping overrides the robot's): the damping
        # force J^{+T} (-D qdot) is logged beside the static force
        plant = None
        if robot.ifc == 'joint_impedance':
            plant = robot if 'damping' not in scenario.sim else robot.with_gains(
                damping=scenario.sim['damping'], where=f'scenario {scenario.scene}: sim.')
        ticks = round(scenario.duration / period)
        steps = round(period / sim.dt)
        rows: dict[str, list[Any]] = {
            k: [] for k in ('t', 'env_q', 'force', 'fs', 'fd', 'est', 'true', 'q', 'ik')}
        t_open = None
        pushes = sorted(scenario.pushes, key=lambda push: push[0])
        for _ in range(ticks):
            s = sim.read_state()
            while pushes and pushes[0][0] <= s.t + 1e-9:
                _, wrench, seconds = pushes.pop(0)
                sim.apply_wrench(frame, wrench, seconds)
            q_v = ctrl.step(s.q, s.qd, s.t)
            kin.update(s.q, s.qd, s.q_v)
            _record(rows, s, ctrl, static_wrench(robot, kin, frame)[0],
                    None if plant is None else
                    static_wrench(plant, kin, frame, include_damping=True)[0], handle(sim))
            sim.write_command(q_v)
            sim.step(steps)
            if t_open is None and abs(s.env_q[0] - rows['env_q'][0]) >= scenario.target:
                t_open = s.t
            if t_open is not None and s.t - t_open >= scenario.settle:
                break
        warnings = sim.warnings()
    finally:
        sim.close()
    arr = {k: np.array(v) for k, v in rows.items()}
    moved = arr['env_q'][-1] - arr['env_q'][0]
    true_dir = arr['true'] * (1.0 if moved >= 0 else -1.0)
    metrics = summarize(arr['t'], arr['env_q'], arr['force'], true_dir, estimate=arr['est'],
                        static_force=arr['fs'],
                        damping_force=None if plant is None else arr['fd'],
                        target=scenario.target,
                        force_limit=scenario.force_limit, skip=SKIP)
    metrics['strategy'] = scenario.strategy
    metrics['scene'] = scenario.scene
    return RunLog(t=arr['t'], env_q=arr['env_q'], force=arr['force'], static_force=arr['fs'],
                  damping_force=arr['fd'],
                  estimate=arr['est'], true_direction=true_dir, metrics=metrics,
                  warnings=warnings, q=arr['q'], ik_residual=arr['ik'])
