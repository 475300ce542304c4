"""The collision_avoidance task type: the stack language (errors name the field), the level
it gives the cascade (the velocity damper), and the distances reported in spg.info."""

import json

import jsonschema
import numpy as np
import pinocchio as pin
import pytest
import yaml

from ifc_spg import RobotModel, SetPointGenerator, TaskStack
from ifc_spg.cli import check
from ifc_spg.geometry import PairQuery
from ifc_spg.kinematics import Kinematics
from ifc_spg.task_stack import TaskStackError, schema

STACK = """
version: 1
name: ball
robot: lbr_iiwa14
obstacles:
  - {name: ball, shape: sphere, radius: 0.06, position: [0.55, 0.0, 0.75]}
  - {name: crate, shape: box, size: [0.2, 0.3, 0.1], position: [0.4, -0.4, 0.3], rpy: [0, 0, 0.5]}
  - {name: table, shape: plane, position: [0, 0, 0.0]}
  - {name: held, shape: capsule, radius: 0.02, length: 0.1, frame: tool}
tasks:
  - name: avoid
    type: collision_avoidance
    pairs: [self, {name: arm_ball, links: all, obstacles: [ball, crate]},
            {links: [link6, link7, tool_tip], obstacles: [table]}]
    margin: 0.02
    influence: 0.12
    gain: 0.4
  - name: reach
    type: cartesian_pose
    frame: tool
    subspace: [x, y, z]
    equal: {trajectory: ramp, by: [0.0, 0.3, 0.0], duration: 1.0}
  - {name: posture, type: joint_position, equal: init, gain: 0.5}
"""


@pytest.fixture(scope='module')
def iiwa():
    return RobotModel.from_config('lbr_iiwa14')


def _stack(text=STACK):
    return TaskStack.from_yaml(text)


def _edit(old, new):
    assert old in STACK
    return STACK.replace(old, new)


def test_round_trip_schema_and_check(iiwa, tmp_path, capsys):
    stack = _stack()
    data = stack.to_dict()
    assert TaskStack.from_dict(data) == stack
    assert TaskStack.from_json(json.dumps(data)).to_dict() == data
    validator = jsonschema.Draft202012Validator(schema.load_schema())
    validator.validate(yaml.safe_load(STACK))
    validator.validate(data)
    assert data['tasks'][0]['pairs'][1] == {'name': 'arm_ball', 'links': 'all',
                                            'obstacles': ['ball', 'crate']}
    stack.validate(iiwa)
    path = tmp_path / 's.yaml'
    path.write_text(STACK)
    assert check.main([str(path)]) == 0
    assert ': ok: 3 tasks' in capsys.readouterr().out


def test_defaults(iiwa):
    stack = _stack(_edit('    margin: 0.02\n    influence: 0.12\n    gain: 0.4\n', ''))
    task = stack.build(iiwa)[0]
    assert (task.margin, task.influence, task.xi) == (0.01, 0.1, 0.5)


@pytest.mark.parametrize('old, new, where, what', [
    ('links: [link6,', 'links: [lnk6,', 'tasks[0].pairs[2].links[0]', "did you mean 'link6'"),
    ('obstacles: [ball, crate]', 'obstacles: [ball, crat]', 'tasks[0].pairs[1].obstacles[1]',
     "did you mean 'crate'"),
    ('margin: 0.02', 'margin: 0.2', 'tasks[0].influence', 'greater than margin'),
    ('margin: 0.02', 'margin: -0.01', 'tasks[0].margin', '>= 0'),
    ('gain: 0.4', 'gain: 0', 'tasks[0].gain', '> 0'),
    ('radius: 0.06', 'radius: .nan', 'obstacles[0].radius', 'finite'),
    ('position: [0.55, 0.0, 0.75]', 'position: [0.55, .inf, 0.75]', 'obstacles[0].position[1]',
     'finite'),
    ('radius: 0.06', 'radius: 0.0', 'obstacles[0].radius', '> 0'),
    ('size: [0.2, 0.3, 0.1]', 'size: [0.2, 0.3]', 'obstacles[1].size', '3 numbers'),
    ('size: [0.2, 0.3, 0.1]', 'size: [0.2, -0.3, 0.1]', 'obstacles[1].size[1]', '> 0'),
    ('shape: sphere', 'shape: sphre', 'obstacles[0].shape', "did you mean 'sphere'"),
    ('shape: sphere, radius: 0.06', 'shape: sphere, length: 0.06', 'obstacles[0].length',
     'has no length'),
    ('frame: tool}', 'frame: tol}', 'obstacles[3].frame', "did you mean 'tool'"),
    ('{name: table,', '{name: ball,', 'obstacles[2].name', 'used twice'),
    ('pairs: [self,', 'pairs: [slf,', 'tasks[0].pairs[0]', "did you mean 'self'"),
    ('    margin: 0.02\n', '    margin: 0.02\n    margn: 1\n', 'tasks[0].margn',
     "did you mean 'margin'"),
])
def test_bad_input_names_the_field(iiwa, old, new, where, what):
    with pytest.raises(TaskStackError) as err:
        _stack(_edit(old, new)).validate(iiwa)
    msg = str(err.value)
    assert where in msg and what in msg, msg


def test_undeclared_obstacle_says_where_to_declare(iiwa):
    text = STACK.split('obstacles:\n')[0] + 'tasks:\n' + STACK.split('tasks:\n')[1]
    text = text.replace(', {name: arm_ball, links: all, obstacles: [ball, crate]},\n', ',')
    with pytest.raises(TaskStackError, match='obstacles:'):
        _stack(text).validate(iiwa)


@pytest.mark.parametrize('max_rows', [24, 3])
def test_level_is_the_velocity_damper(iiwa, max_rows):
    """Rows and bounds against the formula, on distances computed without the cull: the
    closest pairs within the influence distance (at most max_rows), then open rows."""
    task = _stack(_edit('    gain: 0.4\n', f'    gain: 0.4\n    max_rows: {max_rows}\n')) \
        .build(iiwa)[0]
    assert task.dim == max_rows
    full = PairQuery(task.geometry, task.pairs)
    kin = Kinematics(iiwa)
    data = iiwa.create_data()
    rng = np.random.default_rng(2)
    active_seen = dropped_seen = 0
    for _ in range(30):
        q = rng.uniform(iiwa.q_min, iiwa.q_max)
        kin.update(q, np.zeros(iiwa.n), q)
        level = task.level(kin, 0.0)
        pin.computeJointJacobians(iiwa.model, data, q)
        ref = full.compute(data)
        near = np.flatnonzero(ref.distance < task.influence)
        closest = near[np.argsort(ref.distance[near], kind='stable')][:task.dim]
        order = task.row_pairs  # the pair of each row
        assert sorted(order.tolist()) == sorted(closest.tolist())
        k = order.size
        expect = -task.xi * (ref.distance[order] - task.margin) / (task.influence - task.margin)
        np.testing.assert_allclose(level.lower[:k], expect, atol=1e-7)
        # witness points of parallel faces are not unique: GJK's warm start may pick another
        np.testing.assert_allclose(level.A[:k], ref.rows[order], atol=1e-4)
        assert np.all(np.isneginf(level.lower[k:])) and np.all(level.A[k:] == 0)
        assert np.all(np.isposinf(level.upper)) and not level.equality
        assert level.A.shape == (task.dim, iiwa.n)
        assert task.rows_dropped == max(0, near.size - task.dim)
        active_seen += k
        dropped_seen += task.rows_dropped
    assert active_seen > 30
    assert (dropped_seen > 0) == (max_rows == 3)


def test_info_reports_min_distance_per_group(iiwa):
    spg = SetPointGenerator(iiwa, _stack())
    q = iiwa.q_home.copy()
    spg.step(q, np.zeros(iiwa.n), 0.0)
    (report,) = spg.info.collision
    groups = report['groups']
    assert set(groups) == {'self', 'arm_ball', 'pairs[2]'}
    task = spg.tasks[0]
    full = PairQuery(task.geometry, task.pairs)
    data = iiwa.create_data()
    pin.forwardKinematics(iiwa.model, data, q)  # the tick's q_v was q
    d = full.distances_only(data)
    for name, idx in task.groups:
        k = idx[np.argmin(d[idx])]
        if d[k] < task.influence:
            assert groups[name]['min_distance'] == pytest.approx(d[k], abs=1e-9)
            assert groups[name]['pair'] == list(task.names[k])
        else:  # all beyond the influence distance: culled, or exact (a plane is never culled)
            assert groups[name]['min_distance'] is None or \
                groups[name]['min_distance'] == pytest.approx(d[k], abs=1e-9)
    json.dumps(spg.info.as_dict())


def test_status_document_carries_the_distances():
    from ifc_spg.node.config import SpgConfig
    from ifc_spg.node.core import SpgRunner, status_json

    runner = SpgRunner(SpgConfig(robot='lbr_iiwa14'))
    assert runner.handle_task_stack(STACK).accepted
    names, q = list(runner.robot.joint_names), list(runner.robot.q_home)
    for k in range(3):
        runner.handle_joint_state(names, q, [0.0] * 7, k * 2_000_000)
    (doc,) = json.loads(status_json(runner.status()))['collision']
    assert doc['task'] == 'avoid' and doc['margin'] == 0.02
    assert set(doc['groups']) == {'self', 'arm_ball', 'pairs[2]'}


def test_bad_stack_is_refused_and_the_running_one_continues():
    from ifc_spg.node.config import SpgConfig
    from ifc_spg.node.core import SpgRunner

    runner = SpgRunner(SpgConfig(robot='lbr_iiwa14'))
    assert runner.handle_task_stack(STACK).accepted
    names, q = list(runner.robot.joint_names), list(runner.robot.q_home)
    runner.handle_joint_state(names, q, [0.0] * 7, 0)
    event = runner.handle_task_stack(_edit('radius: 0.06', 'radius: -0.06'))
    assert not event.accepted and 'obstacles[0].radius' in event.message
    cmd = runner.handle_joint_state(names, q, [0.0] * 7, 2_000_000)
    assert cmd is not None and runner.spg.info.collision[0]['task'] == 'avoid'


def test_info_reports_distances_at_the_measured_q_too(iiwa):
    spg = SetPointGenerator(iiwa, _stack())
    q0 = iiwa.q_home.copy()
    spg.step(q0, np.zeros(iiwa.n), 0.0)
    q1 = q0 + np.array([0.3, 0.2, 0.0, -0.3, 0.0, 0.4, 0.0])  # far from q_v
    spg.step(q1, np.zeros(iiwa.n), 0.002)
    (report,) = spg.info.collision
    task = spg.tasks[0]
    full = PairQuery(task.geometry, task.pairs)
    data = iiwa.create_data()
    pin.forwardKinematics(iiwa.model, data, q1)
    d = full.distances_only(data)
    for name, idx in task.groups:
        k = idx[np.argmin(d[idx])]
        got = report['measured'][name]['min_distance']
        if d[k] < task.influence:
            assert got == pytest.approx(d[k], abs=1e-7)
    assert report['groups'] != report['measured']  # q_v (one tick from q0) is not q1


def test_an_infeasible_row_is_reported_with_its_pair(iiwa):
    """The ball overlaps link 5 at q_home: pushing out at once exceeds the acceleration box."""
    spg = SetPointGenerator(iiwa, _stack())
    spg.step(iiwa.q_home, np.zeros(iiwa.n), 0.0)
    assert spg.info.status == 'ok'
    msg = spg.info.message
    assert "collision_avoidance 'avoid'" in msg and 'obstacle:ball' in msg, msg
    assert 'link5_geom' in msg and 'margin 20.0 mm' in msg
    slack = spg.info.slacks[spg.info.level_names.index('avoid')]
    assert np.max(np.abs(slack)) > 1e-3
    task = spg.tasks[0]
    rows = task.row_pairs.size
    assert task.slack_message(np.zeros(rows)) == '' and task.slack_message(None) == ''
    assert task.slack_message(np.full(rows, 9e-7)) == ''
    down = np.zeros(rows)
    down[0] = -0.25  # the magnitude counts, whatever the sign
    assert 'short by 0.25 m/s' in task.slack_message(down)
    assert 'short by nan' in task.slack_message(np.full(rows, np.nan))
