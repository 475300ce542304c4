"""Streamed task references: a bound that follows the latest message on a topic.

A task stack writes ``equal: {stream: TOPIC, stale_after: S}`` (TOPIC null: the default
``spg/reference/<task name>``) on a ``cartesian_pose`` (geometry_msgs/PoseStamped),
``joint_position`` (sensor_msgs/JointState) or ``wrench`` (geometry_msgs/WrenchStamped)
task. :class:`StreamReference` holds what arrived; the node shell (``spg_node``) feeds it
every message with its receive time, and nothing here knows about DDS. :class:`StreamBound`
is the task's bound:

- until the first accepted message it is the task value at activation (``init``: hold);
- then it is the task value of the latest accepted message (rate zero: no feed-forward of a
  stream's jumps), converted with the task's own definition (a pose: S^T [p - p_ref;
  log3(R R_ref^T)]; joint positions by name; a wrench: S^T [f; tau]);
- a reference older than ``stale_after`` [s] keeps the last one and is reported
  (:meth:`StreamReference.status`), so a stream that stops holds its last target;
- messages with a non-finite number, in a frame the task does not take, or (joint states)
  without every joint of the task are rejected and counted.

The joint position, velocity and acceleration limits, the torque limits and the PSPM bound
the result like any bound: a jumpy stream never yields a jumpy command.

Frames: a pose is in the robot's base frame (``frame_id`` empty, ``world`` or the root
link name ``base_frames``); a wrench in the frame of the task's subspace (``base``: as a
pose; ``ee``/``ee_orientation``: empty or the task's chain id, e.g. ``tool``).
"""

from __future__ import annotations

from collections import deque
import math
from typing import Any

import numpy as np
import pinocchio as pin

from ifc_spg.tasks.bounds import Bound

__all__ = ['StreamBound', 'StreamReference', 'base_frames', 'default_topic', 'streams_of']

MSG_TYPES = {'cartesian_pose': 'geometry_msgs/msg/PoseStamped',
             'joint_position': 'sensor_msgs/msg/JointState',
             'wrench': 'geometry_msgs/msg/WrenchStamped'}
REJECT_REASONS = ('nonfinite', 'frame', 'joints')


def default_topic(task_name: str) -> str:
    """The topic of ``{stream: null}``: ``spg/reference/<task name>``."""
    return f'spg/reference/{task_name}'


class StreamReference:
    """The latest accepted reference of one streamed task, fed by the node shell.

    Args:
        task: The task (its ``kind`` decides the message type; ``name`` reports).
        topic: Topic name (relative names resolve in the node's namespace).
        stale_after: Age [s] after which the reference is reported stale.
        base_frames: Frame ids a pose (and a base-frame wrench) may be given in.

    Attributes:
        latest: The last accepted reference (a (p, R) pose, joint positions (m,) or a
            wrench (6,)), None before the first.
        received: Messages fed; accepted: accepted ones; rejected: reason -> count.
        stale: True while the latest reference is older than ``stale_after``.
        age: Age [s] of the latest reference at the last :meth:`update` (None: none yet).
        latencies: [s] from the receipt of each used reference to the end of the first
            tick that followed it (the last 1000; :meth:`update` runs after the tick).
    """

    def __init__(self, task: Any, topic: str, stale_after: float = 0.2,
                 base_frames: tuple = ('', 'world')) -> None:
        self.task, self.topic = task, topic
        self.msgtype = MSG_TYPES[task.kind]
        self.stale_after = float(stale_after)
        self.base_frames = tuple(base_frames)
        self.latest: Any = None
        self.version = 0
        self.received = self.accepted = 0
        self.rejected = dict.fromkeys(REJECT_REASONS, 0)
        self.last_reject: str | None = None
        self.stale = False
        self.stale_episodes = 0
        self.age: float | None = None
        self._received_ns: int | None = None
        self._used_version = 0
        self.latencies: deque = deque(maxlen=1000)  # [s] receipt -> the tick that used it

    # -- feeding ---------------------------------------------------------------------------
    def feed(self, msg: Any, now_ns: int) -> bool:
        """Take one message received at ``now_ns`` [ns]; True if accepted."""
        self.received += 1
        value, reason = self._parse(msg)
        if reason is not None:
            self.rejected[reason[0]] += 1
            self.last_reject = reason[1]
            return False
        self.latest = value
        self.version += 1
        self.accepted += 1
        self._received_ns = int(now_ns)
        return True

    def _parse(self, msg: Any) -> tuple[Any, tuple[str, str] | None]:
        kind = self.task.kind
        frame = str(msg.header.frame_id) if kind != 'joint_position' else ''
        nums: tuple[Any, ...]
        if kind == 'cartesian_pose':
            p, o = msg.pose.position, msg.pose.orientation
            nums = (p.x, p.y, p.z, o.x, o.y, o.z, o.w)
        elif kind == 'wrench':
            f, t = msg.wrench.force, msg.wrench.torque
            nums = (f.x, f.y, f.z, t.x, t.y, t.z)
        else:
            nums = tuple(msg.position)
        try:
            vals = np.array([float(v) for v in nums])
        except (TypeError, ValueError):
            return None, ('nonfinite', 'not numbers')
        if not np.all(np.isfinite(vals)):
            return None, ('nonfinite', f'non-finite values {vals.tolist()}')
        if kind == 'joint_position':
            return self._joints(msg, vals)
        frames = self.base_frames
        if kind == 'wrench' and self.task.subspace_frame != 'base':
            frames = ('', self.task.frame)
        if frame not in frames:
            return None, ('frame', f"frame_id '{frame}'; this task takes "
                                   f"{' or '.join(repr(f) for f in frames)}")
        if kind == 'wrench':
            return vals, None
        qn = math.sqrt(float(vals[3:] @ vals[3:]))
        if not 0.5 < qn < 2.0:  # not a rotation (a zero quaternion: an unset orientation)
            return None, ('nonfinite', f'orientation quaternion of norm {qn:.3g} (give a '
                                       'unit quaternion)')
        q = vals[3:] / qn
        R = pin.Quaternion(q[3], q[0], q[1], q[2]).toRotationMatrix()
        return (vals[:3].copy(), R), None

    def _joints(self, msg: Any, vals: np.ndarray) -> tuple[Any, tuple[str, str] | None]:
        names = list(msg.name)
        if len(names) != vals.size:
            return None, ('joints', f'{len(names)} names but {vals.size} positions')
        index = {n: i for i, n in enumerate(names)}
        wanted = [self.task.robot.joint_names[i] for i in self.task.indices]
        missing = [n for n in wanted if n not in index]
        if missing:
            return None, ('joints', f"no position for joint(s) {', '.join(missing)}")
        return vals[[index[n] for n in wanted]], None

    def update(self, now_ns: int) -> None:
        """Age and staleness at ``now_ns`` [ns] (call once per tick)."""
        if self._received_ns is None:
            self.age, self.stale = None, False
            return
        self.age = max(0.0, (int(now_ns) - self._received_ns) * 1e-9)
        if self.version != self._used_version:  # this tick was the first to use it
            self._used_version = self.version
            self.latencies.append(self.age)
        stale = self.age > self.stale_after
        if stale and not self.stale:
            self.stale_episodes += 1
        self.stale = stale

    def status(self) -> dict[str, Any]:
        """The ``spg/status`` entry of this stream (JSON-ready)."""
        state = 'waiting' if self.latest is None else 'stale' if self.stale else 'live'
        latency = None
        if self.latencies:
            lat = np.percentile(np.array(self.latencies), [50, 99, 100])
            latency = {'p50': float(lat[0]), 'p99': float(lat[1]), 'max': float(lat[2]),
                       'n': len(self.latencies)}
        return {'latency': latency, 'task': self.task.name, 'topic': self.topic, 'state': state,
                'age': None if self.age is None else round(self.age, 6),
                'stale_after': self.stale_after, 'received': self.received,
                'accepted': self.accepted, 'rejected': dict(self.rejected),
                'last_reject': self.last_reject, 'stale_episodes': self.stale_episodes}


class StreamBound(Bound):
    """A task bound that is the latest streamed reference (see the module docstring).

    Args:
        topic: The topic (None: set by :meth:`bind` to :func:`default_topic`).
        stale_after: Age [s] after which the reference is reported stale.
    """

    def __init__(self, topic: str | None = None, stale_after: float = 0.2) -> None:
        self.topic_arg, self.stale_after = topic, float(stale_after)
        self.reference: StreamReference | None = None
        self._init: np.ndarray | None = None
        self._value: np.ndarray | None = None
        self._version = -1
        self._rate: np.ndarray | None = None
        self._used: np.ndarray | None = None     # the value the last evaluate returned
        self._replayed: np.ndarray | None = None  # a recorded value that overrides the stream

    def bind(self, task: Any, base_frames: tuple = ('', 'world')) -> StreamReference:
        """Attach to ``task`` (after it is built); returns its :class:`StreamReference`."""
        self.task = task
        self.reference = StreamReference(task, self.topic_arg or default_topic(task.name),
                                         self.stale_after, base_frames)
        self.dim = task.dim
        self._rate = np.zeros(task.dim)
        self._rate.setflags(write=False)
        return self.reference

    def activate(self, init_value: np.ndarray) -> StreamBound:
        """Hold ``init_value`` until the first message; the task time restarts."""
        self._init = np.array(init_value, dtype=float)
        self._init.setflags(write=False)
        self._version = -1
        self._value = self._used = None  # (a replayed value stays: it may be this tick's)
        return self

    def evaluate(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """The latest reference in task coordinates (or the ``init`` value), rate zero."""
        ref, rate = self.reference, self._rate
        if rate is None:
            raise ValueError('a streamed bound is not bound to a task (bind it first)')
        if self._replayed is not None:
            value = self._replayed
        elif ref is None or ref.latest is None:
            if self._init is None:
                raise ValueError('a streamed bound has no value before activation')
            value = self._init
        elif ref.version != self._version or self._value is None:
            value = np.asarray(self._to_value(ref.latest), dtype=float)
            value.setflags(write=False)
            self._value, self._version = value, ref.version
        else:
            value = self._value
        self._used = value
        return value, rate

    def used(self) -> np.ndarray:
        """The value (task coordinates) the last tick used; NaN before any tick.

        What ``spg/state`` records so a replay can use the same value
        (:meth:`replay_value`) without the stream's messages and their timing.
        """
        if self._used is None:
            return np.full(self.dim or 0, np.nan)
        return self._used

    def replay_value(self, value: np.ndarray) -> None:
        """From now on, evaluate to ``value`` (a recorded :meth:`used`) instead of the stream.

        NaN values (nothing recorded yet) leave the bound as it is.
        """
        value = np.array(value, dtype=float)
        if value.shape != (self.dim,):
            raise ValueError(f'a replayed value of task {self.task.name!r} has shape '
                             f'{value.shape}, expected ({self.dim},)')
        if np.all(np.isfinite(value)):
            value.setflags(write=False)
            self._replayed = value

    def _to_value(self, latest: Any) -> np.ndarray:
        task = self.task
        if task.kind == 'joint_position':
            return latest
        if task.kind == 'wrench':  # given in the subspace's frame (checked on arrival)
            return task.S.T @ latest
        p, R = latest
        x = np.concatenate((p - task._p_ref, pin.log3(R @ task.reference_orientation(R).T)))
        return task._S_base(R).T @ x

    def __repr__(self) -> str:
        return f'StreamBound({self.topic_arg!r})'


def base_frames(robot: Any) -> tuple:
    """Frame ids a streamed pose may name: '', ``world`` and the robot's root link(s).

    The root links are the body frames on pinocchio's universe joint at its origin (the
    base frame of every task).
    """
    roots = [f.name for f in robot.model.frames if f.type == pin.FrameType.BODY
             and f.parentJoint == 0 and f.placement.isIdentity(1e-12)]
    return ('', 'world', *roots)


def stream_bounds(tasks: Any) -> list[StreamBound]:
    """The :class:`StreamBound` of every streamed task in ``tasks`` (bound to a task)."""
    bounds = (getattr(task, 'upper_bound', None) for task in tasks)
    return [b for b in bounds if isinstance(b, StreamBound) and b.reference is not None]


def streams_of(tasks: Any) -> list[StreamReference]:
    """The :class:`StreamReference` of every streamed task in ``tasks``."""
    out = []
    for task in tasks:
        bound = getattr(task, 'upper_bound', None)
        if isinstance(bound, StreamBound) and bound.reference is not None:
            out.append(bound.reference)
    return out
