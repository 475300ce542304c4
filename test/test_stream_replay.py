"""A run whose stack follows streams replays bit for bit from its ``spg/state`` alone.

The live SPG takes each stream message whenever it arrives (between ticks, at times a bag
cannot pin down); its ``spg/state`` records the reference each streamed task used at each
tick. A fresh runner restored mid-run from a recorded state, told before each tick which
references the recording shows (``replay_streams``), and fed the same joint states computes
the same q_v at every later tick (max |dq_v| == 0), across a stack switch to another
streamed stack that took messages while it waited. Without the recorded references, it
does not (the check can fail).
"""

import json

import numpy as np
import pinocchio as pin
from plants import JointImpedancePlant

from ifc_spg.node.config import SpgConfig
from ifc_spg.node.core import SpgRunner
from ifc_spg.ros import messages as m

POSE = """
version: 1
name: teleop
tasks:
  - {name: tool, type: cartesian_pose, frame: tool, equal: {stream: null}, gain: 10.0}
  - {name: posture, type: joint_position, equal: init, gain: 1.0}
"""
JOINTS = """
version: 1
name: joints
tasks:
  - {name: tool, type: cartesian_pose, frame: tool, subspace: [z], equal: {stream: null},
     gain: 5.0}
  - {name: elbow, type: joint_position, joints: [A4], equal: {stream: null}, gain: 2.0}
"""
SWITCH = 400


def _pose(p):
    msg = m.PoseStamped()
    msg.header.frame_id = 'world'
    msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = (float(v) for v in p)
    msg.pose.orientation.y = 1.0  # 180 deg about y: the tool down
    return msg


def _joint(name, value):
    msg = m.JointState()
    msg.name, msg.position = [name], [float(value)]
    return msg


def _live(seed, ticks):
    """The live run: streams fed at random moments between ticks; states and records."""
    rng = np.random.default_rng(seed)
    runner = SpgRunner(SpgConfig(robot='lbr_iiwa14'), clock=lambda: 0.0)
    q0 = np.array([0.0, 0.5, 0.0, -1.2, 0.0, 1.0, 0.0]) + rng.uniform(-0.1, 0.1, 7)
    plant = JointImpedancePlant(runner.robot, q0, substeps=2, diagonal_inertia=np.full(7, 0.5))
    data = runner.robot.create_data()
    pin.framesForwardKinematics(runner.robot.model, data, q0)
    p0 = data.oMf[runner.robot.frame_id('tool')].translation.copy()
    assert runner.handle_task_stack(POSE).accepted
    q, qdot = plant.q.copy(), plant.qdot.copy()
    states, q_v, snaps, configs = [], [], {}, {}
    for k in range(ticks):
        if k == SWITCH - 30:
            assert runner.handle_task_stack(JOINTS).accepted  # takes over at a quiet tick
        for _ in range(rng.poisson(0.3)):  # 0-3 messages between two ticks, any of them
            runner.handle_reference('spg/reference/tool',
                                    _pose(p0 + rng.uniform(-0.05, 0.05, 3)))
        if k >= SWITCH - 30 and rng.random() < 0.2:
            runner.handle_reference('spg/reference/elbow', _joint('A4', rng.uniform(-1.5, -1)))
        stamp = 1_000_000_000 + 2_000_000 * k
        states.append((q, qdot, stamp))
        cmd = runner.handle_joint_state(runner.joint_names, q, qdot, stamp)
        q_v.append(np.array(cmd.position))
        snaps[k] = json.loads(json.dumps(runner.state_vector().tolist()))  # as a bag has it
        configs[k] = json.loads(json.dumps(runner.config_doc()))
        q, qdot, _ = plant.step(cmd.position)
    assert runner.stack_name == 'joints'
    return runner.joint_names, states, q_v, snaps, configs


def _replay(names, states, q_v, snaps, configs, start, use_streams=True):
    """max |dq_v| of a runner restored after tick ``start``, over every later tick."""
    runner = SpgRunner(SpgConfig(robot='lbr_iiwa14'), clock=lambda: 0.0)
    runner.restore(snaps[start], configs[start])
    worst = 0.0
    for k in range(start + 1, len(states)):
        if k == SWITCH - 30:
            assert runner.handle_task_stack(JOINTS).accepted
        if use_streams:
            runner.replay_streams(snaps[k], configs[k])
        q, qdot, stamp = states[k]
        cmd = runner.handle_joint_state(names, q, qdot, stamp)
        worst = max(worst, float(np.max(np.abs(np.array(cmd.position) - q_v[k]))))
    return worst


def test_streamed_run_replays_exactly_from_its_recorded_references():
    live = _live(7, 700)
    assert [f for f, _ in live[4][SWITCH - 40]['state_layout']][-1] == 'stream:tool'
    assert [f for f, _ in live[4][SWITCH + 10]['state_layout']][-2:] == \
        ['stream:tool', 'stream:elbow']
    for start in (20, 150, SWITCH - 31, SWITCH + 50):
        assert _replay(*live, start) == 0.0, start
    # the references matter: without them the replay holds its init targets
    assert _replay(*live, 150, use_streams=False) > 1e-3
