"""Passive set-point modulation (SPEC 6): tanks never go negative and (4.84) holds."""

import numpy as np
import pytest

from ifc_spg import RobotModel
from ifc_spg.errors import ParameterError
from ifc_spg.pspm import EnergyTanks, PspmConfig
from ifc_spg.spg import SetPointGenerator
from ifc_spg.tasks import CartesianPoseTask, JointPositionTask
from ifc_spg.testing import JointImpedancePlant

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


@pytest.mark.parametrize('seed', [0, 1, 2])
def test_randomized_closed_loop_runs_are_passive(seed):
    rng = np.random.default_rng(seed)
    cfg = PspmConfig(initial_energy=float(rng.uniform(0.0, 0.2)),
                     max_energy=float(rng.uniform(0.2, 1.0)),
                     shuffle=float(rng.uniform(0.0, 1e-3)),
                     shuffle_budget=float(rng.uniform(0.0, 0.1)))
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
        return tasks

    spg = SetPointGenerator(robot, random_stack(), pspm=cfg)
    plant = JointImpedancePlant(robot, robot.q_home)
    q, qd, t = plant.q, plant.qdot, 0.0
    for i in range(3000):
        if i % 500 == 499:
            spg.set_stack(random_stack())
        q_v = spg.step(q, qd, t)
        assert spg.tanks.deficit < 1e-12
        assert np.all(spg.tanks.energy >= 0.0)
        tau_ext = rng.normal(scale=5.0, size=7) if rng.random() < 0.05 else None
        q, qd, t = plant.step(q_v, tau_ext=tau_ext)
    c2 = cfg.initial_energy + spg.tanks.shuffled  # E_K(0) = 0: q_v starts at q
    assert np.all(spg.tanks.shuffled <= cfg.shuffle_budget + 1e-15)
    np.testing.assert_array_less(-c2 - 1e-9, plant.work_in)


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
            np.testing.assert_allclose(dE, tanks._avail, rtol=1e-9, atol=1e-12)
        step = rng.uniform(box.lower, box.upper)
        tanks.update(q_new, q_v, step)
        assert np.all(tanks.energy >= 0) and np.all(tanks.energy <= 0.1)
        q = q_new


@pytest.mark.parametrize('kwargs', [dict(initial_energy=-1.0), dict(max_energy=float('nan')),
                                    dict(initial_energy=3.0, max_energy=1.0)])
def test_bad_config_is_rejected(kwargs):
    with pytest.raises(ParameterError, match='pspm'):
        PspmConfig(**kwargs)
