"""Tests of the programmatic scenes: stability, mechanism parameters, break-away latches."""

import numpy as np
import pytest

from ifc_spg.errors import ParameterError
from ifc_spg.model.robot_model import CartesianAdmittance
from sim_bridge.scenes import scene_names
from sim_bridge.simulation import Simulation

MECHANISMS = ('drawer_horizontal', 'drawer_vertical', 'crank', 'cupboard_door',
              'microwave_door')


def _hold(sim, seconds):
    q_v = sim.q0.copy()
    for _ in range(round(seconds / 0.002)):
        sim.write_command(q_v)
        sim.step(2)
    return sim.read_state()


#: options a scene needs (the others run with their defaults)
NEEDS = {'obstacles': {'obstacles': [{'name': 'ball', 'shape': 'sphere', 'radius': 0.05,
                                      'position': [0.5, 0.5, 0.5]}]}}


@pytest.mark.parametrize('scene', scene_names())
def test_scene_steps_10_s_without_warnings(scene):
    sim = Simulation(robot='lbr_iiwa14', scene=scene, scene_options=NEEDS.get(scene, {}))
    s = _hold(sim, 10.0)
    assert sim.warnings() == {}
    assert np.all(np.isfinite(s.q))
    assert np.abs(s.q - sim.q0).max() < 0.01  # the grasp does not drag the robot around
    assert len(s.env_q) == (1 if scene in MECHANISMS else 0)


@pytest.mark.parametrize('scene', ['drawer_horizontal', 'crank', 'cupboard_door'])
def test_accrea_grasp_is_stable_with_heavy_admittance(scene):
    k_x = np.array([500.0, 500.0, 500.0, 50.0, 50.0, 50.0])
    m_x = np.array([10.0, 10.0, 10.0, 0.5, 0.5, 0.5])
    adm = CartesianAdmittance(stiffness=k_x, damping=2 * np.sqrt(k_x * m_x), mass=m_x)
    sim = Simulation(robot='accrea_dual_arm', scene=scene,
                     admittance={'l_tool': adm, 'r_tool': adm})
    s = _hold(sim, 2.0)
    assert sim.warnings() == {}
    assert np.abs(s.contact_wrench).max() < 2.0


def test_mechanism_parameters():
    sim = Simulation(robot='lbr_iiwa14', scene='drawer_vertical')
    m = sim.model
    assert m.body_subtreemass[m.body('drawer').id] == pytest.approx(1.2)
    np.testing.assert_allclose(m.jnt_range[m.joint('drawer').id], [0.0, 0.3])
    np.testing.assert_allclose(sim.data.site('handle').xpos, sim.chain_pose('tool')[0],
                               atol=1e-9)
    sim = Simulation(robot='lbr4', scene='crank')
    m, d = sim.model, sim.data
    j = m.joint('crank').id
    axis = d.xaxis[j]
    r = d.site('handle').xpos - d.xanchor[j]
    assert np.linalg.norm(r - axis * (r @ axis)) == pytest.approx(0.17)


def test_drawer_reports_env_joint_state_and_stops_at_travel():
    sim = Simulation(robot='lbr_iiwa14', scene='drawer_horizontal',
                     scene_options={'grasp': 'none'})
    sim.apply_wrench('handle', [-4.0, 0, 0, 0, 0, 0], duration=3.0)  # pull towards robot
    s = _hold(sim, 0.3)
    assert 0.01 < s.env_q[0] < 0.3 and s.env_qd[0] > 0
    s = _hold(sim, 2.7)
    assert s.env_q[0] == pytest.approx(0.3, abs=0.005)
    assert s.env_joint_names == ('drawer',)


@pytest.mark.parametrize('scene, force', [('cupboard_door', 20.0), ('microwave_door', 15.0)])
def test_door_needs_break_away_force(scene, force):
    """A slowly ramped pull on the handle: the door moves only once f >= break-away."""
    sim = Simulation(robot='lbr_iiwa14', scene=scene, scene_options={'grasp': 'none'})
    rate = 5.0  # N/s
    onset = None
    for k in range(int(1.6 * force / rate / 0.002)):
        f = rate * 0.002 * (k + 1)
        sim.clear_wrenches()
        sim.apply_wrench('handle', [-f, 0, 0, 0, 0, 0])
        sim.write_command(sim.q0)
        sim.step(2)
        if sim.read_state().env_q[0] > 0.01:
            onset = f
            break
    assert onset is not None, 'the door never opened'
    assert force <= onset <= 1.1 * force
    s = _hold(sim, 0.5)
    assert s.env_q[0] > 0.1  # no noteworthy resistance once released
    assert sim.warnings() == {}


def test_unknown_scene_and_option_are_rejected_with_choices():
    with pytest.raises(ParameterError, match="did you mean 'table'.*available"):
        Simulation(robot='lbr4', scene='tabel')
    with pytest.raises(ParameterError, match="no option 'solrf'.*did you mean 'solref'"):
        Simulation(robot='lbr4', scene='table', scene_options={'solrf': (0.01, 1)})
    with pytest.raises(ParameterError, match='grasp must be one of'):
        Simulation(robot='lbr4', scene='crank', scene_options={'grasp': 'glue'})


def test_table_stiffness_option_changes_penetration():
    def depth(solref):
        sim = Simulation(robot='lbr_iiwa14', scene='table', scene_options={'solref': solref})
        sim.apply_wrench('tool', [0, 0, -40.0, 0, 0, 0])
        _hold(sim, 1.5)
        return sim.chain_pose('tool')[0][2]

    soft, stiff = depth((0.1, 1.0)), depth((0.005, 1.0))
    assert soft < stiff - 3e-4


def test_table_obstacle_stands_on_the_table_ahead_of_the_tool():
    opts = {'gap': 0.005, 'obstacle_offset': (0.0, 0.08), 'obstacle_size': (0.05, 0.02, 0.02)}
    sim = Simulation(robot='lbr4', scene='table', scene_options=opts)
    m, d = sim.model, sim.data
    tool = sim.chain_pose('tool')[0]
    top = d.geom('table_top').xpos[2] + m.geom('table_top').size[2]
    box = d.geom('table_obstacle').xpos
    np.testing.assert_allclose(top, tool[2] - 0.005, atol=1e-9)
    np.testing.assert_allclose(box, [tool[0], tool[1] + 0.08, top + 0.02], atol=1e-9)
    np.testing.assert_allclose(m.geom('table_obstacle').size, [0.05, 0.02, 0.02])
    # pushed along +y the tool is stopped by the obstacle's face (y + 0.06, tip radius 1 cm);
    # without the obstacle the same push carries it further
    def pushed(options):
        s = Simulation(robot='lbr4', scene='table', scene_options=options)
        s.apply_wrench('tool', [0, 30.0, 0, 0, 0, 0], duration=2.0)
        st = _hold(s, 2.0)
        return s.chain_pose('tool')[0][1] - tool[1], st.contact_wrench
    y_blocked, w = pushed(opts)
    y_free, _ = pushed({'gap': 0.005})
    assert 0.045 < y_blocked < 0.052
    assert w[1] < -5.0  # the obstacle pushes back along -y (the joint springs carry the rest)
    assert y_free > y_blocked + 0.02


def test_table_offset_and_obstacle_options_are_checked():
    sim = Simulation(robot='lbr4', scene='table', scene_options={'offset': (0.1, -0.05)})
    tool = sim.chain_pose('tool')[0]
    np.testing.assert_allclose(sim.data.geom('table_top').xpos[:2], tool[:2] + [0.1, -0.05],
                               atol=1e-9)
    with pytest.raises(ParameterError, match='inside the box'):
        Simulation(robot='lbr4', scene='table', scene_options={'obstacle_offset': (0.0, 0.01)})
    with pytest.raises(ParameterError, match='obstacle_size'):
        Simulation(robot='lbr4', scene='table',
                   scene_options={'obstacle_offset': (0.0, 0.1), 'obstacle_size': (0.1, 0.1)})
    with pytest.raises(ParameterError, match='obstacle_offset must be'):
        Simulation(robot='lbr4', scene='table', scene_options={'obstacle_offset': 0.1})


def test_icub_table_placement_of_table_3_7_touches_only_the_left_hand():
    """The Table 3.7 table at the scenario's q0: 2 mm below the left forearm's wiping pad
    (the closest robot geom), the fingers and everything else > 1 cm above it."""
    import mujoco

    from ifc_spg.offline.runner import find_config_dir, load_scenario

    sc = load_scenario(find_config_dir() / 'scenarios' /
                       'thesis_3_7_icub_wiping_cup_holding.yaml')
    sim = Simulation(robot='icub_upper_body', scene='table', scene_options=sc.scene_options,
                     q0=sc.q0, contact_chain='l_contact')
    m, d = sim.model, sim.data
    table = m.geom('table_top').id
    pad = m.geom('l_wipe_pad').id
    # distance of every robot geom to the table top at q0
    near = {}
    for g in range(m.ngeom):
        if m.geom_bodyid[g] in (m.body('table').id, 0):
            continue
        dist = mujoco.mj_geomDistance(m, d, g, table, 0.05, None)
        if dist < 0.05:
            near[m.geom(g).name or m.body(m.geom_bodyid[g]).name] = dist
    assert abs(near.pop('l_wipe_pad') - 0.002) < 5e-4
    assert all(dist > 0.01 for dist in near.values()), near
    assert m.geom_bodyid[pad] == m.site('l_contact').bodyid[0]  # on the chain's last link


def test_drawer_breakaway_latch_holds_below_and_releases_above_its_force():
    """``breakaway=20``: a steady 10 N pull does not move the drawer, 30 N does."""
    def pulled(f, seconds=1.0):
        sim = Simulation(robot='lbr_iiwa14', scene='drawer_horizontal',
                         scene_options={'grasp': 'none', 'breakaway': 20.0})
        assert [la.force for la in sim.scene.latches] == [20.0]
        sim.apply_wrench('handle', [-f, 0, 0, 0, 0, 0])
        s = _hold(sim, seconds)
        assert sim.warnings() == {}
        return s.env_q[0]

    assert abs(pulled(10.0)) < 1e-3
    assert pulled(30.0) > 0.05
    # no latch by default: 10 N moves it
    sim = Simulation(robot='lbr_iiwa14', scene='drawer_horizontal',
                     scene_options={'grasp': 'none'})
    assert sim.scene.latches == ()
    sim.apply_wrench('handle', [-10.0, 0, 0, 0, 0, 0])
    assert _hold(sim, 1.0).env_q[0] > 0.05
    with pytest.raises(ParameterError, match='breakaway must be a force >= 0 N'):
        Simulation(robot='lbr4', scene='drawer_vertical', scene_options={'breakaway': -1.0})


def test_obstacles_scene_holds_the_stacks_obstacles_where_the_stack_has_them():
    """Every shape of the stack's obstacles in the MuJoCo world: MuJoCo's distances from the
    robot's geoms to them are coal's on the stack's own geometry (sizes, poses, rpy)."""
    import mujoco
    import pinocchio as pin

    from ifc_spg import RobotModel, TaskStack
    from ifc_spg.geometry import PairQuery

    obstacles = [
        {'name': 'ball', 'shape': 'sphere', 'radius': 0.06, 'position': [0.45, 0.1, 0.6]},
        {'name': 'crate', 'shape': 'box', 'size': [0.2, 0.1, 0.3], 'position': [0.3, -0.35, 0.5],
         'rpy': [0.3, -0.2, 0.5]},
        {'name': 'bar', 'shape': 'capsule', 'radius': 0.03, 'length': 0.4,
         'position': [0.0, 0.45, 0.7], 'rpy': [1.2, 0.0, 0.3]},
        {'name': 'post', 'shape': 'cylinder', 'radius': 0.05, 'length': 0.8,
         'position': [-0.4, -0.2, 0.4], 'rpy': [0.0, 0.4, 0.0]},
    ]
    robot = RobotModel.from_config('lbr_iiwa14')
    stack = TaskStack.from_dict({
        'version': 1, 'name': 's', 'robot': 'lbr_iiwa14', 'obstacles': obstacles,
        'tasks': [{'name': 'avoid', 'type': 'collision_avoidance',
                   'pairs': [{'links': 'all', 'obstacles': [o['name'] for o in obstacles]}]}]})
    task = stack.build(robot)[0]
    query = PairQuery(task.geometry, task.pairs)
    sim = Simulation(robot='lbr_iiwa14', scene='obstacles',
                     scene_options={'obstacles': obstacles})
    m, d = sim.model, mujoco.MjData(sim.model)
    gid = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, name.removeprefix('obstacle:'))
           for name in (task.geometry.shape_name(i) for i in range(len(task.geometry.robot_geoms)
                                                                     + len(obstacles)))]
    assert min(gid) >= 0
    rng = np.random.default_rng(3)
    data = robot.create_data()
    checked = worst = 0.0
    for _ in range(10):
        q = rng.uniform(robot.q_min, robot.q_max)
        pin.forwardKinematics(robot.model, data, q)
        ours = query.distances_only(data)
        d.qpos[:robot.n] = q
        mujoco.mj_kinematics(m, d)
        for k, (a, b) in enumerate(query.pairs):
            ref = mujoco.mj_geomDistance(m, d, gid[a], gid[b], 10.0, None)
            if ref > 1e-3 and ours[k] > 1e-3:
                worst = max(worst, abs(ref - ours[k]))
                checked += 1
    assert checked > 100 and worst < 5e-4, (checked, worst)


def test_obstacles_scene_refuses_bad_obstacles_naming_the_field():
    with pytest.raises(ParameterError, match=r"scene 'obstacles': obstacles\[0\]\.radius: sizes"):
        Simulation(robot='lbr_iiwa14', scene='obstacles', scene_options={
            'obstacles': [{'name': 'ball', 'shape': 'sphere', 'radius': -0.1}]})
    with pytest.raises(ParameterError, match="fixed to frame 'tool'"):
        Simulation(robot='lbr_iiwa14', scene='obstacles', scene_options={
            'obstacles': [{'name': 'held', 'shape': 'sphere', 'radius': 0.02, 'frame': 'tool'}]})
    with pytest.raises(ParameterError, match='non-empty list'):
        Simulation(robot='lbr_iiwa14', scene='obstacles')
    with pytest.raises(ParameterError, match=r"obstacles\[0\]\.shape: .*did you mean 'sphere'"):
        Simulation(robot='lbr_iiwa14', scene='obstacles', scene_options={
            'obstacles': [{'name': 'ball', 'shape': 'spher', 'radius': 0.02}]})
    with pytest.raises(ParameterError, match=r'obstacles\[0\]\.length: a sphere has no length'):
        Simulation(robot='lbr_iiwa14', scene='obstacles', scene_options={
            'obstacles': [{'name': 'ball', 'shape': 'sphere', 'radius': 0.02, 'length': 1.0}]})
    with pytest.raises(ParameterError, match=r'obstacles\[0\]\.position: finite'):
        Simulation(robot='lbr_iiwa14', scene='obstacles', scene_options={
            'obstacles': [{'name': 'ball', 'shape': 'sphere', 'radius': 0.02,
                           'position': [0.0, float('nan'), 0.0]}]})
