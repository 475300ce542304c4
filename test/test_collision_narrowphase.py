"""The C++ narrowphase (ifc_spg/kernels/_coal_native.cpp) against pinocchio's Python bindings
(ifc_spg.geometry.narrowphase): the same pairs, distances, witness points and rows over seeded
random configurations of the iiwa (self pairs, obstacles of every shape), the ACCREA dual arm
and the iCub (convex hulls of its URDF meshes); the level in one call (Pairs.level) against its
steps; the fallback where the module is absent, and a stale or mismatched build refused."""

import importlib
import os
import types

import numpy as np
import pinocchio as pin
import pytest

from ifc_spg import RobotModel, SetPointGenerator, TaskStack
from ifc_spg.geometry import CollisionGeometry, Obstacle, PairQuery, narrowphase, rpy_matrix
from ifc_spg.kernels import reference as ref

try:
    compiled = importlib.import_module('ifc_spg.kernels._coal_native')
except ImportError:  # test_the_module_is_built says so
    compiled = None
needs_module = pytest.mark.skipif(compiled is None, reason='_coal_native not built')

OBSTACLES = (
    Obstacle('ball', 'sphere', (0.06,), position=(0.45, 0.1, 0.6)),
    Obstacle('crate', 'box', (0.2, 0.1, 0.3), position=(0.3, -0.35, 0.5),
             rotation=tuple(map(tuple, rpy_matrix((0.3, -0.2, 0.5))))),
    Obstacle('bar', 'capsule', (0.03, 0.4), position=(0.0, 0.45, 0.7),
             rotation=tuple(map(tuple, rpy_matrix((1.2, 0.0, 0.3))))),
    Obstacle('post', 'cylinder', (0.05, 0.8), position=(-0.4, -0.2, 0.4)),
    Obstacle('floor', 'plane', (), position=(0.0, 0.0, -0.05)),
    Obstacle('held', 'sphere', (0.02,), frame='tool', position=(0.0, 0.0, 0.05)),
)
CONFIGS = 150
TOL = 1e-9  # [m]


def _queries(geometry, pairs, monkeypatch):
    """Two queries of the same pairs: on the C++ module and on pinocchio's bindings."""
    with monkeypatch.context() as m:
        m.setattr(narrowphase, 'native', compiled)
        fast = PairQuery(geometry, pairs)
        m.setattr(narrowphase, 'native', None)
        slow = PairQuery(geometry, pairs)
    return fast, slow


@pytest.fixture(scope='module')
def iiwa():
    robot = RobotModel.from_config('lbr_iiwa14')
    geometry = CollisionGeometry(robot, OBSTACLES)
    pairs = geometry.self_pairs() + [(a, b) for b in geometry.obstacles.values()
                                     for link in ('link3', 'link4', 'link5', 'link6', 'link7')
                                     for a in geometry.link_shapes(link)
                                     if geometry.parent_joint[a] != geometry.parent_joint[b]]
    return geometry, pairs


@pytest.fixture(scope='module')
def accrea():
    geometry = CollisionGeometry(RobotModel.from_config('accrea_dual_arm'))
    return geometry, geometry.self_pairs()


@pytest.fixture(scope='module')
def icub():
    geometry = CollisionGeometry(RobotModel.from_config('icub_upper_body'))
    return geometry, geometry.self_pairs()


def _compare(geometry, pairs, monkeypatch, seed):
    """Largest differences over CONFIGS random configurations, with and without the cull."""
    fast, slow = _queries(geometry, pairs, monkeypatch)
    assert fast._narrow is not fast._pin and slow._narrow is slow._pin
    robot = geometry.robot
    model, data = robot.model, robot.create_data()
    rng = np.random.default_rng(seed)
    worst = {'distance': 0.0, 'points': 0.0, 'rows': 0.0}
    counted = {'exact': 0, 'within': 0}
    for _ in range(CONFIGS):
        q = rng.uniform(model.lowerPositionLimit, model.upperPositionLimit)
        pin.computeJointJacobians(model, data, q)
        for influence in (np.inf, 0.1):
            a, b = fast.compute(data, influence), slow.compute(data, influence)
            np.testing.assert_array_equal(a.exact, b.exact)
            np.testing.assert_array_equal(fast.within, slow.within)
            w = fast.within
            ex = a.exact
            worst['distance'] = max(worst['distance'],
                                    float(np.abs(a.distance[ex] - b.distance[ex]).max(initial=0)))
            worst['points'] = max(worst['points'],
                                  float(np.abs(a.point_a[w] - b.point_a[w]).max(initial=0)),
                                  float(np.abs(a.point_b[w] - b.point_b[w]).max(initial=0)))
            worst['rows'] = max(worst['rows'], float(np.abs(a.rows - b.rows).max()))
            # nothing outside the pairs within is written
            assert np.isnan(a.point_a[np.setdiff1d(np.arange(len(pairs)), w)]).all()
            counted['exact'] += int(ex.sum())
            counted['within'] += w.size
        np.testing.assert_allclose(fast.lower_bounds(data), slow.lower_bounds(data), rtol=0,
                                   atol=TOL)
    print(f'{robot.name}: {len(pairs)} pairs, {CONFIGS} configurations: {counted}; largest '
          f'differences {worst}')
    assert counted['within'] > CONFIGS  # the comparison saw witness points
    assert worst['distance'] <= TOL and worst['points'] <= TOL and worst['rows'] <= 1e-8


@needs_module
def test_iiwa_with_obstacles_of_every_shape_matches_the_bindings(iiwa, monkeypatch):
    _compare(*iiwa, monkeypatch, seed=1)


@needs_module
def test_accrea_dual_arm_matches_the_bindings(accrea, monkeypatch):
    _compare(*accrea, monkeypatch, seed=2)


@needs_module
def test_icub_convex_hulls_match_the_bindings(icub, monkeypatch):
    _compare(*icub, monkeypatch, seed=3)


@needs_module
def test_moved_obstacles_and_the_cull_across_calls_match(iiwa, monkeypatch):
    """Obstacles moved at run time (move_shape) and the cull across calls (q given)."""
    geometry, pairs = iiwa
    fast, slow = _queries(geometry, pairs, monkeypatch)
    robot = geometry.robot
    data = robot.create_data()
    rng = np.random.default_rng(4)
    q = np.array(robot.q_home)
    for k in range(CONFIGS):
        q = np.clip(q + rng.normal(scale=0.02, size=robot.n), robot.model.lowerPositionLimit,
                    robot.model.upperPositionLimit)
        if k % 10 == 0:
            placement = pin.SE3(rpy_matrix(rng.uniform(-1, 1, 3)), rng.uniform(-0.6, 0.6, 3))
            for query in (fast, slow):
                query.move_shape(geometry.obstacles['ball'], placement)
        pin.computeJointJacobians(robot.model, data, q)
        a, b = fast.compute(data, 0.1, q=q), slow.compute(data, 0.1, q=q)
        np.testing.assert_array_equal(fast.within, slow.within)
        np.testing.assert_allclose(a.distance, b.distance, rtol=0, atol=TOL)
        np.testing.assert_allclose(a.rows, b.rows, rtol=0, atol=1e-8)
        np.testing.assert_allclose(fast.distances_only(data), slow.distances_only(data),
                                   rtol=0, atol=TOL)


def test_the_module_is_built():
    """./run setup builds it (cmeel-eigen in requirements.lock); IFC_SPG_NATIVE=0 opts out."""
    assert compiled is not None, narrowphase.describe()
    if os.environ.get('IFC_SPG_NATIVE', '1').strip() == '0':
        assert narrowphase.native is None and 'IFC_SPG_NATIVE=0' in narrowphase.describe()
    else:
        assert narrowphase.native is compiled, narrowphase.describe()
        assert narrowphase.describe().startswith('C++ on coal')


def _stack(robot):
    return TaskStack.from_dict({
        'version': 1, 'name': 'fallback', 'robot': robot.name,
        'obstacles': [{'name': 'ball', 'shape': 'sphere', 'radius': 0.06,
                       'position': [0.5, 0.25, 0.55]}],
        'tasks': [{'name': 'avoid', 'type': 'collision_avoidance',
                   'pairs': ['self', {'links': ['link5', 'link6', 'link7'],
                                      'obstacles': ['ball']}]},
                  {'name': 'reach', 'type': 'cartesian_pose', 'frame': 'tool',
                   'subspace': ['x', 'y', 'z'], 'equal': [0.5, 0.25, 0.55]},
                  {'name': 'posture', 'type': 'joint_position', 'equal': 'init'}]})


def test_without_the_module_the_bindings_run_the_level(monkeypatch):
    """The module absent (an install without a C++ compiler or Eigen): describe() says so,
    the queries use pinocchio's bindings and the SPG runs the level."""
    real = importlib.import_module

    def no_module(name, *args):
        if name == 'ifc_spg.kernels._coal_native':
            raise ImportError(f'No module named {name!r}')
        return real(name, *args)

    monkeypatch.setattr(importlib, 'import_module', no_module)
    monkeypatch.setattr(narrowphase, 'refused', '')
    monkeypatch.delenv('IFC_SPG_NATIVE', raising=False)
    assert narrowphase._load() is None
    monkeypatch.setattr(narrowphase, 'native', None)
    assert 'was not built' in narrowphase.describe()
    assert narrowphase.describe().startswith("pinocchio's Python bindings")
    robot = RobotModel.from_config('lbr_iiwa14')
    spg = SetPointGenerator(robot, _stack(robot), dt=0.002)
    q, qdot = np.array(robot.q_home), np.zeros(robot.n)
    for k in range(100):
        q = spg.step(q, qdot, k * 0.002)
        qdot = spg.qdot_v.copy()
    task = spg.tasks[0]
    assert isinstance(task.query._narrow, narrowphase.PinocchioPairs)
    assert spg.info.status == 'ok' and task.last is not None and task.last.exact.any()


@pytest.mark.parametrize('attr, value', [('API', narrowphase.API + 1),
                                         ('API', None),
                                         ('COAL_VERSION', '2.4.5'),
                                         ('PINOCCHIO_VERSION', '3.0.0')])
def test_a_stale_or_mismatched_build_is_refused(monkeypatch, attr, value):
    """Another API (a build from an older _coal_native.cpp) or another coal or pinocchio
    than the ones imported (its C++ objects would not be theirs): not used, and why."""
    import coal

    fake = types.ModuleType('ifc_spg.kernels._coal_native')
    fake.API, fake.COAL_VERSION = narrowphase.API, coal.__version__
    fake.PINOCCHIO_VERSION = pin.__version__
    monkeypatch.setattr(importlib, 'import_module', lambda name, *args: fake)
    monkeypatch.setattr(narrowphase, 'refused', '')
    monkeypatch.delenv('IFC_SPG_NATIVE', raising=False)
    assert narrowphase._load() is fake and narrowphase.refused == ''
    if value is None:
        delattr(fake, attr)
    else:
        setattr(fake, attr, value)
    assert narrowphase._load() is None
    assert 'stale or mismatched build' in narrowphase.refused
    monkeypatch.setattr(narrowphase, 'native', None)
    assert 'rebuild it' in narrowphase.describe()


@needs_module
def test_bad_arguments_are_refused(iiwa):
    geometry, pairs = iiwa
    objs = geometry.model.geometryObjects
    args = ([o.geometry for o in objs], np.array([o.parentJoint for o in objs]),
            np.array([o.placement.rotation for o in objs]),
            np.array([o.placement.translation for o in objs]), geometry.radius,
            np.array(pairs), 1e-9)
    with pytest.raises(TypeError, match='not a coal shape'):
        compiled.Pairs(['ball', *args[0][1:]], *args[1:])
    with pytest.raises(ValueError, match='is not two shapes'):
        compiled.Pairs(*args[:5], np.array([[0, 0]]), 1e-9)
    native = compiled.Pairs(*args)
    m = len(pairs)
    out = np.empty(m)
    with pytest.raises(TypeError, match='pinocchio Data'):
        native.distances(types.SimpleNamespace(oMi=[]), out)
    data = geometry.robot.create_data()
    pin.forwardKinematics(geometry.robot.model, data, np.array(geometry.robot.q_home))
    with pytest.raises(ValueError, match='writeable C-contiguous float64'):
        native.distances(data, np.empty(m + 1))
    scratch = [np.empty(m), np.empty((m, 3)), np.empty((m, 3)), np.empty((m, 3))]
    with pytest.raises(IndexError):
        native.narrowphase(data, np.array([m]), 0.1, 1e-6, *scratch)
    n = geometry.robot.n
    pin.computeJointJacobians(geometry.robot.model, data, np.array(geometry.robot.q_home))
    state = [np.zeros(m), np.zeros((m, n)), np.zeros(n), np.zeros((m, n)), np.zeros((m, n)),
             np.zeros((m, 3))]
    native.level(data, data.J, np.zeros(n), 0.1, 1e-6, 1.0, 0.01, 4, *state)  # (fits)
    with pytest.raises(ValueError, match='lever must be a C-contiguous float64 array'):
        native.level(data, data.J, np.zeros(n), 0.1, 1e-6, 1.0, 0.01, 4, state[0],
                     np.zeros((m, n + 1)), *state[2:])
    with pytest.raises(ValueError, match='last_q must be a writeable'):
        native.level(data, data.J, np.zeros(n), 0.1, 1e-6, 1.0, 0.01, 4, *state[:2],
                     np.zeros(n)[::-1], *state[3:])
    with pytest.raises(ValueError, match='J must have 6 rows'):
        native.level(data, data.J[:3], np.zeros(n), 0.1, 1e-6, 1.0, 0.01, 4, *state)
    with pytest.raises(ValueError, match='R must be >= 0'):
        native.level(data, data.J, np.zeros(n), 0.1, 1e-6, 1.0, 0.01, -1, *state)


@needs_module
@pytest.mark.parametrize('R', [24, 3])
def test_the_level_in_one_call_matches_its_steps_and_the_bindings(iiwa, monkeypatch, R):
    """PairQuery.level in one C++ call (Pairs.level) against the same steps one by one
    (compute on the C++ narrowphase, then the C kernel collision_level: the same arithmetic,
    so equal to the last bit) and against pinocchio's bindings, over a walk with the cull
    across calls and an obstacle moved every 10 steps; R = 3 rows cuts the level short."""
    geometry, pairs = iiwa
    fast, slow = _queries(geometry, pairs, monkeypatch)
    with monkeypatch.context() as m:
        m.setattr(narrowphase, 'native', compiled)
        steps = PairQuery(geometry, pairs)
    steps._fused = None
    assert fast._fused is not None and slow._fused is None
    robot = geometry.robot
    data = robot.create_data()
    rng = np.random.default_rng(7)
    q = np.array(robot.q_home)
    rows_seen = cut = 0
    for k in range(CONFIGS):
        q = np.clip(q + rng.normal(scale=0.03, size=robot.n), robot.model.lowerPositionLimit,
                    robot.model.upperPositionLimit)
        if k % 10 == 5:
            placement = pin.SE3(rpy_matrix(rng.uniform(-1, 1, 3)), rng.uniform(-0.5, 0.5, 3))
            for query in (fast, steps, slow):
                query.move_shape(geometry.obstacles['ball'], placement)
        pin.computeJointJacobians(robot.model, data, q)
        a, b, c = (query.level(data, 0.1, q, 2.0, 0.01, R) for query in (fast, steps, slow))
        for x, y in zip(a[0], b[0]):  # Distances: bitwise (NaN where NaN)
            np.testing.assert_array_equal(x, y)
        for x, y in zip(a[1:], b[1:]):  # the pairs of the rows, A, lower
            np.testing.assert_array_equal(x, y)
        np.testing.assert_array_equal(fast.within, steps.within)
        np.testing.assert_array_equal(fast.within, slow.within)
        np.testing.assert_array_equal(a[1], c[1])
        np.testing.assert_allclose(a[0].distance, c[0].distance, rtol=0, atol=TOL)
        np.testing.assert_allclose(a[2], c[2], rtol=0, atol=1e-8)
        np.testing.assert_allclose(a[3], c[3], rtol=0, atol=TOL)
        rows_seen += min(a[1].size, R)
        cut += a[1].size > R
    print(f'R = {R}: {rows_seen} rows over {CONFIGS} steps, {cut} steps with more pairs than R')
    assert rows_seen > CONFIGS  # the comparison saw rows
    if R == 3:
        assert cut  # and the level cut short


def test_collision_rows_take_points_already_written():
    """found None: the points are in point_a and point_b already (the narrowphase wrote
    them); the same rows and normals as with the list, C and numpy."""
    from ifc_spg import kernels

    rng = np.random.default_rng(9)
    m, n = 47, 7
    J = np.asfortranarray(rng.normal(size=(6, n)))
    within = np.sort(rng.choice(m, size=15, replace=False))
    found = list(rng.normal(size=(2 * within.size, 3)))
    dist = np.full(m, 0.5)
    dist[within] = np.linalg.norm(np.array(found[1::2]) - np.array(found[0::2]), axis=1)
    dist[within[:3]] = 0.0  # touching: coal's normal kept
    mask_a = (rng.random((m, n)) < 0.5).astype(float)
    mask_b = (rng.random((m, n)) < 0.5).astype(float)
    normal0 = rng.normal(size=(m, 3))
    out = []
    for kern in [ref] + ([kernels.native] if kernels.native is not None else []):
        for points in (found, None):
            pa, pb = np.full((m, 3), np.nan), np.full((m, 3), np.nan)
            if points is None:
                pa[within], pb[within] = found[0::2], found[1::2]
            normal, rows = normal0.copy(), np.zeros((m, n))
            kern.collision_rows(J, within, points, pa, pb, dist, normal, mask_a, mask_b, 1e-6,
                                rows)
            out.append((normal, rows, pa, pb))
    for got in out[1:]:
        for x, y in zip(got, out[0]):
            np.testing.assert_allclose(x, y, rtol=0, atol=1e-12)
