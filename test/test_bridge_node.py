"""In-process tests of the sim_bridge node on the built-in Cyclone DDS backend (loopback)."""

import functools
import operator
import time

import numpy as np
import pytest

from ifc_spg import ros
from ifc_spg.errors import ParameterError
from ifc_spg.ros import msg as ros_msg
from sim_bridge.node import SimBridge, main, parse_push_frame
from sim_bridge.simulation import Simulation

pytestmark = [pytest.mark.dds, pytest.mark.ros]


def _commands(k, q0):
    return q0 + 0.05 * np.sin(0.02 * k + np.arange(len(q0)))


class EchoSpg:
    """A stand-in SPG: answers each joint state with q_v(k), stamped like the state."""

    def __init__(self, node, q0, answer=lambda k: True):
        self.node, self.q0, self.answer = node, np.asarray(q0), answer
        self.states, self.contact, self.env = [], [], []
        self.pub = node.create_publisher(ros_msg.JointState, 'command/joint_position', 10)
        node.create_subscription(ros_msg.JointState, 'joint_states', self._on_state, 10)
        node.create_subscription(ros_msg.WrenchStamped, 'sim/contact_wrench',
                                 self.contact.append, ros.qos_profile_sensor_data)
        node.create_subscription(ros_msg.JointState, 'sim/env_joint_states', self.env.append,
                                 10)

    def _on_state(self, msg):
        k = len(self.states)
        self.states.append(msg)
        if not self.answer(k):
            return
        cmd = ros_msg.JointState(name=list(msg.name),
                                  position=_commands(k, self.q0).tolist())
        cmd.header.stamp = msg.header.stamp
        self.pub.publish(cmd)


def _bridge(args):
    ros.init(['prog', '--ros-args',
              *functools.reduce(operator.iadd, (['-p', a] for a in args), [])])
    node = ros.Node('sim_bridge')
    spg_node = ros.Node('spg')
    spin = ros.executor((node, spg_node)).spin_once
    bridge = SimBridge(node, spin=spin)
    return bridge, spg_node, spin


def test_lockstep_over_dds_equals_in_process_run(domain):
    bridge, spg_node, _spin = _bridge(['robot:=lbr4', 'scene:=drawer_horizontal',
                                      'mode:=lockstep'])
    spg = EchoSpg(spg_node, bridge.sim.q0)
    assert ros.spin_until(lambda: spg.pub.get_subscription_count() == 1, 5.0,
                          nodes=(bridge.node, spg_node))
    bridge.run_lockstep(max_ticks=40)
    final = bridge.sim.read_state()
    assert bridge.ticks == 40 and final.t == pytest.approx(0.08)
    stamps = [m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec for m in spg.states[:40]]
    np.testing.assert_allclose(stamps, 0.002 * np.arange(40), atol=1e-9)
    # The same commands in process give bit-identical joint trajectories.
    ref = Simulation(robot='lbr4', scene='drawer_horizontal')
    for k in range(40):
        np.testing.assert_array_equal(spg.states[k].position, ref.read_state().q)
        ref.write_command(_commands(k, ref.q0))
        ref.step(2)
    np.testing.assert_array_equal(final.q, ref.read_state().q)
    assert final.missed_commands == 0
    assert ros.spin_until(lambda: spg.env and spg.contact, 2.0, nodes=(spg_node,))
    assert list(spg.env[0].name) == ['drawer']
    bridge.close()


def test_fri_delay_parameter_over_dds_equals_the_in_process_delayed_run(domain):
    """fri_delay:=2 reaches the emulated FRI: the lockstep run over DDS is the in-process
    run with fri_delay 2, whose first two periods still hold q0; bad values are refused."""
    bridge, spg_node, _spin = _bridge(['robot:=lbr4', 'mode:=lockstep', 'fri_delay:=2'])
    spg = EchoSpg(spg_node, bridge.sim.q0)
    assert ros.spin_until(lambda: spg.pub.get_subscription_count() == 1, 5.0,
                          nodes=(bridge.node, spg_node))
    bridge.run_lockstep(max_ticks=30)
    final = bridge.sim.read_state()
    ref = Simulation(robot='lbr4', fri_delay=2)
    for k in range(30):
        np.testing.assert_array_equal(spg.states[k].position, ref.read_state().q)
        ref.write_command(_commands(k, ref.q0))
        if k < 2:
            np.testing.assert_array_equal(ref.read_state().q_v, ref.q0)
        ref.step(2)
    np.testing.assert_array_equal(final.q, ref.read_state().q)
    np.testing.assert_array_equal(final.q_v, _commands(28, ref.q0))  # sent at 28: acts at 30
    bridge.close()
    ros.shutdown()
    with pytest.raises(ParameterError, match=r"'fri_delay': value -1 is outside its range"):
        _bridge(['fri_delay:=-1'])
    ros.shutdown()
    with pytest.raises(ParameterError, match=r"'fri_delay': value 1.5 has type "
                                             r'PARAMETER_DOUBLE, expected PARAMETER_INTEGER'):
        _bridge(['fri_delay:=1.5'])


@pytest.mark.realtime
def test_realtime_holds_q_v_and_counts_missing_commands(domain):
    bridge, spg_node, _spin = _bridge(['robot:=lbr4', 'mode:=realtime'])
    spg = EchoSpg(spg_node, bridge.sim.q0, answer=lambda k: k == 0)
    assert ros.spin_until(lambda: spg.pub.get_subscription_count() == 1, 5.0,
                          nodes=(bridge.node, spg_node))
    # until the one command has arrived (in one process: on a slow machine that took 72
    # periods), then 100 periods without one
    want = _commands(0, bridge.sim.q0)
    deadline = time.monotonic() + 10.0
    while not np.allclose(bridge.sim.read_state().q_v, want) and time.monotonic() < deadline:
        bridge.run_realtime(max_ticks=bridge.ticks + 1)
    before = bridge.sim.read_state().missed_commands
    stats = bridge.run_realtime(max_ticks=bridge.ticks + 100)
    s = bridge.sim.read_state()
    assert s.missed_commands - before >= 99  # nothing after it: held and counted
    np.testing.assert_allclose(s.q_v, want)
    # the pacer's lateness is a benchmark's business; here only that it paced (3x a period)
    assert stats['n'] == 100 and stats['p50'] < 0.006
    bridge.close()


def test_latency_summary_tells_no_command_from_unanswered_states(domain):
    bridge, _, _ = _bridge(['robot:=lbr4', 'mode:=realtime'])
    assert bridge.latency_summary() == 'no command received'
    stamp = bridge.publish_state()
    command = ros_msg.JointState(name=list(bridge.sim.joint_names),
                                 position=[float(x) for x in bridge.sim.q0])
    command.header.stamp.sec, command.header.stamp.nanosec = stamp[0], stamp[1] + 1
    bridge._on_command(command)  # not the stamp of a published state (a timer-tick SPG's)
    assert bridge.latency_summary().startswith('1 commands received, none with the stamp')
    command.header.stamp.nanosec = stamp[1]
    bridge._on_command(command)  # the answer to the state
    assert bridge.latency_summary().startswith('command latency p50')
    assert bridge.latency_summary().endswith('over 1 commands')
    bridge.close()


def test_push_topic_moves_the_tool(domain):
    bridge, spg_node, _spin = _bridge(['robot:=lbr4', 'mode:=lockstep'])
    pub = spg_node.create_publisher(ros_msg.WrenchStamped, 'sim/apply_wrench', 10)
    assert ros.spin_until(lambda: pub.get_subscription_count() == 1, 5.0,
                          nodes=(bridge.node, spg_node))
    push = ros_msg.WrenchStamped()
    push.header.frame_id = 'tool;duration=0.1'
    push.wrench.force.z = 20.0
    pub.publish(push)
    assert ros.spin_until(lambda: bridge.pending_pushes, 5.0, nodes=(bridge.node, spg_node))
    bridge.apply_inputs()
    z0 = bridge.sim.chain_pose('tool')[0][2]
    bridge.sim.step(101)
    assert bridge.sim.chain_pose('tool')[0][2] > z0 + 1e-3
    assert bridge.sim.active_pushes == () and not bridge.sim.data.xfrc_applied.any()  # expired
    bridge.close()


def test_push_frame_and_parameter_errors(domain):
    assert parse_push_frame('handle;duration=2', 'tool', 0.5) == ('handle', 2.0)
    assert parse_push_frame('', 'tool', 0.5) == ('tool', 0.5)
    with pytest.raises(ParameterError, match='duration'):
        parse_push_frame('tool;duration=abc', 'tool', 0.5)
    with pytest.raises(ParameterError, match="mode 'fast'"):
        _bridge(['mode:=fast'])


def test_a_bad_hot_path_is_named_with_the_fix(domain):
    with pytest.raises(ParameterError, match="hot_path 'wait-set' is not one of wait_set, "
                                             "executor; did you mean 'wait_set'"):
        _bridge(['hot_path:=wait-set'])


def test_main_help_and_bad_parameter_exit_code(domain, capsys):
    assert main(['sim_bridge', '--help']) == 0
    assert 'lockstep' in capsys.readouterr().out
    assert main(['sim_bridge', '--ros-args', '-p', 'scene:=tabel']) == 2
    assert "did you mean 'table'" in capsys.readouterr().err



def _impedance_torque(bridge, dq, qd):
    """The emulated controller's actuator torque at q_v = q + dq, q_v's rate 0, qdot = qd."""
    sim = bridge.sim
    sim.reset()
    q = sim.read_state().q
    sim.data.qvel[sim.dof_index] = qd
    sim.write_command(q + dq)
    sim.step(1)
    return sim.data.actuator_force[sim.actuator_ids].copy()


def test_stiffness_and_damping_parameters_set_the_emulated_impedance(domain):
    """The bridge's stiffness / damping parameters reach the physics: the torque of the
    emulated FRI joint impedance is K (q_v - q) - D qdot (one 1 ms step after the
    command, so q and qdot have barely moved)."""
    K = np.array([300.0, 300.0, 250.0, 250.0, 120.0, 80.0, 40.0])
    dq, qd = np.full(7, 1e-3), np.linspace(-0.2, 0.2, 7)
    bridge, _, _ = _bridge([f'stiffness:={K.tolist()}', 'damping:=[7.5]', 'mode:=lockstep'])
    tau = _impedance_torque(bridge, dq, qd)
    bridge.close()
    ros.shutdown()
    np.testing.assert_allclose(tau, K * dq - 7.5 * qd, rtol=0.05, atol=0.02)
    bridge, _, _ = _bridge(['mode:=lockstep'])  # not given: the robot configuration's
    robot = bridge.sim.robot
    tau = _impedance_torque(bridge, dq, qd)
    bridge.close()
    ros.shutdown()
    np.testing.assert_allclose(tau, robot.stiffness * dq - robot.damping * qd, rtol=0.05,
                               atol=0.02)
    with pytest.raises(ParameterError, match='stiffness must be one number or 7 numbers'):
        _bridge(['stiffness:=[1.0, 2.0]'])


def test_zero_damping_is_a_setting_not_the_default(domain):
    """damping:=[0.0] asks for an undamped controller; only the robot's own gains (the
    declared default) mean 'not set'."""
    dq, qd = np.zeros(7), np.linspace(-0.2, 0.2, 7)
    bridge, _, _ = _bridge(['damping:=[0.0]', 'mode:=lockstep'])
    assert bridge.node.get_parameter('stiffness').value == list(bridge.sim.robot.stiffness)
    tau = _impedance_torque(bridge, dq, qd)
    bridge.close()
    ros.shutdown()
    np.testing.assert_allclose(tau, 0.0, atol=0.02)
