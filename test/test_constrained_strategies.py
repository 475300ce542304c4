"""Tests of the three constrained-manipulation strategies: tick-level oracles and closed-loop
runs in the lockstep MuJoCo scenes (LBR-IV joint impedance, K = 40 / 200 Nm/rad)."""

import math

import numpy as np
import pytest

from ifc_spg.constrained import (
    ConstrainedWrenchTask,
    DirectionEstimator,
    FixedDirection,
    JointComplianceStrategy,
    StrategyParams,
    build_tasks,
)
from ifc_spg.constrained.evaluate import CRANK_ESTIMATOR
from ifc_spg.constrained.runner import Scenario, robot_with_stiffness, run
from ifc_spg.errors import ParameterError, UnknownFrame
from ifc_spg.kinematics import Kinematics
from ifc_spg.tasks import WrenchTask
from ifc_spg.tasks.static_interaction import static_wrench


@pytest.fixture(scope='module')
def lbr():
    return robot_with_stiffness('lbr4', 40.0)


def _kin(robot, rng):
    kin = Kinematics(robot)
    q = robot.q_home + rng.normal(scale=0.2, size=robot.n)
    kin.update(q, rng.normal(scale=0.1, size=robot.n), q + rng.normal(scale=0.05, size=robot.n))
    return kin


def test_wrench_level_equals_a_plain_wrench_task_with_the_table_5_1_bounds(lbr):
    """Level 1 == WrenchTask(S = [I3; 0], equal = P f_s, ff = kappa d, no compensation)."""
    rng = np.random.default_rng(7)
    kin = _kin(lbr, rng)
    d = np.array([0.3, -0.2, 0.9])
    task = ConstrainedWrenchTask(lbr, frame='tool', estimator=FixedDirection(d), kappa=9.0,
                                 gain=30.0)
    level = task.level(kin, 0.0)
    d = d / np.linalg.norm(d)
    f = static_wrench(lbr, kin, 'tool')[0][:3]
    ref = WrenchTask(lbr, frame='tool', axes=('fx', 'fy', 'fz'), equal=d * (d @ f), gain=30.0,
                     feedforward=9.0 * d, compensate_velocity=False).level(kin, 0.0)
    np.testing.assert_allclose(level.A, ref.A, atol=1e-12)
    np.testing.assert_allclose(level.lower, ref.lower, atol=1e-12)
    np.testing.assert_allclose(level.upper, ref.upper, atol=1e-12)
    # With the velocity compensation on, gamma = S^T J^{+T} K qdot is added back (5.13).
    on = ConstrainedWrenchTask(lbr, frame='tool', estimator=FixedDirection(d), kappa=9.0,
                               gain=30.0, compensate_velocity=True).level(kin, 0.0)
    np.testing.assert_allclose(on.lower - level.lower, static_wrench(lbr, kin, 'tool')[2][:3],
                               atol=1e-12)


def test_task_level_updates_the_estimator_from_the_measured_velocity(lbr):
    rng = np.random.default_rng(2)
    kin = _kin(lbr, rng)
    est = DirectionEstimator(window=1, v_threshold=0.0, initial_direction=(1, 0, 0))
    task = ConstrainedWrenchTask(lbr, frame='tool', estimator=est)
    task.level(kin, 0.1)
    _, _, J = kin.frame(lbr.frame_id('tool'), virtual=False)
    v = J[:3] @ kin.qdot
    np.testing.assert_allclose(est.direction, v / np.linalg.norm(v), atol=1e-12)


def test_joint_compliance_step_aligns_the_static_wrench_with_d(lbr):
    """After one tick (5.9) the static wrench is along [d; 0]: no f_perp, no moment."""
    rng = np.random.default_rng(4)
    q = lbr.q_home + rng.normal(scale=0.2, size=lbr.n)
    d = np.array([0.0, 0.6, 0.8])
    params = StrategyParams(orientation='free')
    jc = JointComplianceStrategy(lbr, params, estimator=FixedDirection(d))
    jc.reset(q)
    jc.q_v = q + rng.normal(scale=0.02, size=lbr.n)  # accumulated erroneous torques
    q_v = jc.step(q, np.zeros(lbr.n), 0.0)
    kin = Kinematics(lbr)
    kin.update(q, np.zeros(lbr.n), q_v)
    # The static torque K (q_v - q) is exactly J^T [s d; 0] for some s ...
    tau = lbr.stiffness * (q_v - q)
    jtd = kin.frame(lbr.frame_id('tool'), virtual=False)[2][:3].T @ (d / np.linalg.norm(d))
    s = (tau @ jtd) / (jtd @ jtd)
    np.testing.assert_allclose(tau, s * jtd, atol=1e-9 * np.abs(tau).max())
    # ... so the static wrench (damped J^{+T}, lambda = 1e-3) is along [d; 0] to ~lambda^2.
    h = static_wrench(lbr, kin, 'tool')[0]
    f_par = h[:3] @ d
    assert abs(f_par) > 0.1
    assert np.linalg.norm(h[:3] - f_par * d) < 1e-4 * abs(f_par)
    assert np.linalg.norm(h[3:]) < 1e-4 * abs(f_par)


def test_build_tasks_levels_and_errors(lbr):
    tasks = build_tasks(lbr, {'frame': 'tool', 'kappa': 5, 'orientation': 'align_z',
                              'estimator': {'window': 100}})
    assert [t.name for t in tasks] == ['constrained.exploration', 'constrained.hold_z',
                                       'constrained.align_z', 'constrained.posture']
    assert all(getattr(t, 'estimator', tasks[0].estimator) is tasks[0].estimator for t in tasks)
    assert len(build_tasks(lbr, {'orientation': 'release_y', 'posture': False})) == 3
    with pytest.raises(ParameterError, match="unknown key 'kapa'; did you mean 'kappa'"):
        build_tasks(lbr, {'kapa': 5})
    with pytest.raises(ParameterError, match="orientation 'align' unknown.*align_z"):
        build_tasks(lbr, {'orientation': 'align'})
    with pytest.raises(ParameterError, match="unknown key 'estimator.N'"):
        build_tasks(lbr, {'estimator': {'N': 3}})
    with pytest.raises(ParameterError, match="'force' must be 'measured'"):
        build_tasks(lbr, {'force': 3.0})
    with pytest.raises(UnknownFrame, match="'tol'"):
        build_tasks(lbr, {'frame': 'tol'})


def _run(strategy, scene='drawer_vertical', target=0.29, duration=30.0, **kw):
    options = {} if scene.startswith('drawer') else {'grasp': 'connect'}
    params = kw.pop('params', StrategyParams())
    log = run(Scenario(strategy=strategy, scene=scene, params=params, target=target,
                       duration=duration, scene_options=options, **kw))
    assert log.warnings == {}
    return log


def test_joint_compliance_opens_the_vertical_drawer_from_45_degrees():
    m = _run('joint_compliance').metrics
    assert m['success'], m
    assert m['final_error_angle_deg'] < 2.0


def test_task_specification_opens_the_vertical_drawer_from_45_degrees():
    # kappa = 15 N/s (thesis range 5...15) keeps the run short; kappa = 9 opens it in ~32 s.
    m = _run('task_specification', params=StrategyParams(kappa=15.0)).metrics
    assert m['success'], m
    assert m['final_error_angle_deg'] < 2.0


def test_admittance_strategy_opens_the_vertical_drawer_on_the_lbr():
    """Sec. 5.4.3: the Cartesian strategy on a joint-impedance robot opens the drawer but
    leaves erroneous forces (misaligned deflection and force)."""
    log = _run('admittance')
    m = log.metrics
    assert m['success'], m
    jc = _run('joint_compliance').metrics
    assert m['rms_f_perp'] > jc['rms_f_perp']


@pytest.mark.parametrize('strategy', ['joint_compliance', 'task_specification'])
def test_crank_quarter_turn(strategy):
    params = StrategyParams(orientation='free', estimator=CRANK_ESTIMATOR)
    m = _run(strategy, scene='crank', target=math.pi / 2, params=params).metrics
    assert m['success'], m


@pytest.mark.parametrize('strategy', ['joint_compliance', 'task_specification'])
def test_microwave_door_opens(strategy):
    m = _run(strategy, scene='microwave_door', target=0.4).metrics
    assert m['success'], m
    assert m['max_force'] < 40.0


def test_task_specification_has_less_f_perp_than_joint_compliance_at_k200():
    """SPEC 7 trend, fixed true direction (5.5.3), K = 200 Nm/rad, short run."""
    params = StrategyParams(stiffness=200.0)
    jc = _run('joint_compliance', params=params, fixed_direction=True, target=0.05,
              duration=8.0).metrics
    ts = _run('task_specification', params=params, fixed_direction=True, target=0.05,
              duration=8.0).metrics
    assert ts['travel'] > 0.02
    assert ts['rms_f_perp'] < 0.7 * jc['rms_f_perp'], (jc, ts)
