"""Named robot models: pinocchio (SPG) and MuJoCo (simulator) load the same file and agree.

References: the datasheet / docs/SPEC.md §8 numbers are written out literally here (not
imported from the tables under test); MuJoCo is the independent oracle for kinematics and inertias.
"""

import math

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from ifc_spg.cli import generate  # the command line; generate.generate is the library call
from ifc_spg.errors import ModelError, ParameterError, UnknownJoint, UnknownRobot
from ifc_spg.model import CARTESIAN_ADMITTANCE, JOINT_IMPEDANCE, RobotModel
from ifc_spg.model import registry as robots
from ifc_spg.model.registry import ROBOTS
from sim_bridge import models as mj_models
from sim_bridge.models import mjcf_spec, mujoco_indices, robot_mjcf_spec

load_robot = RobotModel.from_config

N_RANDOM = 50


@pytest.fixture(scope='module', params=ROBOTS)
def pair(request):
    """(RobotModel, MjModel, qpos addresses, dof addresses) of each named robot."""
    robot = load_robot(request.param)
    mj = robot_mjcf_spec(robot).compile()
    qadr, dadr = mujoco_indices(robot, mj)
    return robot, mj, qadr, dadr


def _mj_state(mj, qadr, q):
    data = mujoco.MjData(mj)
    data.qpos[qadr] = q
    mujoco.mj_forward(mj, data)
    return data


def _full_mass(mj, data, dadr):
    m = np.zeros((mj.nv, mj.nv))
    mujoco.mj_fullM(mj, data, m)
    return m[np.ix_(dadr, dadr)]


# -- loading, names, limits -------------------------------------------------------------------
@pytest.mark.parametrize('name, n', [('lbr4', 7), ('lbr_iiwa14', 7), ('icub_upper_body', 17),
                                     ('accrea_dual_arm', 14)])
def test_named_robot_loads(name, n):
    robot = RobotModel.from_config(name)
    assert robot.name == name and robot.n == n and robot.model.nq == n
    assert robot.model_file and robots.model_file(name) == robot.model_file
    assert np.all(robot.q_home >= robot.q_min) and np.all(robot.q_home <= robot.q_max)


@pytest.mark.parametrize('name', ['lbr4', 'lbr_iiwa14'])
def test_kuka_joint_names_and_frames(name):
    robot = load_robot(name)
    assert robot.joint_names == ('A1', 'A2', 'A3', 'A4', 'A5', 'A6', 'A7')
    assert set(robot.chains) == {'flange', 'tool'}
    assert robot.ifc == JOINT_IMPEDANCE


def _deg(*xs):
    return np.radians(np.array(xs, dtype=float))


def test_lbr4_limits_table_b1():
    robot = load_robot('lbr4')
    q = _deg(170, 120, 170, 120, 170, 105, 170)
    np.testing.assert_allclose(robot.q_max, q, atol=1e-9)
    np.testing.assert_allclose(robot.q_min, -q, atol=1e-9)
    np.testing.assert_allclose(robot.v_max, _deg(*[20] * 7), rtol=1e-12)
    np.testing.assert_allclose(robot.a_max, _deg(*[500] * 7), rtol=1e-12)
    np.testing.assert_allclose(robot.tau_max, [50] * 7, rtol=1e-12)
    np.testing.assert_allclose(robot.stiffness, [200] * 7)


def test_iiwa14_limits_datasheet():
    robot = load_robot('lbr_iiwa14')
    q = _deg(170, 120, 170, 120, 170, 120, 175)
    np.testing.assert_allclose(robot.q_max, q, atol=1e-9)
    np.testing.assert_allclose(robot.q_min, -q, atol=1e-9)
    np.testing.assert_allclose(robot.v_max, _deg(85, 85, 100, 75, 130, 135, 135), rtol=1e-12)
    np.testing.assert_allclose(robot.tau_max, [320, 320, 176, 176, 110, 40, 40], rtol=1e-12)
    assert np.all(robot.a_max > 0)


@pytest.mark.parametrize('name, offsets', [('lbr4', (0.31, 0.40, 0.39, 0.078)),
                                           ('lbr_iiwa14', (0.36, 0.42, 0.40, 0.126))])
def test_kuka_published_link_offsets(name, offsets):
    """Stretched out (q = 0): shoulder A2, elbow A4, wrist A6 and flange on the z axis."""
    robot = load_robot(name)
    data = robot.create_data()
    pin.framesForwardKinematics(robot.model, data, np.zeros(7))
    z = [data.oMi[robot.model.getJointId(j)].translation for j in ('A2', 'A4', 'A6')]
    z.append(data.oMf[robot.frame_id('flange')].translation)
    heights = np.cumsum(offsets)
    for p, h in zip(z, heights):
        np.testing.assert_allclose(p, [0, 0, h], atol=1e-12)
    tool = data.oMf[robot.frame_id('tool')].translation
    assert 0.05 <= tool[2] - heights[-1] <= 0.1


@pytest.mark.parametrize('name, total', [('lbr4', 15.0), ('lbr_iiwa14', 30.0)])
def test_kuka_total_mass_plausible(name, total):
    mj = mjcf_spec(name).compile()
    assert abs(mj.body_subtreemass[0] - total) <= 0.1 * total


@pytest.mark.parametrize('name', ['lbr4', 'lbr_iiwa14'])
def test_kuka_home_tool_down_not_singular_and_damping_rule(name):
    """Home: tool z axis down, well-conditioned Jacobian; D = 0.7 * 2 sqrt(K M_ii(q_home))."""
    robot = load_robot(name)
    data = robot.create_data()
    q = robot.q_home
    pin.framesForwardKinematics(robot.model, data, q)
    np.testing.assert_allclose(data.oMf[robot.frame_id('tool')].rotation[:, 2], [0, 0, -1],
                               atol=1e-9)
    jac = pin.computeFrameJacobian(robot.model, data, q, robot.frame_id('tool'),
                                   pin.LOCAL_WORLD_ALIGNED)
    assert np.linalg.svd(jac, compute_uv=False)[-1] > 0.05
    mass = pin.crba(robot.model, data, q)
    np.testing.assert_allclose(robot.damping, 1.4 * np.sqrt(robot.stiffness * np.diag(mass)),
                               rtol=0.05)


def test_icub_joints_frames_and_ifc_parameters():
    robot = load_robot('icub_upper_body')
    arm = ['shoulder_pitch', 'shoulder_roll', 'shoulder_yaw', 'elbow', 'wrist_prosup',
           'wrist_pitch', 'wrist_yaw']
    expected = {'torso_pitch', 'torso_roll', 'torso_yaw'} | {f'{s}_{j}' for s in 'lr'
                                                              for j in arm}
    assert set(robot.joint_names) == expected and robot.n == 17
    for chain in ('l_contact', 'r_contact', 'l_palm', 'r_palm', 'l_hand', 'r_hand'):
        robot.frame_id(chain)
    for i, j in enumerate(robot.joint_names):
        torso = j.startswith('torso')
        assert robot.stiffness[i] == (50.0 if torso else 5.0)
        assert robot.damping[i] == (0.5 if torso else 0.2)
        assert robot.stiff_mask[i] == ('wrist' in j)
    assert robot.stiff_mask.sum() == 6
    assert robot.model_file.endswith('iCubGazeboV2_7/model.urdf')
    # The URDF's own limits are kept (e.g. elbow 15..106 deg); effort/velocity replaced.
    k = robot.joint_index('l_elbow')
    assert robot.q_min[k] == pytest.approx(math.radians(15), abs=1e-6)
    assert np.all(robot.tau_max < 100) and np.all(robot.v_max < 10)


def test_icub_contact_chain_excludes_hand_joints():
    """The wrist contact point moves with the compliant joints and prosup, never the hand."""
    robot = load_robot('icub_upper_body')
    data = robot.create_data()
    q = robot.q_home
    for side in 'lr':
        jac = pin.computeFrameJacobian(robot.model, data, q, robot.frame_id(f'{side}_contact'),
                                       pin.LOCAL_WORLD_ALIGNED)
        for j in (f'{side}_wrist_pitch', f'{side}_wrist_yaw'):
            assert np.all(jac[:, robot.joint_index(j)] == 0)
        assert np.any(jac[:, robot.joint_index(f'{side}_elbow')] != 0)


def test_accrea_admittance_and_frames():
    robot = load_robot('accrea_dual_arm')
    assert robot.ifc == CARTESIAN_ADMITTANCE
    assert robot.joint_names == tuple(f'{s}_A{i}' for s in 'lr' for i in range(1, 8))
    assert set(robot.admittance) == {'l_tool', 'r_tool'}
    for adm in robot.admittance.values():
        k, d, m = adm.stiffness, adm.damping, adm.mass
        assert k.shape == d.shape == m.shape == (6,)
        # at least critically damped on its own; the defaults damp against the stiff inner
        # position loop of a rigid grasp (see robots.py), which needs more
        assert np.all(d >= 2 * np.sqrt(k * m))
    # Home: both tools in front of the torso, pointing down, mirror images of each other.
    data = robot.create_data()
    pin.framesForwardKinematics(robot.model, data, robot.q_home)
    left = data.oMf[robot.frame_id('l_tool')]
    right = data.oMf[robot.frame_id('r_tool')]
    np.testing.assert_allclose(right.translation, left.translation * [1, -1, 1], atol=1e-9)
    assert left.translation[0] > 0.3 and left.translation[1] > 0.15
    np.testing.assert_allclose(left.rotation[:, 2], [0, 0, -1], atol=1e-9)


def test_unknown_robot_did_you_mean():
    with pytest.raises(UnknownRobot, match=r"unknown robot 'lbr_iwa14'; did you mean "
                                           r"'lbr_iiwa14'\?; available: lbr4, lbr_iiwa14"):
        load_robot('lbr_iwa14')
    with pytest.raises(UnknownRobot, match="did you mean 'icub_upper_body'"):
        RobotModel.from_config('icub_upperbody')
    with pytest.raises(UnknownRobot, match='available'):
        mj_models.mjcf_spec('pr2')


def test_mujoco_indices_unknown_joint():
    robot = load_robot('lbr4')
    mj = mujoco.MjModel.from_xml_string(
        '<mujoco><worldbody><body><joint name="A9"/><geom size="0.1"/></body></worldbody>'
        '</mujoco>')
    with pytest.raises(UnknownJoint, match="joint 'A1' of robot 'lbr4'"):
        mujoco_indices(robot, mj)


# -- one file, two engines: pinocchio vs MuJoCo ------------------------------------------------
def test_generated_files_are_up_to_date():
    for fname, text in generate.generate().items():
        with open(f'{robots.DATA_DIR}/{fname}', encoding='utf-8') as f:
            assert f.read() == text, f'{fname} is stale: run python -m ifc_spg.cli.generate'
    assert generate.main(['--check']) == 0


def test_fk_matches_mujoco(pair):
    """Every chain frame: position 1e-9 m, rotation 1e-9, at seeded random configurations."""
    robot, mj, qadr, _ = pair
    data = robot.create_data()
    rng = np.random.default_rng(1234)
    worst_p = worst_r = 0.0
    for _ in range(N_RANDOM):
        q = rng.uniform(robot.q_min, robot.q_max)
        mjd = _mj_state(mj, qadr, q)
        pin.framesForwardKinematics(robot.model, data, q)
        for chain, frame in robot.frames.items():
            site = mj.site(frame).id
            pose = data.oMf[robot.frame_id(chain)]
            worst_p = max(worst_p, np.abs(pose.translation - mjd.site_xpos[site]).max())
            worst_r = max(worst_r, np.abs(pose.rotation
                                          - mjd.site_xmat[site].reshape(3, 3)).max())
    assert worst_p < 1e-9 and worst_r < 1e-9, (worst_p, worst_r)


def test_mass_matrix_and_gravity_match_mujoco(pair):
    """Inertias and armature identical on both sides: M(q) to 1e-8 relative, g(q) too."""
    robot, mj, qadr, dadr = pair
    data = robot.create_data()
    rng = np.random.default_rng(99)
    for _ in range(N_RANDOM):
        q = rng.uniform(robot.q_min, robot.q_max)
        mjd = _mj_state(mj, qadr, q)
        mass = pin.crba(robot.model, data, q)
        mass = np.triu(mass) + np.triu(mass, 1).T
        mj_mass = _full_mass(mj, mjd, dadr)
        assert np.abs(mass - mj_mass).max() <= 1e-8 * np.abs(mj_mass).max()
        grav = pin.computeGeneralizedGravity(robot.model, data, q)
        mj_grav = mjd.qfrc_bias[dadr]
        assert np.abs(grav - mj_grav).max() <= 1e-8 * max(1.0, np.abs(mj_grav).max())


def test_armature_is_in_both_mass_matrices(pair):
    robot, mj, _, dadr = pair
    np.testing.assert_allclose(robot.model.armature, mj.dof_armature[dadr], rtol=0, atol=0)


def test_mujoco_holds_home_without_warnings(pair):
    """PD + gravity compensation at home for 0.5 s: no warnings, no contacts, no drift."""
    robot, mj, qadr, dadr = pair
    mjd = _mj_state(mj, qadr, robot.q_home)
    assert mjd.ncon == 0
    for _ in range(500):
        q, qd = mjd.qpos[qadr], mjd.qvel[dadr]
        mjd.qfrc_applied[dadr] = (mjd.qfrc_bias[dadr] + 10.0 * robot.stiffness
                                  * (robot.q_home - q) - robot.damping * qd)
        mujoco.mj_step(mj, mjd)
    assert all(w.number == 0 for w in mjd.warning)
    assert np.abs(mjd.qpos[qadr] - robot.q_home).max() < 1e-3
    assert np.all(np.isfinite(mjd.qacc))


def test_robot_geoms_do_not_self_collide(pair):
    _, mj, _, _ = pair
    assert np.all(mj.geom_contype == 1) and np.all(mj.geom_conaffinity == 0)


def test_accrea_ft_sensor_reads_tool_weight():
    """Static: the wrist F/T sensor reports the weight of sensor + tool, in the sensor frame."""
    robot = load_robot('accrea_dual_arm')
    mj = mjcf_spec('accrea_dual_arm').compile()
    qadr, _ = mujoco_indices(robot, mj)
    mjd = mujoco.MjData(mj)
    mjd.qpos[qadr] = robot.q_home
    mujoco.mj_inverse(mj, mjd)  # qvel = qacc = 0: the robot held still
    tool_mass = mj.body_subtreemass[mj.body('l_tool_link').id]
    assert tool_mass > 0
    site = mj.site('l_ft').id
    rot = mjd.site_xmat[site].reshape(3, 3)
    expected = rot.T @ np.array([0.0, 0.0, tool_mass * 9.81])
    np.testing.assert_allclose(mjd.sensor('l_ft_force').data, expected, atol=1e-9)


def test_robot_model_mjcf_spec_default_and_missing_file():
    """Without a builder, robot_mjcf_spec(robot) loads model_file; without a file it raises."""
    path = robots.model_file('lbr4')
    robot = RobotModel.from_mjcf(path, name='mine', frames={'tool': 'tool'}, stiffness=100.0,
                                 damping=1.0, v_max=1.0)
    mj = robot_mjcf_spec(robot).compile()
    assert [mj.joint(i).name for i in range(mj.njnt)] == list(robot.joint_names)
    bare = RobotModel(robot.model, name='bare', frames={}, stiffness=1.0, damping=0.0,
                      v_max=1.0)
    with pytest.raises(ModelError, match="model 'bare' has no model_file"):
        robot_mjcf_spec(bare)


def test_with_gains_builds_a_validated_model_whose_compliant_gains_follow():
    """with_gains goes through the constructor: the static interaction model's compliant gains
    follow the new K/D (stiff joints stay at zero), the original is untouched, the pinocchio
    model is shared, and bad gains are refused with the joints named."""
    robot = RobotModel.from_config('icub_upper_body')
    assert np.all(robot.compliant_stiffness[robot.stiff_mask] == 0)
    other = robot.with_gains(stiffness=17.0, damping=np.full(robot.n, 0.3))
    assert other is not robot and other.model is robot.model
    np.testing.assert_array_equal(other.compliant_stiffness, np.where(robot.stiff_mask, 0, 17.0))
    np.testing.assert_array_equal(other.compliant_damping, np.where(robot.stiff_mask, 0, 0.3))
    np.testing.assert_array_equal(robot.compliant_stiffness,
                                  np.where(robot.stiff_mask, 0, robot.stiffness))
    kept = robot.with_gains(damping=0.1)
    np.testing.assert_array_equal(kept.stiffness, robot.stiffness)
    assert robot.with_gains() is robot
    for k in (0.0, -1.0, float('nan'), [1.0, 2.0]):
        with pytest.raises(ParameterError,
                           match=f'x: stiffness must be > 0 .*{robot.joint_names[0]}'):
            robot.with_gains(stiffness=k, where='x: ')
    with pytest.raises(ParameterError, match='damping must be >= 0'):
        robot.with_gains(damping=-0.1)
