"""The ``sim_bridge`` node: a MuJoCo robot behind its emulated IFC interface, on ROS topics.

    sim_bridge --ros-args -p robot:=lbr_iiwa14 -p scene:=table -p mode:=lockstep

Parameters: ``robot``, ``interface`` (``lbr_fri|icub|accrea``, empty: implied by the
robot), ``scene``, ``scene_options`` (JSON object), ``mode`` (``realtime|lockstep``),
``rate`` [Hz] (500), ``timestep`` [s] (0.001), ``q0`` [rad] (empty: home), ``duration``
[s] of simulated time (0: forever), ``push_duration`` [s] (0.5), ``ft_raw`` (false),
``fri_delay`` (FRI loop delay in whole periods, ``lbr_fri`` only; 0: the command acts in the
period it answers, n: n periods later — see :mod:`sim_bridge.simulation`).

Topics (relative names, ARCHITECTURE.md "Topics"):

- publishes ``joint_states`` (position, velocity, effort = measured torque; stamp = sim
  time), ``ft_sensor/wrench`` (one message per wrist sensor; ``frame_id`` = chain id, base
  frame components, moment about the chain frame, tool weight removed — with
  ``ft_raw:=true`` the raw reading in the sensor frame, ``frame_id`` = sensor site),
  ``sim/contact_wrench`` (ground truth on the tool, environment on robot, base frame,
  ``frame_id`` = chain id), ``sim/env_joint_states`` (scene mechanisms).
- subscribes ``command/joint_position`` (JointState: names + positions q_v; names may be
  omitted if all joints are given in model order) and ``sim/apply_wrench`` (WrenchStamped,
  base frame; ``header.frame_id`` = ``"<target>;duration=<s>"`` where the target is a chain,
  site or body — empty target: the contact chain; no duration: ``push_duration``).

Modes: ``lockstep`` publishes the state, waits for the command answering it (stamp equal to
the state's, or unstamped) and then steps — deterministic and as fast as the SPG allows; the
state is re-published every second while waiting. ``realtime`` paces to the wall clock with
absolute deadlines; a period without a command holds the last q_v (as FRI does) and is
counted and reported.
"""

from collections.abc import Callable
from dataclasses import dataclass
import gc
import json
import math
import sys
import time
from typing import Any

import numpy as np

from ifc_spg import ros
from ifc_spg.errors import IfcSpgError, ParameterError, did_you_mean
from ifc_spg.model import robot_gains
from ifc_spg.ros import COMMAND_INTERFACES, HOT_PATHS, msg
from ifc_spg.ros.parameters import declare_checked
from ifc_spg.ros.protocols import Node as RosNode
from ifc_spg.ros.signals import StopSignals
from sim_bridge.pacing import DeadlinePacer
from sim_bridge.simulation import SimConfig, Simulation

__all__ = ['BridgeParams', 'SimBridge', 'main', 'parse_push_frame']

MODES = ('realtime', 'lockstep')


@dataclass(frozen=True)
class BridgeParams:
    """The node's parameters, validated (one source of truth: :func:`declare`)."""

    robot: str = 'lbr_iiwa14'
    interface: str = ''
    scene: str = 'free'
    scene_options: str = '{}'
    mode: str = 'realtime'
    rate: float = 500.0
    timestep: float = 0.001
    q0: tuple[float, ...] = ()
    duration: float = 0.0
    push_duration: float = 0.5
    ft_raw: bool = False
    stiffness: tuple[float, ...] = ()
    damping: tuple[float, ...] = ()
    wait_for_subscribers: int = 0
    command_interface: str = 'joint_state'
    command_topic: str = 'command/joint_position'
    command_joints: tuple[str, ...] = ()
    state_rate: float = 0.0
    fri_delay: int = 0
    hot_path: str = 'wait_set'


_DESCRIPTIONS = {
    'state_rate': 'joint_states rate in [Hz] in realtime mode (0: the command rate); rate / '
                  'state_rate must be a whole number, e.g. 100 at rate 500, or 1000 at rate '
                  '1000 with an SPG ticking at 500 Hz on its timer',
    'command_interface': 'The command message the emulated controller takes: joint_state '
                         '(sensor_msgs/JointState), float64_multi_array (ros2_control '
                         'JointGroupPositionController) or joint_trajectory (the last point '
                         'of each trajectory_msgs/JointTrajectory)',
    'command_topic': 'Topic of the commands',
    'command_joints': "Joint order of float64_multi_array commands (the controller's "
                      "'joints'; default: the robot's)",
    'wait_for_subscribers': 'Before the first state, wait (up to 60 s) for this many '
                            'subscriptions on joint_states, then 0.5 s more (discovery is not '
                            'symmetric: a new subscriber may not know us yet); 0: start at once',
    'robot': 'Robot configuration (lbr_iiwa14, lbr4, icub_upper_body, accrea_dual_arm)',
    'interface': 'IFC emulation lbr_fri|icub|accrea (empty: implied by the robot)',
    'scene': 'Scene name (free, table, obstacle, drawer_horizontal, drawer_vertical, crank, '
             'cupboard_door, microwave_door)',
    'scene_options': 'Scene builder options as a JSON object, e.g. {"grasp": "none"}',
    'mode': 'realtime (wall-clock paced) or lockstep (wait for each command)',
    'rate': 'Joint-state / command rate in [Hz]',
    'timestep': 'Physics step in [s] (<= 0.001)',
    'q0': 'Initial joint positions in [rad] (empty: the home pose)',
    'duration': 'Stop after this much simulated time in [s] (0: run forever)',
    'push_duration': 'Default duration of sim/apply_wrench pushes in [s]',
    'ft_raw': 'Publish raw F/T readings (sensor frame) instead of compensated ones',
    'stiffness': 'Joint impedance stiffness K of the emulated controller in [Nm/rad], per '
                 "joint or one for all (default: the robot configuration's; set spg_node's "
                 'impedance.stiffness alike)',
    'damping': 'Joint impedance damping D in [Nms/rad], per joint or one for all (default: '
               "the robot configuration's)",
    'hot_path': "How the commands are served on rclpy: wait_set (taken by the bridge's own wait, "
                "the rest of the node on an executor) or executor (rclpy's "
                'SingleThreadedExecutor for everything); the built-in backend serves both alike',
    'fri_delay': 'FRI loop delay in whole command periods (lbr_fri only): a command acts this '
                 'many periods after the period it answers (0: in that period; 1: a client '
                 'answering at the end of the period)',
}


def declare(node: RosNode) -> 'BridgeParams':
    """Declare every parameter on ``node`` and return the :class:`BridgeParams`."""
    values: dict[str, Any] = {}  # parameter values (ROS parameter types)
    gains = None
    for name, spec in BridgeParams.__dataclass_fields__.items():
        default: Any = spec.default
        if name == 'q0':
            default = [0.0]  # typed as a double array; [] would be untyped
        elif name in ('stiffness', 'damping', 'command_joints'):  # the robot's own values
            gains = gains or robot_gains(values['robot'])
            default = gains[name]
        desc = ros.ParameterDescriptor(description=_DESCRIPTIONS[name])
        if name == 'fri_delay':
            desc.integer_range = [ros.IntegerRange(from_value=0, to_value=1000, step=0)]
        values[name] = declare_checked(node, name, default, desc)
        if name == 'command_joints':
            values[name] = () if list(values[name]) == default else tuple(values[name])
        elif isinstance(default, list):  # not set (q0's placeholder, the robot's gains): ()
            value = [float(x) for x in (values[name] or ())]
            values[name] = () if value == default else tuple(value)
    return validate(BridgeParams(**values))


def validate(p):
    """Return ``p`` if valid, else raise :class:`ParameterError` naming the fix."""
    if p.command_interface not in COMMAND_INTERFACES:
        raise ParameterError(f"command_interface '{p.command_interface}' is not one of "
                             f"{', '.join(COMMAND_INTERFACES)}"
                             f'{did_you_mean(p.command_interface, COMMAND_INTERFACES)}')
    if p.state_rate < 0 or (p.state_rate and (
            abs(p.rate / p.state_rate - round(p.rate / p.state_rate)) > 1e-9 or
            p.state_rate > p.rate)):
        raise ParameterError(f'state_rate {p.state_rate} Hz must divide rate {p.rate} Hz (0: '
                             'the command rate)')
    if p.state_rate and p.state_rate != p.rate and p.mode == 'lockstep':
        raise ParameterError('state_rate other than rate needs mode realtime (lockstep answers '
                             'each state with one command)')
    if p.hot_path not in HOT_PATHS:
        raise ParameterError(f"hot_path '{p.hot_path}' is not one of {', '.join(HOT_PATHS)}"
                             f'{did_you_mean(p.hot_path, HOT_PATHS)}')
    if p.mode not in MODES:
        raise ParameterError(f"mode '{p.mode}' is not one of {', '.join(MODES)}"
                             f'{did_you_mean(p.mode, MODES)}')
    if not p.rate > 0:
        raise ParameterError(f'rate must be > 0 Hz, got {p.rate}')
    steps = (1.0 / p.rate) / p.timestep
    if abs(steps - round(steps)) > 1e-6 or round(steps) < 1:
        raise ParameterError(f'1/rate = {1.0 / p.rate} s must be a multiple of timestep '
                             f'{p.timestep} s (e.g. rate 500 with timestep 0.001 or 0.0005)')
    try:
        options = json.loads(p.scene_options or '{}')
    except json.JSONDecodeError as exc:
        raise ParameterError(f"scene_options must be a JSON object, got '{p.scene_options}': "
                             f'{exc}') from None
    if not isinstance(options, dict):
        raise ParameterError(f"scene_options must be a JSON object, got '{p.scene_options}'")
    return p


def parse_push_frame(frame_id, default_target, default_duration):
    """Parse ``"<target>;duration=<s>"`` into (target, duration [s]).

    Raises:
        ParameterError: A malformed duration.
    """
    parts = [x.strip() for x in (frame_id or '').split(';')]
    target = parts[0] or default_target
    duration = default_duration
    for item in parts[1:]:
        if not item:
            continue
        key, _, value = item.partition('=')
        if key.strip() != 'duration':
            raise ParameterError(f"push frame_id '{frame_id}': unknown field '{key}'; "
                                 "use '<target>;duration=<seconds>'")
        try:
            duration = float(value)
        except ValueError:
            raise ParameterError(f"push frame_id '{frame_id}': duration '{value}' is not a "
                                 'number of seconds') from None
    return target, duration


def _stamp(msg_time_cls, t):
    sec = math.floor(t)
    nsec = round((t - sec) * 1e9)
    if nsec >= 1_000_000_000:
        sec, nsec = sec + 1, nsec - 1_000_000_000
    stamp = msg_time_cls()
    stamp.sec, stamp.nanosec = sec, nsec
    return stamp


class SimBridge:
    """The node body: a :class:`~sim_bridge.simulation.Simulation` wired to topics.

    Args:
        node: A node of the active ROS backend (``ifc_spg.ros.Node``).
        spin: ``spin(timeout_s)`` processing incoming messages (default: as the parameter
            ``hot_path`` says: the commands on an :class:`ifc_spg.ros.HotPath` and the rest
            of ``node`` on its executor, or all of it on the executor).
    """

    def __init__(self, node: RosNode, spin: Callable[[float], object] | None = None) -> None:
        self.node = node
        self.params = p = declare(node)
        self._msg = msg
        self.sim = Simulation(SimConfig(
            robot=p.robot, interface=p.interface or None, scene=p.scene,
            scene_options=json.loads(p.scene_options or '{}'), q0=p.q0 or None,
            timestep=p.timestep, command_period=1.0 / p.rate,
            stiffness=list(p.stiffness) or None, damping=list(p.damping) or None,
            fri_delay=p.fri_delay))
        self.steps_per_tick = round(1.0 / p.rate / p.timestep)
        self.pub_joints = node.create_publisher(msg.JointState, 'joint_states', 10)
        self.pub_ft = node.create_publisher(msg.WrenchStamped, 'ft_sensor/wrench',
                                            ros.qos_profile_sensor_data)
        self.pub_contact = node.create_publisher(msg.WrenchStamped, 'sim/contact_wrench',
                                                 ros.qos_profile_sensor_data)
        self.pub_env = node.create_publisher(msg.JointState, 'sim/env_joint_states', 10)
        command_type = {'joint_state': msg.JointState,
                        'float64_multi_array': msg.Float64MultiArray,
                        'joint_trajectory': msg.JointTrajectory}[p.command_interface]
        self._array_order = None
        if p.command_joints:
            unknown = [n for n in p.command_joints if n not in self.sim.joint_names]
            if unknown or sorted(p.command_joints) != sorted(self.sim.joint_names):
                raise ParameterError(
                    f'command_joints must name each joint once ({", ".join(self.sim.joint_names)}'
                    f'); got {list(p.command_joints)}')
            self._array_order = [list(p.command_joints).index(n) for n in self.sim.joint_names]
        sub_command = node.create_subscription(command_type, p.command_topic, self._on_command,
                                               10)
        node.create_subscription(msg.WrenchStamped, 'sim/apply_wrench', self._on_push, 10)
        # the commands without rclpy's executor (the rest of the node still on one): waiting
        # for each command through it cost the bridge more CPU than its simulation
        self._hot: ros.HotPath | None = None
        if spin is None and p.hot_path == 'wait_set':
            self._hot = ros.HotPath(node, sub_command)
            spin = self._hot.spin_once
        self._spin = spin or (lambda t: ros.spin_once(node, timeout_sec=t))
        self._names = list(self.sim.joint_names)
        self._index = {n: i for i, n in enumerate(self._names)}
        self._command: tuple[np.ndarray, Any] | None = None  # (q_v, stamp of either backend)
        self._pushes: list[tuple[str, list[float], float]] = []  # (target, wrench, duration)
        self._published_stamp: tuple[int, int] | None = None
        # stamp -> monotonic time the state was first published
        self._sent_at: dict[tuple[int, int], float] = {}
        self.latencies: list[float] = []  # [s] state published -> its command received, here
        self.commands_received = 0  # valid commands, answering a state or not
        self.ticks = 0
        self._reported_missed = 0
        node.get_logger().info(
            f"sim_bridge: robot '{self.sim.robot.name}', interface '{self.sim.interface}', "
            f"scene '{p.scene}', mode '{p.mode}', {p.rate:g} Hz, physics {1 / p.timestep:g} Hz"
            + (f', FRI delay {p.fri_delay} period(s)' if p.fri_delay else '')
            + f'; {ros.describe()}')

    # -- callbacks ------------------------------------------------------------------------
    def _on_command(self, message):
        try:
            q_v, stamp = self._decode_command(message)
        except ParameterError as exc:
            self.node.get_logger().error(f'{self.params.command_topic} rejected: {exc}')
            return
        self._command = (q_v, stamp)
        self.commands_received += 1
        sent = self._sent_at.pop(stamp, None)
        if sent is not None:  # the first command answering a state we published
            self.latencies.append(time.monotonic() - sent)

    def _decode_command(self, message):
        """(q_v in the simulation's joint order, stamp) of a command.

        Of the configured interface; a Float64MultiArray has no stamp: (0, 0), which
        lockstep takes as the answer to the state it waits for.
        """
        interface = self.params.command_interface
        if interface == 'float64_multi_array':
            data = np.array(list(message.data), dtype=float)
            if data.size != len(self._names):
                raise ParameterError(f'{data.size} values for {len(self._names)} joints')
            return (data[self._array_order] if self._array_order else data), (0, 0)
        stamp = (int(message.header.stamp.sec), int(message.header.stamp.nanosec))
        if interface == 'joint_trajectory':
            if not message.points:
                raise ParameterError('a JointTrajectory without points')
            point = message.points[-1]

            class _Named:  # the JointState fields _command_vector reads
                name, position = message.joint_names, point.positions
            return self._command_vector(_Named), stamp
        return self._command_vector(message), stamp

    def _command_vector(self, message):
        positions = list(message.position)
        if not message.name:
            if len(positions) != len(self._names):
                raise ParameterError(f'{len(positions)} positions without names; expected '
                                     f'{len(self._names)} ({", ".join(self._names)})')
            return np.array(positions, dtype=float)
        if len(message.name) != len(positions):
            raise ParameterError(f'{len(message.name)} names but {len(positions)} positions')
        q_v = np.array(self.sim.read_state().q_v)
        seen = set()
        for name, value in zip(message.name, positions):
            if name not in self._index:
                raise ParameterError(f"unknown joint '{name}'{did_you_mean(name, self._names)}")
            q_v[self._index[name]] = value
            seen.add(name)
        if len(seen) != len(self._names):
            missing = [n for n in self._names if n not in seen]
            raise ParameterError(f'command lacks joints {missing}')
        return q_v

    def _on_push(self, message):
        try:
            target, duration = parse_push_frame(message.header.frame_id,
                                                self.sim.contact_chain,
                                                self.params.push_duration)
            w = message.wrench
            wrench = [w.force.x, w.force.y, w.force.z, w.torque.x, w.torque.y, w.torque.z]
            self._pushes.append((target, wrench, duration))
        except IfcSpgError as exc:
            self.node.get_logger().error(f'sim/apply_wrench rejected: {exc}')

    # -- publishing -----------------------------------------------------------------------
    def publish_state(self):
        """Publish the current state on every output topic; return its stamp."""
        msg = self._msg
        s = self.sim.read_state()
        stamp = _stamp(msg.Time, s.t)
        js = msg.JointState()
        js.header.stamp = stamp
        js.name = list(s.joint_names)
        js.position = s.q.tolist()
        js.velocity = s.qd.tolist()
        js.effort = s.tau_measured.tolist()
        self.pub_joints.publish(js)
        source = s.ft_wrench if self.params.ft_raw else s.ft_external
        for chain, w in source.items():
            frame = s.ft_frames[chain] if self.params.ft_raw else chain
            self.pub_ft.publish(self._wrench(stamp, frame, w))
        self.pub_contact.publish(self._wrench(stamp, self.sim.contact_chain, s.contact_wrench))
        if s.env_joint_names:
            env = msg.JointState()
            env.header.stamp = stamp
            env.name = list(s.env_joint_names)
            env.position = s.env_q.tolist()
            env.velocity = s.env_qd.tolist()
            self.pub_env.publish(env)
        self._published_stamp = (int(stamp.sec), int(stamp.nanosec))
        self._sent_at.setdefault(self._published_stamp, time.monotonic())
        if len(self._sent_at) > 1000:  # states never answered: forget the oldest
            for key in list(self._sent_at)[:500]:
                del self._sent_at[key]
        return self._published_stamp

    def _wrench(self, stamp, frame, w):
        m = self._msg.WrenchStamped()
        m.header.stamp = stamp
        m.header.frame_id = frame
        f, t = m.wrench.force, m.wrench.torque
        f.x, f.y, f.z = (float(x) for x in w[:3])
        t.x, t.y, t.z = (float(x) for x in w[3:])
        return m

    # -- the loop -------------------------------------------------------------------------
    @property
    def pending_pushes(self):
        """The pushes received on sim/apply_wrench and not yet applied.

        Each is (target, wrench [N, Nm], duration [s]).
        """
        return tuple(self._pushes)

    def apply_inputs(self):
        """Apply the received pushes and the latest command to the simulation (one step)."""
        for target, wrench, duration in self._pushes:
            try:
                self.sim.apply_wrench(target, wrench, duration)
            except IfcSpgError as exc:
                self.node.get_logger().error(f'sim/apply_wrench rejected: {exc}')
        self._pushes = []
        if self._command is not None:
            self.sim.write_command(self._command[0])
            self._command = None

    def _advance(self):
        self.apply_inputs()
        self.sim.step(self.steps_per_tick)
        self.ticks += 1
        missed = self.sim.missed_commands
        if missed > self._reported_missed and self.ticks % int(self.params.rate) == 0:
            self.node.get_logger().warning(
                f'{missed - self._reported_missed} command period(s) without a command in the '
                f'last second (q_v held); {missed} in total')
            self._reported_missed = missed

    def _done(self, max_ticks):
        if max_ticks is not None and self.ticks >= max_ticks:
            return True
        return self.params.duration > 0 and self.sim.read_time() >= self.params.duration - 1e-9

    def run_lockstep(self, max_ticks=None, republish=1.0, ok=lambda: True):
        """Publish, wait for the matching command, step; until ``duration``/``max_ticks``."""
        while ok() and not self._done(max_ticks):
            stamp = self.publish_state()
            last = time.monotonic()
            while ok():
                if self._command is not None and self._command[1] in (stamp, (0, 0)):
                    break
                if self._command is not None:  # stale: answers an older state
                    self._command = None
                self._spin(0.05)
                if time.monotonic() - last > republish:
                    self.publish_state()
                    last = time.monotonic()
            self._advance()

    def run_realtime(self, max_ticks=None, ok=lambda: True):
        """Publish, process messages until the next absolute deadline, step; repeat."""
        pacer = DeadlinePacer(1.0 / self.params.rate)
        pacer.start()
        every = round(self.params.rate / self.params.state_rate) if self.params.state_rate \
            else 1
        while ok() and not self._done(max_ticks):
            if self.ticks % every == 0:
                self.publish_state()
            pacer.wait(idle=self._spin)
            self._advance()
        self.pacing = pacer.stats()
        return self.pacing

    def wait_for_subscribers(self, ok=lambda: True):
        """Wait for ``wait_for_subscribers`` subscriptions on joint_states.

        See its description; False if they did not come within 60 s.
        """
        n = self.params.wait_for_subscribers
        if n <= 0:
            return True
        deadline = time.monotonic() + 60.0
        while ok() and self.pub_joints.get_subscription_count() < n:
            if time.monotonic() > deadline:
                self.node.get_logger().error(f'no {n} subscriber(s) on joint_states after 60 s')
                return False
            self._spin(0.05)
        settle = time.monotonic() + 0.5
        while ok() and time.monotonic() < settle:
            self._spin(0.05)
        return True

    def run(self, max_ticks=None, ok=lambda: True):
        """Run in the configured mode."""
        if not self.wait_for_subscribers(ok):
            return
        if self.params.mode == 'lockstep':
            self.run_lockstep(max_ticks, ok=ok)
            # (a lockstep tick steps only on the command answering its state)
            self.node.get_logger().info(
                f'lockstep: {self.ticks} tick(s), each on the command answering its state '
                f'({self.commands_received} command(s) received)')
        else:
            stats = self.run_realtime(max_ticks, ok=ok)
            self.node.get_logger().info(
                f"realtime pacing: p50 lateness {stats['p50'] * 1e6:.0f} us, p99 "
                f"{stats['p99'] * 1e6:.0f} us, {stats['overruns']} overrun(s), "
                f'{self.sim.missed_commands} missed command(s) of {self.ticks} periods; '
                f'{self.latency_summary()}')

    def latency_summary(self):
        """The commands' latency (state published -> the command with its stamp), in words."""
        lat = np.sort(np.array(self.latencies)) * 1e3
        if lat.size:
            return (f'command latency p50 {np.percentile(lat, 50):.3f} ms, p99 '
                    f'{np.percentile(lat, 99):.3f} ms, max {lat[-1]:.3f} ms over {lat.size} '
                    'commands')
        if self.commands_received:  # e.g. from an SPG ticking on its timer: its own stamps
            return (f'{self.commands_received} commands received, none with the stamp of a '
                    'state published here (no latency)')
        return 'no command received'

    def close(self):
        """Close the simulation; the command subscription goes back to the executors."""
        if self._hot is not None:
            self._hot.close()
        self.sim.close()


def main(argv=None):
    """Entry point of the ``sim_bridge`` executable."""
    argv = list(sys.argv if argv is None else argv)
    if '-h' in argv or '--help' in argv:
        print(__doc__)
        return 0
    ros.init(args=argv)
    node = ros.Node('sim_bridge')
    try:
        bridge = SimBridge(node)
    except IfcSpgError as exc:
        print(f'sim_bridge: {exc}', file=sys.stderr)
        ros.shutdown()
        return 2
    with StopSignals() as stops:
        try:
            gc.collect()  # the model and scene live as long as the node: out of the cyclic
            gc.freeze()   # collector
            bridge.run(ok=ros.ok)
        except BaseException as exc:
            if not stops.stopped_by(exc):
                raise
            node.get_logger().info(f'sim_bridge: stopped by a signal after {bridge.ticks} '
                                   f'periods ({bridge.sim.read_time():.3f} s simulated)')
        finally:
            stops.ignore()  # stopping: a second signal must not interrupt the clean-up
            bridge.close()
            node.destroy_node()
            if ros.ok():
                ros.shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
