"""Collision geometry (ifc_spg.geometry): coal distances against MuJoCo's own, rows against
finite differences, the cull against the exact distances, and bad obstacles."""

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from ifc_spg import RobotModel
from ifc_spg.errors import ParameterError
from ifc_spg.geometry import CollisionGeometry, Obstacle, PairQuery, rpy_matrix
from sim_bridge.models import mujoco_indices, robot_mjcf_spec

OBSTACLES = (
    Obstacle('ball', 'sphere', (0.06,), position=(0.45, 0.1, 0.6)),
    Obstacle('crate', 'box', (0.2, 0.1, 0.3), position=(0.3, -0.35, 0.5),
             rotation=tuple(map(tuple, rpy_matrix((0.3, -0.2, 0.5))))),
    Obstacle('bar', 'capsule', (0.03, 0.4), position=(0.0, 0.45, 0.7),
             rotation=tuple(map(tuple, rpy_matrix((1.2, 0.0, 0.3))))),
    Obstacle('post', 'cylinder', (0.05, 0.8), position=(-0.4, -0.2, 0.4)),
    Obstacle('held', 'sphere', (0.02,), frame='tool', position=(0.0, 0.0, 0.05)),
)
MJ_TYPE = {'sphere': mujoco.mjtGeom.mjGEOM_SPHERE, 'box': mujoco.mjtGeom.mjGEOM_BOX,
           'capsule': mujoco.mjtGeom.mjGEOM_CAPSULE,
           'cylinder': mujoco.mjtGeom.mjGEOM_CYLINDER}


def _mj_size(obs):
    s = obs.size
    if obs.shape == 'box':
        return [x / 2 for x in s]
    if obs.shape in ('capsule', 'cylinder'):
        return [s[0], s[1] / 2, 0.0]
    return [s[0], 0.0, 0.0]


def _mujoco(robot, obstacles):
    """The robot's MJCF in MuJoCo with the obstacles added as geoms (the independent side)."""
    spec = robot_mjcf_spec(robot)
    for obs in obstacles:
        quat = pin.Quaternion(np.array(obs.rotation)).coeffs()  # x y z w
        if obs.frame == 'base':
            parent = spec.worldbody
        else:
            parent = spec.site(obs.frame).parent
            site = spec.site(obs.frame)
            M = pin.SE3(_site_rot(site), np.array(site.pos)) * obs.placement()
            quat = pin.Quaternion(M.rotation).coeffs()
            parent.add_geom(name=f'obstacle:{obs.name}', type=MJ_TYPE[obs.shape],
                            size=_mj_size(obs), pos=list(M.translation),
                            quat=[quat[3], quat[0], quat[1], quat[2]])
            continue
        parent.add_geom(name=f'obstacle:{obs.name}', type=MJ_TYPE[obs.shape],
                        size=_mj_size(obs), pos=list(obs.position),
                        quat=[quat[3], quat[0], quat[1], quat[2]])
    m = spec.compile()
    return m, mujoco.MjData(m)


def _site_rot(site):
    w, x, y, z = site.quat
    return pin.Quaternion(w, x, y, z).matrix()


def _random_q(robot, rng):
    return rng.uniform(robot.q_min, robot.q_max)


@pytest.fixture(scope='module', params=['lbr_iiwa14', 'accrea_dual_arm'])
def setup(request):
    robot = RobotModel.from_config(request.param)
    obstacles = OBSTACLES if request.param == 'lbr_iiwa14' else OBSTACLES[:4]
    geometry = CollisionGeometry(robot, obstacles)
    pairs = geometry.self_pairs()
    robot_links = sorted(geometry.bodies)
    for name in geometry.obstacles:
        for link in robot_links:
            for a in geometry.link_shapes(link):
                if name != 'held' or link not in ('link7',):
                    pairs.append((a, geometry.obstacle_shape(name)))
    return robot, geometry, obstacles, PairQuery(geometry, pairs)


def test_distances_match_mujoco(setup):
    robot, geometry, obstacles, query = setup
    m, d = _mujoco(robot, obstacles)
    qpos, _ = mujoco_indices(robot, m)
    names = [geometry.shape_name(i) for i in range(len(geometry.model.geometryObjects))]
    gid = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, nm) for nm in names]
    assert min(gid) >= 0
    rng = np.random.default_rng(7)
    data = robot.create_data()
    checked = worst = 0
    for _ in range(15):
        q = _random_q(robot, rng)
        pin.computeJointJacobians(robot.model, data, q)
        res = query.compute(data)
        d.qpos[qpos] = q
        mujoco.mj_kinematics(m, d)
        fromto = np.zeros(6)
        for k, (a, b) in enumerate(query.pairs):
            ref = mujoco.mj_geomDistance(m, d, gid[a], gid[b], 10.0, fromto)
            if ref > 1e-3 and res.distance[k] > 1e-3:
                worst = max(worst, abs(ref - res.distance[k]))
                checked += 1
                # the witness points are on the shapes MuJoCo sees
                assert np.linalg.norm(res.point_b[k] - res.point_a[k]) == pytest.approx(
                    res.distance[k], abs=1e-6)
            elif min(ref, res.distance[k]) < -1e-3:  # both see the overlap
                assert max(ref, res.distance[k]) < 2e-3, (names[a], names[b], ref)
    assert checked > 100
    assert worst < 5e-4


def test_rows_match_finite_differences(setup):
    robot, geometry, obstacles, query = setup
    rng = np.random.default_rng(11)
    data = robot.create_data()
    data2 = robot.create_data()
    eps = 1e-5
    checked = 0
    for _ in range(8):
        q = _random_q(robot, rng)
        pin.computeJointJacobians(robot.model, data, q)
        res = query.compute(data)
        fd = np.zeros_like(res.rows)
        for i in range(robot.n):
            dq = np.zeros(robot.n)
            dq[i] = eps
            pin.forwardKinematics(robot.model, data2, q + dq)
            up = query.distances_only(data2)
            pin.forwardKinematics(robot.model, data2, q - dq)
            fd[:, i] = (up - query.distances_only(data2)) / (2 * eps)
        ok = res.distance > 5e-3
        err = np.abs(fd[ok] - res.rows[ok]).max(axis=1)
        scale = 1.0 + np.abs(fd[ok]).max(axis=1)
        # non-smooth points (parallel faces, witness sets not unique) are rare: allow 2 %
        bad = np.count_nonzero(err > 1e-4 * scale)
        assert bad <= 0.02 * ok.sum(), (bad, ok.sum(), err.max())
        checked += ok.sum()
    assert checked > 100


def test_cull_is_a_lower_bound(setup):
    robot, geometry, obstacles, query = setup
    rng = np.random.default_rng(3)
    data = robot.create_data()
    for _ in range(20):
        q = _random_q(robot, rng)
        pin.computeJointJacobians(robot.model, data, q)
        exact = query.compute(data)
        assert exact.exact.all()
        bound = query.lower_bounds(data)
        assert np.all(bound <= exact.distance + 1e-9)
        culled = query.compute(data, influence=0.1)
        near = culled.exact
        np.testing.assert_allclose(culled.distance[near], exact.distance[near], atol=1e-9)
        assert np.all(culled.rows[~near] == 0)
        # every pair within the influence distance is computed
        assert np.all(near[exact.distance <= 0.1])


def test_plane_distance_is_height_above_it():
    robot = RobotModel.from_config('lbr_iiwa14')
    geometry = CollisionGeometry(robot, [Obstacle('table', 'plane', position=(0, 0, 0.2))])
    tip = geometry.link_shapes('tool_tip')[0]
    query = PairQuery(geometry, [(tip, geometry.obstacle_shape('table'))])
    rng = np.random.default_rng(5)
    data = robot.create_data()
    fid = robot.model.getFrameId('tool')
    for _ in range(20):
        q = _random_q(robot, rng)
        pin.computeJointJacobians(robot.model, data, q)
        pin.updateFramePlacements(robot.model, data)
        res = query.compute(data, influence=0.5)
        tool = data.oMf[fid]  # the tip sphere (r = 1 cm) is centered 1 cm behind 'tool'
        z = (tool.translation - 0.01 * tool.rotation[:, 2])[2]
        assert res.distance[0] == pytest.approx(z - 0.2 - 0.01, abs=1e-6)


def test_self_pairs_exclude_fixed_adjacent_and_touching():
    robot = RobotModel.from_config('lbr_iiwa14')
    geometry = CollisionGeometry(robot)
    pairs = {tuple(sorted((geometry.shape_name(a), geometry.shape_name(b))))
             for a, b in geometry.self_pairs()}
    excluded = {tuple(sorted(e[:2])): e[2] for e in geometry.excluded}
    assert ('link7_geom', 'tool_tip') in excluded and 'same joint' in excluded[
        ('link7_geom', 'tool_tip')]
    assert 'adjacent' in excluded[('link1_geom', 'link2_geom')]
    assert not pairs & set(excluded)
    n = len(geometry.robot_geoms)
    assert len(pairs) + len(excluded) == n * (n - 1) // 2
    data = robot.create_data()
    pin.forwardKinematics(robot.model, data, robot.q_home)
    query = PairQuery(geometry, geometry.self_pairs())
    assert np.all(query.distances_only(data) > 0)


@pytest.mark.parametrize('kw, field', [
    ({'shape': 'sphere', 'size': (float('nan'),)}, 'size'),
    ({'shape': 'sphere', 'size': (0.0,)}, 'size'),
    ({'shape': 'box', 'size': (0.1, 0.1)}, 'size'),
    ({'shape': 'cylinder', 'size': (0.1, -1.0)}, 'size'),
    ({'shape': 'sphere', 'size': (0.1,), 'position': (0, float('inf'), 0)}, 'position'),
    ({'shape': 'spere', 'size': (0.1,)}, "did you mean 'sphere'"),
])
def test_bad_obstacles(kw, field):
    with pytest.raises(ParameterError, match=field):
        Obstacle('x', **kw)


def test_unknown_names_suggest():
    geometry = CollisionGeometry(RobotModel.from_config('lbr_iiwa14'),
                                 [Obstacle('ball', 'sphere', (0.05,))])
    with pytest.raises(ParameterError, match="did you mean 'link5'"):
        geometry.link_shapes('lnk5')
    with pytest.raises(ParameterError, match="did you mean 'ball'"):
        geometry.obstacle_shape('bal')


def test_cull_across_calls_keeps_every_pair_within_influence(setup):
    """The motion bound (last distances minus lever x |dq|) along a random walk with jumps."""
    robot, geometry, obstacles, query = setup
    coherent = PairQuery(geometry, query.pairs)
    rng = np.random.default_rng(8)
    data = robot.create_data()
    q = robot.q_home.copy()
    skipped = rows_differ = rows_total = 0
    for k in range(300):
        step = rng.normal(0, 0.5 if k % 50 == 49 else 0.01, robot.n)  # a jump now and then
        q = np.clip(q + step, robot.q_min, robot.q_max)
        pin.computeJointJacobians(robot.model, data, q)
        exact = query.compute(data)
        res = coherent.compute(data, 0.1, q=q)
        assert np.all(res.distance <= exact.distance + 1e-7)  # GJK: 1e-9 m tolerance
        within = exact.distance <= 0.1
        assert np.all(res.exact[within])
        np.testing.assert_allclose(res.distance[within], exact.distance[within], atol=1e-7)
        # witness points of parallel faces are not unique (GJK warm starts differ): both
        # rows are valid; they differ on a few pairs only
        differ = np.abs(res.rows[within] - exact.rows[within]).max(axis=1) > 1e-5
        rows_differ += np.count_nonzero(differ)
        rows_total += np.count_nonzero(within)
        skipped += np.count_nonzero(~res.exact)
    assert skipped > 0  # the bound does cull
    assert rows_differ <= 0.03 * rows_total, (rows_differ, rows_total)


def _point_row(robot, data, joint, p, n):
    """n^T J(p) of point p fixed to joint's body: J_lin - [p - o_joint]_x J_ang (LWA)."""
    if joint == 0:
        return np.zeros(robot.n)
    J = pin.getJointJacobian(robot.model, data, joint, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
    r = p - data.oMi[joint].translation
    return n @ (J[:3] - pin.skew(r) @ J[3:])


def test_rows_match_point_jacobians_with_either_kernels(setup):
    """The rows (C kernel and numpy reference alike) are n^T (J_b(p_b) - J_a(p_a)) with each
    witness point's Jacobian from its joint's, over many random configurations, to 1e-9."""
    from ifc_spg import kernels

    robot, geometry, obstacles, query = setup
    queries = [PairQuery(geometry, query.pairs, kernels=k)
               for k in (kernels.reference, kernels.native) if k is not None]
    rng = np.random.default_rng(5)
    data = robot.create_data()
    checked = 0
    for _ in range(150):
        q = _random_q(robot, rng)
        pin.computeJointJacobians(robot.model, data, q)
        results = [qu.compute(data, 0.1) for qu in queries]
        res = results[0]
        for other in results[1:]:
            np.testing.assert_array_equal(other.distance, res.distance)
            np.testing.assert_array_equal(other.point_a, res.point_a)
            np.testing.assert_allclose(other.rows, res.rows, rtol=0, atol=1e-12)
        for k in np.flatnonzero(res.exact & (res.distance <= 0.1)):
            a, b = query.pairs[k]
            pa, pb, d = res.point_a[k], res.point_b[k], res.distance[k]
            if d <= 1e-6:
                continue  # coal's normal: checked by the finite differences
            n = (pb - pa) / d
            ja, jb = int(geometry.parent_joint[a]), int(geometry.parent_joint[b])
            row = _point_row(robot, data, jb, pb, n) - _point_row(robot, data, ja, pa, n)
            np.testing.assert_allclose(res.rows[k], row, rtol=0, atol=1e-9)
            checked += 1
        far = ~(res.exact & (res.distance <= 0.1))
        assert not res.rows[far].any() and np.isnan(res.point_a[far]).all()
    assert checked > 200
