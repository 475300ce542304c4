"""Obstacles that move at run time (``spg/obstacles``, no DDS here: the runner's core).

A MarkerArray moves the obstacles the running stack declares: a marker is checked (name,
frame, finite pose, unit quaternion, shape, size) and rejected with its reason, counted in
``spg/status``, while the stack keeps running; accepted poses apply at the next tick
boundary. An obstacle that moves breaks the cull's lower bound (the last distance minus
how far the joints moved): the pairs with it are recomputed, so a ball pushed into a
resting arm finds it holding the margin (without that reset the ball goes through the arm:
the check can fail). ``spg/state`` records the poses each tick used: a run replays exactly.
"""

import json

import numpy as np
import pinocchio as pin
import pytest

from ifc_spg.geometry import PairQuery
from ifc_spg.node.config import SpgConfig
from ifc_spg.node.core import SpgRunner, status_json
from ifc_spg.node.obstacles import OBSTACLE_MARKER_ID, obstacle_marker, obstacle_markers
from ifc_spg.ros import messages as m

MARGIN, INFLUENCE, GAIN = 0.03, 0.06, 1.0   # [m], [m], [m/s]: k = 33 /s
RADIUS = 0.05                               # [m] the ball
START = np.array([0.21, 0.25, 0.724])       # [m] the ball, beside the elbow (link 4)
STACK = f"""
version: 1
name: ball
robot: lbr_iiwa14
obstacles:
  - {{name: ball, shape: sphere, radius: {RADIUS}, position: {START.tolist()}}}
  - {{name: crate, shape: box, size: [0.2, 0.3, 0.1], position: [0.4, -0.6, 0.3]}}
  - {{name: held, shape: capsule, radius: 0.02, length: 0.1, frame: tool}}
tasks:
  - name: avoid
    type: collision_avoidance
    pairs: [{{name: arm_ball, links: all, obstacles: [ball, crate]}}]
    margin: {MARGIN}
    influence: {INFLUENCE}
    gain: {GAIN}
  - {{name: posture, type: joint_position, equal: init, gain: 0.5}}
"""
DT_NS = 2_000_000
UNIT = (0.0, 0.0, 0.0, 1.0)


def _runner():
    runner = SpgRunner(SpgConfig(robot='lbr_iiwa14'), clock=lambda: 0.0)
    assert runner.handle_task_stack(STACK).accepted
    return runner


def _marker(runner, name, position, quaternion=UNIT, frame='world'):
    task = runner.spg.tasks[0] if runner.spg.tasks else runner.spg.pending_tasks[0]
    return obstacle_marker(m, task.geometry.declared[name], position, quaternion, frame)


def _tick(runner, k, q):
    return runner.handle_joint_state(runner.joint_names, q, np.zeros(7), k * DT_NS)


def test_markers_are_checked_counted_and_applied_at_the_tick_boundary():
    runner = _runner()
    q = np.array(runner.robot.q_home)
    assert _tick(runner, 0, q) is not None
    task = runner.spg.tasks[0]
    good = _marker(runner, 'ball', START + [0.0, 0.05, 0.0])
    bad = {}
    bad['unknown_obstacle'] = _marker(runner, 'ball', START)
    bad['unknown_obstacle'].ns = 'bal'
    bad['unknown_frame'] = _marker(runner, 'ball', START, frame='link0_typo')
    bad['attached'] = _marker(runner, 'held', START)
    bad['non_finite'] = _marker(runner, 'ball', [0.2, float('nan'), 0.7])
    bad['not_unit_quaternion'] = _marker(runner, 'ball', START, (0.0, 0.0, 0.0, 1.01))
    bad['wrong_shape'] = _marker(runner, 'ball', START)
    bad['wrong_shape'].type = m.Marker.CUBE
    bad['size_change'] = _marker(runner, 'ball', START)
    bad['size_change'].scale.x = 0.2
    bad['out_of_reach'] = _marker(runner, 'held', [3.0, 0.0, 0.0], frame='tool')
    delete = m.Marker()
    delete.action = m.Marker.DELETEALL
    errors = runner.handle_obstacles([delete, good, *bad.values()])
    assert [reason for reason, _ in errors] == list(bad)
    text = dict(errors)
    assert "did you mean 'ball'" in text['unknown_obstacle']
    assert "'link0_typo'" in text['unknown_frame'] and "'world'" in text['unknown_frame']
    assert "fixed to frame 'tool'" in text['attached'] and "frame_id 'tool'" in text['attached']
    assert "beyond the collision cull's bound" in text['out_of_reach']
    assert 'norm 1.01' in text['not_unit_quaternion']
    assert 'marker type 2 (SPHERE), got 1' in text['wrong_shape']
    assert 'declared size drawn ([0.1, 0.1, 0.1])' in text['size_change']
    # accepted poses wait for the tick boundary
    assert np.array_equal(task.obstacle_poses['ball'][:3], START)
    # zero scale, the base frame as '' and a quaternion within 1e-3 of unit are fine
    ok = _marker(runner, 'crate', [0.4, -0.5, 0.3], (0.0, 0.0, 0.0, 1.0005), frame='')
    ok.scale.x = ok.scale.y = ok.scale.z = 0.0
    assert runner.handle_obstacles([ok]) == []
    cmd = _tick(runner, 1, q)
    assert cmd is not None   # the stack kept running
    assert np.array_equal(task.obstacle_poses['ball'][:3], START + [0.0, 0.05, 0.0])
    assert np.array_equal(task.obstacle_poses['crate'], [0.4, -0.5, 0.3, 0, 0, 0, 1.0])
    doc = json.loads(status_json(runner.status()))
    assert doc['obstacles'] == {'received': 11, 'accepted': 2, 'ignored': 1, 'moved': 2,
                                'rejected': dict.fromkeys(bad, 1)}
    assert any(e['source'] == 'obstacles' and 'size_change' in e['message']
               for e in doc['errors'])
    assert runner.diagnostics().level == 'WARN'
    assert runner.diagnostics().values['obstacles.rejected.wrong_shape'] == '1'
    # the moved ball is where the level computes it: 5 cm farther from the elbow
    data = runner.robot.create_data()
    pin.forwardKinematics(runner.robot.model, data, runner.spg.q_v)
    declared = PairQuery(task.geometry, task.pairs).distances_only(data)
    now = task.query.distances_only(data)
    ball = [i for i, (_, b) in enumerate(task.names) if b == 'obstacle:ball']
    assert np.min(now[ball]) > np.min(declared[ball]) + 0.049


def test_an_obstacle_fixed_to_a_frame_moves_relative_to_it():
    """'held' is fixed to the tool: a marker in frame_id 'tool' moves it along the tool (a
    held object shifted in the gripper); the level's distances are those of a geometry that
    declares it there (the reference), at the SPG's next tick and after the arm moved."""
    from ifc_spg.geometry import CollisionGeometry, Obstacle

    runner = _runner()
    q = np.array(runner.robot.q_home)
    _tick(runner, 0, q)
    task = runner.spg.tasks[0]
    shifted = [0.05, -0.02, 0.12]
    quat = (0.0, np.sin(0.2), 0.0, np.cos(0.2))  # 0.4 rad about y
    assert runner.handle_obstacles([_marker(runner, 'held', shifted, quat, frame='tool')]) == []
    _tick(runner, 1, q)
    assert np.allclose(task.obstacle_poses['held'], [*shifted, *quat])
    declared = dict(task.geometry.declared)
    held = declared['held']
    declared['held'] = Obstacle('held', held.shape, held.size, frame='tool',
                                position=tuple(shifted),
                                rotation=tuple(map(tuple, pin.Quaternion(
                                    quat[3], *quat[:3]).toRotationMatrix())))
    reference = CollisionGeometry(runner.robot, declared.values())
    shape = task.geometry.obstacles['held']
    pairs = [(a, shape) for a in range(len(task.geometry.robot_geoms))
             if task.geometry.parent_joint[a] != task.geometry.parent_joint[shape]]
    ours, ref_query = PairQuery(task.geometry, pairs), PairQuery(reference, pairs)
    ours.move_shape(shape, task.geometry.obstacle_placement('held', task.obstacle_poses['held']))
    before = PairQuery(task.geometry, pairs)  # (as declared)
    data = runner.robot.create_data()
    for q_test in (q, q + 0.3):
        pin.forwardKinematics(runner.robot.model, data, q_test)
        d = ours.distances_only(data)
        np.testing.assert_allclose(d, ref_query.distances_only(data), rtol=0, atol=1e-9)
        assert np.abs(d - before.distances_only(data)).max() > 0.01  # it did move
    # the task's own query moved it too
    assert np.array_equal(task.query._pin.model.geometryObjects[shape].placement,
                          ours._pin.model.geometryObjects[shape].placement)


def test_the_spg_draws_obstacles_with_the_markers_it_takes():
    runner = _runner()
    _tick(runner, 0, np.array(runner.robot.q_home))
    runner.handle_obstacles([_marker(runner, 'ball', [0.2, 0.3, 0.7],
                                     (0.0, 0.0, np.sin(0.2), np.cos(0.2)))])
    _tick(runner, 1, np.array(runner.robot.q_home))
    drawn = obstacle_markers(m, runner.spg.tasks, 'world', DT_NS)
    # the base-frame obstacles (not 'held', on the tool), the ball where it was moved
    assert [(mk.ns, mk.id, mk.type) for mk in drawn] == [
        ('ball', OBSTACLE_MARKER_ID, m.Marker.SPHERE), ('crate', OBSTACLE_MARKER_ID,
                                                        m.Marker.CUBE)]
    p, o = drawn[0].pose.position, drawn[0].pose.orientation
    assert [p.x, p.y, p.z] == [0.2, 0.3, 0.7] and o.z == pytest.approx(np.sin(0.2))
    assert [drawn[1].scale.x, drawn[1].scale.y, drawn[1].scale.z] == [0.2, 0.3, 0.1]
    assert drawn[0].scale.x == 2 * RADIUS
    # sent back, they are accepted and move nothing
    assert runner.handle_obstacles(drawn) == []
    _tick(runner, 2, np.array(runner.robot.q_home))
    assert runner.obstacles.moved == 1 and runner.obstacles.accepted == 3


def _push(no_reset=False, monkeypatch=None, seconds=8.0, speed=0.02):
    """A ball pushed at ``speed`` [m/s] in -y into the resting elbow, one marker per tick.

    Returns the smallest exact distance over the ball's pairs at q_v after each tick (the
    ball at the pose that tick used), and how far the elbow moved [m].
    """
    if no_reset:  # the obstacle moves, the cull keeps its stale lower bounds (the broken
        # variant of the method has to reach the query's own model: no public way to it)
        def move_shape(self, shape, placement):  # both narrowphases, no bound reset
            rotation, translation = placement.rotation, placement.translation
            self._pin.move_shape(shape, rotation, translation)
            if self._narrow is not self._pin:
                self._narrow.move_shape(shape, rotation, translation)
        monkeypatch.setattr(PairQuery, 'move_shape', move_shape)
    runner = _runner()
    q = np.array(runner.robot.q_home)
    robot, data = runner.robot, runner.robot.create_data()
    steps = round(seconds / 0.002)
    worst, task, full = np.inf, None, None
    for k in range(steps):
        y = START[1] - speed * 0.002 * k
        if k:
            runner.handle_obstacles([_marker(runner, 'ball', [START[0], y, START[2]])])
        cmd = _tick(runner, k, q)
        q = cmd.position  # a tracking robot
        if task is None:
            task = runner.spg.tasks[0]
            ball = [i for i, (_, b) in enumerate(task.names) if b == 'obstacle:ball']
            full = PairQuery(task.geometry, [task.pairs[i] for i in ball])
        full.move_shape(task.geometry.obstacles['ball'],
                        pin.SE3(np.eye(3), task.obstacle_poses['ball'][:3].copy()))
        pin.forwardKinematics(robot.model, data, q)
        worst = min(worst, float(full.distances_only(data).min()))
    pin.framesForwardKinematics(robot.model, data, q)
    elbow = data.oMf[robot.model.getFrameId('link4')].translation
    return worst, float(np.linalg.norm(elbow - [0.21, 0.0, 0.724]))


def test_ball_pushed_into_the_resting_arm_keeps_the_margin():
    worst, moved = _push()
    print(f'ball pushed at 20 mm/s: closest {worst * 1e3:.2f} mm (margin {MARGIN * 1e3:g} mm),'
          f' elbow moved {moved * 1e3:.1f} mm')
    assert worst >= MARGIN - 1e-3
    assert moved > 0.03   # the arm gave way (the ball went 16 cm, 13 cm from it)


def test_without_the_bound_reset_the_ball_goes_through_the_arm(monkeypatch):
    worst, moved = _push(no_reset=True, monkeypatch=monkeypatch)
    print(f'without the reset: closest {worst * 1e3:.2f} mm, elbow moved {moved * 1e3:.1f} mm')
    assert worst < 0.0


def _live(seed, ticks):
    """The ball pushed into the arm by markers at random moments; states and records."""
    rng = np.random.default_rng(seed)
    runner = _runner()
    q = np.array(runner.robot.q_home)
    states, q_v, snaps, configs = [], [], {}, {}
    y = START[1]
    for k in range(ticks):
        for _ in range(rng.poisson(0.5)):  # 0-3 markers between two ticks, 50 mm/s
            y -= rng.uniform(0.0, 0.0004)
            runner.handle_obstacles([_marker(runner, 'ball', [START[0], y, START[2]])])
        states.append((q, k * DT_NS))
        cmd = _tick(runner, k, q)
        q_v.append(np.array(cmd.position))
        snaps[k] = json.loads(json.dumps(runner.state_vector().tolist()))  # as a bag has it
        configs[k] = json.loads(json.dumps(runner.config_doc()))
        q = cmd.position
    return runner.joint_names, states, q_v, snaps, configs


def _replay(names, states, q_v, snaps, configs, start, use_poses=True):
    """max |dq_v| of a runner restored after tick ``start``, over every later tick."""
    runner = SpgRunner(SpgConfig(robot='lbr_iiwa14'), clock=lambda: 0.0)
    runner.restore(snaps[start], configs[start])
    worst = 0.0
    for k in range(start + 1, len(states)):
        if use_poses:
            runner.replay_streams(snaps[k], configs[k])
        q, stamp = states[k]
        cmd = runner.handle_joint_state(names, q, np.zeros(7), stamp)
        worst = max(worst, float(np.max(np.abs(np.array(cmd.position) - q_v[k]))))
    return worst


def test_a_run_with_moving_obstacles_replays_exactly():
    live = _live(3, 1500)
    layout = [f for f, _ in live[4][10]['state_layout']]
    assert layout[-3:] == ['obstacle:ball', 'obstacle:crate', 'obstacle:held']
    moved = np.abs(np.array(live[2]) - live[2][0]).max()
    assert moved > 0.05  # [rad] the ball pushed the arm
    for start in (5, 600, 1200):
        assert _replay(*live, start) == 0.0, start
    # the poses matter: without them the replay keeps the ball where the restore put it
    without = _replay(*live, 600, use_poses=False)
    print(f'replay: arm pushed {moved:.3f} rad; without the recorded poses max |dq_v| '
          f'{without:.3g} rad')
    assert without > 1e-3


def test_distances_do_not_depend_on_what_the_query_computed_before():
    """coal's GJK would start from the pair's last solution: a replay restored mid-run
    (a fresh query) would then differ from the live run by up to ~5e-6 in the rows (the
    post's cylinder beside the links' capsules), and its q_v by ~1e-9 rad."""
    from ifc_spg.geometry import CollisionGeometry, Obstacle
    from ifc_spg.model import RobotModel

    robot = RobotModel.from_config('lbr_iiwa14')
    geometry = CollisionGeometry(robot, [Obstacle('post', 'cylinder', (0.04, 1.2),
                                                  position=(0.21, 0.13, 0.6))])
    pairs = [(a, geometry.obstacles['post']) for a in range(len(geometry.robot_geoms))]
    data = robot.create_data()

    def at_home(history):
        query, rng = PairQuery(geometry, pairs), np.random.default_rng(0)
        for _ in range(history):
            pin.computeJointJacobians(robot.model, data, robot.q_home + rng.normal(0, 0.3, 7))
            query.compute(data, 0.2)
        pin.computeJointJacobians(robot.model, data, robot.q_home)
        return query.compute(data, 0.2)

    fresh, used = at_home(0), at_home(50)
    assert np.array_equal(fresh.distance, used.distance)
    assert np.array_equal(fresh.rows, used.rows)
    assert np.array_equal(fresh.point_a, used.point_a, equal_nan=True)
