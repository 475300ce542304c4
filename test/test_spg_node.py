"""In-process tests of ``spg_node`` on the built-in Cyclone DDS backend (loopback, own domain):
the node and a fake robot (joint-state publisher, command/status listener) in one process."""

import json
import threading

from helpers import CONFIG, DT_NS, TARGET, parse_stack, reach_stack
import numpy as np
import pytest
from ros_testing import stamp_ns
import yaml

from ifc_spg import ros
from ifc_spg.model import RobotModel
from ifc_spg.node.config import PARAMETERS
from ifc_spg.node.spg_node import SpgNode, main
from ifc_spg.pspm import PspmConfig
from ifc_spg.ros import msg as ros_msg
from ifc_spg.spg import SetPointGenerator

pytestmark = [pytest.mark.dds, pytest.mark.ros]

STACK = reach_stack()
BAD_STACK = STACK.replace('type: joint_position', 'type: joint_positon')


class FakeRobot:
    """Publishes joint states and stacks; records commands, status documents, diagnostics."""

    def __init__(self, node, spg_node):
        self.node, self.nodes = node, (spg_node, node)
        self.commands, self.status, self.diag = [], [], []
        self.pub = node.create_publisher(ros_msg.JointState, 'joint_states', 10)
        self.stack_pub = node.create_publisher(ros_msg.String, 'spg/task_stack', ros.latched(1))
        node.create_subscription(ros_msg.JointState, 'command/joint_position',
                                 self.commands.append, 10)
        node.create_subscription(ros_msg.String, 'spg/status',
                                 lambda m: self.status.append(json.loads(m.data)), 10)
        node.create_subscription(ros_msg.DiagnosticArray, 'spg/diagnostics', self.diag.append,
                                 10)
        assert self.spin_until(lambda: self.pub.get_subscription_count() == 1 and
                               self.stack_pub.get_subscription_count() == 1)

    def spin_until(self, condition, timeout=5.0):
        return ros.spin_until(condition, timeout, nodes=self.nodes)

    def send(self, names, q, qdot, stamp_ns):
        msg = ros_msg.JointState(name=list(names), position=list(map(float, q)),
                                  velocity=list(map(float, qdot)))
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(int(stamp_ns), 10**9)
        self.pub.publish(msg)

    def tick(self, names, q, qdot, stamp_ns):
        """Send one state and return the command answering it."""
        n = len(self.commands)
        self.send(names, q, qdot, stamp_ns)
        assert self.spin_until(lambda: len(self.commands) > n), 'no command'
        assert len(self.commands) == n + 1
        return self.commands[-1]

    def events(self, kind):
        return [s['event'] for s in self.status if s.get('event', {}).get('type') == kind]

    def publish_stack(self, text, kind):
        n = len(self.events(kind))
        self.stack_pub.publish(ros_msg.String(data=text))
        assert self.spin_until(lambda: len(self.events(kind)) > n), f'no {kind} event'
        return self.events(kind)[-1]


def _start(params):
    args = ['spg_node', '--ros-args', '--params-file', str(CONFIG / 'lbr_iiwa14.yaml')]
    for p in params:
        args += ['-p', p]
    ros.init(args)
    node = ros.Node('spg_node')
    spg = SpgNode(node)
    return spg, FakeRobot(ros.Node('fake_robot'), node)


def _reference(robot, config):
    return SetPointGenerator(robot, parse_stack(STACK), dt=config.dt,
                             pspm=PspmConfig(config.pspm_initial_energy, config.pspm_max_energy),
                             solver=config.solver, rho=config.rho,
                             torque_limits=config.torque_limits)


def _closed_loop(robot, spg, ref, fake, q, ticks, k0=0, names=None):
    """Perfectly tracking robot (q <- q_v); the node's commands must equal ``ref``'s."""
    qdot = np.zeros(robot.n)
    names = list(names or robot.joint_names)
    order = [robot.joint_names.index(n) for n in names]
    for k in range(k0, k0 + ticks):
        cmd = fake.tick(names, q[order], qdot[order], k * DT_NS)
        assert stamp_ns(cmd) == k * DT_NS and list(cmd.name) == list(robot.joint_names)
        expected = ref.step(q, qdot, k * DT_NS * 1e-9)
        np.testing.assert_array_equal(cmd.position, expected)
        np.testing.assert_array_equal(cmd.velocity, ref.qdot_v)
        qdot = (np.asarray(cmd.position) - q) / spg.config.dt
        q = np.asarray(cmd.position)
    return q


def test_commands_equal_the_library_and_follow_the_stack(domain):
    spg, fake = _start(['watchdog.timeout:=0.0', 'status.decimation:=25'])
    robot = spg.runner.robot
    event = fake.publish_stack(STACK, 'stack_accepted')
    assert "'reach'" in event['message']
    ref = _reference(robot, spg.config)
    q0 = robot.q_home.copy()
    q = _closed_loop(robot, spg, ref, fake, q0, 150, names=list(reversed(robot.joint_names)))
    err0, err = np.abs(q0 - TARGET).max(), np.abs(q - TARGET).max()
    assert err < 0.35 * err0, (err0, err)  # 0.3 s with gain 5/s: exp(-1.5) = 0.22
    assert fake.spin_until(lambda: len([s for s in fake.status if 'event' not in s]) == 6)
    periodic = [s for s in fake.status if 'event' not in s]
    assert [s['tick'] for s in periodic] == [25, 50, 75, 100, 125, 150]
    last = periodic[-1]
    assert last['stack'] == {'id': 1, 'name': 'reach', 'since': 0.0,
                             'task_time': pytest.approx(149 * 0.002)}
    assert not any('config' in s for s in periodic)  # sent with the first document only
    assert fake.events('stack_accepted') and \
        [s for s in fake.status if 'event' in s][0]['config']['robot'] == 'lbr_iiwa14'
    assert [lv['name'] for lv in last['levels']] == ['torque_limits', 'posture']
    assert len(last['tank_energy']) == 7 and last['state'] == 'running'


def test_the_hot_path_commands_what_the_executor_does(domain):
    """``spin_hot`` (hot_path wait_set): joint states taken by its own loop, here in a thread,
    the stack and status on its executor; commands equal the library bit for bit."""
    spg, fake = _start(['watchdog.timeout:=0.0', 'status.decimation:=25'])
    fake.nodes = (fake.node,)  # the SPG node is the hot loop's alone
    stop = threading.Event()
    loop = threading.Thread(target=ros.spin_hot, args=(spg.node, spg.sub_states, 0.02,
                                                       stop.is_set))
    loop.start()
    try:
        fake.publish_stack(STACK, 'stack_accepted')
        robot = spg.runner.robot
        ref = _reference(robot, spg.config)
        _closed_loop(robot, spg, ref, fake, robot.q_home.copy(), 60)
        assert fake.spin_until(lambda: [s['tick'] for s in fake.status if 'event' not in s] ==
                               [25, 50])
    finally:
        stop.set()
        loop.join(5.0)
    assert not loop.is_alive()


def test_bad_stack_is_reported_with_its_field_and_the_old_one_continues(domain):
    spg, fake = _start(['watchdog.timeout:=0.0'])
    robot = spg.runner.robot
    fake.publish_stack(STACK, 'stack_accepted')
    ref = _reference(robot, spg.config)
    q = _closed_loop(robot, spg, ref, fake, robot.q_home.copy(), 20)
    event = fake.publish_stack(BAD_STACK, 'stack_rejected')
    assert 'tasks[0].type' in event['message'] and 'joint_positon' in event['message']
    _closed_loop(robot, spg, ref, fake, q, 20, k0=20)  # same commands as without it
    assert spg.runner.stack_id == 1 and fake.status[-1]['errors'][-1]['source'] == 'task_stack'


def test_bad_messages_are_counted_not_fatal(domain):
    spg, fake = _start(['watchdog.timeout:=0.0', 'status.decimation:=1'])
    names = list(spg.runner.joint_names)
    q, z = spg.runner.robot.q_home.copy(), np.zeros(7)
    first = fake.tick(names, q, z, 5 * DT_NS)
    np.testing.assert_array_equal(first.position, q)  # no stack: q_v starts at (and holds) q
    bad = [(names[:6], q[:6], z[:6], 6), (names[:6] + ['a7'], q, z, 6),
           (names[:6] + ['A1'], q, z, 6), (names, np.full(7, np.nan), z, 6),
           (names, q, z, 4)]
    for k, (n, qq, zz, stamp) in enumerate(bad):
        fake.send(n, qq, zz, stamp * DT_NS)
        cmd = fake.tick(names, q, z, (6 + k) * DT_NS)  # the next good one is answered
        assert stamp_ns(cmd) == (6 + k) * DT_NS
    again = fake.tick(names, q, z, 10 * DT_NS)  # duplicate stamp: the same answer again
    assert stamp_ns(again) == 10 * DT_NS and again.position == fake.commands[-2].position
    fake.tick(names, q, z, 11 * DT_NS)
    assert fake.spin_until(lambda: fake.status[-1]['tick'] == 7)
    status = fake.status[-1]
    assert status['rejected'] == {'wrong_count': 1, 'unknown_name': 1, 'duplicate_name': 1,
                                  'non_finite': 1, 'stamp_backwards': 1, 'duplicate_stamp': 1}
    assert spg.runner.ticks == 7
    assert any("unknown joint 'a7'" in e['message'] for e in status['errors'])
    spg.publish_diagnostics()
    assert fake.spin_until(lambda: fake.diag)
    values = {kv.key: kv.value for kv in fake.diag[-1].status[0].values}
    assert fake.diag[-1].status[0].level == ros_msg.DiagnosticStatus.WARN
    assert values['rejected.non_finite'] == '1' and values['ticks'] == '7'


def test_watchdog_stops_commanding_and_resumes_from_the_measured_q(domain):
    spg, fake = _start(['watchdog.timeout:=0.05', 'status.decimation:=1000'])
    robot = spg.runner.robot
    fake.publish_stack(STACK, 'stack_accepted')
    names, q, z = list(robot.joint_names), robot.q_home.copy(), np.zeros(7)
    for k in range(10):  # the robot does not follow: q_v runs away from q
        cmd = fake.tick(names, q, z, k * DT_NS)
    q_v = np.asarray(cmd.position)
    assert np.abs(q_v - q).max() > 1e-3
    n = len(fake.commands)
    assert fake.spin_until(lambda: fake.events('watchdog'), 2.0)
    assert 'no joint state' in fake.events('watchdog')[-1]['message']
    assert fake.spin_until(lambda: fake.diag and fake.diag[-1].status[0].level ==
                           ros_msg.DiagnosticStatus.STALE, 2.0)
    assert len(fake.commands) == n  # nothing commanded while stale
    q_new = q + 0.05  # the robot sagged meanwhile
    cmd = fake.tick(names, q_new, z, 200 * DT_NS)
    assert fake.spin_until(lambda: fake.events('resumed'))
    step = np.asarray(cmd.position) - q_new
    assert np.all(np.abs(step) <= robot.v_max * spg.config.dt + 1e-12)  # no jump
    fresh = _reference(robot, spg.config)
    np.testing.assert_allclose(cmd.position, fresh.step(q_new, z, 0.0), atol=1e-9)
    assert spg.runner.watchdog_trips >= 1 and spg.runner.resumes == 1


def test_a_paused_source_continues_then_a_stamp_jump_restarts(domain):
    """The node reports each of the runner's events: 'continued' (a paused source, continuous
    stamps) and then 'resumed' (stamps jumped) in one process (rclpy's logger wants one
    severity per call site: logging both from one line raised in the second report)."""
    spg, fake = _start(['watchdog.timeout:=0.05', 'status.decimation:=1000'])
    robot = spg.runner.robot
    fake.publish_stack(STACK, 'stack_accepted')
    names, q, z = list(robot.joint_names), robot.q_home.copy(), np.zeros(7)
    k = 0
    for episode, kind in enumerate(('continued', 'resumed', 'continued')):
        for _ in range(5):
            fake.tick(names, q, z, k * DT_NS)
            k += 1
        assert fake.spin_until(lambda e=episode: len(fake.events('watchdog')) > e, 2.0)
        if kind == 'resumed':
            k += 100  # the stamps jumped by 0.2 s > watchdog.timeout
        assert fake.tick(names, q, z, k * DT_NS) is not None
        k += 1
        want = 2 if episode == 2 else 1
        assert fake.spin_until(lambda kind=kind, want=want: len(fake.events(kind)) >= want)
    assert len(fake.events('continued')) == 2 and len(fake.events('resumed')) == 1
    assert spg.runner.resumes == 1


@pytest.mark.parametrize('param, message', [
    ('dt:=1', "'dt': value 1 has type PARAMETER_INTEGER, expected PARAMETER_DOUBLE"),
    ('dt:=0.5', "'dt': value 0.5 is outside its range"),
    ('status.decimation:=0', "'status.decimation': value 0 is outside its range"),
    ('solver:=qp', "'solver': 'qp' is not one of"),
    ('pspm.initial_enrgy:=1.0', "did you mean 'pspm.initial_energy'"),
    ('impedance.stiffness:=500.0', 'expected PARAMETER_DOUBLE_ARRAY (write a list, e.g. [500.0])'),
    ('impedance.stiffness:=[500,500]', '(write 1.0, not 1, for a double)'),
    ('impedance.stiffness:=[500.0,500.0]', 'impedance.stiffness must be > 0 (scalar or 7 values'
                                           ' for A1, A2'),
    ('impedance.damping:=[-1.0]', 'impedance.damping must be >= 0'),
    ('hot_path:=waitset', "'hot_path': 'waitset' is not one of wait_set, executor; did you "
                          "mean 'wait_set'"),
])
def test_bad_parameters_exit_2_naming_them(domain, capsys, param, message):
    assert main(['spg_node', '--ros-args', '-p', param]) == 2
    assert message in capsys.readouterr().err


def test_task_stack_file_parameter(domain, tmp_path, capsys):
    good, bad = tmp_path / 'good.yaml', tmp_path / 'bad.yaml'
    good.write_text(STACK)
    bad.write_text(BAD_STACK)
    assert main(['spg_node', '--ros-args', '-p', f'task_stack_file:={bad}']) == 2
    err = capsys.readouterr().err
    assert str(bad) in err and 'tasks[0].type' in err
    ros.init(['spg_node', '--ros-args', '-p', f'task_stack_file:={good}'])
    spg = SpgNode(ros.Node('spg_node'))
    assert spg.runner.spg.pending_stack is not None and \
        spg.runner.status()['pending_stack'] == {'id': 1, 'name': 'reach'}


def test_velocity_box_false_is_warned_at_start(domain, capfd):
    """velocity_box:=false (the Ch. 3 baseline) drops the velocity/acceleration guarantee:
    the node says so when it starts; the default does not."""
    for value, warned in (('false', True), ('true', False)):
        ros.init(['spg_node', '--ros-args', '-p', f'velocity_box:={value}'])
        node = ros.Node('spg_node')
        SpgNode(node)
        err = capfd.readouterr().err
        assert ('velocity_box is false' in err) is warned, err
        node.destroy_node()
        ros.shutdown()


def test_help_exits_0(capsys):
    assert main(['spg_node', '--help']) == 0
    assert 'watchdog.timeout' in capsys.readouterr().out


def _flatten(prefix, mapping, out):
    for key, value in mapping.items():
        name = f'{prefix}.{key}' if prefix else key
        if isinstance(value, dict):
            _flatten(name, value, out)
        else:
            out[name] = value
    return out


@pytest.mark.parametrize('robot', ['lbr_iiwa14', 'lbr4', 'icub_upper_body', 'accrea_dual_arm'])
def test_config_files_load_into_the_node(domain, robot):
    path = CONFIG / f'{robot}.yaml'
    expected = _flatten('', yaml.safe_load(path.read_text())['/**']['ros__parameters'], {})
    ros.init(['spg_node', '--ros-args', '--params-file', str(path)])
    node = ros.Node('spg_node')
    spg = SpgNode(node)
    assert spg.config.robot == robot and spg.runner.robot.name == robot
    by_name = {p.name: p.field for p in PARAMETERS}
    for name, value in expected.items():
        assert getattr(spg.config, by_name[name]) == value, name
        assert node.describe_parameter(name).description
    assert RobotModel.from_config(robot).n == len(spg.runner.joint_names)


def test_impedance_parameters_set_the_gains_the_spg_computes_with(domain):
    """impedance.stiffness / damping: the K, D of the robot's impedance controller (FRI).
    Not given, the node declares the robot configuration's own, for ``ros2 param get``."""
    spg, _ = _start([])
    default = RobotModel.from_config('lbr_iiwa14')
    assert spg.config.stiffness == () and spg.config.damping == ()
    assert spg.node.get_parameter('impedance.stiffness').value == list(default.stiffness)
    np.testing.assert_array_equal(spg.runner.robot.stiffness, default.stiffness)
    ros.shutdown()
    K = [800.0, 800.0, 600.0, 600.0, 300.0, 200.0, 100.0]
    spg, fake = _start([f'impedance.stiffness:={K}', 'impedance.damping:=[12.5]'])
    np.testing.assert_array_equal(spg.runner.robot.stiffness, K)
    np.testing.assert_array_equal(spg.runner.robot.damping, np.full(7, 12.5))
    # the SPG's robot, which the torque-limit level |K (q_v - q)| <= tau_max is built from,
    # and the energy tanks use them
    np.testing.assert_array_equal(spg.runner.spg.robot.stiffness, K)
    np.testing.assert_array_equal(spg.runner.spg.tanks.K, K)
    np.testing.assert_array_equal(spg.runner.spg.tanks.D, np.full(7, 12.5))
    # and the status (hence every bag) records what the SPG used
    fake.tick(list(default.joint_names), default.q_home, np.zeros(7), 0)
    assert fake.spin_until(lambda: any('robot_params' in st for st in fake.status))
    params = next(st['robot_params'] for st in fake.status if 'robot_params' in st)
    assert params['stiffness'] == K and params['damping'] == [12.5] * 7


def test_proxsuite_is_started_with_a_warning(domain, capfd):
    _start(['solver:=proxsuite'])  # rclpy logs from C to fd 2: capfd, not capsys
    err = capfd.readouterr().err
    assert '[WARN]' in err and 'use daqp on a robot' in err
    ros.shutdown()
    _start([])
    assert 'use daqp on a robot' not in capfd.readouterr().err


def test_live_parameters_apply_and_the_others_are_refused(domain):
    """set_parameters on the node (both backends; with rclpy also through its services, see
    test_spg_node_parameters): live ones apply from the next tick, the others are refused."""
    spg, fake = _start([])
    robot = RobotModel.from_config('lbr_iiwa14')
    results = spg.node.set_parameters([ros.Parameter('status.decimation', value=2),
                                       ros.Parameter('robot', value='lbr4'),
                                       ros.Parameter('watchdog.timeout', value=0.5)])
    assert [r.successful for r in results] == [True, False, True]
    assert "'robot' cannot change while spg_node runs" in results[1].reason
    assert spg.config.status_decimation == 2 and spg.runner.config.watchdog_timeout == 0.5
    assert spg.node.get_parameter('robot').value == 'lbr_iiwa14'
    for k in range(4):
        fake.tick(list(robot.joint_names), robot.q_home, np.zeros(7), k * DT_NS)
    assert fake.spin_until(lambda: [s['tick'] for s in fake.status if 'event' not in s] ==
                           [2, 4])


def test_disabled_node_commands_nothing_then_enables_from_the_measured_q(domain):
    """enable:=false publishes nothing; hold_when_disabled publishes the measured q; the
    latched spg/enable topic switches it on, and the first command is the measured q plus at
    most one v_max dT step (a restart), whatever the robot did meanwhile."""
    spg, fake = _start(['enable:=false'])
    fake.publish_stack(STACK, 'stack_accepted')
    robot = RobotModel.from_config('lbr_iiwa14')
    names, q = list(robot.joint_names), np.array(robot.q_home, dtype=float)
    fake.send(names, q, np.zeros(7), 0)
    fake.spin_until(lambda: False, 0.3)
    assert fake.commands == [] and spg.runner.ticks == 0
    spg.node.set_parameters([ros.Parameter('command.hold_when_disabled', value=True)])
    held = fake.tick(names, q + 0.01, np.zeros(7), DT_NS)   # the measured q, in limits
    np.testing.assert_array_equal(held.position, q + 0.01)
    assert list(held.velocity) == [0.0] * 7 and spg.runner.ticks == 0
    enable = fake.node.create_publisher(ros_msg.Bool, 'spg/enable', ros.latched(1))
    assert fake.spin_until(lambda: enable.get_subscription_count() == 1)
    enable.publish(ros_msg.Bool(data=True))
    assert fake.spin_until(lambda: spg.config.enable)
    moved = q + 0.05    # the robot was moved while disabled
    cmd = fake.tick(names, moved, np.zeros(7), 2 * DT_NS)
    step = np.abs(np.asarray(cmd.position) - moved)
    assert np.all(step <= robot.v_max * spg.config.dt + 1e-12), step
    assert spg.runner.ticks == 1
    fake.tick(names, np.asarray(cmd.position), np.zeros(7), 3 * DT_NS)
    enable.publish(ros_msg.Bool(data=False))
    assert fake.spin_until(lambda: not spg.config.enable)
    assert fake.events('disabled') or fake.spin_until(lambda: fake.events('disabled'))


@pytest.mark.parametrize('interface', ['float64_multi_array', 'joint_trajectory'])
def test_command_interfaces_carry_the_same_command_in_the_given_joint_order(domain, interface):
    robot = RobotModel.from_config('lbr_iiwa14')
    order = list(reversed(robot.joint_names))
    topic = {'float64_multi_array': 'forward_position_controller/commands',
             'joint_trajectory': 'joint_trajectory_controller/joint_trajectory'}[interface]
    spg, fake = _start([f'command.interface:={interface}', f'topics.command:={topic}',
                        f'command.joints:={order}'])
    kind = {'float64_multi_array': ros_msg.Float64MultiArray,
            'joint_trajectory': ros_msg.JointTrajectory}[interface]
    got = []
    fake.node.create_subscription(kind, topic, got.append, 100)
    fake.publish_stack(STACK, 'stack_accepted')
    ref = _reference(robot, spg.config)
    q, qdot = np.array(robot.q_home, dtype=float), np.zeros(7)
    assert fake.spin_until(lambda: spg.pub_command.get_subscription_count() >= 1)
    perm = [list(robot.joint_names).index(n) for n in order]
    for k in range(5):
        n = len(got)
        fake.send(list(robot.joint_names), q, qdot, k * DT_NS)
        assert fake.spin_until(lambda n=n: len(got) > n), 'no command'
        expected = ref.step(q, qdot, k * DT_NS * 1e-9)
        msg = got[-1]
        if interface == 'float64_multi_array':
            np.testing.assert_array_equal(msg.data, expected[perm])
        else:
            assert list(msg.joint_names) == order and len(msg.points) == 1
            point = msg.points[0]
            np.testing.assert_array_equal(point.positions, expected[perm])
            np.testing.assert_array_equal(point.velocities, ref.qdot_v[perm])
            assert (point.time_from_start.sec, point.time_from_start.nanosec) == (0, 2_000_000)
            assert stamp_ns(msg) == k * DT_NS
        qdot = (expected - q) / spg.config.dt
        q = expected


def test_command_joints_must_be_the_robots(domain, capsys):
    assert main(['spg_node', '--ros-args', '--params-file', str(CONFIG / 'lbr_iiwa14.yaml'),
                 '-p', "command.joints:=['A1', 'A2']"]) == 2
    err = capsys.readouterr().err
    assert "parameter 'command.joints'" in err


@pytest.mark.parametrize('path', sorted((CONFIG / 'real').glob('*.yaml')), ids=lambda p: p.name)
def test_real_robot_configs_start_disabled_on_a_controller_topic(domain, path):
    """config/real/*.yaml load as written, start disabled, command a ros2_control controller
    in its joint order; enabling them is a live parameter change."""
    written = yaml.safe_load(path.read_text())['/**']['ros__parameters']
    ros.init(['spg_node', '--ros-args', '--params-file', str(path)])
    spg = SpgNode(ros.Node('spg_node'))
    c = spg.config
    assert c.enable is False and c.dt == written['dt']
    assert c.command_interface == written['command']['interface'] == 'float64_multi_array'
    assert list(spg.command_joints) == written['command']['joints']
    assert c.command_topic == written['topics']['command']
    assert c.pspm_max_power == 0.0   # strictly passive until a safety engineer allows more
    [result] = spg.node.set_parameters([ros.Parameter('enable', value=True)])
    assert result.successful and spg.config.enable
