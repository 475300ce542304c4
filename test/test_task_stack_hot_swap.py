"""Hot swap: a new stack replaces the running one between ticks without a jump.

On the iiwa 14 in a joint-impedance plant, switch between two different stacks mid-motion
and check every tick: |dq_v| <= v_max dT and |d qdot_v| <= a_max dT. A rejected stack
leaves the running one untouched.
"""

from types import ModuleType

import numpy as np
from plants import JointImpedancePlant
import pytest

from ifc_spg import kernels
from ifc_spg.limits import VelocityBox
from ifc_spg.model import RobotModel
from ifc_spg.spg import SetPointGenerator
from ifc_spg.task_stack import TaskStack, TaskStackError

DT = 0.002

CIRCLE = """
version: 1
name: circle
tasks:
  - name: orientation
    type: cartesian_pose
    frame: tool
    subspace: [rx, ry, rz]
    equal: init
    gain: 5.0
  - name: circle
    type: cartesian_pose
    frame: tool
    subspace: [x, y, z]
    equal: {trajectory: circle, plane: xy, radius: 0.1, frequency: 0.5}
    gain: 10.0
  - name: posture
    type: joint_position
    equal: 0.0
"""

SWING = """
version: 1
name: swing
tasks:
  - name: swing
    type: joint_position
    joints: [A1, A4, A6]
    equal: {trajectory: sine, amplitude: [0.6, 0.4, 0.5], frequency: [0.7, 0.9, 0.5],
            phase: [3.0, 1.0, 2.0]}
    gain: 20.0
  - name: rest
    type: joint_position
    equal: init
"""


def run(pspm, switches, ticks=900, record=False):
    """Run with stack switches at the given ticks; returns per-tick records."""
    robot = RobotModel.from_config('lbr_iiwa14')
    stacks = {'circle': TaskStack.from_yaml(CIRCLE), 'swing': TaskStack.from_yaml(SWING)}
    spg = SetPointGenerator(robot, stacks['circle'], dt=DT, pspm=pspm)
    hard_boxes = []
    if record:  # record the hard box (joint limits and PSPM) of each tick
        recording = ModuleType('recording')  # the tick's kernels, velocity_box wrapped
        recording.__dict__.update(vars(kernels.active))

        def velocity_box(lower, upper, pb_lower, pb_upper, qdot_prev, accel):
            hard_boxes.append(VelocityBox(np.maximum(lower, pb_lower),
                                          np.minimum(upper, pb_upper)))
            return kernels.active.velocity_box(lower, upper, pb_lower, pb_upper, qdot_prev,
                                               accel)
        recording.velocity_box = velocity_box
        spg = SetPointGenerator(robot, stacks['circle'], dt=DT, pspm=pspm, kernels=recording)
    plant = JointImpedancePlant(robot, robot.q_home, dt=DT, substeps=2)
    q, qdot, t = plant.q.copy(), plant.qdot.copy(), 0.0
    q_v_prev, qdot_v_prev = None, np.zeros(robot.n)
    rec = {'v': [], 'a': [], 'forced': [], 'moving': []}
    for k in range(ticks):
        if k in switches:
            rec['moving'].append(np.abs(spg.qdot_v).max())
            spg.set_stack(stacks[switches[k]])
        q_v = spg.step(q, qdot, t)
        qdot_v = spg.info.qdot_v
        acc = robot.a_max * DT
        if q_v_prev is not None:
            rec['v'].append(np.max(np.abs(q_v - q_v_prev) / (robot.v_max * DT)))
            rec['a'].append(np.max(np.abs(qdot_v - qdot_v_prev) / acc))
            if hard_boxes:
                hard = hard_boxes[-1]
                # joints whose hard box does not meet the acceleration box: safety wins
                rec['forced'].append((hard.upper < qdot_v_prev - acc - 1e-12)
                                     | (hard.lower > qdot_v_prev + acc + 1e-12))
        q_v_prev, qdot_v_prev = q_v, qdot_v.copy()
        q, qdot, t = plant.step(q_v)
    rec = {k: np.array(v) for k, v in rec.items()}
    return spg, rec


def test_switch_mid_motion_respects_velocity_and_acceleration_limits():
    spg, rec = run(False, {300: 'swing', 600: 'circle'})
    assert np.all(rec['moving'] > 0.05), rec['moving']  # really mid-motion [rad/s]
    assert rec['v'].max() <= 1.0 + 1e-9, rec['v'].max()
    assert rec['a'].max() <= 1.0 + 1e-9, rec['a'].max()
    assert rec['a'].max() > 0.5  # the acceleration limit is reached: the check has teeth
    assert spg.stack.name == 'circle'


def test_with_pspm_only_passivity_overrides_the_acceleration_limit():
    """With PSPM, an empty tank may stop a joint faster than a_max (the velocity box is
    intersected softly: position safety and passivity win). Every tick that exceeds
    a_max dT must be one where the hard box excludes the acceleration box."""
    _, rec = run(True, {300: 'swing', 600: 'circle'}, record=True)
    assert np.all(rec['moving'] > 0.05), rec['moving']
    assert rec['v'].max() <= 1.0 + 1e-9
    over = rec['a'] > 1.0 + 1e-9
    assert np.all(rec['forced'][over].any(axis=1)), np.flatnonzero(over)
    assert not over[[298, 299, 598, 599]].any()  # the swap ticks themselves keep a_max
    # and without switching the same overrides happen: they are PSPM's, not the swap's
    _, still = run(True, {}, record=True)
    assert (still['a'] > 1.0 + 1e-9).any()


def test_rejected_stack_leaves_the_running_one_untouched():
    robot = RobotModel.from_config('lbr_iiwa14')
    spg = SetPointGenerator(robot, TaskStack.from_yaml(CIRCLE), dt=DT)
    plant = JointImpedancePlant(robot, robot.q_home, dt=DT, substeps=2)
    q, qdot, t = plant.q.copy(), plant.qdot.copy(), 0.0
    for _ in range(50):
        q, qdot, t = plant.step(spg.step(q, qdot, t))
    stack, tasks = spg.stack, spg.tasks
    bad = TaskStack.from_yaml(SWING.replace('A4', 'A44'))
    with pytest.raises(TaskStackError, match="'A44' not in model 'lbr_iiwa14'"):
        spg.set_stack(bad)
    for _ in range(5):
        q, qdot, t = plant.step(spg.step(q, qdot, t))
    assert spg.stack is stack and spg.tasks is tasks
    assert spg.info.task_time == pytest.approx(54 * DT)


def test_init_is_captured_at_activation():
    """After a swap, 'init' bounds hold the task value of the swap tick, not of the start."""
    robot = RobotModel.from_config('lbr_iiwa14')
    spg = SetPointGenerator(robot, TaskStack.from_yaml(SWING), dt=DT, pspm=False)
    plant = JointImpedancePlant(robot, robot.q_home, dt=DT, substeps=2)
    q, qdot, t = plant.q.copy(), plant.qdot.copy(), 0.0
    for _ in range(200):
        q, qdot, t = plant.step(spg.step(q, qdot, t))
    hold = TaskStack.from_yaml('version: 1\ntasks: [{type: joint_position, equal: init}]\n')
    spg.set_stack(hold)
    q_v_at_swap = spg.q_v.copy()
    q, qdot, t = plant.step(spg.step(q, qdot, t))
    lower, _ = spg.tasks[0].bounds_at(0.0)
    np.testing.assert_allclose(lower, q_v_at_swap)
    assert spg.info.task_time == 0.0


def test_pending_stack_is_the_stack_until_the_next_tick():
    robot = RobotModel.from_config('lbr_iiwa14')
    stack = TaskStack.from_yaml(CIRCLE)
    spg = SetPointGenerator(robot, dt=DT)
    assert spg.pending_stack is None
    spg.set_stack(stack)
    assert spg.pending_stack is stack and spg.stack is None
    spg.step(np.zeros(robot.n), np.zeros(robot.n), 0.0)
    assert spg.pending_stack is None and spg.stack is stack
