"""Tests of the MuJoCo bridge's IFC emulations against statics computed with pinocchio."""

import numpy as np
import pinocchio as pin
import pytest

from ifc_spg.errors import ParameterError, UnknownFrame
from ifc_spg.model.robot_model import CartesianAdmittance, RobotModel
from sim_bridge.interface import FakeInterface
from sim_bridge.simulation import Simulation


def _jacobian(model, q, chain):
    """6 x n frame Jacobian (linear; angular) in the base frame, from pinocchio."""
    data = model.create_data()
    return pin.computeFrameJacobian(model.model, data, np.asarray(q), model.frame_id(chain),
                                    pin.LOCAL_WORLD_ALIGNED)


def _settle(sim, q_v, seconds):
    for _ in range(round(seconds / 0.002)):
        sim.write_command(q_v)
        sim.step(2)
    return sim.read_state()


def test_lbr_static_deflection_matches_inverse_stiffness_times_jt_f():
    """docs/SPEC.md §1: a constant wrench f at the tool gives q_v − q = K⁻¹Jᵀf_robot (5 %)."""
    sim = Simulation(robot='lbr_iiwa14', scene='free')
    q_v = sim.q0.copy()
    f_push = np.array([6.0, -4.0, 9.0, 0.3, -0.2, 0.1])  # environment on robot
    sim.apply_wrench('tool', f_push)
    s = _settle(sim, q_v, 6.0)
    assert not sim.warnings()
    assert np.abs(s.qd).max() < 1e-4
    jac = _jacobian(sim.robot, s.q, 'tool')
    k = np.asarray(sim.robot.stiffness)
    expected = (jac.T @ -f_push) / k  # f_robot = -f_push: what the robot exerts
    got = q_v - s.q
    assert np.linalg.norm(got - expected) <= 0.05 * np.linalg.norm(expected)
    # The FRI-like external torque estimate sees J^T f, the measured torque holds it.
    np.testing.assert_allclose(s.tau_ext_est, jac.T @ f_push, atol=0.02 * np.abs(
        jac.T @ f_push).max())


def test_lbr_without_wrench_converges_to_q_v():
    sim = Simulation(robot='lbr_iiwa14', scene='free')
    q_v = sim.q0 + np.radians([5, -5, 5, 5, -5, 5, 5])
    s = _settle(sim, q_v, 5.0)
    assert np.abs(q_v - s.q).max() < 1e-4
    assert np.linalg.norm(s.tau_ext_est) < 1e-6
    assert not sim.warnings()


def test_lbr_measured_torque_is_spring_damper_plus_compensation():
    """B.1: τ = K(q_v − q) − D q̇ + g(q) + C(q, q̇)q̇, the compensation from pinocchio's RNEA."""
    k, d = 300.0, 5.0
    sim = Simulation(robot='lbr4', scene='free', stiffness=k, damping=d)
    q_v = sim.q0 + 0.05
    sim.write_command(q_v)
    sim.step(20)
    q, qd = sim.read_state().q, sim.read_state().qd  # the state the next step starts from
    sim.step(1)
    s = sim.read_state()
    model = sim.robot
    comp = pin.rnea(model.model, model.create_data(), q, qd, np.zeros(7))
    expected = k * (q_v - q) - d * qd + comp
    np.testing.assert_allclose(s.tau_measured, expected, rtol=1e-6, atol=1e-6)


def test_lockstep_free_space_run_is_bit_identical():
    def run():
        sim = Simulation(robot='lbr_iiwa14', scene='free')
        traj = []
        for k in range(500):
            t = 0.002 * k
            sim.write_command(sim.q0 + 0.2 * np.sin(2 * np.pi * 0.5 * t + np.arange(7)))
            sim.step(2)
            traj.append(sim.read_state().q)
        return np.array(traj)

    a, b = run(), run()
    assert np.array_equal(a, b)
    assert np.ptp(a, axis=0).min() > 0.01


def test_missing_commands_hold_q_v_and_are_counted():
    sim = Simulation(robot='lbr_iiwa14', scene='free')
    q_v = sim.q0 + 0.01
    sim.write_command(q_v)
    sim.step(2)
    assert sim.read_state().missed_commands == 0
    sim.step(6)  # three command periods without a command
    s = sim.read_state()
    assert s.missed_commands == 3
    np.testing.assert_array_equal(s.q_v, q_v)


def _sent(sim, k):
    """A distinct q_v per command period k."""
    return sim.q0 + 0.05 * np.sin(0.1 * k + np.arange(7))


@pytest.mark.parametrize('n', [0, 1, 3])
def test_fri_delay_applies_the_sent_commands_n_periods_later(n):
    """Lockstep (write at the period's start, then step): the q_v acting during period k
    (the actuators' ctrl, and State.q_v) is the one sent at period k - n (q0 before)."""
    sim = Simulation(robot='lbr4', scene='free', fri_delay=n)
    sent, applied, reported = [], [], []
    for k in range(12):
        sent.append(_sent(sim, k))
        sim.write_command(sent[-1])
        applied.append(sim.data.ctrl[sim.actuator_index].copy())
        reported.append(sim.read_state().q_v)
        sim.step(1)
        np.testing.assert_array_equal(sim.data.ctrl[sim.actuator_index], applied[-1])
        sim.step(1)
    expected = [sim.q0] * n + sent[:len(sent) - n]
    np.testing.assert_array_equal(applied, expected)
    np.testing.assert_array_equal(reported, expected)
    assert sim.read_state().missed_commands == 0


def test_fri_delay_equals_the_undelayed_run_of_the_shifted_commands():
    """The delay changes nothing but when a command acts: fri_delay 2 with commands c_k is
    bit for bit fri_delay 0 with c_(k-2); fri_delay 0 is the default."""
    def run(n, shift):
        sim = Simulation(robot='lbr4', scene='free', **({'fri_delay': n} if n else {}))
        q = []
        for k in range(150):
            sim.write_command(_sent(sim, k - shift) if k >= shift else sim.q0)
            sim.step(2)
            q.append(sim.read_state().q)
        return np.array(q)

    delayed = run(2, 0)
    assert np.array_equal(delayed, run(0, 2))
    assert not np.array_equal(delayed, run(0, 0))
    sim = Simulation(robot='lbr4', scene='free', fri_delay=1)
    sim.step(1)  # mid-period: the command counts from the next boundary (step 2), acts at 4
    sim.write_command(sim.q0 + 0.01)
    sim.step(2)
    np.testing.assert_array_equal(sim.read_state().q_v, sim.q0)
    sim.step(1)
    np.testing.assert_array_equal(sim.read_state().q_v, sim.q0 + 0.01)


def test_fri_delay_errors_name_the_value_and_fix():
    for bad in (-1, 1.5, True, '1'):
        with pytest.raises(ParameterError, match=r'fri_delay must be a whole number of FRI '
                                                 r'periods >= 0.*got'):
            Simulation(robot='lbr4', scene='free', fri_delay=bad)
    with pytest.raises(ParameterError, match="fri_delay is a parameter of the 'lbr_fri' "
                                             "interface, not 'icub'"):
        Simulation(robot='icub_upper_body', scene='free', fri_delay=1)


def test_admittance_static_pose_offset_matches_inverse_cartesian_stiffness():
    """ACCREA (2.22): a constant tool force f gives x − x_d = K_x⁻¹ f (5 %)."""
    k_x = np.array([500.0, 500.0, 500.0, 50.0, 50.0, 50.0])
    m_x = np.array([10.0, 10.0, 10.0, 0.5, 0.5, 0.5])
    adm = CartesianAdmittance(stiffness=k_x, damping=2 * np.sqrt(k_x * m_x), mass=m_x)
    sim = Simulation(robot='accrea_dual_arm', scene='free',
                     admittance={'l_tool': adm, 'r_tool': adm})
    p_d, _r_d = sim.chain_pose('l_tool')
    p_r, _ = sim.chain_pose('r_tool')
    f = np.array([4.0, -3.0, 5.0])
    sim.apply_wrench('l_tool', np.r_[f, 0.0, 0.0, 0.0])
    s = _settle(sim, sim.q0, 3.0)
    p, _r = sim.chain_pose('l_tool')
    expected = f / k_x[:3]
    assert np.linalg.norm(p - p_d - expected) <= 0.05 * np.linalg.norm(expected)
    # The sensor (tool weight compensated) reads the push, the right arm does not move.
    np.testing.assert_allclose(s.ft_external['l_tool'][:3], f, atol=0.05)
    assert np.linalg.norm(sim.chain_pose('r_tool')[0] - p_r) < 1e-4
    assert not sim.warnings()


def test_admittance_force_following_with_zero_stiffness():
    """K_x = 0 (2.23): a constant force gives the velocity f / D_x."""
    m_x = np.full(6, 10.0)
    d_x = np.full(6, 100.0)
    adm = CartesianAdmittance(stiffness=np.zeros(6), damping=d_x, mass=m_x)
    sim = Simulation(robot='accrea_dual_arm', scene='free', admittance={'l_tool': adm})
    f = np.array([0.0, 3.0, 0.0])
    sim.apply_wrench('l_tool', np.r_[f, 0.0, 0.0, 0.0])
    _settle(sim, sim.q0, 1.0)
    p1 = sim.chain_pose('l_tool')[0]
    _settle(sim, sim.q0, 0.5)
    v = (sim.chain_pose('l_tool')[0] - p1) / 0.5
    np.testing.assert_allclose(v, f / d_x[:3], atol=0.05 * np.linalg.norm(f / d_x[:3]))


def test_icub_wrists_track_while_compliant_joints_deflect_per_k():
    sim = Simulation(robot='icub_upper_body', scene='free')
    robot = sim.robot
    q_v = sim.q0.copy()
    f = np.array([0.0, 0.0, -2.0, 0.0, 0.0, 0.0])  # 2 N down on the left palm
    sim.apply_wrench('l_palm', f)
    s = _settle(sim, q_v, 4.0)
    assert not sim.warnings()
    stiff = np.asarray(robot.stiff_mask)
    assert np.abs(q_v - s.q)[stiff].max() < 1e-3
    jac = _jacobian(robot, s.q, 'l_palm')
    expected = (jac.T @ -f) / np.asarray(robot.stiffness)
    got = (q_v - s.q)[~stiff]
    assert np.linalg.norm(got - expected[~stiff]) <= 0.05 * np.linalg.norm(expected[~stiff])
    assert np.abs(got).max() > 0.01  # the compliant joints really deflect


def test_icub_tau_offset_input():
    sim = Simulation(robot='icub_upper_body', scene='free')
    sim.write_command(sim.q0, tau_offset=np.zeros(len(sim.joint_names)))
    s = _settle(sim, sim.q0, 0.2)  # gravity no longer compensated: the arms sag
    assert np.abs(s.q - sim.q0).max() > 0.01
    with pytest.raises(ParameterError, match='icub'):
        Simulation(robot='lbr4').write_command(np.zeros(7), tau_offset=np.zeros(7))


def test_contact_wrench_matches_joint_space_statics_on_table():
    """Ground-truth tool contact wrench: Jᵀ(f_contact + f_push) = −K(q_v − q) at rest."""
    sim = Simulation(robot='lbr_iiwa14', scene='table')
    push = np.array([0.0, 0.0, -30.0, 0.0, 0.0, 0.0])
    sim.apply_wrench('tool', push)
    s = _settle(sim, sim.q0, 3.0)
    assert s.contact_wrench[2] > 5.0  # the table pushes the tool up
    jac = _jacobian(sim.robot, s.q, 'tool')
    lhs = jac.T @ (s.contact_wrench + push)
    rhs = -np.asarray(sim.robot.stiffness) * (s.q_v - s.q)
    np.testing.assert_allclose(lhs, rhs, atol=0.02 * np.abs(rhs).max())
    np.testing.assert_allclose(s.tau_ext_est, lhs, atol=0.02 * np.abs(rhs).max())


def test_errors_name_the_bad_value_and_choices():
    with pytest.raises(ParameterError, match="unknown interface 'lbr'.*lbr_fri"):
        Simulation(robot='lbr4', interface='lbr')
    with pytest.raises(ParameterError, match='timestep'):
        Simulation(robot='lbr4', timestep=0.002)
    with pytest.raises(ParameterError, match="'accrea' needs"):
        Simulation(robot='lbr4', interface='accrea')
    sim = Simulation(robot='lbr4')
    with pytest.raises(ParameterError, match='q_v must have 7'):
        sim.write_command(np.zeros(6))
    with pytest.raises(UnknownFrame, match="did you mean 'tool'"):
        sim.apply_wrench('tool9', np.zeros(6))
    sim.close()
    with pytest.raises(ParameterError, match='closed'):
        sim.read_state()


def test_fake_interface_follows_commands():
    fake = FakeInterface(['a', 'b'], stiffness=100.0)
    fake.write_command([0.1, -0.2])
    fake.step(2000)
    s = fake.read_state()
    np.testing.assert_allclose(s.q, [0.1, -0.2], atol=1e-6)
    assert s.t == pytest.approx(2.0)
    with pytest.raises(ParameterError):
        fake.write_command([0.0])


def test_inline_mjcf_model(tmp_path):
    """A tiny inline arm through RobotModel.from_mjcf: gravity is compensated exactly."""
    xml = """
<mujoco model="arm2">
  <compiler angle="radian"/>
  <worldbody>
    <body name="l1" pos="0 0 0.1">
      <inertial pos="0.15 0 0" mass="1" diaginertia="0.01 0.01 0.01"/>
      <joint name="j1" axis="0 1 0" range="-3 3"/>
      <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03"/>
      <body name="l2" pos="0.3 0 0">
        <inertial pos="0.1 0 0" mass="0.5" diaginertia="0.005 0.005 0.005"/>
        <joint name="j2" axis="0 1 0" range="-3 3"/>
        <geom type="capsule" fromto="0 0 0 0.2 0 0" size="0.02"/>
        <site name="tip" pos="0.2 0 0"/>
      </body>
    </body>
  </worldbody>
</mujoco>"""
    path = tmp_path / 'arm2.xml'
    path.write_text(xml)
    model = RobotModel.from_mjcf(str(path), name='arm2', frames={'tool': 'tip'},
                                 stiffness=50.0, damping=1.0, v_max=2.0, tau_max=50.0)
    sim = Simulation(robot=model, scene='free', q0=[0.3, -0.5])
    s = _settle(sim, sim.q0, 1.0)
    np.testing.assert_allclose(s.q, sim.q0, atol=1e-9)
    f = np.array([0.0, 0.0, 2.0, 0.0, 0.0, 0.0])
    sim.apply_wrench('tool', f)
    s = _settle(sim, sim.q0, 4.0)
    expected = _jacobian(model, s.q, 'tool').T @ -f / 50.0
    np.testing.assert_allclose(sim.q0 - s.q, expected, rtol=0.01, atol=1e-6)
