"""SetPointGenerator: closed loop, limits, bad input, fallbacks and the nullspace baseline."""

from pathlib import Path

import numpy as np
import pinocchio as pin
from plants import JointImpedancePlant
import pytest

from ifc_spg import RobotModel
from ifc_spg.cascade import CascadeResult, DaqpCascade, NullspaceCascade
from ifc_spg.errors import ParameterError
from ifc_spg.limits import VelocityBox
from ifc_spg.pspm import PspmConfig
from ifc_spg.spg import SetPointGenerator, SpgInfo
from ifc_spg.tasks import CartesianPoseTask, JointPositionTask, JointTorqueTask, Level, WrenchTask
from ifc_spg.tasks.task import Task

IIWA = RobotModel.from_config('lbr_iiwa14')
DT = 0.002


def tool_position(robot, q):
    data = robot.create_data()
    pin.framesForwardKinematics(robot.model, data, q)
    return data.oMf[robot.frame_id('tool')].translation.copy()


def closed_loop(spg, robot, ticks, q0=None, tau_ext=None):
    plant = JointImpedancePlant(robot, robot.q_home if q0 is None else q0, substeps=2)
    q, qd, t = plant.q, plant.qdot, 0.0
    log = []
    for _ in range(ticks):
        q_v = spg.step(q, qd, t)
        log.append((q_v, spg.qdot_v.copy(), spg.info.status))
        q, qd, t = plant.step(q_v, tau_ext=tau_ext)
    return q, log


def test_pose_task_converges_in_closed_loop():
    target = tool_position(IIWA, IIWA.q_home) + [0.05, -0.1, 0.08]
    tasks = [CartesianPoseTask(IIWA, frame='tool', axes=['x', 'y', 'z'], equal=target, gain=5.0),
             CartesianPoseTask(IIWA, frame='tool', axes=['rx', 'ry', 'rz'], equal='init',
                               gain=5.0, name='orientation'),
             JointPositionTask(IIWA, equal='init', gain=1.0, name='posture')]
    spg = SetPointGenerator(IIWA, tasks)
    q, log = closed_loop(spg, IIWA, 2000)
    assert all(s == 'ok' for _, _, s in log)
    np.testing.assert_allclose(tool_position(IIWA, log[-1][0]), target, atol=1e-4)
    np.testing.assert_allclose(tool_position(IIWA, q), target, atol=1e-3)


def check_limits(robot, log):
    q_v = np.array([x[0] for x in log])
    qd_v = np.array([x[1] for x in log])
    assert np.all(np.isfinite(q_v))
    assert np.all(q_v >= robot.q_min - 1e-12) and np.all(q_v <= robot.q_max + 1e-12)
    assert np.all(np.abs(qd_v) <= robot.v_max + 1e-9)
    assert np.all(np.abs(np.diff(q_v, axis=0)) <= robot.v_max * DT + 1e-9)


def test_contradictory_and_unreachable_stacks_stay_inside_limits():
    far = [3.0, 3.0, 3.0]  # unreachable position
    tasks = [CartesianPoseTask(IIWA, frame='tool', axes=['x', 'y', 'z'], equal=far, gain=50.0),
             JointPositionTask(IIWA, equal=IIWA.q_max + 1.0, gain=100.0, name='beyond_limits'),
             JointTorqueTask(IIWA, equal=1e4, gain=1e3, name='huge_torque')]
    spg = SetPointGenerator(IIWA, tasks)
    q, log = closed_loop(spg, IIWA, 1500)
    check_limits(IIWA, log)
    # torque limit task on top: |K (q_v - q)| stays within tau_max
    q_v = log[-1][0]
    assert np.all(np.abs(IIWA.stiffness * (q_v - q)) <= IIWA.tau_max * 1.05)


@pytest.mark.parametrize('pspm', [False, PspmConfig(initial_energy=100.0, max_energy=100.0)])
def test_acceleration_limit_holds_when_position_safety_allows(pspm):
    """|dqdot_v| <= a_max dT, also when braking into a joint limit. (An empty energy tank
    is a hard bound too and may stop a joint faster: passivity wins over smoothness.)"""
    tasks = [JointPositionTask(IIWA, equal=IIWA.q_home + 0.5, gain=20.0)]
    spg = SetPointGenerator(IIWA, tasks, pspm=pspm)
    _, log = closed_loop(spg, IIWA, 500)
    qd_v = np.array([x[1] for x in log])
    assert np.all(np.abs(np.diff(qd_v, axis=0)) <= IIWA.a_max * DT + 1e-9)
    check_limits(IIWA, log)


def test_singular_configuration_gives_finite_commands():
    q0 = np.zeros(7)  # stretched arm: singular
    tasks = [CartesianPoseTask(IIWA, frame='tool', equal=[0.5, 0, 0.8, 0, 0, 0], gain=10.0,
                               orientation=np.eye(3)),
             WrenchTask(IIWA, frame='tool', axes=['fz'], equal=10.0, gain=5.0)]
    spg = SetPointGenerator(IIWA, tasks)
    _, log = closed_loop(spg, IIWA, 300, q0=q0)
    check_limits(IIWA, log)


def test_non_finite_input_holds_the_last_command():
    spg = SetPointGenerator(IIWA, [JointPositionTask(IIWA, equal=IIWA.q_home + 0.2, gain=5.0)])
    q = IIWA.q_home.copy()
    for i in range(10):
        q_v = spg.step(q, np.zeros(7), i * DT)
    bad = q.copy()
    bad[3] = np.nan
    held = spg.step(bad, np.zeros(7), 10 * DT)
    assert spg.info.status == 'bad_input'
    np.testing.assert_array_equal(held, q_v)
    spg.step(q, np.zeros(7), float('inf'))
    assert spg.info.status == 'bad_input'
    with pytest.raises(ParameterError, match='7 entries'):
        spg.step(np.zeros(6), np.zeros(6), 0.0)


class _FailingCascade(DaqpCascade):
    """DAQP until ``failing`` is set; then its first level fails ('hold')."""

    failing = False

    def solve(self, levels, box, q_v=None):
        if not self.failing:
            return super().solve(levels, box, q_v)
        return CascadeResult(np.clip(np.zeros(self.n), box.lower, box.upper),
                             [np.full(lv.A.shape[0], np.nan) for lv in levels], 'hold', 0)


def test_failed_solve_holds_and_reports():
    solver = _FailingCascade(7)
    spg = SetPointGenerator(IIWA, [JointPositionTask(IIWA, equal=IIWA.q_home + 0.2, gain=5.0)],
                            solver=solver)
    assert spg.solver is solver
    q = IIWA.q_home.copy()
    q_v = spg.step(q, np.zeros(7), 0.0)
    solver.failing = True
    out = spg.step(q, np.zeros(7), DT)
    assert spg.info.status == 'hold' and spg.info.failed_level == 1  # (the torque limit is 0)
    assert "level 1 ('joint_position') could not be solved; holding q_v" in spg.info.message
    assert np.all(np.isfinite(out))
    np.testing.assert_allclose(out, q_v, atol=IIWA.a_max.max() * DT * DT)


def test_spg_info_is_frozen_and_rejects_unknown_fields():
    spg = SetPointGenerator(IIWA, [JointPositionTask(IIWA, equal='init')])
    spg.step(IIWA.q_home, np.zeros(7), 0.0)
    with pytest.raises(AttributeError):
        spg.info.status = 'ok'
    with pytest.raises(TypeError, match='unexpected keyword'):
        SpgInfo(status='ok', statuss='ok')


def test_nullspace_baseline_matches_cascade_for_equality_stacks():
    """For feasible equality hierarchies both give the minimum-norm solution (rho, lambda -> 0)."""
    rng = np.random.default_rng(11)
    box = VelocityBox(np.full(7, -1e3), np.full(7, 1e3))
    for _ in range(50):
        levels, rows = [], 0
        for i in range(int(rng.integers(2, 5))):
            m = int(rng.integers(1, 4))
            rows += m
            if rows > 6:  # keep the stack feasible and well conditioned
                break
            b = rng.normal(size=m)
            levels.append(Level(f'L{i}', rng.normal(size=(m, 7)), b, b, True))
        ns_solver = NullspaceCascade(7, q_min=IIWA.q_min, q_max=IIWA.q_max, damping=1e-7)
        ns, clamped = ns_solver.mapping(levels, np.zeros(7))
        assert clamped.size == 0
        np.testing.assert_allclose(ns_solver.solve(levels, box, np.zeros(7)).qdot_v, ns,
                                   rtol=0, atol=1e-12)
        hqp = DaqpCascade(7, rho=1e-12).solve(levels, box).qdot_v
        np.testing.assert_allclose(ns, hqp, rtol=1e-4, atol=1e-6)
    spg = SetPointGenerator(IIWA, [JointPositionTask(IIWA, equal='init')], solver='nullspace',
                            torque_limits=False)
    with pytest.raises(ParameterError, match='equality tasks only'):
        spg.set_stack([JointPositionTask(IIWA, lower=IIWA.q_min, gain=1.0)])
    with pytest.raises(ParameterError, match='equality tasks only'):
        SetPointGenerator(IIWA, [JointPositionTask(IIWA, lower=IIWA.q_min, gain=1.0)],
                          solver='nullspace', torque_limits=False)


def test_nullspace_saturates_the_box_within_the_hierarchy():
    """SNS: a joint that would leave the velocity box is saturated at its bound and the
    level is solved again with the others, so the level keeps its solution, where clipping
    the result per joint (the baseline before issue 21) breaks it; when the remaining
    joints cannot, the level is scaled down and stays inside the box."""
    lev = Level('L1', np.array([[2.0, 1.0, 1.0]]), np.array([3.0]), np.array([3.0]), True)
    box = VelocityBox(np.array([-0.5, -1.5, -1.5]), np.array([0.5, 1.5, 1.5]))
    ns = NullspaceCascade(3, damping=1e-9)
    free, _ = ns.mapping([lev], None)
    np.testing.assert_allclose(free, [1.0, 0.5, 0.5], atol=1e-8)  # min-norm, outside the box
    clipped = np.clip(free, box.lower, box.upper)
    assert abs(lev.A @ clipped - 3.0)[0] > 0.9
    qdot = ns.solve([lev], box).qdot_v
    np.testing.assert_allclose(qdot, [0.5, 1.0, 1.0], atol=1e-8)
    # infeasible: 2 qdot1 + qdot2 + qdot3 = 6 needs more than the box gives (max 4):
    # scaled by 4/6 with every joint on its bound
    big = Level('L1', lev.A, np.array([6.0]), np.array([6.0]), True)
    qdot = ns.solve([big], box).qdot_v
    np.testing.assert_allclose(qdot, [0.5, 1.5, 1.5], atol=1e-8)


def test_nullspace_box_saturation_keeps_the_higher_levels():
    """Seeded random two-level hierarchies with a binding box: the mapping stays in the box
    (without the last-guard clip);
    when the free mapping is inside the box after each level it is the result unchanged
    (SNS keeps every level's partial solution in the box); whenever the first
    level alone is solved unscaled, adding the second level does not change its residual
    (the saturations of level 2 go through level 1's null space)."""
    rng = np.random.default_rng(21)
    ns = NullspaceCascade(7, damping=1e-9)
    inside = kept = 0
    for _ in range(200):
        levels = []
        for i, m in enumerate((int(rng.integers(1, 4)), int(rng.integers(1, 3)))):
            b = rng.normal(size=m)
            levels.append(Level(f'L{i}', rng.normal(size=(m, 7)), b, b, True))
        half = rng.uniform(0.2, 2.0, size=7)
        box = VelocityBox(-half, half)
        free, _ = ns.mapping(levels, None)
        partial, _ = ns.mapping(levels[:1], None)
        qdot, _ = ns.mapping(levels, None, box)  # before the last-guard clip of solve()
        assert np.all(qdot >= box.lower - 1e-9) and np.all(qdot <= box.upper + 1e-9)
        if np.all(np.abs(free) <= half) and np.all(np.abs(partial) <= half):
            inside += 1
            np.testing.assert_allclose(qdot, free, atol=1e-9)
            continue
        first = ns.solve(levels[:1], box).qdot_v
        A1, b1 = levels[0].A, levels[0].lower
        if np.allclose(A1 @ first, b1, atol=1e-8):  # level 1 alone: exact, unscaled
            np.testing.assert_allclose(A1 @ qdot, b1, atol=1e-6)
            kept += 1
    assert inside > 20 and kept > 40, (inside, kept)


def test_nullspace_level_spanned_by_the_levels_above_moves_nothing():
    """A consistent level that the levels above already span (A2 = C A1) leaves A2 N at
    rounding (1e-14 |A2|), whatever the BLAS: its rank is 0 against |A2|, so it adds no
    motion and takes no direction from the null space, with or without the box; the
    levels below are solved as if it were absent (a rank taken against A2 N's own largest
    rounding value inverted noise: a random direction lost, qdot out of the box)."""
    rng = np.random.default_rng(5)
    ns = NullspaceCascade(7, damping=1e-9)
    for _ in range(40):
        A1 = rng.normal(size=(int(rng.integers(2, 4)), 7))
        b1 = rng.normal(size=A1.shape[0])
        C = rng.normal(size=(int(rng.integers(1, 3)), A1.shape[0]))
        A3, b3 = rng.normal(size=(2, 7)), rng.normal(size=2)
        top, low = Level('L1', A1, b1, b1, True), Level('L3', A3, b3, b3, True)
        mid = Level('L2', C @ A1, C @ b1, C @ b1, True)
        half = rng.uniform(0.2, 2.0, size=7)
        for box in (None, VelocityBox(-half, half)):
            with_mid, _ = ns.mapping([top, mid, low], None, box)
            without, _ = ns.mapping([top, low], None, box)
            np.testing.assert_allclose(with_mid, without, atol=1e-9)
            if box is not None:
                assert np.all(np.abs(with_mid) <= half + 1e-9)


def test_nullspace_with_torque_limits_is_refused_naming_the_fix():
    with pytest.raises(ParameterError, match='torque_limits=False'):
        SetPointGenerator(IIWA, None, solver='nullspace')


def test_nullspace_baseline_clamps_joints_near_limits():
    q0 = IIWA.q_home.copy()
    q0[0] = IIWA.q_max[0] - 0.01  # joint 1 within dl_crit of its limit
    tasks = [CartesianPoseTask(IIWA, frame='tool', axes=['y'], equal=[0.5], gain=5.0)]
    spg = SetPointGenerator(IIWA, tasks, solver='nullspace', pspm=False, torque_limits=False)
    _, log = closed_loop(spg, IIWA, 200, q0=q0)
    q_v = np.array([x[0] for x in log])
    assert q_v[:, 0].max() <= IIWA.q_max[0]
    assert q_v[-1, 0] <= q0[0] + 1e-9  # joint 1 was clamped, not driven into its limit


def test_without_the_velocity_box_only_the_position_limits_bound_qdot_v():
    """Alg. C.1/C.2 (the Ch. 3 baseline) know no velocity or acceleration limit:
    ``velocity_box=False`` leaves qdot_v above v_max and its step above a_max dT, and
    q_v inside its position limits (the one-step bound and C.2's clamp)."""
    target = tool_position(IIWA, IIWA.q_home) + [0.3, -0.3, 0.0]
    tasks = [CartesianPoseTask(IIWA, frame='tool', axes=['x', 'y', 'z'], equal=target,
                               gain=50.0)]
    runs = {}
    for box in (True, False):
        spg = SetPointGenerator(IIWA, tasks, solver='nullspace', pspm=False,
                                torque_limits=False, velocity_box=box)
        _, log = closed_loop(spg, IIWA, 50)
        runs[box] = np.array([x[1] for x in log]), np.array([x[0] for x in log])
    qd, _ = runs[True]
    assert np.all(np.abs(qd) <= IIWA.v_max + 1e-9)
    assert np.all(np.abs(np.diff(qd, axis=0)) <= IIWA.a_max * DT + 1e-9)
    qd, q_v = runs[False]
    assert np.any(np.abs(qd) > IIWA.v_max)
    assert np.abs(qd[0]).max() > IIWA.a_max.max() * DT  # from rest in one tick
    assert np.all((q_v >= IIWA.q_min) & (q_v <= IIWA.q_max))


def test_velocity_box_must_be_a_bool():
    with pytest.raises(ParameterError, match='velocity_box must be True'):
        SetPointGenerator(IIWA, None, velocity_box='off')
    from ifc_spg.node.config import SpgConfig
    with pytest.raises(ParameterError, match="'velocity_box': 'off' is a str, expected a bool"):
        SpgConfig(velocity_box='off')


def test_info_reports_levels_and_tanks():
    tasks = [JointPositionTask(IIWA, equal='init', name='posture')]
    spg = SetPointGenerator(IIWA, tasks)
    spg.step(IIWA.q_home, np.zeros(7), 0.0)
    d = spg.info.as_dict()
    assert d['level_names'] == ['torque_limits', 'posture']
    assert len(d['tank_energy']) == 7 and d['status'] == 'ok'
    assert d['solve_time'] > 0


def test_a_stacks_solver_models_are_built_when_it_is_accepted_not_at_its_first_tick():
    """Building DAQP models lazily made the first and the stack-switch tick 1-1.8 ms against
    a 0.1 ms median: set_stack builds them, so activating the stack builds none."""
    from ifc_spg import RobotModel, SetPointGenerator, TaskStack

    robot = RobotModel.from_config('lbr_iiwa14')
    cfg = Path(__file__).resolve().parent.parent / 'config' / 'tasks'
    first = TaskStack.from_file(str(cfg / 'table_4_3_pose_wrench_limits.yaml'))
    second = TaskStack.from_file(str(cfg / 'table_4_2_orientation_box.yaml'))
    spg = SetPointGenerator(robot, first, dt=0.002)
    solver = spg.solver
    q, qdot = np.array(robot.q_home, dtype=float), np.zeros(robot.n)
    built = solver.model_count
    assert built > 0                       # by set_stack, before any tick
    for k in range(5):
        q_v = spg.step(q, qdot, k * 0.002)
        qdot, q = (q_v - q) / 0.002, q_v
    assert solver.model_count == built     # the first ticks built nothing
    spg.set_stack(second)
    built = solver.model_count
    for k in range(5, 10):
        q_v = spg.step(q, qdot, k * 0.002)
        qdot, q = (q_v - q) / 0.002, q_v
    assert solver.model_count == built     # nor did the switch


def test_tick_says_what_happened_and_step_is_its_q_v():
    """``tick`` returns q_v, qdot_v, the info and the events of the tick; ``step`` the same
    q_v (two SPGs side by side, one ticked, one stepped, stay bit-identical)."""
    def stack(dz):
        target = tool_position(IIWA, IIWA.q_home) + [0.0, 0.0, dz]
        return [CartesianPoseTask(IIWA, frame='tool', axes=['x', 'y', 'z'], equal=target,
                                  gain=5.0),
                JointPositionTask(IIWA, equal='init', gain=1.0, name='posture')]
    ticked, stepped = SetPointGenerator(IIWA, stack(0.05)), SetPointGenerator(IIWA, stack(0.05))
    plant = JointImpedancePlant(IIWA, IIWA.q_home, substeps=2)
    q, qd, t = plant.q, plant.qdot, 0.0
    events = []
    for k in range(300):
        if k == 100:
            ticked.set_stack(stack(-0.05))
            stepped.set_stack(stack(-0.05))
        if k == 200:
            ticked.reset(q)
            stepped.reset(q)
        tick = ticked.tick(q, qd, t)
        q_v = stepped.step(q, qd, t)
        np.testing.assert_array_equal(tick.q_v, q_v)
        np.testing.assert_array_equal(tick.qdot_v, stepped.qdot_v)
        assert tick.info is ticked.info and tick.info.status == 'ok'
        events.append(tick.events)
        q, qd, t = plant.step(q_v)
    assert events[0] == ('stack_taken', 'activated')  # the constructor's stack
    assert events[100] == ('stack_taken', 'activated')
    assert events[200] == ('activated',)
    assert all(e == () for k, e in enumerate(events) if k not in (0, 100, 200))
    bad = ticked.tick(np.full(IIWA.n, np.nan), qd, t)
    assert bad.events == ('bad_input',) and bad.info.status == 'bad_input'
    np.testing.assert_array_equal(bad.q_v, ticked.q_v)  # held


def test_the_construction_warm_up_changes_no_result(monkeypatch):
    """The warm-up (13 ticks and a stack switch of a throwaway SPG, once per process and
    configuration) runs at construction, and each stack's dry run (its levels and cascade
    once, at set_stack) runs before its first tick; both leave the results alone: closed
    loops of the Table 4.3 stack switched to Table 4.2 and back, and restarted, with and
    without them are equal bit for bit, first and switch ticks included."""
    from ifc_spg import TaskStack
    from ifc_spg.offline.runner import find_config_dir
    import ifc_spg.spg as spg_module

    tasks = find_config_dir() / 'tasks'
    stacks = [TaskStack.from_file(str(tasks / name)) for name in
              ('table_4_3_pose_wrench_limits.yaml', 'table_4_2_orientation_box.yaml')]

    step, steps = SetPointGenerator.step, []

    def counted_step(self, *args):
        steps.append(self)
        return step(self, *args)

    monkeypatch.setattr(SetPointGenerator, 'step', counted_step)
    level, leveled = Task.level, []

    def counted_level(self, *args):
        leveled.append(self)
        return level(self, *args)

    monkeypatch.setattr(Task, 'level', counted_level)

    def run(warm_up):  # the process's record of warm-ups has no public API: emptied here
        monkeypatch.setattr(spg_module, '_WARMED_UP', set())
        steps.clear()
        spg = SetPointGenerator(IIWA, stacks[0], warm_up=warm_up)
        assert len(steps) == (spg_module._WARM_UP_TICKS + 3 if warm_up else 0)
        # the stack's tasks built their levels before its first tick only in the dry run
        assert (set(spg.pending_tasks) <= set(leveled)) == warm_up
        assert spg not in steps and len(spg_module._WARMED_UP) == int(warm_up)
        if warm_up:  # warmed up already: a second SPG runs none
            SetPointGenerator(IIWA, stacks[0])
            assert len(steps) == spg_module._WARM_UP_TICKS + 3
        plant = JointImpedancePlant(IIWA, IIWA.q_home, substeps=2)
        q, qd, t = plant.q, plant.qdot, 0.0
        log = []
        for k in range(300):
            if k in (150, 225):
                leveled.clear()
                spg.set_stack(stacks[int(k == 150)])
                assert (set(spg.pending_tasks) <= set(leveled)) == warm_up
            if k == 260:
                spg.reset(q)  # a restart: init values captured anew
            q_v = spg.step(q, qd, t)
            assert spg.info.status == 'ok', (k, spg.info.message)
            log.append(np.concatenate([q_v, spg.qdot_v, spg.tanks.energy]))
            q, qd, t = plant.step(q_v)
        return np.array(log)

    cold, warm = run(False), run(True)
    assert np.array_equal(cold, warm)
    assert np.abs(cold[150] - cold[0]).max() > 0  # the loop moved
    assert np.abs(cold[259] - cold[225]).max() > 0
