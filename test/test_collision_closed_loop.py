"""Collision avoidance in closed loop: seeded random targets behind random obstacles.

The virtual robot (the SPG's q_v) must never come closer than margin - 1 mm to a listed
obstacle or link, at any tick, while a Cartesian target pulls the tool through the
obstacle; without the avoidance level the same runs collide. Distances are checked with
the exact (uncut) coal distances of every listed pair, validated against MuJoCo in
test_collision_geometry.py. Most runs use a tracking plant (q = q_v: the SPG alone); a few
run the MuJoCo robot (the FRI emulation under joint impedance) in lockstep.
"""

import os

import coal
import mujoco
import numpy as np
import pinocchio as pin
from plants import JointImpedancePlant
import pytest

from ifc_spg import RobotModel, SetPointGenerator, TaskStack
from ifc_spg.geometry import CollisionGeometry, PairQuery
from ifc_spg.pspm import PspmConfig
from ifc_spg.task_stack.collision import ObstacleSpec

INFLUENCE = 0.13  # the largest influence distance drawn
DT = 0.002
SHAPES = ('sphere', 'box', 'capsule', 'cylinder')


@pytest.fixture(scope='module')
def iiwa():
    return RobotModel.from_config('lbr_iiwa14')


def _tool(robot, data, q):
    pin.framesForwardKinematics(robot.model, data, q)
    return data.oMf[robot.model.getFrameId('tool')].translation.copy()


def _obstacle(rng, center):
    shape = SHAPES[rng.integers(len(SHAPES))]
    o = {'name': 'obs', 'shape': shape, 'position': [float(x) for x in center],
         'rpy': [float(x) for x in rng.uniform(-np.pi, np.pi, 3)]}
    if shape == 'box':
        o['size'] = [float(x) for x in rng.uniform(0.04, 0.15, 3)]
    else:
        o['radius'] = float(rng.uniform(0.02, 0.07))
    if shape in ('capsule', 'cylinder'):
        o['length'] = float(rng.uniform(0.05, 0.3))
    return o


def _params(rng):
    """margin d_s, influence d_i, gain xi drawn at random (the guarantee holds for all)."""
    margin = float(rng.uniform(0.005, 0.03))
    return margin, margin + float(rng.uniform(0.05, INFLUENCE - margin)), \
        float(rng.uniform(0.2, 0.8))


def _stack(obstacle, target, params, avoid=True, reach_gain=3.0, power_budget=None):
    tasks = [
        {'name': 'reach', 'type': 'cartesian_pose', 'frame': 'tool', 'subspace': ['x', 'y', 'z'],
         'equal': [float(x) for x in target], 'gain': reach_gain},
        {'name': 'posture', 'type': 'joint_position', 'equal': 'init', 'gain': 0.5},
    ]
    if avoid:
        tasks.insert(0, {'name': 'avoid', 'type': 'collision_avoidance',
                         'pairs': ['self', {'name': 'arm', 'links': 'all',
                                            'obstacles': ['obs']}],
                         'margin': params[0], 'influence': params[1], 'gain': params[2]})
    doc = {'version': 1, 'name': 'run', 'robot': 'lbr_iiwa14', 'obstacles': [obstacle],
           'tasks': tasks}
    if power_budget is not None:
        doc['power_budget'] = power_budget
    return TaskStack.from_dict(doc)


def _arm_distance(robot, data, q0, obstacle):
    """Distance of the robot's shapes at q0 to ``obstacle`` (coal, for the scenario draw)."""
    geometry = _BASE[robot.name]
    gd = pin.GeometryData(geometry.model)
    pin.forwardKinematics(robot.model, data, q0)
    pin.updateGeometryPlacements(robot.model, data, geometry.model, gd)
    spec = ObstacleSpec(obstacle['name'], obstacle['shape'],
                        tuple(obstacle.get('size') or [obstacle[k] for k in ('radius', 'length')
                                                       if k in obstacle]),
                        position=tuple(obstacle['position']), rpy=tuple(obstacle['rpy']))
    obs = spec.obstacle()
    shape, pose = obs.geometry(), obs.placement()
    T_obs = coal.Transform3s(pose.rotation, pose.translation)
    req, best = coal.DistanceRequest(), np.inf
    for o, M in zip(geometry.model.geometryObjects, gd.oMg):
        res = coal.DistanceResult()
        coal.distance(o.geometry, coal.Transform3s(M.rotation, M.translation), shape, T_obs,
                      req, res)
        best = min(best, res.min_distance)
    return best


_BASE = {}


def _scenario(robot, rng, data):
    """A start pose, a tool target 0.2-0.4 m away and an obstacle on the way.

    The obstacle is 5-50 mm outside the influence distance from the arm at the start, and
    the self-collision pairs are farther than the margin.

    Returns (q0, target, obstacle, params, query) with the query over every listed pair.
    """
    if robot.name not in _BASE:
        _BASE[robot.name] = CollisionGeometry(robot)
    base = _BASE[robot.name]
    self_query = PairQuery(base, base.self_pairs())
    params = _params(rng)
    while True:
        q0 = np.clip(robot.q_home + rng.normal(0, 0.3, robot.n), robot.q_min + 0.1,
                     robot.q_max - 0.1)
        pin.forwardKinematics(robot.model, data, q0)
        if self_query.distances_only(data).min() < params[0] + 0.005:
            continue
        start = _tool(robot, data, q0)
        direction = rng.normal(size=3)
        direction /= np.linalg.norm(direction)
        target = start + rng.uniform(0.2, 0.4) * direction
        if target[2] < 0.25 or np.linalg.norm(target[:2]) < 0.3:
            continue
        for _ in range(5):
            center = start + rng.uniform(0.2, 0.6) * (target - start) + rng.normal(0, 0.02, 3)
            obstacle = _obstacle(rng, center)
            if params[1] + 0.005 < _arm_distance(robot, data, q0, obstacle) < params[1] + 0.05:
                task = _stack(obstacle, target, params).build(robot)[0]
                query = PairQuery(task.geometry, task.pairs)
                query.obstacle_pairs = dict(task.groups)['arm']
                return q0, target, obstacle, params, query


def _run(robot, q0, stack, query, ticks, data, plant=None):
    """Closed loop; returns (min distance of q_v over the run: all pairs, the obstacle's
    pairs; q_v inside the limits, the SPG).

    Distances below 0.05 m are exact for every pair (coal, no cull; farther pairs get the
    bounding spheres' lower bound, test_collision_geometry checks both).
    """
    spg = SetPointGenerator(robot, stack, dt=DT)
    q, qdot = q0.copy(), np.zeros(robot.n)
    worst, inside = np.full(2, np.inf), True
    arm = query.obstacle_pairs
    for k in range(ticks):
        q_v = spg.step(q, qdot, k * DT)
        inside &= bool(np.all(q_v >= robot.q_min) and np.all(q_v <= robot.q_max))
        pin.forwardKinematics(robot.model, data, q_v)
        d = query.compute(data, 0.05, jacobians=False).distance
        worst = np.minimum(worst, (d.min(), d[arm].min()))
        if plant is None:
            q, qdot = q_v, spg.qdot_v.copy()
        else:
            q, qdot, _ = plant.step(q_v)
    return worst, inside, spg


def _runs(iiwa, seed, runs, ticks, avoid=True):
    """``runs`` seeded random runs; per run (params, min distance all pairs, obstacle's)."""
    rng = np.random.default_rng(seed)
    data = iiwa.create_data()
    out = []
    for _ in range(runs):
        q0, target, obstacle, params, query = _scenario(iiwa, rng, data)
        (worst, near), inside, spg = _run(iiwa, q0, _stack(obstacle, target, params, avoid),
                                          query, ticks, data)
        assert inside  # q_v inside the joint limits at every tick
        if avoid:
            assert spg.info.status in ('ok', 'fallback'), spg.info.message
        out.append((params, worst, near))
    return out


@pytest.mark.parametrize('seed', [1, 2, 3, 4])
def test_virtual_robot_keeps_the_margin_in_200_random_runs(iiwa, seed):
    """4 x 50 short runs (0.2 s): the obstacle comes within the influence distance."""
    runs = _runs(iiwa, seed, 50, 100)
    for params, worst, _ in runs:
        assert worst >= params[0] - 1e-3, (params, worst)
    engaged = sum(near < params[1] for params, _, near in runs)
    assert engaged >= 35, engaged


def test_long_runs_come_to_the_margin_and_stay_there(iiwa):
    runs = _runs(iiwa, 5, 15, 400)
    for params, worst, _ in runs:
        assert worst >= params[0] - 1e-3, (params, worst)
    close = sum(near < params[0] + 0.01 for params, _, near in runs)
    assert close >= 8, close


def test_without_the_level_the_same_runs_collide(iiwa):
    runs = _runs(iiwa, 5, 15, 400, avoid=False)
    collided = sum(near < params[0] - 1e-3 for params, _, near in runs)
    assert collided >= 8, collided


def test_impedance_plant_runs_keep_the_margin(iiwa):
    """The SPG against a rigid joint-impedance plant (q lags q_v): q_v still keeps it."""
    rng = np.random.default_rng(99)
    data = iiwa.create_data()
    for _ in range(5):
        q0, target, obstacle, params, query = _scenario(iiwa, rng, data)
        plant = JointImpedancePlant(iiwa, q0, dt=DT, substeps=1)
        (worst, _), inside, _ = _run(iiwa, q0, _stack(obstacle, target, params), query, 300,
                                     data, plant)
        assert inside and worst >= params[0] - 1e-3, worst


# -- MuJoCo: the physical robot (FRI emulation, joint impedance) in lockstep ---------------
POST_STACK = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))),
                          'config', 'tasks', 'table_4_1_collision_avoidance_post.yaml')


def _mujoco_run(stack, position, ticks):
    """The shipped post stack against the MuJoCo iiwa in the ``post`` scene.

    Returns (min distance of q_v, of the measured q, MuJoCo contacts with the post, final
    tool position, margin).
    """
    from sim_bridge.simulation import Simulation

    sim = Simulation(robot='lbr_iiwa14', scene='post',
                     scene_options={'position': list(position), 'radius': 0.04,
                                    'height': 1.2})
    robot = sim.robot
    task = _post_stack(position).build(robot)[0]  # the listed pairs, the post where it is
    query = PairQuery(task.geometry, task.pairs)
    # the iiwa's shipped ceiling (config/lbr_iiwa14.yaml): the stack asks for 1 W
    spg = SetPointGenerator(robot, stack, dt=DT, pspm=PspmConfig(max_power=2.0))
    data = robot.create_data()
    post = mujoco.mj_name2id(sim.model, mujoco.mjtObj.mjOBJ_GEOM, 'post')
    worst_v = worst_q = np.inf
    contacts = 0
    for _ in range(ticks):
        s = sim.read_state()
        q_v = spg.step(s.q, s.qd, s.t)
        assert np.all(q_v >= robot.q_min) and np.all(q_v <= robot.q_max)
        sim.write_command(q_v)
        sim.step(2)
        for q, which in ((q_v, 0), (s.q, 1)):
            pin.forwardKinematics(robot.model, data, q)
            d = query.compute(data, 0.05, jacobians=False).distance.min()
            worst_v, worst_q = (min(worst_v, d), worst_q) if which == 0 else \
                (worst_v, min(worst_q, d))
        contacts += sum(post in (c.geom1, c.geom2) for c in sim.data.contact[:sim.data.ncon])
    tool = _tool(robot, data, sim.read_state().q)
    return worst_v, worst_q, contacts, tool, task.margin


def _post_stack(position, avoid=True):
    stack = TaskStack.from_file(POST_STACK).to_dict()
    stack['obstacles'][0]['position'][:2] = list(position)
    if not avoid:
        stack['tasks'] = stack['tasks'][1:]
    return TaskStack.from_dict(stack)


@pytest.mark.parametrize('position', [(0.4, 0.25), (0.42, 0.2), (0.38, 0.3)])
def test_mujoco_post_elbow_held_off_and_tool_arrives(position):
    worst_v, worst_q, contacts, tool, margin = _mujoco_run(_post_stack(position), position,
                                                           2000)
    assert worst_v >= margin - 1e-3
    assert contacts == 0 and worst_q > 0.0
    # the tool slid past the post (it starts at y = 0, the post stands at y = 0.2-0.3)
    assert tool[1] > 0.45, tool
    if position == (0.4, 0.25):  # the shipped scene: the tool arrives
        assert np.linalg.norm(tool - [0.61, 0.5, 0.5]) < 0.01, tool


def test_mujoco_post_without_the_level_hits_it():
    position = (0.4, 0.25)
    worst_v, _, contacts, tool, _ = _mujoco_run(_post_stack(position, avoid=False), position,
                                                2000)
    assert worst_v < 0 and contacts > 0


# -- MuJoCo: random runs on the physical robot too ------------------------------------------
def _mujoco_random_runs(iiwa, seed, runs, ticks, avoid=True):
    """``runs`` of the random scenarios of :func:`_runs` on the MuJoCo iiwa (FRI emulation,
    joint impedance) in lockstep, the obstacle in the scene (``obstacles``, with a contact
    pair against every robot geom).

    Per run: (params, min distance of q_v over every listed pair, of the measured q, MuJoCo
    contacts between listed geometries, q_v inside the limits at every tick).
    """
    from sim_bridge.simulation import Simulation

    rng = np.random.default_rng(seed)
    data = iiwa.create_data()
    out = []
    for _ in range(runs):
        q0, target, obstacle, params, query = _scenario(iiwa, rng, data)
        sim = Simulation(robot='lbr_iiwa14', scene='obstacles',
                         scene_options={'obstacles': [obstacle]}, q0=list(q0))
        names = [query.geometry.shape_name(i)
                 for i in range(len(query.geometry.model.geometryObjects))]
        gid = [mujoco.mj_name2id(sim.model, mujoco.mjtObj.mjOBJ_GEOM,
                                 'obs' if nm == 'obstacle:obs' else nm) for nm in names]
        assert min(gid) >= 0, names
        listed = {frozenset((gid[a], gid[b])) for a, b in query.pairs}
        # with PSPM a trailing robot drains the tanks: the stack asks for a budget within the
        # iiwa's shipped ceiling (config/lbr_iiwa14.yaml), as the post stack does
        spg = SetPointGenerator(iiwa, _stack(obstacle, target, params, avoid, power_budget=1.0),
                                dt=DT, pspm=PspmConfig(max_power=2.0))
        worst, contacts, inside = np.full(2, np.inf), 0, True
        for _ in range(ticks):
            s = sim.read_state()
            q_v = spg.step(s.q, s.qd, s.t)
            inside &= bool(np.all(q_v >= iiwa.q_min) and np.all(q_v <= iiwa.q_max))
            sim.write_command(q_v)
            sim.step(2)
            for i, q in enumerate((q_v, s.q)):
                pin.forwardKinematics(iiwa.model, data, q)
                worst[i] = min(worst[i], query.compute(data, 0.05, jacobians=False).distance.min())
            contacts += sum(frozenset((c.geom1, c.geom2)) in listed
                            for c in sim.data.contact[:sim.data.ncon])
        out.append((params, *worst, contacts, inside))
    return out


@pytest.mark.parametrize('seed', [11, 12, 13, 14])
def test_mujoco_random_runs_keep_the_margin_for_q_v(iiwa, seed):
    """4 x 50 random runs (0.4 s) on the MuJoCo robot: q_v never closer than the margin -
    1 mm and inside the joint limits, while the measured q feeds the SPG. The physical robot
    trails q_v (joint impedance, 200 Nm/rad): where q_v slides around the obstacle at the
    margin, the trailing arm can cut the corner and touch it (printed; README "Collision
    avoidance": the margin is the physical robot's room for its tracking error)."""
    runs = _mujoco_random_runs(iiwa, seed, 50, 200)
    for params, worst_v, _, _, inside in runs:
        assert inside and worst_v >= params[0] - 1e-3, (params, worst_v)
    touched = [(p[0], q) for p, _, q, c, _ in runs if c]
    print(f'seed {seed}: {len(touched)} of 50 runs touched on the physical robot; deepest '
          f'{min([q for _, q in touched], default=0.0) * 1e3:.1f} mm (margins '
          f'{[round(m * 1e3, 1) for m, _ in touched]} mm)')


def test_mujoco_random_runs_without_the_level_hit_the_obstacle(iiwa):
    """The same kind of runs without the level: q_v goes through the obstacle and the
    physical robot runs into it (MuJoCo contacts: the scene's obstacle is where the stack
    declares it, so the count can fail)."""
    runs = _mujoco_random_runs(iiwa, 15, 15, 400, avoid=False)
    hit = sum(c > 0 and v < p[0] - 0.01 for p, v, _, c, _ in runs)
    assert hit >= 8, [(round(v, 4), c) for _, v, _, c, _ in runs]
