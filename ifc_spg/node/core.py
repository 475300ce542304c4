"""The SPG node's logic without ROS: joint states in, commands, status and diagnostics out.

:class:`SpgRunner` wraps a :class:`~ifc_spg.spg.SetPointGenerator` with everything the
live node must do around a tick, so that ``spg_node`` stays a thin shell and the offline
runner and replay reuse the same code::

    runner = SpgRunner(SpgConfig(robot='lbr_iiwa14'))
    event = runner.handle_task_stack(text)              # StackEvent(accepted, ...)
    cmd = runner.handle_joint_state(names, q, qdot, stamp_ns)   # Command or None
    runner.handle_obstacles(markers)                    # spg/obstacles: next tick's poses
    runner.check_watchdog()                             # from a timer; True when it trips
    runner.status()  /  runner.diagnostics()            # JSON-ready dict / DiagItem

Input checks (each rejected message is counted by reason in ``rejected`` and recorded as
an error; nothing raises): a wrong number of joints, unknown or repeated joint names,
non-finite values (also values that are not numbers, a stamp that is not a finite whole
number of ns, and positions whose finite-difference velocity overflows), a stamp older
than the last one (``stamp_backwards``) and a repeated stamp (``duplicate_stamp``: the
last command is returned again, so a lockstep bridge that re-publishes a state it got no
answer for is answered, but the SPG does not tick twice).

Watchdog: when no joint state was handled for more than ``watchdog_timeout`` [s] of the
``clock`` (checked by :meth:`check_watchdog`, measured from the end of the last tick, so
the SPG's own computing time does not count), the runner is *stale*: it reports it and
commands nothing. Whether the next state restarts the SPG is decided by the stamps alone,
so a replay of the recorded states reproduces it: a stamp more than the timeout after the
last one (the robot moved on without us), or, while stale, a stamp older than the last one
(a restarted driver or simulator), restarts from the measured q (q_v := q, the tanks
refilled, the running stack re-activated: ``init`` values are captured at the measured
pose and its task time starts again). A state that continues the stamps (a lockstep
simulator that paused, or a backlog after this process stalled) continues without a jump.

Task time comes from the stamps only; ``clock`` is used for the watchdog alone.
"""

from collections import deque
from collections.abc import Callable, Sequence
import dataclasses
import json
import math
import time
from typing import Any, NamedTuple

import numpy as np

from ifc_spg.errors import IfcSpgError, ParameterError, did_you_mean
from ifc_spg.model import JOINT_IMPEDANCE, RobotModel
from ifc_spg.node.config import SpgConfig
from ifc_spg.node.obstacles import ObstacleInput, obstacle_poses, obstacle_tasks
from ifc_spg.ros.stamps import join_ns, split_ns
from ifc_spg.spg import Activation, SetPointGenerator, SpgState
from ifc_spg.task_stack import TaskStack
from ifc_spg.tasks.stream import base_frames, stream_bounds, streams_of

__all__ = ['SpgRunner', 'Command', 'StackEvent', 'DiagItem', 'REJECT_REASONS',
           'parse_task_stack', 'robot_gains', 'robot_params', 'status_json']

REJECT_REASONS = ('wrong_count', 'unknown_name', 'duplicate_name', 'non_finite',
                  'stamp_backwards', 'duplicate_stamp')
_MAX_ERRORS = 8
#: a joint vector as a message gives it (list, array.array) or an array
Vector = Sequence[float] | np.ndarray


class Command(NamedTuple):
    """One output of a tick (the ``command/joint_position`` message).

    Attributes:
        stamp_ns: Stamp of the joint state it answers in [ns] (header stamp to publish).
        names: Joint names in model order.
        position: Virtual joint positions q_v in [rad] (n,).
        velocity: Virtual joint velocities qdot_v in [rad/s] (n,).
        tick: Tick counter (1 for the first tick).
        resumed: True for the first command after a start or a watchdog restart.
    """

    stamp_ns: int
    names: tuple
    position: np.ndarray
    velocity: np.ndarray
    tick: int
    resumed: bool


class Event(NamedTuple):
    """Something a joint state's tick did that the node reports (log, status, diagnostics).

    Attributes:
        kind: 'rejected' (the state; ``message`` says why), 'watchdog' (the stamps jumped
            past watchdog.timeout: commanding stopped until the restart), 'started' (the
            first command, from the measured q), 'resumed' (a restart from the measured q
            after the watchdog), 'continued' (states came back with continuous stamps after
            the watchdog: no restart), 'stack_taken' (a new stack runs from this tick),
            'pspm_stall' (a new PSPM stall episode; ``message`` names the joints and the fix).
        message: What to log or publish.
    """

    kind: str
    message: str


class Outcome(NamedTuple):
    """What :meth:`SpgRunner.tick` did with one joint state.

    The command (None: no command) and the events of the tick, in order.
    """

    command: 'Command | None'
    events: tuple[Event, ...]


class StackEvent(NamedTuple):
    """The outcome of :meth:`SpgRunner.handle_task_stack`.

    Attributes:
        accepted: True if the stack replaces the running one at the next tick.
        stack_id: Id of the stack that runs next (1, 2, ... per accepted stack; 0: none).
        name: Name of the stack that runs next ('' for none).
        message: What happened; for a rejected stack the error naming the field.
    """

    accepted: bool
    stack_id: int
    name: str
    message: str


class DiagItem(NamedTuple):
    """One diagnostic status: ``level`` is 'OK', 'WARN', 'ERROR' or 'STALE'."""

    level: str
    name: str
    message: str
    values: dict


def parse_task_stack(text: str, source: str | None = None) -> TaskStack:
    """Parse a task-stack document (YAML or JSON text) with :mod:`ifc_spg.task_stack`.

    Args:
        text: The document.
        source: Name for error messages (e.g. the topic or file name).

    Raises:
        IfcSpgError: ``TaskStackError`` naming the field path, line and column.
    """
    return TaskStack.from_text(text, source=source)


def _stamp_ns(stamp):
    """The stamp as an int [ns], or None if it is not a finite whole number."""
    if isinstance(stamp, (int, np.integer)) and not isinstance(stamp, bool):
        return int(stamp)
    try:
        value = float(stamp)
    except (TypeError, ValueError, OverflowError):
        return None
    return int(value) if math.isfinite(value) and value.is_integer() else None


def _finite(x):
    if isinstance(x, float) and not math.isfinite(x):
        return None
    if isinstance(x, dict):
        return {k: _finite(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_finite(v) for v in x]
    return x


def robot_params(robot):
    """The robot parameters the SPG computes with, as a JSON-ready dict.

    ``ifc-spg replay`` applies ``stiffness`` and ``damping`` (which a scenario may override)
    and compares the rest with the named configuration it loads.

    Keys: robot (configuration name), joint_names, stiffness K [Nm/rad], damping D
    [Nms/rad], stiff_joints (position-controlled joints), tau_max [Nm], v_max [rad/s],
    a_max [rad/s^2], q_min / q_max [rad] (per joint, model order).
    """
    def floats(x):
        return [float(v) for v in np.ravel(x)]

    return {'robot': robot.name, 'joint_names': list(robot.joint_names),
            'stiffness': floats(robot.stiffness), 'damping': floats(robot.damping),
            'stiff_joints': [j for j, s in zip(robot.joint_names, robot.stiff_mask) if s],
            'tau_max': floats(robot.tau_max), 'v_max': floats(robot.v_max),
            'a_max': floats(robot.a_max), 'q_min': floats(robot.q_min),
            'q_max': floats(robot.q_max)}


def status_json(status: dict[str, Any]) -> str:
    """Serialize a status dict as strict JSON (non-finite numbers become null)."""
    return json.dumps(_finite(status), allow_nan=False, separators=(',', ':'))


def robot_gains(robot, config):
    """``robot`` with the IFC gains of ``config`` (``impedance.stiffness`` / ``damping``).

    Raises:
        ParameterError: Gains for a Cartesian-admittance robot, a wrong count, K <= 0 or
            D < 0 (the message names the parameter, the joints and the values).
    """
    if not config.stiffness and not config.damping:
        return robot
    if robot.ifc != JOINT_IMPEDANCE:
        raise ParameterError(f"parameters impedance.stiffness/damping set the joint impedance; "
                             f"robot '{robot.name}' is under {robot.ifc.replace('_', ' ')} "
                             '(its gains come with the robot configuration)')
    return robot.with_gains(stiffness=list(config.stiffness) or None,
                            damping=list(config.damping) or None, where='parameter impedance.')


STREAM_FIELD = 'stream:'  # spg/state field of a streamed task: 'stream:<task name>'
OBSTACLE_FIELD = 'obstacle:'  # spg/state field of an obstacle's pose: 'obstacle:<name>'


def _base_layout(n):
    """The ``spg/state`` fields before the cascade's warm start, [(name, length)]."""
    return (('tick', 1), ('stamp_sec', 1), ('stamp_nanosec', 1), ('q', n), ('q_v', n),
            ('qdot_v', n), ('tank_energy', n), ('shuffled', n))


def _levels_status(info):
    """The ``levels`` entry of the status: per level its name, residual and slack."""
    levels = []
    for i, name in enumerate(info.level_names or []):
        residual = info.residuals[i] if i < len(info.residuals or []) else np.zeros(0)
        slack = info.slacks[i] if i < len(info.slacks or []) else None
        levels.append({
            'name': name,
            'residual': float(np.max(residual)) if np.size(residual) else 0.0,
            'slack': None if slack is None else [float(x) for x in np.ravel(slack)]})
    return levels


class SpgRunner:
    """The SPG node body: validated ticks, hot-swapped stacks, watchdog, status.

    Args:
        config: :class:`~ifc_spg.node.config.SpgConfig`.
        robot: The :class:`~ifc_spg.model.RobotModel` (default: ``config.robot``).
        clock: Monotonic clock in [s] for the watchdog (default ``time.monotonic``).
        parse_stack: ``parse_stack(text) -> stack``, called as ``parse_stack(text,
            source=source)`` when :meth:`handle_task_stack` is given a source (default
            :func:`parse_task_stack`).
    """

    def __init__(self, config: SpgConfig | None = None, robot: RobotModel | None = None,
                 clock: Callable[[], float] = time.monotonic,
                 parse_stack: Callable[..., TaskStack] | None = None) -> None:
        self.config = config = config or SpgConfig()
        self.robot = robot or robot_gains(RobotModel.from_config(config.robot), config)
        self.spg = SetPointGenerator(self.robot, None, dt=config.dt, pspm=config.pspm_config(),
                                     solver=config.solver, rho=config.rho,
                                     torque_limits=config.torque_limits,
                                     velocity_box=config.velocity_box)
        self.clock = clock
        self._parse = parse_stack or parse_task_stack
        self.joint_names = tuple(self.robot.joint_names)
        self._n = len(self.joint_names)
        self._index = {n: i for i, n in enumerate(self.joint_names)}
        # names tuple -> index array (validated once)
        self._perm: dict[tuple[str, ...], np.ndarray] = {}
        self.rejected = dict.fromkeys(REJECT_REASONS, 0)
        #: ``spg/obstacles``: checks the markers, moves obstacles at tick boundaries
        self.obstacles = ObstacleInput(base_frames(self.robot) + (config.markers_frame,))
        self.errors: deque[dict[str, Any]] = deque(maxlen=_MAX_ERRORS)
        self.last_error = ''
        self.ticks = 0
        self.watchdog_trips = 0
        self.resumes = 0
        self.pspm_stalls = 0            # PSPM stalls reported (once per episode and joint)
        self.last_stall = ''            # the last stall's message (log it when the count grows)
        self.stale = False              # watchdog tripped, not yet resumed
        self.started = False            # at least one tick since the start/restart
        self._restart_requested = False
        self.stack_id = 0
        self.stack_name = ''
        self._stack_since: float | None = None
        self._config_sent = False
        self.stack_text: str | None = None  # the running stack's document (spg/config)
        self._pending_text: str | None = None
        self.config_version = 0         # grows when config_doc() changes (stack, restart)
        self._events: list[Event] = []   # the current tick's (see tick)
        self._next_id = 0
        self._pending_name: str | None = None
        self._last_stamp: int | None = None  # [ns]
        self._last_seen: float | None = None  # clock() [s]
        self._last_q: np.ndarray | None = None
        self._last_command: Command | None = None
        self._period: deque[float] = deque(maxlen=500)    # stamp differences [s]
        self._tick_times: deque[float] = deque(maxlen=500)

    # -- inputs -------------------------------------------------------------------------
    def handle_task_stack(self, text: str, source: str | None = None) -> 'StackEvent':
        """Parse, build and schedule a task stack; a bad one leaves the running one.

        Args:
            text: YAML or JSON document.
            source: Name for error messages (e.g. the topic or file name).
        """
        try:
            stack = self._parse(text) if source is None else self._parse(text, source=source)
            self.spg.set_stack(stack)
        except IfcSpgError as exc:
            message = f'task stack rejected: {exc}'
            self._error('task_stack', message)
            return StackEvent(False, self.stack_id if self._pending_name is None else
                              self._next_id, self._pending_name or self.stack_name, message)
        except Exception as exc:  # a parser bug must not take the node down
            message = f'task stack rejected (internal error {type(exc).__name__}): {exc}'
            self._error('task_stack', message)
            return StackEvent(False, self.stack_id, self.stack_name, message)
        self._next_id += 1
        self._pending_name = str(getattr(stack, 'name', '') or f'stack_{self._next_id}')
        self._pending_text = text
        written_for = getattr(stack, 'robot', None)
        note = f" (written for '{written_for}')" if written_for not in (
            None, self.robot.name) else ''
        return StackEvent(True, self._next_id, self._pending_name,
                          f"task stack '{self._pending_name}' (id {self._next_id}) accepted"
                          f'{note}; active from the next tick')

    def streams(self):
        """The streamed references of the running and the pending stack.

        :class:`~ifc_spg.tasks.stream.StreamReference` objects; the node subscribes to
        their topics.
        """
        return streams_of(self.spg.tasks) + streams_of(self.spg.pending_tasks)

    def handle_reference(self, topic: str, message: Any) -> bool:  # a message of the backend
        """A message on a streamed task's ``topic`` (as the stack wrote it); False if rejected."""
        now_ns = int(self.clock() * 1e9)
        ok = True
        for stream in self.streams():
            if stream.topic == topic:
                ok = stream.feed(message, now_ns) and ok
        return ok

    def handle_obstacles(self, markers):
        """Markers of ``spg/obstacles`` (:mod:`ifc_spg.node.obstacles`).

        Accepted poses apply from the next tick; each rejected marker is counted by reason
        (``spg/status`` → ``obstacles``) and recorded as an error.

        Returns:
            ``[(reason, message)]`` of the rejected markers.
        """
        errors = self.obstacles.handle(markers, list(self.spg.tasks) + self.spg.pending_tasks)
        for reason, message in errors:
            self._error('obstacles', f'obstacle marker rejected ({reason}): {message}')
        return errors

    def _update_streams(self):
        """Age the running stack's streams; log a stream that went stale (once per episode)."""
        now_ns = int(self.clock() * 1e9)
        for stream in streams_of(self.spg.tasks):
            episodes = stream.stale_episodes
            stream.update(now_ns)
            if stream.stale_episodes != episodes:
                self._error('stream', f"task '{stream.task.name}': no reference on "
                            f"'{stream.topic}' for {stream.age:.3f} s > stale_after "
                            f'{stream.stale_after:g} s; holding the last one')

    def tick(self, names: Sequence[str], position: Vector, velocity: Vector,
             stamp_ns: int) -> Outcome:
        """:meth:`handle_joint_state`, and the events of the tick (what a node reports)."""
        command = self.handle_joint_state(names, position, velocity, stamp_ns)
        return Outcome(command, tuple(self._events))

    def handle_joint_state(self, names: Sequence[str], position: Vector, velocity: Vector,
                           stamp_ns: int) -> Command | None:
        """One tick for one joint-state message; None when the message is rejected.

        Args:
            names: Joint names (any order; all joints of the model exactly once).
            position: Measured joint positions q in [rad], same order as ``names``.
            velocity: Measured joint velocities in [rad/s] (empty: finite differences of
                the positions over the stamps, zero on the first tick).
            stamp_ns: Measurement stamp in [ns] (sets task time and the command stamp).
        """
        self._events = []
        was_stale = self.stale
        measured = self._measured(names, position, velocity, stamp_ns)
        if measured is None:
            return None
        q, velocity, perm, stamp_ns = measured
        last = self._last_stamp
        if last is not None and stamp_ns == last:
            self._reject('duplicate_stamp', f'stamp {stamp_ns * 1e-9:.9f} s seen before; '
                         'answering with the last command again')
            return self._last_command
        restart = self._needs_restart(stamp_ns)
        if restart is None:
            return None
        qdot = self._joint_velocity(q, velocity, perm, stamp_ns, restart)
        if qdot is None:
            return None
        if restart:
            self._restart(q)
        self.stale = False
        if last is not None and not restart:
            self._period.append((stamp_ns - last) * 1e-9)
        if self.obstacles.due:  # at the tick boundary; no task list per tick otherwise
            self.obstacles.apply(list(self.spg.tasks) + self.spg.pending_tasks)
        tick = self.spg.tick(q, qdot, stamp_ns * 1e-9)
        self._after_tick(stamp_ns, tick.events)
        self._last_stamp, self._last_q = stamp_ns, q
        qdot_v = np.array(tick.qdot_v, dtype=float)
        self._last_command = Command(stamp_ns, self.joint_names, tick.q_v, qdot_v, self.ticks,
                                     restart)
        self._last_seen = self.clock()
        self._report_restart(restart, was_stale, stamp_ns)
        return self._last_command

    def _report_restart(self, restart, was_stale, stamp_ns):
        if restart and self.resumes:
            self._events.append(Event('resumed', f'joint states are back (stamp '
                                      f'{stamp_ns * 1e-9:.3f} s): restarted from the measured'
                                      f' q (restart {self.resumes})'))
        elif restart:
            self._events.append(Event('started', 'first joint state: commanding from the '
                                      'measured q'))
        elif was_stale:
            self._events.append(Event('continued', 'joint states are back with continuous '
                                      'stamps (the source paused): continuing without a '
                                      'restart'))

    def _measured(self, names, position, velocity, stamp_ns):
        """The checked message: (q in model order, velocity, permutation, stamp [ns]) or None."""
        names = tuple(names)
        perm = self._perm.get(names)
        if perm is None:
            perm = self._check_names(names)
            if perm is None:
                return None
        try:
            position = np.asarray(position, dtype=float)
            velocity = np.asarray(velocity, dtype=float)
        except (TypeError, ValueError) as exc:
            return self._reject('non_finite', f'joint positions/velocities are not numbers '
                                f'({exc})')
        if position.shape != (self._n,) or velocity.shape not in ((0,), (self._n,)):
            return self._reject('wrong_count', f'{position.size} positions and {velocity.size}'
                                f' velocities for {self._n} joints')
        q = np.empty(self._n)
        q[perm] = position
        if not np.all(np.isfinite(q)) or not np.all(np.isfinite(velocity)):
            return self._reject('non_finite', 'non-finite joint position or velocity')
        stamp_ns = _stamp_ns(stamp_ns)
        if stamp_ns is None:
            return self._reject('non_finite', 'the stamp is not a finite whole number of ns')
        return q, velocity, perm, stamp_ns

    def _needs_restart(self, stamp_ns):
        """Whether a new stamp restarts from the measured q; None if it is rejected."""
        restart = not self.started or self._restart_requested
        last = self._last_stamp
        if last is None:
            return restart
        timeout_ns = int(self.config.watchdog_timeout * 1e9)
        if stamp_ns < last:
            if not self.stale:
                return self._reject('stamp_backwards', f'stamp {stamp_ns * 1e-9:.9f} s is '
                                    f'older than the last one {last * 1e-9:.9f} s')
            return True  # a new session (restarted driver or simulator)
        if timeout_ns and stamp_ns - last > timeout_ns:
            if not self.stale:
                self._trip(f'joint-state stamps jumped by {(stamp_ns - last) * 1e-9:.3f} s'
                           f' > watchdog.timeout {self.config.watchdog_timeout} s')
            return True
        return restart

    def _joint_velocity(self, q, velocity, perm, stamp_ns, restart):
        """The joint velocities in model order (measured, else differenced); None if absurd."""
        if velocity.size:
            qdot = np.empty(self._n)
            qdot[perm] = velocity
            return qdot
        if restart:
            return np.zeros(self._n)
        with np.errstate(over='ignore', invalid='ignore'):
            qdot = (q - self._last_q) / ((stamp_ns - self._last_stamp) * 1e-9)
        if not np.all(np.isfinite(qdot)):
            return self._reject('non_finite', 'the finite-difference joint velocity '
                                'overflows (absurd positions)')
        return qdot

    def _after_tick(self, stamp_ns, events):
        """Book-keeping after a tick: the stack taken over, errors and stalls, counters.

        ``events`` are the SPG's (:attr:`~ifc_spg.spg.Tick.events`).
        """
        info = self.spg.info
        if 'stack_taken' in events and self._pending_name is not None:
            self.stack_id, self.stack_name = self._next_id, self._pending_name
            self.stack_text = self._pending_text
            self._pending_name = None
            self._stack_since = stamp_ns * 1e-9
            self._events.append(Event('stack_taken', f"task stack '{self.stack_name}' (id "
                                      f'{self.stack_id}) runs from t = {stamp_ns * 1e-9:.3f} s'))
        if 'activated' in events:  # a new stack, or a restart: new activation values
            self.config_version += 1
        if info.status in ('fallback', 'hold', 'bad_input'):
            self._error('spg', f'{info.status}: {info.message}')
        if 'pspm_stall' in events:  # the first stall of this episode (stack activation or
            # restart), or one of joints that had not stalled in it
            self.pspm_stalls += 1
            self.last_stall = info.message or ''
            self._error('pspm', self.last_stall)
            self._events.append(Event('pspm_stall', self.last_stall))
        self.ticks += 1
        self._tick_times.append(info.tick_time or 0.0)
        self._update_streams()

    def _check_names(self, names):
        if len(names) != self._n:
            return self._reject('wrong_count', f'{len(names)} joint names, expected {self._n} '
                                f"({', '.join(self.joint_names)})")
        if len(set(names)) != len(names):
            dup = sorted({n for n in names if names.count(n) > 1})
            return self._reject('duplicate_name', f'joint names repeated: {dup}')
        unknown = [n for n in names if n not in self._index]
        if unknown:
            return self._reject('unknown_name', f"unknown joint '{unknown[0]}' for robot "
                                f"'{self.robot.name}'{did_you_mean(unknown[0], self.joint_names)}")
        perm = np.array([self._index[n] for n in names], dtype=int)
        if len(self._perm) < 64:
            self._perm[names] = perm
        return perm

    def request_restart(self):
        """Restart from the measured q at the next joint state.

        For example after the node was disabled: the robot may have been moved meanwhile.
        """
        self._restart_requested = True

    def _restart(self, q):
        """Start (or restart after the watchdog) from the measured ``q``."""
        self._restart_requested = False
        self.spg.reset(q)  # also re-activates the stack: init values, task time from here
        if self.started:
            self.resumes += 1
        self.started = True
        self.stale = False

    def _reject(self, reason, message):
        self.rejected[reason] += 1
        self._error('joint_states', f'joint state rejected ({reason}): {message}')
        self._events.append(Event('rejected', self.last_error))
        return None

    def _error(self, where, message):
        self.errors.append({'tick': self.ticks, 'source': where, 'message': message})
        self.last_error = message

    # -- watchdog ----------------------------------------------------------------------
    def check_watchdog(self) -> bool:
        """Trip the watchdog if the last tick is older than the timeout; True if it tripped."""
        timeout = self.config.watchdog_timeout
        if not timeout or self.stale or self._last_seen is None:
            return False
        idle = self.clock() - self._last_seen
        if idle > timeout:
            self._trip(f'no joint state for {idle * 1e3:.0f} ms > watchdog.timeout '
                       f'{timeout * 1e3:.0f} ms: commanding stopped (a restart from the '
                       'measured q follows if the stamps jumped)')
            return True
        return False

    def mark_stale(self, message: str = 'marked stale') -> None:
        """Trip the watchdog now (offline replay of a recorded ``watchdog`` status event)."""
        if not self.stale:
            self._trip(message)

    def _trip(self, message):
        self.stale = True
        self.watchdog_trips += 1
        self._error('watchdog', message)
        self._events.append(Event('watchdog', message))

    @property
    def state(self) -> str:
        """'waiting' (no state yet), 'running' or 'stale' (watchdog tripped)."""
        if self.stale:
            return 'stale'
        return 'running' if self.started else 'waiting'

    # -- outputs -----------------------------------------------------------------------
    def status(self, event: str | None = None) -> dict[str, Any]:  # JSON document
        """The ``spg/status`` document (JSON-ready dict; use :func:`status_json`).

        Keys: robot, state, tick, stamp [s], stack {id, name, since [s] (stamp of its first
        tick), task_time [s]}, pending_stack, spg {status, message, solver}, levels [{name,
        residual (max violation of the level's velocity bounds), slack}], tank_energy [J],
        solve_time / tick_time [s], qdot_v [rad/s], rejected {reason: count}, watchdog
        {timeout, trips, resumes}, pspm {power_budget and max_power [W], refilled [J] per
        joint, stall: None or {joints, requested_power [W] per joint, total_power and
        robot_power [W], since [s], fix, message}, stalls (reports, once per episode and
        joint)} (None without PSPM), collision (per collision_avoidance task: margin,
        influence and per pair group the minimum distance of q_v [m], its pair and the pairs
        within the influence distance; None without such a task), obstacles
        (``spg/obstacles`` markers: received, accepted, ignored, moved, rejected {reason:
        count}, :mod:`ifc_spg.node.obstacles`), errors (the last few),
        event {type, message} (when given)
        config (the :class:`SpgConfig` as a dict) and robot_params (:func:`robot_params`: the
        K, D and limits the SPG uses), both in the first document and every event.

        Args:
            event: Optional event name and message, e.g. ``('stack_rejected', text)``.
        """
        info = self.spg.info
        doc = {
            'robot': self.robot.name,
            'state': self.state,
            'tick': self.ticks,
            'stamp': None if self._last_stamp is None else self._last_stamp * 1e-9,
            'stack': {'id': self.stack_id, 'name': self.stack_name, 'since': self._stack_since,
                      'task_time': info.task_time} if self.stack_id else None,
            'pending_stack': None if self._pending_name is None else
            {'id': self._next_id, 'name': self._pending_name},
            'spg': {'status': info.status, 'message': info.message or '',
                    'solver': info.solver},
            'levels': _levels_status(info),
            'tank_energy': None if info.tank_energy is None else
            [float(x) for x in info.tank_energy],
            'solve_time': info.solve_time,
            'tick_time': info.tick_time,
            'qdot_v': None if info.qdot_v is None else [float(x) for x in info.qdot_v],
            'rejected': dict(self.rejected),
            'watchdog': {'timeout': self.config.watchdog_timeout,
                         'trips': self.watchdog_trips, 'resumes': self.resumes},
            'pspm': self._pspm_status(info),
            'collision': info.collision,
            'obstacles': self.obstacles.status(),
            'errors': list(self.errors),
        }
        streams = streams_of(self.spg.tasks)
        if streams:
            doc['streams'] = [st.status() for st in streams]
        if event is not None:
            doc['event'] = {'type': event[0], 'message': event[1]}
        if event is not None or not self._config_sent:
            doc['config'] = dataclasses.asdict(self.config)  # replay rebuilds the runner
            doc['robot_params'] = robot_params(self.robot)   # ... with these K, D
            self._config_sent = True
        return doc

    def config_doc(self) -> dict[str, Any]:  # JSON document
        """The ``spg/config`` document (JSON-ready).

        What a replay needs besides the recorded joint states to recompute q_v from any
        tick on.

        Keys: config (the :class:`SpgConfig` as a dict), robot_params (:func:`robot_params`),
        stack (None, or {id, name, text (the document as received), since [s] (stamp of its
        first tick), activations: [first, latest] ticks at which its tasks captured their
        ``init`` values, each {q, qdot, q_v [rad, rad/s], t [s]}}), state_layout (the fields
        of ``spg/state``: [name, length] in order; ``warm_start``'s length depends on the
        running stack, so a new stack publishes a new document).
        """
        def floats(x):
            return [float(v) for v in np.ravel(x)]

        stack = None
        if self.stack_id and self.stack_text is not None:
            stack = {'id': self.stack_id, 'name': self.stack_name, 'text': self.stack_text,
                     'since': self._stack_since,
                     'activations': [{'q': floats(a.q), 'qdot': floats(a.qdot),
                                      'q_v': floats(a.q_v), 't': float(a.t)}
                                     for a in self.spg.activations]}
        return {'config': dataclasses.asdict(self.config),
                'robot_params': robot_params(self.robot), 'stack': stack,
                'state_layout': [[name, size] for name, size in self._state_layout()]}

    def _state_layout(self):
        n = self._n
        streams = tuple((STREAM_FIELD + b.task.name, b.dim) for b in stream_bounds(self.spg.tasks))
        obstacles = tuple((OBSTACLE_FIELD + name, 7) for name in obstacle_poses(self.spg.tasks))
        warm_start = self.spg.snapshot().warm_start
        if warm_start is None:  # snapshot() always gives it
            raise IfcSpgError('internal: the SPG snapshot has no warm start')
        return _base_layout(n) + (('warm_start', warm_start.size),) + streams + obstacles

    def state_vector(self) -> np.ndarray:
        """The ``spg/state`` data after the last tick.

        Floats in the layout ``state_layout`` of :meth:`config_doc` (NaN where there are no
        tanks): the tick count, its stamp, the measured q and the SPG's state the next tick
        starts from, with the cascade's working sets (``warm_start``: DAQP's sense flag per
        constraint of each level model of the running stack), and per streamed task the
        reference the tick used (``stream:<task name>``, in task coordinates; NaN before
        the first tick), which a replay uses instead of the stream's messages and their timing,
        and per obstacle of the running stack the pose the tick used (``obstacle:<name>``:
        x, y, z [m], qx, qy, qz, qw in its frame), which it uses instead of ``spg/obstacles``.
        """
        snap = self.spg.snapshot()
        # after a tick: q measured, q_v set, and snapshot() always gives the warm start
        if self._last_q is None or snap.q_v is None or snap.warm_start is None:
            raise IfcSpgError('internal: spg/state asked for before the first tick')
        nan = np.full(self._n, np.nan)
        sec, nsec = split_ns(self._last_stamp or 0)
        return np.concatenate((
            [float(self.ticks), float(sec), float(nsec)], self._last_q, snap.q_v, snap.qdot_v,
            nan if snap.tank_energy is None else snap.tank_energy,
            nan if snap.shuffled is None else snap.shuffled, snap.warm_start,
            *(b.used() for b in stream_bounds(self.spg.tasks)),
            *obstacle_poses(self.spg.tasks).values()))

    def replay_streams(self, vector, doc):
        """Make the streamed tasks use the references a recorded ``spg/state`` shows.

        For a replay: call it before the tick whose ``spg/state`` ``vector`` (with its
        ``spg/config`` ``doc``) was recorded; the running and the pending stack's streamed
        tasks of the same name use the recorded value from then on (the live SPG's stream
        messages, and when each arrived, are not needed); the obstacles go to the recorded
        poses (``spg/obstacles`` is not needed either).
        """
        parts = self._state_parts(np.asarray(vector, dtype=float), doc)
        tasks = list(self.spg.tasks) + self.spg.pending_tasks
        for bound in stream_bounds(tasks):
            value = parts.get(STREAM_FIELD + bound.task.name)
            if value is not None and value.size == bound.dim:
                bound.replay_value(value)
        for task in obstacle_tasks(tasks):
            for name in task.obstacle_poses:
                pose = parts.get(OBSTACLE_FIELD + name)
                if pose is not None and pose.size == 7 and np.all(np.isfinite(pose)):
                    task.move_obstacle(name, pose)

    def _state_parts(self, vector, doc):
        """Split an ``spg/state`` vector by the ``state_layout`` of its ``spg/config``.

        Documents without a layout, or without ``warm_start`` (bags recorded before it was
        published), have the fields before it; their replay starts the cascade cold.
        """
        layout = doc.get('state_layout')
        if layout is None:
            layout = _base_layout(self._n)
        try:
            layout = [(str(name), int(size)) for name, size in layout]
        except (TypeError, ValueError):
            raise ParameterError(f'spg/config: state_layout must list [name, length] pairs, '
                                 f'got {layout!r}') from None
        fixed = dict(_base_layout(self._n))
        names = [name for name, _ in layout]
        wrong = [f'{name} ({size})' for name, size in layout
                 if name in fixed and size != fixed[name]]
        if wrong or not set(fixed) <= set(names) or len(set(names)) != len(names):
            raise ParameterError(f'spg/config: state_layout {layout} does not describe the '
                                 f'{self._n} joints of {self.robot.name!r} (expected the fields '
                                 f'{list(fixed)} with lengths {list(fixed.values())})')
        total = sum(size for _, size in layout)
        if vector.size != total:
            raise ParameterError(f'spg/state has {vector.size} values, expected {total} '
                                 f'(state_layout of spg/config) for the {self._n} joints of '
                                 f'{self.robot.name!r}')
        parts, i = {}, 0
        for name, size in layout:
            parts[name] = vector[i:i + size]
            i += size
        return parts

    def restore(self, vector, doc):
        """Continue from a recorded ``spg/state`` ``vector`` and ``spg/config`` ``doc``.

        For a replay that starts mid-run; the stack of ``doc`` becomes the running one.

        Args:
            vector: The ``spg/state`` data (:meth:`state_vector`).
            doc: The ``spg/config`` document (:meth:`config_doc`).

        Returns:
            The stamp [ns] of the restored tick (the next state must be newer).

        Raises:
            ParameterError: A vector or document that does not fit this robot.
        """
        vector = np.asarray(vector, dtype=float)
        parts = self._state_parts(vector, doc)
        stack = doc.get('stack')
        acts = []
        if stack:
            event = self.handle_task_stack(stack['text'])
            if not event.accepted:
                raise ParameterError(f'spg/config: the recorded stack does not build here: '
                                     f'{event.message}')
            acts = [Activation(np.array(a['q']), np.array(a['qdot']), np.array(a['q_v']),
                               float(a['t'])) for a in stack['activations']]
        tanks = None if np.isnan(parts['tank_energy']).any() else parts['tank_energy']
        self.spg.restore(SpgState(parts['q_v'], parts['qdot_v'], tanks,
                                  None if tanks is None else parts['shuffled'],
                                  parts.get('warm_start')),
                         parts['q'], acts)
        stamp = join_ns(parts['stamp_sec'][0], parts['stamp_nanosec'][0])
        if stack:
            self.stack_id, self.stack_name = int(stack['id']), str(stack['name'])
            self.stack_text, self._stack_since = stack['text'], stack.get('since')
            self._next_id, self._pending_name = self.stack_id, None
        self.replay_streams(vector, doc)
        self.ticks = int(parts['tick'][0])
        self.started, self.stale = True, False
        self._last_stamp, self._last_q = stamp, parts['q'].copy()
        return stamp

    def _pspm_status(self, info):
        """The ``pspm`` entry of the status: the tick's PSPM document with the stall count."""
        doc = info.pspm
        if doc is not None:
            doc['stalls'] = self.pspm_stalls
        return doc

    def diagnostics(self) -> 'DiagItem':
        """A :class:`DiagItem` summarizing the node (for a ~1 Hz DiagnosticArray).

        A PSPM stall (an empty tank clipping the stack) is a WARN naming the joints, the
        power the stack asks for and the setting that would allow it.
        """
        values = self._diag_values()
        level, message = self._diag_level(values)
        return DiagItem(level, 'spg_node', message, values)

    def _diag_values(self):
        """The key-value pairs of :meth:`diagnostics` (strings)."""
        values = {'ticks': str(self.ticks), 'state': self.state,
                  'stack': f'{self.stack_name} (id {self.stack_id})' if self.stack_id else '',
                  'spg_status': self.spg.info.status,
                  'watchdog_trips': str(self.watchdog_trips), 'resumes': str(self.resumes)}
        for reason, count in self.rejected.items():
            values[f'rejected.{reason}'] = str(count)
        for reason, count in self.obstacles.rejected.items():
            values[f'obstacles.rejected.{reason}'] = str(count)
        stall = self.spg.info.stall
        if self.spg.tanks is not None:
            values['pspm.power_budget_w'] = f'{self.spg.tanks.power:g}'
            values['pspm.max_power_w'] = f'{self.spg.tanks.config.max_power:g}'
            values['pspm.stalls'] = str(self.pspm_stalls)
            if stall is not None:
                names = self.joint_names
                values['pspm.stalled_joints'] = ','.join(names[j] for j in stall.joints)
                values['pspm.requested_power_w'] = f'{stall.total_power:.3g}'
                values['pspm.fix'] = stall.suggestion()
        if self._period:
            period = float(np.median(self._period))
            values['period_median_s'] = f'{period:.6f}'
        if self._tick_times:
            tt = np.sort(np.array(self._tick_times))
            values['tick_time_p50_ms'] = f'{tt[len(tt) // 2] * 1e3:.3f}'
            values['tick_time_max_ms'] = f'{tt[-1] * 1e3:.3f}'
        return values

    def _diag_level(self, values):
        """The (level, message) of :meth:`diagnostics`, the most severe condition first."""
        info = self.spg.info
        if self.state == 'waiting':
            return 'STALE', 'waiting for joint states'
        if self.state == 'stale':
            return 'STALE', self._last_error_of('watchdog')
        if info.status in ('hold', 'bad_input'):
            return 'ERROR', info.message
        if info.stall is not None:
            return 'WARN', info.message
        if info.status == 'fallback' or any(self.rejected.values()) or \
                any(self.obstacles.rejected.values()):
            return 'WARN', self.last_error
        if self._period and abs(float(np.median(self._period)) - self.config.dt) > \
                0.2 * self.config.dt:
            return 'WARN', (f'joint-state period {values["period_median_s"]} s differs from '
                            f'dt {self.config.dt} s')
        return 'OK', 'running'

    def _last_error_of(self, source):
        for err in reversed(self.errors):
            if err['source'] == source:
                return err['message']
        return ''
