"""``spg/obstacles`` over DDS: ``spg_node`` as a process, this test plays a resting robot in
lockstep (each joint state waits for its command). It moves the post nearer the elbow with a
MarkerArray and sees the distance ``spg/status`` reports drop by as much, and ``spg/markers``
draw the post where it went; then it sends bad
markers (wrong shape, unknown name), which are rejected and counted while every joint state
is still answered. ``IFC_SPG_TEST_DOMAIN_ID`` pins the ROS domain (default: a random one)."""

import os
import signal

from helpers import record_spg_topics, start_recorder, use_loopback
import numpy as np
import pytest
from ros_testing import ProcessGroup, loopback_env, stamp_ns

from ifc_spg import ros
from ifc_spg.geometry import Obstacle
from ifc_spg.model import RobotModel
from ifc_spg.node.obstacles import obstacle_marker
from ifc_spg.offline.replay import replay
from ifc_spg.ros import msg as ros_msg

pytestmark = [pytest.mark.dds, pytest.mark.ros]

DT_NS = 2_000_000
POST = Obstacle('post', 'cylinder', (0.04, 1.2), position=(0.21, 0.25, 0.6))
STACK = f"""
version: 1
name: post_beside_the_elbow
robot: lbr_iiwa14
obstacles:
  - {{name: post, shape: cylinder, radius: 0.04, length: 1.2, position: {list(POST.position)}}}
tasks:
  - name: avoid
    type: collision_avoidance
    pairs: [{{name: arm_post, links: all, obstacles: [post]}}]
    margin: 0.03
    influence: 0.2
  - {{name: posture, type: joint_position, equal: init, gain: 0.5}}
"""
MOVE, PUSH, BAD, TICKS = 100, 150, 200, 300   # ticks: the post moves 5 cm at MOVE, 7 cm more
# at PUSH (into the margin: the arm gives way), bad markers from BAD


def _distance(doc):
    """The arm_post group's smallest distance at q_v in a status document (None: none)."""
    collision = doc.get('collision') or []
    return collision[0]['groups']['arm_post']['min_distance'] if collision else None


def test_markers_move_the_post_and_bad_ones_are_counted(tmp_path, monkeypatch):
    if ros_msg.MarkerArray is None:
        pytest.skip('rclpy without visualization_msgs (ros-jazzy-visualization-msgs)')
    env = use_loopback(monkeypatch, loopback_env(os.environ.get('IFC_SPG_TEST_DOMAIN_ID')))
    stack = tmp_path / 'post.yaml'
    stack.write_text(STACK)
    robot = RobotModel.from_config('lbr_iiwa14')
    ros.init(['test'])
    node = ros.Node('obstacle_mover')
    _, commands, status = record_spg_topics(node)
    drawn = []  # spg/markers: the obstacle markers the SPG draws
    node.create_subscription(ros_msg.MarkerArray, 'spg/markers', lambda a: drawn.extend(
        mk for mk in a.markers if mk.ns == 'post'), 1000)
    state_pub = node.create_publisher(ros_msg.JointState, 'joint_states', 10)
    obstacles = node.create_publisher(ros_msg.MarkerArray, 'spg/obstacles', 10)
    moved = np.array(POST.position) - [0.0, 0.05, 0.0]
    pushed = moved - [0.0, 0.07, 0.0]
    procs = ProcessGroup(tmp_path, env)
    unanswered = 0
    try:
        spg = procs.start('spg_node', '--ros-args', '-p', 'robot:=lbr_iiwa14',
                          '-p', 'status.decimation:=10', '-p', f'task_stack_file:={stack}')
        start_recorder(procs, tmp_path / 'bag')  # (default topics: not spg/obstacles)
        assert ros.spin_until(lambda: node.count_subscribers('spg/obstacles') >= 1 and
                              node.count_subscribers('joint_states') >= 2 or
                              spg.poll() is not None, 60.0, nodes=node), procs.log('spg_node')
        ros.spin_until(lambda: False, 1.0, nodes=node)  # the recorder meets the SPG's topics
        q = np.array(robot.q_home, float)
        for k in range(TICKS):
            # best effort: the marker goes again with every state (a pose is idempotent)
            if k >= MOVE:
                where = moved if k < PUSH else pushed
                markers = [obstacle_marker(ros_msg, POST, where, (0.0, 0.0, 0.0, 1.0))]
                if k >= BAD:
                    wrong = obstacle_marker(ros_msg, POST, where, (0.0, 0.0, 0.0, 1.0))
                    wrong.type = wrong.CUBE
                    unknown = obstacle_marker(ros_msg, POST, where, (0.0, 0.0, 0.0, 1.0))
                    unknown.ns = 'pots'
                    markers += [wrong, unknown]
                out = ros_msg.MarkerArray()
                out.markers = markers
                obstacles.publish(out)
            state = ros_msg.JointState(name=list(robot.joint_names), position=q.tolist(),
                                       velocity=[0.0] * robot.n, effort=[0.0] * robot.n)
            state.header.stamp.sec, state.header.stamp.nanosec = divmod(k * DT_NS, 10**9)
            state_pub.publish(state)
            if not ros.spin_until(lambda k=k: any(stamp_ns(c) == k * DT_NS
                                                  for c in commands[-5:]), 2.0, nodes=node):
                unanswered += 1
                assert spg.poll() is None, procs.log('spg_node')
        ros.spin_until(lambda: status and status[-1]['tick'] >= TICKS - 10, 2.0, nodes=node)
        ros.spin_until(lambda: False, 0.5, nodes=node)  # the last state reaches the bag
        assert procs.stop('recorder', signal.SIGINT) == 0, procs.log('recorder')
    finally:
        procs.close()
        ros.shutdown()
    log = procs.log('spg_node')
    assert unanswered <= 0.02 * TICKS, log
    last = [d for d in status if d['state'] == 'running'][-1]  # (then the watchdog trips)
    assert last['tick'] >= TICKS - 10
    before = [_distance(d) for d in status if 0 < d['tick'] < MOVE - 5]
    after = [_distance(d) for d in status if MOVE + 20 < d['tick'] < PUSH]
    end = _distance(last)
    q_v = {stamp_ns(c) // DT_NS: np.array(c.position) for c in commands}
    gave_way = np.abs(q_v[TICKS - 1] - robot.q_home).max()
    print(f'DDS obstacles: arm_post {before[-1] * 1e3:.1f} mm before, {after[-1] * 1e3:.1f} mm '
          f'after the post moved 5 cm, {end * 1e3:.1f} mm at the end (pushed to 20 mm, margin '
          f"30 mm: the arm gave way {gave_way:.4f} rad); {last['obstacles']}; {unanswered} "
          f'of {TICKS} states unanswered')
    # the resting arm (the posture holds it; the post is still outside the margin): the
    # distance drops by the 5 cm the post moved towards it, along y; pushed 2 cm into the
    # margin, the arm gives way (the damper: back towards the margin at 2.9 /s)
    assert before and after and None not in before + after
    assert 0.13 < before[-1] < 0.15 and after[-1] == pytest.approx(before[-1] - 0.05,
                                                                   abs=2e-3)
    counts = last['obstacles']
    assert 0.02 < end < 0.03 and gave_way > 1e-3 and np.allclose(q_v[PUSH - 1], robot.q_home)
    assert counts['moved'] == 2 and counts['accepted'] >= 0.8 * (TICKS - MOVE)
    rejected = counts['rejected']
    assert rejected['wrong_shape'] >= 0.8 * (TICKS - BAD) - 10
    assert rejected['unknown_obstacle'] == rejected['wrong_shape']
    assert sum(rejected.values()) == 2 * rejected['wrong_shape']
    assert 'obstacle marker rejected (wrong_shape)' in log
    # commands continued after the bad markers, to the last state
    assert stamp_ns(commands[-1]) == (TICKS - 1) * DT_NS
    assert last['stack']['name'] == 'post_beside_the_elbow'
    # the bag replays exactly without spg/obstacles: spg/state records the poses each tick used
    res = replay(tmp_path / 'bag')
    print(f'DDS obstacles: replay of the bag: max |dq_v| = {res.max_abs_diff:.3g} rad over '
          f'{res.compared} of {res.ticks} commands ({res.skipped} states before the first '
          'spg/state recorded)')
    # (if the recorder met spg/state late, the replay restores from the first one it has:
    # exact all the same; it compares at least the ticks after the push)
    assert res.max_abs_diff == 0.0 and res.compared >= TICKS - PUSH - 60, res
    # spg/markers draws the post where the SPG has it: declared, then moved
    ys = [mk.pose.position.y for mk in drawn]
    assert ys and ys[-1] == pytest.approx(pushed[1]) and drawn[-1].type == drawn[-1].CYLINDER
    assert set(np.round(ys, 9)) <= {round(v[1], 9) for v in (POST.position, moved, pushed)}
