"""ROS-free tests of the SPG node's logic (SpgRunner) and its configuration (SpgConfig)."""

import json

from helpers import DT_NS, FakeClock, parse_stack, reach_stack
import numpy as np
import pytest

from ifc_spg.errors import ParameterError
from ifc_spg.model import RobotModel
from ifc_spg.node.config import PARAMETERS, SpgConfig, config_from_parameters
from ifc_spg.node.core import REJECT_REASONS, SpgRunner, status_json
from ifc_spg.pspm import PspmConfig
from ifc_spg.spg import SetPointGenerator

STACK = reach_stack()


@pytest.fixture(scope='module')
def robot():
    return RobotModel.from_config('lbr_iiwa14')


def _reference(robot, config):
    return SetPointGenerator(robot, parse_stack(STACK), dt=config.dt,
                             pspm=PspmConfig(config.pspm_initial_energy, config.pspm_max_energy),
                             solver=config.solver, rho=config.rho,
                             torque_limits=config.torque_limits)


def test_ticks_equal_the_set_point_generator_with_any_name_order(robot):
    config = SpgConfig(watchdog_timeout=0.0)
    runner = SpgRunner(config, robot)
    ref = _reference(robot, config)
    assert runner.handle_task_stack(STACK).accepted
    rng = np.random.default_rng(7)
    q = robot.q_home.copy()
    qdot = np.zeros(robot.n)
    names = np.array(robot.joint_names)
    for k in range(60):
        perm = rng.permutation(robot.n)
        cmd = runner.handle_joint_state(names[perm], q[perm], qdot[perm], k * DT_NS)
        expected = ref.step(q, qdot, k * DT_NS * 1e-9)
        np.testing.assert_array_equal(cmd.position, expected)
        np.testing.assert_array_equal(cmd.velocity, ref.qdot_v)
        assert cmd.names == robot.joint_names and cmd.stamp_ns == k * DT_NS
        assert cmd.resumed == (k == 0)
        qdot = (cmd.position - q) / config.dt
        q = cmd.position
    assert runner.stack_id == 1 and runner.stack_name == 'reach'
    doc = json.loads(status_json(runner.status()))
    assert [lv['name'] for lv in doc['levels']] == ['torque_limits', 'posture']
    assert doc['stack'] == {'id': 1, 'name': 'reach', 'since': 0.0,
                            'task_time': pytest.approx(59 * 0.002)}
    assert SpgConfig(**doc['config']) == config  # enough to rebuild the runner


def test_every_bad_input_is_counted_and_the_next_good_one_ticks(robot):
    runner = SpgRunner(SpgConfig(watchdog_timeout=0.0), robot)
    names, q, z = list(robot.joint_names), robot.q_home.copy(), np.zeros(robot.n)
    first = runner.handle_joint_state(names, q, z, 10 * DT_NS)
    bad = {
        'wrong_count': (names[:6], q[:6], z[:6], 11 * DT_NS),
        'unknown_name': (names[:6] + ['A8'], q, z, 11 * DT_NS),
        'duplicate_name': (names[:6] + ['A1'], q, z, 11 * DT_NS),
        'non_finite': (names, np.where(np.arange(7) == 3, np.nan, q), z, 11 * DT_NS),
        'stamp_backwards': (names, q, z, 9 * DT_NS),
    }
    for reason, args in bad.items():
        assert runner.handle_joint_state(*args) is None, reason
    assert runner.handle_joint_state(names, q, z, 10 * DT_NS) is first  # answered again
    assert runner.rejected == dict.fromkeys(REJECT_REASONS, 1)
    assert "did you mean 'A1'" in ' '.join(e['message'] for e in runner.errors) or \
        "unknown joint 'A8'" in ' '.join(e['message'] for e in runner.errors)
    assert runner.handle_joint_state(names, q, z, 11 * DT_NS).tick == 2
    assert runner.diagnostics().level == 'WARN'


def test_watchdog_stops_and_restarts_from_the_measured_q(robot):
    clock = FakeClock(100.0)
    config = SpgConfig(watchdog_timeout=0.05)
    runner = SpgRunner(config, robot, clock=clock)
    runner.handle_task_stack(STACK)
    q, z, names = robot.q_home.copy(), np.zeros(robot.n), robot.joint_names
    for k in range(30):
        clock.t += 0.002
        cmd = runner.handle_joint_state(names, q, z, k * DT_NS)
    assert np.max(np.abs(cmd.position - q)) > 1e-3  # q_v moved away from the held robot
    clock.t += 0.049
    assert not runner.check_watchdog() and runner.state == 'running'
    clock.t += 0.002
    assert runner.check_watchdog() and runner.state == 'stale'
    assert runner.diagnostics().level == 'STALE'
    q_sag = q + 0.02  # the robot moved while nobody commanded it
    cmd = runner.handle_joint_state(names, q_sag, z, 100 * DT_NS)
    assert cmd.resumed and runner.state == 'running' and runner.resumes == 1
    fresh = _reference(robot, config)
    np.testing.assert_allclose(cmd.position, fresh.step(q_sag, z, 0.0), atol=1e-9)
    assert np.all(np.abs(cmd.position - q_sag) <= robot.v_max * config.dt + 1e-12)
    assert runner.status()['stack']['task_time'] == 0.0  # the stack restarted


def test_stamp_gap_trips_and_a_restarted_clock_is_accepted_after_it(robot):
    runner = SpgRunner(SpgConfig(watchdog_timeout=0.05), robot, clock=FakeClock(100.0))
    q, z, names = robot.q_home.copy(), np.zeros(robot.n), robot.joint_names
    runner.handle_joint_state(names, q, z, 1000 * DT_NS)
    cmd = runner.handle_joint_state(names, q + 0.01, z, 1000 * DT_NS + 60_000_000)
    assert cmd.resumed and runner.watchdog_trips == 1
    np.testing.assert_allclose(cmd.position, q + 0.01, atol=1e-12)  # idle: q_v = q
    assert runner.handle_joint_state(names, q, z, 0) is None  # backwards while running
    runner.clock.t += 0.06
    assert runner.check_watchdog()  # stale: a restarted bridge may count from 0 again
    assert runner.handle_joint_state(names, q, z, 5 * DT_NS).resumed and runner.resumes == 2
    runner.mark_stale('replayed watchdog event')
    assert runner.handle_joint_state(names, q, z, 0).resumed and runner.resumes == 3


def test_a_paused_source_with_continuous_stamps_continues_without_restart(robot):
    clock = FakeClock(100.0)
    runner = SpgRunner(SpgConfig(watchdog_timeout=0.05), robot, clock=clock)
    ref = SpgRunner(SpgConfig(watchdog_timeout=0.0), robot)
    for r in (runner, ref):
        r.handle_task_stack(STACK)
    q, z, names = robot.q_home.copy(), np.zeros(robot.n), robot.joint_names
    for k in range(20):
        if k == 10:  # a lockstep simulator pauses for 0.2 s of wall time
            clock.t += 0.2
            assert runner.check_watchdog() and runner.state == 'stale'
        cmd = runner.handle_joint_state(names, q, z, k * DT_NS)
        np.testing.assert_array_equal(cmd.position,
                                      ref.handle_joint_state(names, q, z, k * DT_NS).position)
        assert cmd.resumed == (k == 0)
    assert runner.watchdog_trips == 1 and runner.resumes == 0 and runner.state == 'running'


def test_missing_velocities_are_finite_differences(robot):
    seen = []

    class Recorder:
        name = 'rec'

        def build(self, robot):
            return []

    runner = SpgRunner(SpgConfig(watchdog_timeout=0.0), robot, parse_stack=lambda t: Recorder())
    tick = runner.spg.tick
    runner.spg.tick = lambda q, qdot, t: (seen.append(qdot.copy()), tick(q, qdot, t))[1]
    q = robot.q_home.copy()
    runner.handle_joint_state(robot.joint_names, q, [], 0)
    runner.handle_joint_state(robot.joint_names, q + 0.004, [], DT_NS)
    np.testing.assert_array_equal(seen[0], np.zeros(robot.n))
    np.testing.assert_allclose(seen[1], np.full(robot.n, 2.0))


def test_bad_stack_keeps_the_running_one(robot):
    runner = SpgRunner(SpgConfig(watchdog_timeout=0.0), robot)
    assert runner.handle_task_stack(STACK).accepted
    runner.handle_joint_state(robot.joint_names, robot.q_home, np.zeros(7), 0)
    event = runner.handle_task_stack(STACK.replace('joint_position', 'joint_positon'))
    assert not event.accepted and (event.stack_id, event.name) == (1, 'reach')
    assert 'tasks[0].type' in event.message and 'joint_positon' in event.message
    assert runner.spg.stack is not None and runner.spg.pending_stack is None
    doc = runner.status(('stack_rejected', event.message))
    assert doc['event']['type'] == 'stack_rejected' and doc['errors'][-1]['source'] == \
        'task_stack'


@pytest.mark.parametrize('values, match', [
    ({'rho': 1}, None),                      # an int for a double is fine offline
    ({'dt': 0.5}, r"'dt': 0.5 is outside \[0.0001, 0.1\]"),
    ({'solver': 'qpoases'}, "'qpoases' is not one of daqp, proxsuite, nullspace"),
    ({'robot': 'lbr_iiwa'}, "did you mean 'lbr_iiwa14'"),
    ({'pspm.initial_enrgy': 1.0}, "did you mean 'pspm.initial_energy'"),
    ({'status.decimation': 2.5}, "'status.decimation': 2.5 is a float, expected a int"),
    ({'pspm.initial_energy': 3.0}, 'must not exceed'),
    ({'topics.command': ''}, "'topics.command' must name a topic"),
])
def test_config_errors_name_the_parameter(values, match):
    if match is None:
        rho = config_from_parameters(values).rho
        assert rho == 1.0 and type(rho) is float
        return
    with pytest.raises(ParameterError, match=match):
        config_from_parameters(values)


def test_every_config_field_has_exactly_one_parameter():
    fields = [p.field for p in PARAMETERS]
    assert sorted(fields) == sorted(SpgConfig.__dataclass_fields__)
    assert len({p.name for p in PARAMETERS}) == len(PARAMETERS)


def test_status_json_is_strict():
    text = status_json({'a': float('inf'), 'b': [1.0, float('nan')], 'c': {'d': -float('inf')}})
    assert json.loads(text) == {'a': None, 'b': [1.0, None], 'c': {'d': None}}


def test_tick_events_say_what_each_state_did(robot):
    """``SpgRunner.tick`` returns the command and the tick's events, in order: what the
    node logs and publishes (the shell never diffs the runner's counters)."""
    clock = FakeClock(100.0)
    runner = SpgRunner(SpgConfig(watchdog_timeout=0.05), robot, clock=clock)
    runner.handle_task_stack(STACK)
    q, z, names = robot.q_home.copy(), np.zeros(robot.n), robot.joint_names

    def kinds(*args):
        outcome = runner.tick(*args)
        return outcome.command is not None, [e.kind for e in outcome.events], outcome

    assert kinds(names, q, z, 0)[:2] == (True, ['stack_taken', 'started'])
    assert kinds(names, q, z, DT_NS)[:2] == (True, [])
    ok, events, out = kinds(names, q, z, 0)  # backwards while running
    assert (ok, events) == (False, ['rejected']) and 'stamp_backwards' in out.events[0].message
    assert kinds(names[:3], q[:3], z[:3], 2 * DT_NS)[:2] == (False, ['rejected'])
    # the SPG runs the new stack from the next tick
    runner.handle_task_stack(STACK.replace('name: reach', 'name: reach2'))
    ok, events, out = kinds(names, q, z, 2 * DT_NS)
    assert (ok, events) == (True, ['stack_taken']) and 'reach2' in out.events[0].message
    # a stamp gap trips the watchdog and restarts from the measured q
    assert kinds(names, q, z, 2 * DT_NS + 60_000_000)[:2] == (True, ['watchdog', 'resumed'])
    # a paused source (wall-clock watchdog) continuing its stamps
    clock.t += 0.2
    assert runner.check_watchdog()
    assert kinds(names, q, z, 3 * DT_NS + 60_000_000)[:2] == (True, ['continued'])
    assert runner.resumes == 1 and runner.watchdog_trips == 2


def test_live_markers_draw_each_wrench_tasks_commanded_force(robot):
    """``spg/markers`` of the node (MarkerPublisher) carries the commanded force of a wrench
    task as an arrow of FORCE_SCALE m/N at its frame: the demo's 8 N press, pointing down."""
    from types import SimpleNamespace

    from helpers import CONFIG
    import yaml

    from ifc_spg.node.markers import FORCE_SCALE, MarkerPublisher

    published = []
    node = SimpleNamespace(create_publisher=lambda *a: SimpleNamespace(publish=published.append),
                           create_timer=lambda *a: None, get_logger=lambda: None)
    runner = SpgRunner(SpgConfig(watchdog_timeout=0.0), robot)
    doc = yaml.safe_load((CONFIG / 'scenarios' / 'demo_lbr.yaml').read_text())
    assert runner.handle_task_stack(yaml.safe_dump(doc['stacks'][0]['stack'])).accepted
    q, z = robot.q_home.copy(), np.zeros(robot.n)
    for k in range(3):
        runner.handle_joint_state(robot.joint_names, q, z, k * DT_NS)
    markers = MarkerPublisher(node, runner, 30.0)
    markers.publish()
    [arr] = published
    arrows = [m for m in arr.markers if m.type == m.ARROW and len(m.points) == 2]
    assert [m.ns for m in arrows] == ['contact_force']
    start, end = (np.array([p.x, p.y, p.z]) for p in arrows[0].points)
    force = (end - start) / FORCE_SCALE
    assert np.linalg.norm(force) == pytest.approx(8.0, abs=1e-6) and force[2] < -7.0
    tool = runner.spg.kin.frame(robot.frame_id('tool'), virtual=False)[0]
    np.testing.assert_allclose(start, tool, atol=1e-12)
