"""The set-point generator: one tick turns measurements into the virtual joint positions.

``SetPointGenerator.step(q, qdot, t) -> q_v`` (ARCHITECTURE "Python API"):

1. kinematics at the measured q and the virtual q_v,
2. the velocity box: joint limits (docs/SPEC.md §4) intersected with the PSPM passivity bounds
   (docs/SPEC.md §6), then the acceleration limit (soft: position safety and passivity win),
3. the levels: the implicit joint-torque-limit task |tau_s| <= tau_max on top (4.3), then
   the stack's tasks in priority order,
4. the cascade (docs/SPEC.md §3) or the nullspace baseline (docs/SPEC.md §5),
5. q_v <- q_v + dT qdot_v, and the energy tanks are booked.

A failed or non-finite solve, or an exception raised by a task or the solver, never
produces NaN or a q_v outside the limits: qdot_v becomes the point of the safe box nearest
zero (braking within a_max, then holding q_v) and the status says so in ``info``
('hold', with the reason in ``info.message``). A NaN passivity bound (overflow on absurd
measurements) stops that joint.
"""

from collections.abc import Sequence
import math
import time
from types import ModuleType
from typing import TYPE_CHECKING, NamedTuple, Union

import numpy as np

from ifc_spg import kernels as _kernels
from ifc_spg.cascade import SOLVERS, Cascade, level_violation, make_solver
from ifc_spg.errors import IfcSpgError, ParameterError
from ifc_spg.kinematics import Kinematics
from ifc_spg.limits import JointVelocityLimits, VelocityBox, intersect_soft
from ifc_spg.limits.torque_limits import TorqueLimitLevel
from ifc_spg.model import JOINT_IMPEDANCE, RobotModel
from ifc_spg.pspm import EnergyTanks, PspmConfig, StallMonitor, StallReport, stall_message
from ifc_spg.tasks.static_interaction import load_lapack
from ifc_spg.tasks.task import Level, Task

if TYPE_CHECKING:  # task_stack builds on the SPG's tasks: no import at run time
    from ifc_spg.task_stack import TaskStack

#: What set_stack takes: a TaskStack (built for the robot) or the tasks themselves
StackInput = Union['TaskStack', Sequence[Task]]

__all__ = ['Activation', 'SetPointGenerator', 'SpgInfo', 'SpgState']

load_lapack()  # the wrench tasks' solver: imported here, not at an SPG's first tick

#: Ticks of the warm-up run (:meth:`SetPointGenerator._warm_up`).
_WARM_UP_TICKS = 10
#: The solvers warmed up (exact and fast; proxsuite can stall a tick for 0.2 s).
_WARM_UP_SOLVERS = ('daqp', 'nullspace')
#: The configurations warmed up in this process (solver, kernels, PSPM, torque limit, IFC).
_WARMED_UP: set[tuple] = set()


def _dry_run_tasks() -> frozenset:
    """The task classes whose level changes nothing but the activation that deactivate undoes.

    Exact classes (a subclass may keep state in its level: the Ch. 5 exploration task
    updates its direction estimator there); see :meth:`SetPointGenerator._dry_run`.
    """
    from ifc_spg.tasks import CartesianPoseTask, JointPositionTask, JointTorqueTask, WrenchTask
    return frozenset((CartesianPoseTask, JointPositionTask, JointTorqueTask, WrenchTask))


class SpgState(NamedTuple):
    """What the next tick starts from (:meth:`SetPointGenerator.snapshot`).

    Attributes:
        q_v: Virtual joint positions [rad] (None before the first tick).
        qdot_v: The last tick's virtual joint velocity [rad/s] (the acceleration limit).
        tank_energy: PSPM tank energies [J] (None without PSPM).
        shuffled: Energy shuffled into each tank so far [J] (None without PSPM).
        warm_start: The cascade's working sets the next solve starts from (the solver's
            ``warm_start`` vector for the running stack; empty for a solver without one,
            None: unknown, the next solve starts cold).
    """

    q_v: np.ndarray | None
    qdot_v: np.ndarray
    tank_energy: np.ndarray | None
    shuffled: np.ndarray | None
    warm_start: np.ndarray | None = None


class Activation(NamedTuple):
    """The tick at which a stack's tasks captured their ``init`` values.

    The tick at which a stack's tasks captured their ``init`` values: measured q [rad], qdot
    [rad/s], the virtual q_v [rad] before the tick and the stamp t [s].
    """

    q: np.ndarray
    qdot: np.ndarray
    q_v: np.ndarray
    t: float


#: the fields and properties of an :class:`SpgInfo` in ``SpgInfo.as_dict`` (``spg/status``)
_STATUS_FIELDS = ('status', 'solver', 'level_names', 'slacks', 'residuals', 'at_limit',
                  'tank_energy', 'spring_energy_step', 'solve_time', 'tick_time', 'task_time',
                  'qdot_v', 'message', 'failed_level', 'pspm', 'collision')


class SpgInfo(NamedTuple):
    """What the last tick did (a frozen snapshot, built once per tick).

    The snapshot holds values, not the SPG's live objects: the tank energies and refills
    are copies taken at the tick, so an info kept across ticks still says what its tick did.
    (An immutable named tuple: built every tick, it costs about 2 us where a frozen
    dataclass of the same fields cost about 6.)

    Attributes:
        status: 'ok', 'fallback', 'hold', 'bad_input' or 'idle' (no stack).
        solver: Name of the solver.
        level_names: Names of the levels (the torque limit first, if enabled).
        slacks: Slack s* per level (list of arrays).
        residuals: Violation of each level's velocity bounds by the final qdot_v.
        at_limit: Indices of joints whose qdot_v sits on the velocity box.
        tank_energy: PSPM tank energies in [J] after the tick (a copy; None without PSPM).
        spring_energy_step: Change of spring energy 1/2 K dq^2 by this tick's step [J].
        solve_time: Cascade solve time in [s]; tick_time: whole tick in [s].
        task_time: Seconds since the stack became active.
        message: Human-readable reason for a non-'ok' status, or the PSPM stall warning.
        stall: :class:`~ifc_spg.pspm.StallReport` while an empty tank clips the stack's
            solution (status stays 'ok'), else None; stall_new: True on the tick the first
            stall of an episode is reported (log it), and again only if other joints stall.
        power_budget: Refill rate of the tanks in effect [W] (the stack's power_budget).
        pspm: Dict (computed on demand) of power_budget, max_power [W], refilled [J] per
            joint, and stall {joints, requested_power [W] per joint, total_power, since,
            fix, message} or None; None without PSPM.
        qdot_v: The tick's virtual joint velocity [rad/s].
        failed_level: Index of the level that could not be solved, or -1.
        levels: The tick's levels (:class:`~ifc_spg.tasks.Level`, the torque limit first).
        box: The tick's :class:`~ifc_spg.limits.VelocityBox` on qdot_v.
        max_power: The tanks' maximum refill rate in [W] (None without PSPM).
        refilled: Energy the power budget has put into each tank so far in [J], up to and
            including this tick (a copy; None without PSPM).
        joint_names: The robot's joint names (model order).
        distances: The tick's :class:`~ifc_spg.tasks.collision_avoidance.DistanceReport`
            per collision-avoidance task (at q_v); ``collision`` gives them as dicts
            (minimum distance per pair group).
    """

    status: str | None = None
    solver: str | None = None
    slacks: list | None = None
    tank_energy: np.ndarray | None = None
    spring_energy_step: np.ndarray | None = None
    solve_time: float | None = None
    tick_time: float | None = None
    task_time: float | None = None
    qdot_v: np.ndarray | None = None
    message: str | None = None
    failed_level: int | None = None
    levels: list | None = None
    box: VelocityBox | None = None
    stall: StallReport | None = None
    stall_new: bool | None = None
    power_budget: float | None = None
    max_power: float | None = None
    refilled: np.ndarray | None = None
    joint_names: tuple | None = None
    distances: tuple = ()

    @property
    def collision(self) -> list[dict] | None:
        """Minimum distance per pair group of each collision-avoidance task (None: none)."""
        return [r.as_dict() for r in self.distances] or None

    @property
    def level_names(self) -> list[str]:
        """Names of the levels (the torque limit first, if enabled)."""
        return [lv.name for lv in (self.levels or [])]

    @property
    def pspm(self) -> dict | None:
        """Power budget, refill and stall of the energy tanks (None without PSPM)."""
        if self.refilled is None:
            return None
        stall = self.stall
        names = self.joint_names or ()
        return {
            'power_budget': float(self.power_budget or 0.0),
            'max_power': float(self.max_power or 0.0),
            'refilled': [float(x) for x in self.refilled],
            'stall': None if stall is None else {
                'joints': [names[j] for j in stall.joints],
                'requested_power': {names[j]: p for j, p in zip(stall.joints,
                                                                stall.requested_power)},
                'total_power': stall.total_power, 'robot_power': stall.robot_power,
                'since': stall.since,
                'fix': stall.suggestion(), 'message': stall_message(stall, names)}}

    @property
    def residuals(self) -> list[np.ndarray]:
        """Violation of each level's velocity bounds by the final qdot_v (computed on demand)."""
        qdot_v = self.qdot_v
        if qdot_v is None:
            return []
        return [level_violation(lv, qdot_v) for lv in (self.levels or [])]

    @property
    def at_limit(self) -> np.ndarray:
        """Indices of joints whose qdot_v sits on the velocity box."""
        if self.box is None or self.qdot_v is None:
            return np.zeros(0, dtype=int)
        return np.flatnonzero((self.qdot_v <= self.box.lower) | (self.qdot_v >= self.box.upper))

    def as_dict(self) -> dict:
        """JSON-friendly dict (for ``spg/status``)."""
        def conv(v):
            if isinstance(v, np.ndarray):
                return [float(x) for x in v.reshape(-1)]
            if isinstance(v, (list, tuple)):
                return [conv(x) for x in v]
            if isinstance(v, np.generic):
                return v.item()
            return v
        return {k: conv(getattr(self, k)) for k in _STATUS_FIELDS}


class Tick(NamedTuple):
    """What one :meth:`SetPointGenerator.tick` did: the command, the report and the events.

    Attributes:
        q_v: The virtual joint positions in [rad] (a new array; what :meth:`step` returns).
        qdot_v: The virtual joint velocity in [rad/s].
        info: The tick's :class:`SpgInfo` (also ``spg.info`` until the next tick).
        events: What happened in this tick that a caller may report, in order, from
            :data:`TICK_EVENTS`: ``'activated'`` (the stack started this tick — the first
            tick, the first after :meth:`SetPointGenerator.reset`, or a new stack — and its
            tasks took their ``init`` values), ``'stack_taken'`` (the stack given to the
            constructor or to ``set_stack`` took effect this tick), ``'pspm_stall'`` (a
            new stall episode, or other joints stalled; ``info.message`` says which),
            and the non-'ok' statuses ``'fallback'``, ``'hold'``, ``'bad_input'``.
    """

    q_v: np.ndarray
    qdot_v: np.ndarray
    info: SpgInfo
    events: tuple[str, ...] = ()


TICK_EVENTS = ('activated', 'stack_taken', 'pspm_stall', 'fallback', 'hold', 'bad_input')


class SetPointGenerator:
    """Hierarchical set-point generator for an IFC robot.

    Args:
        robot: The :class:`~ifc_spg.model.RobotModel`.
        stack: A task stack (an object with ``build(robot) -> list of tasks``, e.g.
            :class:`~ifc_spg.task_stack.TaskStack`) or a list of tasks, highest priority
            first; None starts idle (holding q_v).
        dt: SPG period dT in [s].
        pspm: True (default parameters), False, or a :class:`~ifc_spg.pspm.PspmConfig`.
        solver: 'daqp' (default), 'proxsuite' or 'nullspace' (baseline, equality tasks
            only, no torque limits), or a :class:`~ifc_spg.cascade.Cascade` object.
        rho: Regularization of qdot_v in each level (4.45).
        torque_limits: Add the implicit top-level task |K (q_v - q)| <= tau_max (4.3) on a
            joint-impedance robot (the nullspace baseline cannot take it: pass False).
        velocity_box: Bound qdot_v by the robot's joint velocity and acceleration limits
            (4.31-4.33, Ch. 4). False: by the position limits only, one step ahead
            ((q_m - q_v)/dT <= qdot_v <= (q_M - q_v)/dT, so q_v never leaves them), as the
            Ch. 3 mapping (Alg. C.1/C.2), which knows no velocity or acceleration limit; the
            passivity bounds of PSPM still apply when it is on.
        kernels: The kernels module of the tick (default :data:`ifc_spg.kernels.active`;
            :mod:`ifc_spg.kernels.reference` for the numpy reference).
        warm_up: Run this configuration's tick code once in the process before the first
            real tick (:meth:`_warm_up`), and each new stack's levels and cascade once when
            it is set (:meth:`_dry_run`); no effect on the results.

    Raises:
        ParameterError: A bad ``dt`` or ``pspm``, or torque limits asked of a solver that
            cannot take them.
    """

    def __init__(self, robot: RobotModel, stack: StackInput | None = None, *, dt: float = 0.002,
                 pspm: bool | PspmConfig = True, solver: str | Cascade = 'daqp',
                 rho: float = 0.01, torque_limits: bool = True, velocity_box: bool = True,
                 kernels: ModuleType | None = None, warm_up: bool = True):
        if not (np.isfinite(dt) and 0 < dt <= 1.0):
            raise ParameterError(f'dt must be a period in (0, 1] s, got {dt!r}')
        if not isinstance(velocity_box, (bool, np.bool_)):
            raise ParameterError(f'velocity_box must be True (the joint velocity and '
                                 f'acceleration limits bound qdot_v) or False (the position '
                                 f'limits only, Alg. C.1/C.2), got {velocity_box!r}')
        self.velocity_box = bool(velocity_box)
        self.robot = robot
        self.dt = float(dt)
        n = robot.n
        self.n = n
        self._kernels = kernels = _kernels.resolve(kernels)
        name = solver if isinstance(solver, str) else solver.name
        self._solver_args = (name, n, rho)
        self._solver: Cascade = self._new_solver() if isinstance(solver, str) else solver
        self.tanks = self._make_tanks(pspm)
        self._stall = None if self.tanks is None else StallMonitor(self.tanks)
        self._probe_solver: Cascade | None = None  # a second cascade for stall probes
        self._torque_limit = None
        if torque_limits and robot.ifc == JOINT_IMPEDANCE:
            if not self._solver.supports_torque_limits:
                raise ParameterError(
                    f"solver '{name}' cannot take the joint-torque-limit level (it does not "
                    'keep qdot_v inside a box); pass torque_limits=False (spg_node parameter '
                    "torque_limits:=false) or use solver 'daqp'")
            self._torque_limit = TorqueLimitLevel(
                np.where(robot.stiff_mask, 0.0, robot.stiffness), robot.tau_max, dt, rho,
                self._solver.lock_tolerance, kernels=kernels)
        self.kin = Kinematics(robot, kernels)
        self._limits = JointVelocityLimits(robot.q_min, robot.q_max, robot.v_max, robot.a_max,
                                           dt, kernels=kernels)
        # Without the velocity box no acceleration limit either (the soft box is unbounded).
        self._accel = np.ascontiguousarray(robot.a_max * self.dt if self.velocity_box
                                           else np.full(n, np.inf), dtype=float)
        self._q_min = np.ascontiguousarray(robot.q_min, dtype=float)
        self._q_max = np.ascontiguousarray(robot.q_max, dtype=float)
        self._zeros = np.zeros(n)
        self.q_v: np.ndarray | None = None
        self.qdot_v = np.zeros(n)
        self.tasks: list[Task] = []
        self._reporting: list = []  # tasks with a report() for info.distances
        self._slack_messages: list = []  # (task index, its slack_message), see _take_pending
        self._pending: tuple | None = None
        self._t0: float | None = None
        self.stack: StackInput | None = None
        #: ``[first, latest]`` :class:`Activation` of the running stack's tasks (the first
        #: fixes orientation references, the latest the ``init`` values after a restart)
        self.activations: list[Activation] = []
        tanks = self.tanks
        self.info = SpgInfo(status='idle', solver=self._solver.name, power_budget=0.0,
                            max_power=None if tanks is None else tanks.config.max_power,
                            refilled=None if tanks is None else tanks.refilled.copy(),
                            joint_names=tuple(robot.joint_names))
        self._dry_runs = bool(warm_up) and name in _WARM_UP_SOLVERS
        if warm_up:
            self._warm_up(pspm, torque_limits)
        if stack is not None:
            self.set_stack(stack)

    def _warm_up(self, pspm: bool | PspmConfig, torque_limits: bool) -> None:
        """Run the tick of this configuration on a throwaway SPG, once per process.

        The first tick of a process took 3x a median tick (620-890 against 220 us, LBR
        Table 4.1 stack, 2 cores): Python specializes a function's bytecode only after it
        ran a few times, and pinocchio, DAQP and numpy have first-call costs. Ten ticks of a
        small stack (a Cartesian inequality and pose on the first chain, a joint-torque
        inequality on a joint-impedance robot, a posture), then a switch to a second stack
        (an orientation, a posture) and three more ticks, on a separate SPG of the same robot
        and parameters take them here (about 10 ms, at most 0.1 s), once per process and
        configuration (solver, kernels, PSPM, torque limits, IFC; DAQP and the nullspace
        baseline, not proxsuite, whose ticks can stall). That SPG
        shares no state with this one, whose results do not change; a failure in it is
        ignored (it only costs the first tick its speed).
        """
        name, _, rho = self._solver_args
        robot = self.robot
        key = (name, self._kernels.__name__, self.tanks is not None,
               self._torque_limit is not None, robot.ifc)
        if name not in _WARM_UP_SOLVERS or key in _WARMED_UP:  # proxsuite can stall a tick
            return
        _WARMED_UP.add(key)
        from ifc_spg.tasks import CartesianPoseTask, JointPositionTask, JointTorqueTask
        try:
            tasks: list[Task] = []
            second: list[Task] = []
            inequalities = self._solver.supports_inequalities
            if robot.chains:
                chain = robot.chains[0]
                if inequalities:  # violated: its slack QP runs
                    tasks.append(CartesianPoseTask(robot, frame=chain, axes=['z'], lower=[1e3],
                                                   name='warm_up_height'))
                tasks.append(CartesianPoseTask(robot, frame=chain, equal='init',
                                               name='warm_up_pose'))
                second.append(CartesianPoseTask(robot, frame=chain, axes=['rx', 'ry', 'rz'],
                                                equal='init', name='warm_up_orientation'))
            if inequalities and robot.ifc == JOINT_IMPEDANCE and not robot.stiff_mask.all():
                tasks.append(JointTorqueTask(robot, lower=-1e4, upper=1e4,
                                             name='warm_up_torque'))
            tasks.append(JointPositionTask(robot, equal='init', name='warm_up_posture'))
            second.append(JointPositionTask(robot, equal='init', name='warm_up_posture'))
            shadow = SetPointGenerator(robot, tasks, dt=self.dt, pspm=pspm, solver=name,
                                       rho=rho, torque_limits=torque_limits,
                                       kernels=self._kernels, warm_up=False)
            q, zeros = np.array(robot.q_home, dtype=float), np.zeros(self.n)
            deadline = time.perf_counter() + 0.1
            for k in range(_WARM_UP_TICKS + 3):
                if k == _WARM_UP_TICKS:
                    shadow.set_stack(second)
                q = shadow.step(q, zeros, k * self.dt)
                if time.perf_counter() > deadline:
                    break
        except Exception:  # a warm-up must never stop a construction
            pass

    def _new_solver(self) -> Cascade:
        name, n, rho = self._solver_args
        if name not in SOLVERS:  # a solver object of the caller's: the probes share it
            return self._solver
        return make_solver(name, n, rho, kernels=self._kernels, q_min=self.robot.q_min,
                           q_max=self.robot.q_max)

    def _make_tanks(self, pspm: bool | PspmConfig) -> EnergyTanks | None:
        if pspm is True:
            pspm = PspmConfig()
        if not pspm:
            return None
        if not isinstance(pspm, PspmConfig):
            raise ParameterError(f'pspm must be True, False or a PspmConfig, got {pspm!r}')
        robot = self.robot
        modulated = ~robot.stiff_mask if robot.ifc == JOINT_IMPEDANCE \
            else np.zeros(self.n, dtype=bool)
        return EnergyTanks(robot.stiffness, robot.damping, modulated, self.dt, pspm,
                           kernels=self._kernels)

    @property
    def solver(self) -> Cascade:
        """The cascade solver of the tick (:class:`~ifc_spg.cascade.Cascade`)."""
        return self._solver

    # -- stack management -----------------------------------------------------------
    @property
    def pending_stack(self) -> StackInput | None:
        """The stack that the next tick takes over, or None.

        The stack given to :meth:`set_stack` that the next tick will take over (it becomes
        :attr:`stack` at that tick boundary), or None when no swap is pending.
        """
        return None if self._pending is None else self._pending[0]

    @property
    def pending_tasks(self) -> list[Task]:
        """The tasks of :attr:`pending_stack` (empty when no swap is pending)."""
        return [] if self._pending is None else list(self._pending[1])

    def set_stack(self, stack: StackInput) -> None:
        """Replace the running stack at the next tick (hot swap, no jump in q_v).

        ``init`` values are captured when the new stack becomes active. Building the tasks
        happens here, so an invalid stack raises and the running one stays untouched, as
        does a stack whose ``power_budget`` [W] exceeds the ceiling ``max_power`` of the
        PSPM configuration (a :class:`~ifc_spg.task_stack.TaskStackError` naming both
        numbers and the parameter to raise), and a stack with an inequality task for a
        solver that takes equalities only (:class:`~ifc_spg.errors.ParameterError`).
        Without PSPM the budget has no effect.
        """
        budget = float(getattr(stack, 'power_budget', None) or 0.0)
        if self.tanks is not None:
            problem = self.tanks.power_error(budget)
            if problem:
                from ifc_spg.task_stack import TaskStackError
                raise TaskStackError(problem, path=('power_budget',),
                                     source=getattr(stack, 'source', None))
        tasks = stack.build(self.robot) if hasattr(stack, 'build') else list(stack)
        if not self._solver.supports_inequalities:
            for task in tasks:
                if not task.equality:
                    raise ParameterError(
                        f"task '{task.name}' is an inequality; the {self._solver.name} "
                        "solver handles equality tasks only (use solver 'daqp')")
        # the solver's models for this stack, now, not at its tick
        dims, equalities = [task.dim for task in tasks], [task.equality for task in tasks]
        self._solver.prepare(dims, equalities)
        if self.tanks is not None:  # also the stall probes' (a stall must not slow a tick)
            if self._probe_solver is None:
                self._probe_solver = self._new_solver()
            self._probe_solver.prepare(dims, equalities)
        # what the tick reads of the tasks, found now (hasattr of a missing name raises inside)
        reporting = [t for t in tasks if hasattr(t, 'report')]
        # (index, slack_message) of each task that names a pair it could not keep
        slack_messages = [(i, t.slack_message) for i, t in enumerate(tasks)
                          if hasattr(t, 'slack_message')]
        self._pending = (stack, tasks, budget, reporting, slack_messages)
        if self._dry_runs:
            self._dry_run(tasks)

    def _dry_run(self, tasks: list[Task]) -> None:
        """Build a new stack's levels and solve its cascade once, before its first tick.

        The first tick of a stack took 3.1 times a steady tick (the first tick of a new SPG,
        LBR Table 4.1 stack), about half of it caches that building the stack had cooled
        and half its tasks' activation and cold solves; this tick, right after the stack
        is set (the node sets it between two ticks on the same thread), takes that. It runs
        at the kinematics of the last tick (at ``q_home`` before the first), which it only
        reads; its tasks are deactivated after (their ``init`` values
        are captured again at the first real tick) and the cascade's working sets
        forgotten, as that tick would forget them. So no result changes (tested bit for
        bit). Only stacks of tasks of :func:`_dry_run_tasks` (no collision avoidance, no
        task of the caller's) and only DAQP and the nullspace baseline (proxsuite can
        stall a solve) are run; a failure is ignored.
        """
        kinds = _dry_run_tasks()
        if not tasks or any(type(task) not in kinds for task in tasks):
            return
        kin = self.kin
        if self.q_v is None:  # no tick yet: at home (the first tick sets its own state)
            q = np.minimum(np.maximum(np.asarray(self.robot.q_home, dtype=float),
                                      self._q_min), self._q_max)
            kin.update(q, np.zeros(self.n), q)
        # else at the last tick's state, which the levels only read (their frames are cached
        # for it already)
        try:
            q_v = kin.q_v
            box = self._limits.box(q_v) if self.velocity_box else self._position_box(q_v)
            self._solver.solve([task.level(kin, 0.0) for task in tasks], box, q_v)
        except Exception:  # a dry run must never stop a stack (its first tick reports)
            pass
        finally:
            for task in tasks:
                task.deactivate()
            self._forget_warm_start()

    def reset(self, q: np.ndarray) -> None:
        """Start from the measured configuration ``q``: q_v = q (clipped into the limits)."""
        q = np.asarray(q, dtype=float)
        # (np.clip's bits, at a third of its cost)
        self.q_v = np.minimum(np.maximum(q, self._q_min), self._q_max)
        self.qdot_v = np.zeros(self.n)
        if self.tanks is not None and self._stall is not None:
            self.tanks.reset(q)
            self._stall.reset()
        self._forget_warm_start()
        self._t0 = None
        for task in self.tasks:
            task.deactivate()

    def snapshot(self) -> SpgState:
        """The state the next tick starts from (:class:`SpgState`, copies)."""
        tanks = self.tanks
        return SpgState(None if self.q_v is None else self.q_v.copy(), self.qdot_v.copy(),
                        None if tanks is None else tanks.energy.copy(),
                        None if tanks is None else tanks.shuffled.copy(),
                        self._warm_start())

    def _levels_shape(self) -> tuple[list, list]:
        """Sizes and kinds (equality or not) of the running stack's cascade levels."""
        return [task.dim for task in self.tasks], [task.equality for task in self.tasks]

    def _warm_start(self) -> np.ndarray:
        """The cascade's working sets for the running stack (empty: the solver has none)."""
        warm_start = getattr(self._solver, 'warm_start', None)
        return np.zeros(0) if warm_start is None else \
            np.asarray(warm_start(*self._levels_shape()), dtype=float)

    def _forget_warm_start(self) -> None:
        """Start the cascade cold at the next tick (a new stack or a restart).

        Its models may hold the working sets of a stack run long before; a replay that
        starts mid-run cannot know them.
        """
        forget = getattr(self._solver, 'forget_warm_start', None)
        if forget is not None:
            forget()

    def restore(self, state: SpgState, q: np.ndarray,
                activations: Sequence[Activation] = ()) -> None:
        """Continue from a :meth:`snapshot` of another SPG.

        Continue from a :meth:`snapshot` taken by another SPG of the same robot, stack and
        parameters (a replay that starts mid-run).

        Args:
            state: The :class:`SpgState` after the last tick.
            q: The measured joint positions [rad] of that tick.
            activations: The running stack's ``[first, latest]`` :class:`Activation` (set the
                stack with :meth:`set_stack` first): its tasks are activated at them, and task
                time counts from the latest one's stamp.

        The cascade continues from ``state.warm_start``; without one (None, or a vector
        that does not fit the stack's levels) it starts cold, and a degenerate level may
        then be solved at another point of its optimal set than the live run's.
        """
        self._take_pending()
        self.q_v = np.array(state.q_v, dtype=float)
        self.qdot_v = np.array(state.qdot_v, dtype=float)
        if self.tanks is not None and self._stall is not None:
            if state.tank_energy is None:
                raise ParameterError('the snapshot has no tank energies (taken without PSPM); '
                                     'restore it into an SPG without PSPM')
            self.tanks.restore(q, state.tank_energy, state.shuffled)
            self._stall.reset()
        self._t0 = None
        for i, act in enumerate(activations):
            self.kin.update(np.asarray(act.q, dtype=float), np.asarray(act.qdot, dtype=float),
                            np.asarray(act.q_v, dtype=float))
            for task in self.tasks:
                if i:
                    task.deactivate()
                task.activate(self.kin)
            self._t0 = float(act.t)
        self.activations = list(activations)[:1] + list(activations)[1:][-1:]
        set_warm_start = getattr(self._solver, 'set_warm_start', None)
        if state.warm_start is not None and set_warm_start is not None:
            set_warm_start(*self._levels_shape(), state.warm_start)

    def _take_pending(self) -> None:
        if self._pending is not None:
            self.stack, self.tasks, budget, self._reporting, self._slack_messages = \
                self._pending
            self._pending = None
            self._t0 = None
            self.activations = []
            self._forget_warm_start()
            if self.tanks is not None and self._stall is not None:
                self.tanks.set_power(budget)
                self._stall.reset()

    # -- the tick -------------------------------------------------------------------
    def step(self, q: np.ndarray, qdot: np.ndarray, t: float) -> np.ndarray:
        """One SPG tick; :meth:`tick` also says what happened in it.

        Args:
            q: Measured joint positions in [rad] (n,).
            qdot: Measured joint velocities in [rad/s] (n,).
            t: Time stamp of the measurement in [s] (task time counts from activation).

        Returns:
            The virtual joint positions q_v in [rad] (a new array).
        """
        return self.tick(q, qdot, t).q_v

    def tick(self, q: np.ndarray, qdot: np.ndarray, t: float) -> Tick:
        """One SPG tick (:meth:`step`): q_v, qdot_v, the report and the tick's events.

        Args:
            q: Measured joint positions in [rad] (n,).
            qdot: Measured joint velocities in [rad/s] (n,).
            t: Time stamp of the measurement in [s] (task time counts from activation).
        """
        t_start = time.perf_counter()
        q, qdot = self._measurement(q, qdot)
        events: list[str] = []
        if self.q_v is None:
            if not math.isfinite(q @ self._zeros):  # (as below)
                raise ParameterError('the first measurement must be finite to start from it')
            self.reset(q)
        # x @ 0 is 0 for every finite x (no overflow, unlike a sum) and NaN for inf / NaN
        if not (math.isfinite(t) and math.isfinite(q @ self._zeros + qdot @ self._zeros)):
            return self._hold('bad_input', 'non-finite joint state or time stamp', t_start)
        if self._pending is not None:
            self._take_pending()
            events.append('stack_taken')
        if self._t0 is None and self.tasks:  # the stack starts: its tasks take init values
            events.append('activated')
        task_time = self._task_time(q, qdot, t)
        q_v = self.q_v
        if q_v is None:  # reset() above sets it
            raise IfcSpgError('internal: q_v is unset after reset')
        self.kin.update(q, qdot, q_v)

        limits_box = self._limits.box(q_v) if self.velocity_box else self._position_box(q_v)
        box = self._velocity_box(q, q_v, limits_box)
        qd_prev = self.qdot_v
        t_solve = time.perf_counter()
        tick = self._solve(q, qdot, q_v, box, task_time)
        solve_time = time.perf_counter() - t_solve

        q_v = self._after_solve(q, qdot, q_v, qd_prev, limits_box, tick, task_time,
                                solve_time, t_start)
        if self.info.stall_new:
            events.append('pspm_stall')
        if tick.status != 'ok':
            events.append(tick.status)
        return Tick(q_v.copy(), tick.qdot_v, self.info, tuple(events))

    def _after_solve(self, q: np.ndarray, qdot: np.ndarray, q_v: np.ndarray,
                     qd_prev: np.ndarray, limits_box: VelocityBox, tick: '_Tick',
                     task_time: float, solve_time: float, t_start: float) -> np.ndarray:
        """The tanks, the stall watch, the integration of q_v and this tick's info; new q_v."""
        energy_step = stall = None
        message = tick.message
        if self._reporting and tick.status == 'ok' and not message:
            message = self._collision_message(tick)
        if self.tanks is not None:
            energy_step = self.tanks.update(q, q_v, tick.qdot_v)
            stall = self._watch_stall(q, qdot, q_v, qd_prev, limits_box, tick.task_levels,
                                      task_time)
            if stall is not None and tick.status == 'ok':
                message = stall_message(stall, self.robot.joint_names)
        self.q_v = q_next = self._kernels.integrate(q_v, self.dt, tick.qdot_v, self._q_min,
                                                    self._q_max)
        self.qdot_v = tick.qdot_v
        tanks = self.tanks
        self.info = SpgInfo(
            status=tick.status, solver=self._solver.name, slacks=tick.slacks,
            levels=tick.levels, box=tick.box,
            tank_energy=None if tanks is None else tanks.energy.copy(),
            spring_energy_step=energy_step, solve_time=solve_time,
            tick_time=time.perf_counter() - t_start, task_time=task_time,
            qdot_v=tick.qdot_v, message=message, failed_level=tick.failed, stall=stall,
            stall_new=stall is not None and self._stall is not None and self._stall.new,
            power_budget=0.0 if tanks is None else tanks.power,
            max_power=None if tanks is None else tanks.config.max_power,
            refilled=None if tanks is None else tanks.refilled.copy(),
            joint_names=self.robot.joint_names,
            distances=self._reports() if self._reporting else ())
        return q_next

    def _reports(self) -> tuple:
        """This tick's report of each task that has one (none before its first level)."""
        reports = [t.report() for t in self._reporting]
        return tuple(reports) if None not in reports else \
            tuple([r for r in reports if r is not None])

    def _collision_message(self, tick: '_Tick') -> str:
        """The pair a collision-avoidance level could not keep this tick (its slack), or ''."""
        top, slacks = len(tick.levels) - len(tick.task_levels), tick.slacks
        for i, slack_message in self._slack_messages:
            if top + i < len(slacks):
                text = slack_message(slacks[top + i])
                if text:
                    return text
        return ''

    def _measurement(self, q: np.ndarray, qdot: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``q`` and ``qdot`` as contiguous float arrays of n entries (or ParameterError)."""
        q = np.asarray(q, dtype=float)
        qdot = np.asarray(qdot, dtype=float)
        if q.shape != (self.n,) or qdot.shape != (self.n,):
            raise ParameterError(f'q and qdot must have {self.n} entries (joints '
                                 f'{", ".join(self.robot.joint_names)}), got {q.shape} and '
                                 f'{qdot.shape}')
        return np.ascontiguousarray(q), np.ascontiguousarray(qdot)

    def _task_time(self, q: np.ndarray, qdot: np.ndarray, t: float) -> float:
        """Seconds since the stack became active; on its first tick, the activation."""
        if self._t0 is None:
            self._t0 = float(t)
            if self.tasks and self.q_v is not None:  # the tasks capture their init values
                act = Activation(q.copy(), qdot.copy(), self.q_v.copy(), float(t))
                self.activations = self.activations[:1] + [act]
        return float(t) - self._t0

    def _position_box(self, q_v: np.ndarray) -> VelocityBox:
        """The position limits one step ahead (``velocity_box`` off): q_v stays inside them."""
        return VelocityBox(np.minimum((self._q_min - q_v) / self.dt, 0.0),
                           np.maximum((self._q_max - q_v) / self.dt, 0.0))

    def _velocity_box(self, q: np.ndarray, q_v: np.ndarray,
                      limits_box: VelocityBox) -> VelocityBox:
        """The joint limits and the passivity bounds, then (softly) the acceleration limit."""
        pb = None if self.tanks is None else self.tanks.bounds(q, q_v)
        return VelocityBox(*self._kernels.velocity_box(
            limits_box.lower, limits_box.upper, None if pb is None else pb.lower,
            None if pb is None else pb.upper, self.qdot_v, self._accel))

    def _solve(self, q: np.ndarray, qdot: np.ndarray, q_v: np.ndarray, box: VelocityBox,
               task_time: float) -> '_Tick':
        """Solve this tick's levels.

        The levels (the torque limit, folded into the box, then the tasks) and the cascade;
        a failure or an exception holds (zero velocity clipped into the box).
        """
        top: list[Level] = []
        slacks: list = []
        status, failed, message = 'ok', -1, ''
        if self._torque_limit is not None:  # the top level, solved in closed form (4.3)
            level, slack, box = self._torque_limit.apply(q, qdot, q_v, box)
            top, slacks = [level], [slack]
        levels, task_levels = top, []
        try:
            kin = self.kin
            task_levels = [task.level(kin, task_time) for task in self.tasks]
            levels = top + task_levels
            if task_levels:
                res = self._solver.solve(task_levels, box, q_v)
                qdot_v, status = res.qdot_v, res.status
                slacks = slacks + res.slacks
                failed = res.failed_level + len(top) if res.failed_level >= 0 else -1
                if failed >= 0:
                    message = (f"level {failed} ('{levels[failed].name}') could not be "
                               'solved; ' + ('holding q_v' if status == 'hold' else
                                             "using the higher levels' solution"))
                elif status != 'ok':
                    message = 'non-finite solution; holding q_v'
            else:
                qdot_v = np.minimum(np.maximum(0.0, box.lower), box.upper)
                status = 'idle' if not self.tasks else status
        except Exception as exc:  # a task or solver bug must not take the robot down
            qdot_v, slacks, status, failed = np.zeros(self.n), slacks[:len(top)], 'hold', -1
            message = (f'internal error in the tasks or the solver ({type(exc).__name__}: '
                       f'{exc}); braking to zero velocity and holding q_v')
        if not math.isfinite(qdot_v @ self._zeros):
            qdot_v, status, message = np.zeros(self.n), 'hold', 'non-finite solution; holding q_v'
        if status == 'hold':
            qdot_v = np.clip(qdot_v, box.lower, box.upper)  # brake within a_max, stay safe
        return _Tick(qdot_v, status, failed, message, slacks, levels, task_levels, box)

    def _watch_stall(self, q: np.ndarray, qdot: np.ndarray, q_v: np.ndarray,
                     qd_prev: np.ndarray, limits_box: VelocityBox, task_levels: list,
                     task_time: float) -> StallReport | None:
        """Book this tick in the stall monitor.

        Book this tick in the stall monitor; on its probe ticks, solve the cascade again
        without the passivity bound to learn the power the stack asks for. Returns the
        :class:`~ifc_spg.pspm.StallReport` or None.
        """
        monitor, tanks = self._stall, self.tanks
        if monitor is None or tanks is None:  # only called with PSPM on
            raise IfcSpgError('internal: the stall monitor runs only with PSPM')
        requested = None
        if monitor.wants_probe:
            requested = np.zeros(self.n)
            if task_levels:
                if self._probe_solver is None:
                    self._probe_solver = self._new_solver()
                box = intersect_soft(VelocityBox(np.array(limits_box.lower, dtype=float),
                                                 np.array(limits_box.upper, dtype=float)),
                                     VelocityBox(qd_prev - self._accel, qd_prev + self._accel))
                if self._torque_limit is not None:
                    _, _, box = self._torque_limit.apply(q, qdot, q_v, box)
                try:
                    res = self._probe_solver.solve(task_levels, box, q_v)
                    if math.isfinite(res.qdot_v @ self._zeros):
                        requested = tanks.requested_power(q, q_v, np.asarray(res.qdot_v))
                except Exception:  # a probe must never take the tick down
                    pass
        monitor.observe(requested, task_time=task_time)
        return monitor.report

    def _hold(self, status: str, message: str, t_start: float) -> Tick:
        if self.q_v is None:  # step() resets from the first measurement before any hold
            raise IfcSpgError('internal: hold before the first measurement')
        self.qdot_v = np.zeros(self.n)
        tanks = self.tanks
        self.info = SpgInfo(status=status, solver=self._solver.name, slacks=[], levels=[],
                            tank_energy=None if tanks is None else tanks.energy.copy(),
                            solve_time=0.0, tick_time=time.perf_counter() - t_start,
                            qdot_v=self.qdot_v, message=message, failed_level=-1,
                            power_budget=0.0 if tanks is None else tanks.power,
                            max_power=None if tanks is None else tanks.config.max_power,
                            refilled=None if tanks is None else tanks.refilled.copy(),
                            joint_names=self.robot.joint_names)
        return Tick(self.q_v.copy(), self.qdot_v, self.info, (status,))


class _Tick(NamedTuple):
    """What :meth:`SetPointGenerator._solve` decided this tick."""

    qdot_v: np.ndarray
    status: str
    failed: int
    message: str
    slacks: list
    levels: list
    task_levels: list
    box: VelocityBox
