"""Passive set-point modulation (docs/SPEC.md §6): tanks never go negative and (4.84) holds."""

import numpy as np
from plants import JointImpedancePlant
import pytest

from ifc_spg import RobotModel
from ifc_spg.errors import ParameterError
from ifc_spg.pspm import EnergyTanks, PspmConfig
from ifc_spg.spg import SetPointGenerator
from ifc_spg.tasks import CartesianPoseTask, JointPositionTask

IIWA = RobotModel.from_config('lbr_iiwa14')


def low_damping_iiwa(d5=0.5):
    """The iiwa with little intrinsic damping on joint 5 (Table 4.5 needs it: by Routh,
    I s^3 + (I k_p + D) s^2 + (D k_p + K (1 - k_d)) s + K k_p is unstable for
    D < ~0.9 Nms/rad with I = 0.034 kg m^2, K = 200, k_p = 100, k_d = 0.8)."""
    D = IIWA.damping.copy()
    D[4] = d5
    return RobotModel(IIWA.model, name='iiwa_low_damping', frames=IIWA.frames,
                      stiffness=IIWA.stiffness, damping=D, v_max=IIWA.v_max,
                      a_max=IIWA.a_max, q_home=IIWA.q_home)


def run_table_4_5(pspm, seconds=10.0):
    robot = low_damping_iiwa()
    regulator = JointPositionTask(robot, joints=['A5'], equal=robot.q_home[4], gain=100.0,
                                  velocity_gain=0.8, name='joint5')
    spg = SetPointGenerator(robot, [regulator], pspm=pspm)
    plant = JointImpedancePlant(robot, robot.q_home)
    q, qd, t = plant.q, plant.qdot, 0.0
    err = []
    for i in range(int(seconds / 0.002)):
        q_v = spg.step(q, qd, t)
        kick = np.zeros(7)
        kick[4] = 2.0 if i < 50 else 0.0  # a short push starts the oscillation
        q, qd, t = plant.step(q_v, tau_ext=kick)
        err.append(q[4] - robot.q_home[4])
    return np.array(err), plant, spg


def test_table_4_5_regulator_is_stabilized_by_pspm():
    cfg = PspmConfig(initial_energy=0.01, max_energy=0.05)
    c2 = cfg.initial_energy  # E_K(0) = 0 (q_v starts at q), no shuffling
    err_off, plant_off, _ = run_table_4_5(pspm=False)
    err_on, plant_on, spg = run_table_4_5(pspm=cfg)
    # without PSPM the SPG keeps injecting energy: the passivity bound is broken
    assert plant_off.work_in[4] < -2 * c2
    assert np.abs(err_off[-500:]).max() > 5e-3  # sustained oscillation
    # with PSPM the joint stays passive and the oscillation dies out
    assert plant_on.work_in[4] >= -c2 - 1e-9
    assert np.abs(err_on[-500:]).max() < 1e-3
    assert spg.info.tank_energy.min() >= 0.0
    print(f'Table 4.5: energy into joint 5 without PSPM {-plant_off.work_in[4]:.4f} J, '
          f'with PSPM {-plant_on.work_in[4]:.4f} J (bound c^2 = {c2} J)')


@pytest.mark.parametrize('seed', [0, 1, 2, 3, 4, 5])
def test_randomized_closed_loop_runs_are_passive(seed):
    """(4.84) with the power budget: per joint -int tau qdot >= -(c^2 + R_j), the refill
    sum_j R_j <= P t, and on the SPG's side the spring energy its steps added is at most
    E_r,init + sum E_Dmin + shuffled + refilled. Seeds 0-2 are strictly passive (P = 0)."""
    rng = np.random.default_rng(seed)
    power = 0.0 if seed < 3 else float(rng.uniform(0.05, 3.0))
    cfg = PspmConfig(initial_energy=float(rng.uniform(0.0, 0.2)),
                     max_energy=float(rng.uniform(0.2, 1.0)),
                     shuffle=float(rng.uniform(0.0, 1e-3)),
                     shuffle_budget=float(rng.uniform(0.0, 0.1)),
                     max_power=power * float(rng.uniform(1.0, 2.0)))
    robot = IIWA
    lo, hi = robot.q_min, robot.q_max

    def random_stack():
        target = robot.q_home + rng.normal(scale=0.4, size=7)
        tasks = [JointPositionTask(robot, equal=np.clip(target, lo + 0.1, hi - 0.1),
                                   gain=float(rng.uniform(1, 50)), velocity_gain=float(
                                       rng.uniform(0, 1.0)), name='posture')]
        if rng.random() < 0.5:
            tasks.insert(0, CartesianPoseTask(robot, frame='tool', axes=['x', 'y', 'z'],
                                              lower=[0.3, -0.3, 0.2], upper=[0.6, 0.3, 0.6],
                                              gain=10.0, name='box'))
        return TaskStack_(tasks, power)

    spg = SetPointGenerator(robot, random_stack(), pspm=cfg)
    plant = JointImpedancePlant(robot, robot.q_home)
    q, qd, t = plant.q, plant.qdot, 0.0
    spring_in = np.zeros(7)      # sum of 1/2 K ((dq + delta)^2 - dq^2): what the steps added
    dissipated = np.zeros(7)     # sum of E_Dmin booked into the tanks
    ticks = 3000
    for i in range(ticks):
        if i % 500 == 499:
            spg.set_stack(random_stack())
        q_v = spg.step(q, qd, t)
        assert spg.tanks.deficit < 1e-12
        assert np.all(spg.tanks.energy >= 0.0)
        assert spg.info.power_budget == power
        spring_in += spg.info.spring_energy_step
        dissipated += spg.tanks.dissipated_min
        # a dissipative environment the tanks cannot see (friction), and random pushes
        tau_ext = -3.0 * qd
        if rng.random() < 0.05:
            tau_ext = tau_ext + rng.normal(scale=5.0, size=7)
        q, qd, t = plant.step(q_v, tau_ext=tau_ext)
    refilled = spg.tanks.refilled
    assert np.all(refilled >= 0.0)
    assert refilled.sum() <= power * ticks * 0.002 * (1 + 1e-12)
    if power > 0:  # the budget was used, not only allowed
        assert refilled.sum() > 0.2 * power * ticks * 0.002
    c2 = cfg.initial_energy + spg.tanks.shuffled  # E_K(0) = 0: q_v starts at q
    assert np.all(spg.tanks.shuffled <= cfg.shuffle_budget + 1e-15)
    np.testing.assert_array_less(-(c2 + refilled) - 1e-9, plant.work_in)
    assert -plant.work_in.sum() <= (c2.sum() + power * ticks * 0.002) + 1e-9
    np.testing.assert_array_less(spring_in, c2 + dissipated + refilled + 1e-9)


class TaskStack_(list):
    """A list of tasks with the power_budget [W] a task stack declares."""

    def __init__(self, tasks, power_budget):
        super().__init__(tasks)
        self.power_budget = power_budget


def test_refill_goes_to_the_emptiest_tanks_and_never_beyond_the_budget():
    K = np.full(4, 100.0)
    cfg = PspmConfig(initial_energy=0.0, max_energy=1.0, max_power=10.0)  # fill up to E_max
    tanks = EnergyTanks(K, np.ones(4), np.array([True, True, True, False]), 0.002, cfg)
    tanks.reset(np.zeros(4))
    tanks.set_power(10.0)
    tanks.energy = np.array([0.0, 0.5, 1.0, 0.0])
    tanks.bounds(np.zeros(4), np.zeros(4))
    tanks.update(np.zeros(4), np.zeros(4), np.zeros(4))
    # emptiest first: joint 1 is raised to 0.04 J; the stiff joint 4 gets nothing
    np.testing.assert_allclose(tanks.refilled, [0.02, 0.0, 0.0, 0.0])
    tanks.energy = np.array([0.3, 0.31, 1.0, 0.0])
    tanks.bounds(np.zeros(4), np.zeros(4))
    tanks.update(np.zeros(4), np.zeros(4), np.zeros(4))  # both raised to 0.315 J
    np.testing.assert_allclose(tanks.refilled, [0.035, 0.005, 0.0, 0.0])
    tanks.energy = np.array([0.995, 1.0, 1.0, 0.0])  # nearly full: the rest is not taken
    tanks.bounds(np.zeros(4), np.zeros(4))
    tanks.update(np.zeros(4), np.zeros(4), np.zeros(4))
    np.testing.assert_allclose(tanks.refilled, [0.04, 0.005, 0.0, 0.0])
    with pytest.raises(ParameterError, match=r'power_budget 11 W exceeds the ceiling of 10 W'
                                             r'.*pspm.max_power'):
        tanks.set_power(11.0)
    # with E_r,init > 0 the refill stops there: the room above is for energy given back
    tanks = EnergyTanks(K, np.ones(4), np.ones(4, bool), 0.002,
                        PspmConfig(initial_energy=0.3, max_energy=1.0, max_power=200.0))
    tanks.reset(np.zeros(4))
    tanks.set_power(200.0)  # 0.4 J per tick, more than the room below 0.3 J
    tanks.energy = np.array([0.0, 0.25, 0.5, 0.3])
    tanks.bounds(np.zeros(4), np.zeros(4))
    tanks.update(np.zeros(4), np.zeros(4), np.zeros(4))
    np.testing.assert_allclose(tanks.refilled, [0.3, 0.05, 0.0, 0.0])
    np.testing.assert_allclose(tanks.energy, [0.3, 0.3, 0.5, 0.3])


def test_a_stack_asking_for_more_than_the_ceiling_is_rejected_naming_both_numbers():
    from ifc_spg.task_stack import TaskStack, TaskStackError

    text = ('version: 1\nname: slide\npower_budget: 2.5\n'
            'tasks: [{name: posture, type: joint_position, equal: 0.0}]\n')
    stack = TaskStack.from_yaml(text, source='slide.yaml')
    strict = SetPointGenerator(IIWA, pspm=PspmConfig())
    with pytest.raises(TaskStackError, match=r'slide.yaml: power_budget: power_budget 2.5 W '
                                             r'.*strictly passive.*pspm.max_power:=2.5'):
        strict.set_stack(stack)
    low = SetPointGenerator(IIWA, pspm=PspmConfig(max_power=1.0))
    with pytest.raises(TaskStackError, match=r'2.5 W exceeds the ceiling of 1 W set by the '
                                             r'spg_node parameter pspm.max_power'):
        low.set_stack(stack)
    ok = SetPointGenerator(IIWA, pspm=PspmConfig(max_power=2.5))
    ok.set_stack(stack)
    ok.step(IIWA.q_home, np.zeros(7), 0.0)
    assert ok.info.power_budget == 2.5 and ok.info.pspm['power_budget'] == 2.5
    SetPointGenerator(IIWA, pspm=False).set_stack(stack)  # no tanks: nothing to refill


def _drive_a1_against_friction(power, seconds=6.0, friction=2.0):
    """Joint A1 follows a 0.3 rad, 0.5 Hz sine against viscous friction [Nms/rad] that the
    tanks cannot see: about 0.9 W of work on the environment."""
    from ifc_spg.task_stack import TaskStack

    stack = TaskStack.from_dict({
        'version': 1, 'name': 'a1_sine', 'power_budget': power,
        'tasks': [{'name': 'a1', 'type': 'joint_position', 'joints': ['A1'], 'gain': 10.0,
                   'equal': {'trajectory': 'sine', 'amplitude': 0.3, 'frequency': 0.5}},
                  {'name': 'rest', 'type': 'joint_position', 'equal': 'init', 'gain': 5.0}]})
    spg = SetPointGenerator(IIWA, stack, pspm=PspmConfig(max_power=max(power, 0.0)))
    plant = JointImpedancePlant(IIWA, IIWA.q_home, substeps=4)
    q, qd, t = plant.q, plant.qdot, 0.0
    swing, new, reports = [], 0, []
    for _ in range(int(seconds / 0.002)):
        q_v = spg.step(q, qd, t)
        new += spg.info.stall_new
        if spg.info.stall is not None:
            reports.append(spg.info)
        tau = np.zeros(7)
        tau[0] = -friction * qd[0]
        q, qd, t = plant.step(q_v, tau_ext=tau)
        if t > seconds - 2.0:
            swing.append(q[0] - IIWA.q_home[0])
    return np.ptp(swing), new, reports, spg


def test_an_empty_tank_that_stalls_the_stack_is_diagnosed_once_and_the_budget_fixes_it():
    span, new, reports, spg = _drive_a1_against_friction(power=0.0)
    assert span < 0.3          # the sine (0.6 rad peak to peak) is stalled
    assert new == 1            # reported once in the episode
    info = reports[-1]
    stall = info.pspm['stall']
    assert stall['joints'] == ['A1']
    assert 0.2 < stall['total_power'] < 5.0, stall
    assert 'power_budget' in stall['fix'] and 'pspm.max_power' in stall['fix']
    assert info.message.startswith('PSPM stall: the energy tanks of A1 are empty')
    assert info.status == 'ok'
    need = float(stall['fix'].split('power_budget: ')[1].split("'")[0])
    assert need >= 2 * stall['total_power']
    # a budget for the ~1 W of friction work (with the margin the tanks need) lets it run
    need = 10.0
    span, new, reports, spg = _drive_a1_against_friction(power=need)
    assert span > 0.55 and new == 0 and not reports
    assert spg.tanks.refilled.sum() <= need * 6.0


def test_the_info_is_a_snapshot_of_its_tick_not_the_live_tanks():
    from ifc_spg.task_stack import TaskStack

    stack = TaskStack.from_dict({
        'version': 1, 'name': 'a1_sine', 'power_budget': 10.0,
        'tasks': [{'name': 'a1', 'type': 'joint_position', 'joints': ['A1'], 'gain': 10.0,
                   'equal': {'trajectory': 'sine', 'amplitude': 0.3, 'frequency': 0.5}},
                  {'name': 'rest', 'type': 'joint_position', 'equal': 'init', 'gain': 5.0}]})
    spg = SetPointGenerator(IIWA, stack, pspm=PspmConfig(max_power=10.0))
    plant = JointImpedancePlant(IIWA, IIWA.q_home, substeps=4)
    q, qd, t = plant.q, plant.qdot, 0.0
    kept = []
    for i in range(600):
        q, qd, t = plant.step(spg.step(q, qd, t), tau_ext=np.r_[-2.0 * qd[0], np.zeros(6)])
        if i % 100 == 0:
            kept.append((spg.info, spg.info.tank_energy.copy(), spg.info.pspm))
    assert not np.array_equal(kept[0][1], spg.tanks.energy)   # the tanks moved on ...
    assert sum(kept[0][2]['refilled']) < spg.tanks.refilled.sum()
    for info, energy, pspm in kept:  # ... the infos of earlier ticks did not
        np.testing.assert_array_equal(info.tank_energy, energy)
        assert info.pspm == pspm
        assert not any(isinstance(getattr(info, f), EnergyTanks) for f in info.__slots__)


def test_bounds_are_exact_and_contain_zero():
    rng = np.random.default_rng(4)
    K = rng.uniform(20, 400, 7)
    tanks = EnergyTanks(K, rng.uniform(0.5, 5, 7), np.ones(7, bool), 0.002,
                        PspmConfig(initial_energy=0.05, max_energy=0.1))
    q = rng.normal(size=7)
    tanks.reset(q)
    for _ in range(100):
        q_new = q + rng.normal(scale=1e-3, size=7)
        q_v = q_new + rng.normal(scale=0.05, size=7)
        box = tanks.bounds(q_new, q_v)
        assert np.all(box.lower <= 0) and np.all(box.upper >= 0)
        # a step exactly on either bound uses exactly the available energy
        for edge in (box.lower, box.upper):
            dq = q_v - q_new
            dE = 0.5 * K * ((dq + 0.002 * edge) ** 2 - dq ** 2)
            np.testing.assert_allclose(dE, tanks.available, rtol=1e-9, atol=1e-12)
        step = rng.uniform(box.lower, box.upper)
        tanks.update(q_new, q_v, step)
        assert np.all(tanks.energy >= 0) and np.all(tanks.energy <= 0.1)
        q = q_new


@pytest.mark.parametrize('kwargs', [dict(initial_energy=-1.0), dict(max_energy=float('nan')),
                                    dict(initial_energy=3.0, max_energy=1.0)])
def test_bad_config_is_rejected(kwargs):
    with pytest.raises(ParameterError, match='pspm'):
        PspmConfig(**kwargs)


A1_SINE = """version: 1
name: a1_sine
tasks:
  - {name: a1, type: joint_position, joints: [A1], gain: 10.0,
     equal: {trajectory: sine, amplitude: 0.3, frequency: 0.5}}
  - {name: rest, type: joint_position, equal: init, gain: 5.0}
"""


def test_the_node_logic_reports_a_stall_on_status_and_diagnostics_once_per_episode():
    from ifc_spg.node.config import SpgConfig
    from ifc_spg.node.core import SpgRunner, status_json

    runner = SpgRunner(SpgConfig(robot='lbr_iiwa14', status_decimation=1))
    too_much = runner.handle_task_stack(A1_SINE.replace('tasks:', 'power_budget: 3\ntasks:'),
                                        source='a1.yaml')
    assert not too_much.accepted
    assert 'a1.yaml' in too_much.message and 'power_budget 3 W' in too_much.message
    assert 'pspm.max_power' in too_much.message
    assert runner.handle_task_stack(A1_SINE).accepted
    plant = JointImpedancePlant(IIWA, IIWA.q_home, substeps=4)
    q, qd, t = plant.q, plant.qdot, 0.0
    levels, logged = [], 0
    for i in range(1500):
        before = runner.pspm_stalls
        runner.handle_joint_state(IIWA.joint_names, q, qd, round(t * 1e9))
        logged += runner.pspm_stalls != before
        if i % 50 == 0:
            levels.append(runner.diagnostics().level)
        tau = np.zeros(7)
        tau[0] = -2.0 * qd[0]
        q, qd, t = plant.step(runner.spg.q_v, tau_ext=tau)
    assert logged == 1 and runner.pspm_stalls == 1
    assert levels[0] == 'OK' and levels[-1] == 'WARN'
    status = runner.status()
    stall = status['pspm']['stall']
    assert stall['joints'] == ['A1'] and stall['total_power'] > 0.0
    assert status['spg']['status'] == 'ok' and status['spg']['message'] == stall['message']
    assert status['pspm']['power_budget'] == 0.0 and status['pspm']['stalls'] == 1
    assert any(e['source'] == 'pspm' for e in status['errors'])
    diag = runner.diagnostics()
    assert diag.values['pspm.stalled_joints'] == 'A1'
    assert 'power_budget' in diag.values['pspm.fix'] and 'pspm.max_power' in diag.message
    status_json(status)  # strict JSON
