"""The ``spg_node``: the set-point generator on ROS topics.

    spg_node --ros-args --params-file config/lbr_iiwa14.yaml [-p status.decimation:=1]

One tick per ``joint_states`` message, one ``command/joint_position`` per tick (names +
q_v, velocity qdot_v, header stamp = the joint state's stamp, so a lockstep bridge matches
it). It starts from the measured q; task stacks (YAML/JSON text) arrive latched on
``spg/task_stack`` — a bad one is rejected with the field named on ``spg/status`` and the
running one continues. ``spg/obstacles`` (visualization_msgs/MarkerArray, best effort) moves
the obstacles the running stack declares from the next tick (:mod:`ifc_spg.node.obstacles`:
a marker per obstacle, ``ns`` its name; a bad marker is rejected, counted and reported on
``spg/status`` → ``obstacles``). ``spg/status`` (JSON) is published every ``status.decimation``
ticks and immediately on stack and watchdog events; ``spg/diagnostics`` every
``diagnostics.period`` seconds. Latched (transient local, depth 1), so a recorder started at
any time has them: ``spg/config`` (JSON: SPG settings, robot K, D and limits, the running
stack's text and the ticks its tasks captured their ``init`` values; republished when a
stack becomes active or the SPG restarts) and ``spg/state`` (Float64MultiArray after every
tick: tick, stamp, measured q, q_v, qdot_v, tank energies; layout in ``spg/config``), from
which ``ifc-spg replay`` recomputes q_v of a bag recorded mid-run. Without joint states for
``watchdog.timeout`` seconds the node stops commanding and reports it; when states return
with stamps that jumped (or restarted) it restarts from the measured q (see
:mod:`ifc_spg.node.core`).

Parameters (``ros2 param describe`` shows ranges and units): robot, dt, solver, rho,
torque_limits, velocity_box, pspm.{enabled, initial_energy, max_energy, shuffle, shuffle_budget,
max_power}, impedance.{stiffness, damping}, watchdog.timeout, status.decimation,
diagnostics.period, task_stack_file, topics.{joint_states, command, task_stack, status,
diagnostics}, enable, command.{interface, joints, hold_when_disabled}, tick, hot_path. An unknown,
mistyped or out-of-range parameter ends the node with exit code 2 and a message naming it.

Real robots (README, "On a real robot"): ``command.interface`` joint_state |
float64_multi_array (ros2_control JointGroupPositionController, in ``command.joints`` order) |
joint_trajectory; ``tick`` joint_states | timer (every dt with the latest state); ``enable``
false publishes nothing until switched on (parameter or the latched ``spg/enable`` Bool),
then restarts from the measured q.

``hot_path`` (rclpy): ``wait_set`` (default) serves ``joint_states`` from a loop that waits on
the node's wait set and takes each state itself (:func:`ifc_spg.ros.spin_hot`), leaving
parameters, stacks, timers and status to a SingleThreadedExecutor spun only when they are
ready; ``executor`` runs every callback from the executor as before (README, latency).

At run time (``ros2 param set``, rcl_interfaces SetParameters with rclpy) status.decimation,
diagnostics.period, watchdog.timeout, enable and command.hold_when_disabled change from the
next tick; every other parameter is refused with the reason in the SetParametersResult
(restart the node to change it).

The logic lives in :class:`ifc_spg.node.core.SpgRunner` (no ROS); this module only wires
it to topics and timers.
"""

from collections import deque
from collections.abc import Callable
from dataclasses import replace
import gc
import sys
import time
from typing import Any

import numpy as np

from ifc_spg import ros
from ifc_spg.errors import IfcSpgError, ParameterError, did_you_mean
from ifc_spg.node.config import PARAMETERS, declare_parameters
from ifc_spg.node.core import SpgRunner, status_json
from ifc_spg.node.markers import MarkerPublisher
from ifc_spg.node.stream_subscriptions import StreamSubscriptions
from ifc_spg.ros import msg
from ifc_spg.ros.protocols import Node as RosNode
from ifc_spg.ros.protocols import Timer as RosTimer
from ifc_spg.ros.signals import StopSignals
from ifc_spg.ros.stamps import set_stamp, stamp_to_ns

__all__ = ['SpgNode', 'main']

_LEVELS = {'OK': 0, 'WARN': 1, 'ERROR': 2, 'STALE': 3}


#: Parameters that may change while the node runs (applied from the next tick): how often it
#: reports and when it stops commanding. The rest define the solver, the model, the energy
#: tanks or the topics, and are refused at run time with the reason.
LIVE_PARAMETERS = ('status.decimation', 'diagnostics.period', 'watchdog.timeout', 'enable',
                   'command.hold_when_disabled')
_FIXED_WHY = {
    'impedance': "the energy tanks, the torque-limit level and the wrench tasks are built "
                 "with the robot's K and D, and a bag records them once",
    'pspm': 'the energy tanks are built with them; changing them would change what '
            'passivity guarantees mid-run',
    'topics': 'the subscriptions and publishers are made at start-up',
    'robot': 'the model, limits and joint names come from it',
    'dt': 'the cascade, the limits and the tanks are discretised with it',
    'solver': 'the cascade is built with it',
}


def _command_order(config, joint_names):
    """Indices into the robot's joints, in ``command.joints`` order (default: the robot's).

    Raises:
        ParameterError: Not exactly the robot's joints (names the missing / unknown ones).
    """
    names = list(config.command_joints) or list(joint_names)
    unknown = [n for n in names if n not in joint_names]
    if unknown:
        raise ParameterError(f"parameter 'command.joints': unknown joint '{unknown[0]}'"
                             f'{did_you_mean(unknown[0], joint_names)}; the robot '
                             f"'{config.robot}' has {', '.join(joint_names)}")
    missing = [n for n in joint_names if n not in names]
    if missing or len(set(names)) != len(names):
        raise ParameterError(f"parameter 'command.joints' must name each of the robot's joints "
                             f"once ({', '.join(joint_names)}); missing {missing}, given "
                             f'{names}')
    return [list(joint_names).index(n) for n in names]


class PeriodCounter:
    """Periods of a timer that passed without a callback (``tick: timer``).

    A timer driven by the executor cannot fire while the process has no CPU: on a loaded
    machine periods pass without a callback (rcl skips them rather than catching up). The
    counter compares the callbacks with the periods elapsed since the first one.

    Args:
        period: The timer's period [s].
    """

    def __init__(self, period: float):
        self.period = float(period)
        self.first: float | None = None
        self.last: float | None = None
        self.calls = 0

    def book(self, now: float) -> None:
        """Book a callback at ``now`` [s, monotonic]."""
        if self.first is None:
            self.first = now
        self.last = now
        self.calls += 1

    def summary(self) -> dict:
        """The periods, callbacks, missed periods and the callback rate.

        Returns:
            ``{'periods', 'calls', 'missed', 'rate'}``: periods from the first callback to
            the last (both included), the callbacks, the periods without one, and the
            callback rate [Hz] (0 before two).
        """
        if self.first is None or self.last is None:
            return {'periods': 0, 'calls': 0, 'missed': 0, 'rate': 0.0}
        span = self.last - self.first
        periods = round(span / self.period) + 1
        return {'periods': periods, 'calls': self.calls,
                'missed': max(0, periods - self.calls),
                'rate': (self.calls - 1) / span if span > 0 else 0.0}


class SpgNode:
    """Wires an :class:`~ifc_spg.node.core.SpgRunner` to a node of the active ROS backend.

    Args:
        node: ``ifc_spg.ros.Node`` (rclpy or the built-in backend).
        clock: Monotonic clock in [s] for the watchdog (tests may pass a fake one).
    """

    def __init__(self, node: RosNode, clock: Callable[[], float] = time.monotonic) -> None:
        self.node = node
        self.config = c = declare_parameters(node)
        self.runner = SpgRunner(c, clock=clock)
        self.log = node.get_logger()
        self._command_order = _command_order(c, self.runner.joint_names)
        #: the joint order of the commands (``command.joints``, default the robot's)
        self.command_joints = tuple(self.runner.joint_names[i] for i in self._command_order)
        self._write = {'joint_state': self._joint_state_command,
                       'float64_multi_array': self._float64_multi_array_command,
                       'joint_trajectory': self._joint_trajectory_command}[c.command_interface]
        command_type = {'joint_state': msg.JointState, 'float64_multi_array':
                        msg.Float64MultiArray, 'joint_trajectory': msg.JointTrajectory}
        self.pub_command = node.create_publisher(command_type[c.command_interface],
                                                 c.command_topic, 10)
        self.sub_enable = node.create_subscription(msg.Bool, 'spg/enable', self.on_enable,
                                                   ros.latched(1))
        self.pub_status = node.create_publisher(msg.String, c.status_topic, 10)
        self.pub_diag = node.create_publisher(msg.DiagnosticArray, c.diagnostics_topic, 10)
        # what a bag recorded from any tick on needs to recompute q_v (ifc-spg replay): the
        # configuration and running stack, and the state after the last tick, both latched
        self.pub_config = node.create_publisher(msg.String, 'spg/config', ros.latched(1))
        self.pub_state = node.create_publisher(msg.Float64MultiArray, 'spg/state',
                                               ros.latched(1))
        self._config_version: int | None = None
        self.sub_states = node.create_subscription(msg.JointState, c.joint_states_topic,
                                                   self.on_joint_state, 10)
        self.sub_stack = node.create_subscription(msg.String, c.task_stack_topic,
                                                  self.on_task_stack, ros.latched(1))
        self.streams = StreamSubscriptions(node, self.runner)  # streamed task references
        self.markers = MarkerPublisher(node, self.runner, c.markers_rate, c.markers_frame)
        self.sub_obstacles = None  # spg/obstacles: moving the running stack's obstacles
        if msg.MarkerArray is not None:
            self.sub_obstacles = node.create_subscription(
                msg.MarkerArray, 'spg/obstacles', self.on_obstacles,
                ros.qos_profile_sensor_data)
        else:
            self.log.warning('spg/obstacles is off: rclpy has no visualization_msgs here '
                             '(install ros-jazzy-visualization-msgs, requirements.txt)')
        self._watchdog_timer: RosTimer | None = None
        self._diag_timer: RosTimer | None = None
        # tick: timer: the latest (state message, monotonic time of arrival)
        self._latest: tuple[Any, float] | None = None
        self._last_tick_ns = -1
        self._ages: deque[float] = deque(maxlen=1000)  # [s] state age at each timer tick
        self.timer_periods = PeriodCounter(c.dt)       # tick: timer, late or missed periods
        if c.tick == 'timer':
            node.create_timer(c.dt, self.on_timer_tick)
        self._start_timers()
        node.add_on_set_parameters_callback(self.on_set_parameters)
        self._logged: dict[str, tuple[float, int]] = {}  # kind -> (last logged, suppressed)
        self.commands_sent = 0
        self.log.info(f"spg_node: robot '{c.robot}' ({self.runner.robot.n} joints), dt {c.dt} s,"
                      f" solver {c.solver}, pspm {'on' if c.pspm else 'off'}, watchdog "
                      f'{c.watchdog_timeout * 1e3:g} ms; {ros.describe()}; waiting for '
                      f'{c.joint_states_topic}')
        if c.solver == 'proxsuite':
            self.log.warning('solver proxsuite is for comparisons: on degenerate levels it '
                             'falls back to the higher levels on most ticks, and one tick can '
                             'take seconds (README, Benchmarks); use daqp on a robot')
        if not c.velocity_box:
            self.log.warning('velocity_box is false: q_v is kept inside the position limits '
                             'only, not the velocity and acceleration limits (the thesis Ch. 3 '
                             'baseline, for comparisons; README, What is always true)')
        if c.task_stack_file:
            self.load_file(c.task_stack_file)
        self.publish_config()

    def _start_timers(self):
        """(Re)create the watchdog and diagnostics timers with the configured periods."""
        c, node = self.config, self.node
        for timer in (self._watchdog_timer, self._diag_timer):
            if timer is not None:
                node.destroy_timer(timer)
        self._watchdog_timer = None
        if c.watchdog_timeout > 0:
            self._watchdog_timer = node.create_timer(
                min(max(c.watchdog_timeout / 4, 0.002), 0.1), self.on_watchdog)
        self._diag_timer = node.create_timer(c.diagnostics_period, self.publish_diagnostics)

    def on_set_parameters(self, parameters):
        """A parameter change at run time (``ros2 param set``, SetParameters).

        The :data:`LIVE_PARAMETERS` apply from the next tick; the others are refused with
        the reason (they shape the solver, the model or the topics: restart the node).

        Args:
            parameters: The ``Parameter`` objects to set.
        """
        fields = {p.name: p.field for p in PARAMETERS}
        changes = {}
        for param in parameters:
            if param.name not in LIVE_PARAMETERS:
                why = _FIXED_WHY.get(param.name.split('.')[0], 'it is read at start-up')
                return ros.SetParametersResult(successful=False, reason=(
                    f"'{param.name}' cannot change while spg_node runs ({why}); restart "
                    f"spg_node with -p {param.name}:=... . Live parameters: "
                    f"{', '.join(LIVE_PARAMETERS)}"))
            value = param.value
            if isinstance(getattr(self.config, fields[param.name]), float):
                value = float(value)
            changes[fields[param.name]] = value
        try:
            config = replace(self.config, **changes)
        except IfcSpgError as exc:
            return ros.SetParametersResult(successful=False, reason=str(exc))
        old = self.config
        self.config = self.runner.config = config
        if (old.watchdog_timeout, old.diagnostics_period) != (config.watchdog_timeout,
                                                              config.diagnostics_period):
            self._start_timers()
        self._set_enable(old.enable, config.enable)
        self.log.info('parameters changed from the next tick: ' + ', '.join(
            f'{p.name} {getattr(old, fields[p.name])} -> {getattr(config, fields[p.name])}'
            for p in parameters))
        return ros.SetParametersResult(successful=True)

    def load_file(self, path):
        """Run the task stack in file ``path`` (as if it arrived on the task topic)."""
        try:
            with open(path, encoding='utf-8') as f:
                text = f.read()
        except OSError as exc:
            raise IfcSpgError(f"parameter 'task_stack_file': cannot read '{path}': "
                              f'{exc.strerror}') from None
        event = self.runner.handle_task_stack(text, source=path)
        if not event.accepted:
            raise IfcSpgError(event.message)
        self._report_stack(event)

    # -- callbacks ----------------------------------------------------------------------
    def on_enable(self, message):
        """``spg/enable`` (latched Bool): switch commanding on or off, as the parameter."""
        results = self.node.set_parameters([ros.Parameter('enable', value=bool(message.data))])
        if not results[0].successful:
            self.log.error(f'spg/enable: {results[0].reason}')

    def _set_enable(self, old, new):
        """Log and report a change of ``enable``; enabling restarts from the measured q."""
        if new and not old:
            self.runner.request_restart()
            self.log.warning('enabled: commanding from the measured q at the next joint state')
            self.publish_status(('enabled', 'commanding from the measured q'))
        elif old and not new:
            self.log.warning('disabled: no commands' + (
                ' (holding the measured q)' if self.config.hold_when_disabled else ''))
            self.publish_status(('disabled', 'no commands'))

    def _hold(self, message, stamp):
        """While disabled: the measured q, in the command's joint order (if asked to)."""
        if not self.config.hold_when_disabled:
            return
        index = {n: i for i, n in enumerate(message.name)}
        try:
            q = np.array([float(message.position[index[n]]) for n in self.runner.joint_names])
        except (KeyError, IndexError, TypeError, ValueError):
            return
        if not np.all(np.isfinite(q)):
            return
        robot = self.runner.robot
        self._write(stamp, np.clip(q, robot.q_min, robot.q_max), np.zeros(q.size))

    def on_joint_state(self, message):
        """A joint state: a tick (``tick: joint_states``), or the latest state for the timer."""
        if self.config.tick == 'timer':
            self._latest = (message, time.monotonic())
            return
        self._tick(message, message.header.stamp)

    def on_timer_tick(self):
        """``tick: timer``: one tick with the latest joint state.

        The tick is stamped with the state's stamp plus its age (task time runs on; q is not
        extrapolated). A state older than watchdog.timeout stops commanding, as a stopped
        stream does.
        """
        now = time.monotonic()
        self.timer_periods.book(now)
        if self._latest is None:
            return
        message, arrived = self._latest
        age = now - arrived
        timeout = self.config.watchdog_timeout
        if timeout and age > timeout:
            if self.config.enable and self.runner.started and not self.runner.stale:
                text = (f'the latest joint state is {age * 1e3:.0f} ms old > watchdog.timeout '
                        f'{timeout * 1e3:.0f} ms: commanding stopped')
                self.runner.mark_stale(text)
                self.log.warning(text)
                self.publish_status(('watchdog', text))
            return
        stamp_ns = stamp_to_ns(message.header.stamp) + round(age * 1e9)
        if stamp_ns <= self._last_tick_ns:
            return
        self._last_tick_ns = stamp_ns
        self._ages.append(age)
        stamp = msg.Time()
        set_stamp(stamp, stamp_ns)
        self._tick(message, stamp)

    def _tick(self, message, stamp):
        """Tick: validate, step the SPG, publish the command (and status every N ticks)."""
        if not self.config.enable:
            self._hold(message, stamp)
            return
        runner = self.runner
        cmd, events = runner.tick(message.name, message.position, message.velocity,
                                  stamp_to_ns(stamp))
        if cmd is not None:
            self._write(stamp, cmd.position, cmd.velocity)
            self.commands_sent += 1
            if runner.config_version != self._config_version:
                self.publish_config()
            self.pub_state.publish(msg.Float64MultiArray(data=runner.state_vector().tolist()))
        for event in events:
            self._report(event)
        if cmd is not None and cmd.tick % self.config.status_decimation == 0:
            self.publish_status()

    def _report(self, event):
        """Map one of the runner's tick events to the log, ``spg/status`` and the streams."""
        kind, text = event
        if kind == 'rejected':
            self._log_throttled('error', text)
        elif kind == 'watchdog':  # a stamp gap tripped it
            self.log.warning(text)
        elif kind == 'stack_taken':  # its streams replace the old stack's
            self.streams.sync()
        elif kind == 'started':
            self.log.info(text)
        elif kind == 'continued':  # rclpy's logger wants one severity per call site
            self.log.info(text)
            self.publish_status((kind, text))
        elif kind in ('resumed', 'pspm_stall'):
            self.log.warning(text)
            self.publish_status((kind, text))

    def on_obstacles(self, message):
        """``spg/obstacles`` (MarkerArray): obstacle poses for the next tick; bad ones counted."""
        for reason, text in self.runner.handle_obstacles(message.markers):
            self._log_throttled('error', f'obstacle marker rejected ({reason}): {text}')

    def on_task_stack(self, message):
        """A new task stack: accept (hot swap at the next tick) or reject with the reason."""
        event = self.runner.handle_task_stack(message.data, source=self.sub_stack.topic_name)
        self._report_stack(event)

    def _report_stack(self, event):
        """Log a stack event and publish it on the status topic."""
        if event.accepted:
            self.log.info(event.message)
            self.streams.sync()
            self.publish_status(('stack_accepted', event.message))
        else:
            self.log.error(f'{event.message}; keeping stack '
                           f"'{event.name or 'none'}'")
            self.publish_status(('stack_rejected', event.message))

    # -- commands, one writer per interface (q_v, qdot_v in the robot's joint order) -------
    def _joint_state_command(self, stamp, position, velocity):
        out = msg.JointState()
        out.header.stamp = stamp
        order = self._command_order
        out.name = [self.runner.joint_names[i] for i in order]
        out.position = [float(position[i]) for i in order]
        out.velocity = [float(velocity[i]) for i in order]
        self.pub_command.publish(out)

    def _float64_multi_array_command(self, stamp, position, velocity):
        out = msg.Float64MultiArray()
        out.data = [float(position[i]) for i in self._command_order]
        self.pub_command.publish(out)

    def _joint_trajectory_command(self, stamp, position, velocity):
        out = msg.JointTrajectory()
        out.header.stamp = stamp
        order = self._command_order
        out.joint_names = [self.runner.joint_names[i] for i in order]
        point = msg.JointTrajectoryPoint()
        point.positions = [float(position[i]) for i in order]
        point.velocities = [float(velocity[i]) for i in order]
        set_stamp(point.time_from_start, round(self.config.dt * 1e9))
        out.points = [point]
        self.pub_command.publish(out)

    def on_watchdog(self):
        """Timer: trip the watchdog when joint states stopped."""
        if not self.config.enable:
            return
        if self.runner.check_watchdog():
            self.log.warning(self.runner.last_error)
            self.publish_status(('watchdog', self.runner.last_error))
            self.publish_diagnostics()

    # -- outputs ------------------------------------------------------------------------
    def publish_status(self, event=None):
        """Publish the runner's status JSON on the status topic.

        With ``tick: timer``, also the joint states' age at the ticks: ``state_age``
        p50/p99/max [s], and the timer's periods: ``timer`` {periods, calls, missed, rate}
        (:class:`PeriodCounter`).

        Args:
            event: Optional (type, message) of an event, see :meth:`SpgRunner.status`.
        """
        status = self.runner.status(event)
        if self.config.tick == 'timer':
            status['timer'] = self.timer_periods.summary()
        if self._ages:
            ages = np.sort(np.array(self._ages))
            status['state_age'] = {'p50': float(np.percentile(ages, 50)),
                                   'p99': float(np.percentile(ages, 99)),
                                   'max': float(ages[-1]), 'n': int(ages.size)}
        self.pub_status.publish(msg.String(data=status_json(status)))

    def publish_config(self):
        """Publish the runner's :meth:`~ifc_spg.node.core.SpgRunner.config_doc` (latched)."""
        self._config_version = self.runner.config_version
        self.pub_config.publish(msg.String(data=status_json(self.runner.config_doc())))

    def publish_diagnostics(self):
        """Publish one DiagnosticArray with the runner's summary."""
        item = self.runner.diagnostics()
        status = msg.DiagnosticStatus()
        level = _LEVELS[item.level]
        status.level = bytes([level]) if isinstance(status.level, bytes) else level
        status.name = f'{self.node.get_name()}: set-point generator'
        status.message = item.message or item.level
        status.hardware_id = self.runner.robot.name
        status.values = [msg.KeyValue(key=k, value=v) for k, v in item.values.items()]
        array = msg.DiagnosticArray()
        now = time.time_ns()
        set_stamp(array.header.stamp, now)
        array.status = [status]
        self.pub_diag.publish(array)

    def _log_throttled(self, level, text, period=1.0):
        """Log ``text`` at most once per ``period`` [s] per kind (the text before ':')."""
        key = text.split(':', 1)[0]
        now = time.monotonic()
        last, suppressed = self._logged.get(key, (-1e18, 0))
        if now - last >= period:
            more = f' ({suppressed} similar suppressed)' if suppressed else ''
            getattr(self.log, level)(text + more)
            self._logged[key] = (now, 0)
        else:
            self._logged[key] = (last, suppressed + 1)


def main(argv=None):
    """Entry point of the ``spg_node`` executable; returns the exit code."""
    argv = list(sys.argv if argv is None else argv)
    if '-h' in argv or '--help' in argv:
        print(__doc__)
        return 0
    try:
        ros.init(args=argv)
    except IfcSpgError as exc:
        print(f'spg_node: {exc}', file=sys.stderr)
        return 2
    node = ros.Node('spg_node')
    try:
        spg = SpgNode(node)
    except IfcSpgError as exc:
        print(f'spg_node: {exc}', file=sys.stderr)
        node.destroy_node()
        ros.shutdown()
        return 2

    # everything built so far (models, solvers, ROS entities) lives as long as the node: keep
    # it out of the cyclic collector, whose full passes over it stalled ticks by 10-30 ms
    with StopSignals() as stops:
        try:
            gc.collect()
            gc.freeze()
            if spg.config.hot_path == 'wait_set':
                ros.spin_hot(node, spg.sub_states)  # rclpy: joint states without the executor
            else:
                ros.spin(node)
        except BaseException as exc:
            if not stops.stopped_by(exc):
                raise
        finally:
            stops.ignore()  # stopping: a second signal must not interrupt the clean-up
            node.get_logger().info(f'spg_node: {spg.runner.ticks} ticks, {spg.commands_sent} '
                                   f'commands, rejected {spg.runner.rejected}, '
                                   f'{spg.runner.watchdog_trips} watchdog trip(s)')
            node.destroy_node()
            if ros.ok():
                ros.shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
