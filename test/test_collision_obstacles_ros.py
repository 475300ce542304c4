"""``spg/obstacles`` over DDS: ``spg_node`` as a process, this test plays a resting robot in
lockstep (each joint state waits for its command). It moves the post nearer the elbow with a
MarkerArray and sees the distance ``spg/status`` reports drop by as much, and ``spg/markers``
draw the post where it went; then it sends bad
markers (wrong shape, unknown name), which are rejected and counted while every joint state
is still answered. ``IFC_SPG_TEST_DOMAIN_ID`` pins the ROS domain (default: a random one)."""

import os

from helpers import record_spg_topics, use_loopback
import numpy as np
import pytest

from ifc_spg import ros
from ifc_spg.geometry import Obstacle
from ifc_spg.model import RobotModel
from ifc_spg.node.obstacles import obstacle_marker
from ifc_spg.ros import msg as ros_msg
from ifc_spg.ros.testing import ProcessGroup, loopback_env, stamp_ns

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
MOVE, BAD, TICKS = 100, 200, 300   # ticks: the post moves 5 cm at MOVE, bad markers from BAD


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
    procs = ProcessGroup(tmp_path, env)
    unanswered = 0
    try:
        spg = procs.start('spg_node', '--ros-args', '-p', 'robot:=lbr_iiwa14',
                          '-p', 'status.decimation:=10', '-p', f'task_stack_file:={stack}')
        assert ros.spin_until(lambda: node.count_subscribers('spg/obstacles') >= 1 and
                              node.count_subscribers('joint_states') >= 1 or
                              spg.poll() is not None, 60.0, nodes=node), procs.log('spg_node')
        q = np.array(robot.q_home, float)
        for k in range(TICKS):
            # best effort: the marker goes again with every state (a pose is idempotent)
            if k >= MOVE:
                markers = [obstacle_marker(ros_msg, POST, moved, (0.0, 0.0, 0.0, 1.0))]
                if k >= BAD:
                    wrong = obstacle_marker(ros_msg, POST, moved, (0.0, 0.0, 0.0, 1.0))
                    wrong.type = wrong.CUBE
                    unknown = obstacle_marker(ros_msg, POST, moved, (0.0, 0.0, 0.0, 1.0))
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
    finally:
        procs.close()
        ros.shutdown()
    log = procs.log('spg_node')
    assert unanswered <= 0.02 * TICKS, log
    before = [_distance(d) for d in status if 0 < d['tick'] < MOVE - 5]
    after = [_distance(d) for d in status if MOVE + 20 < d['tick']]
    last = status[-1]
    print(f'DDS obstacles: arm_post {before[-1] * 1e3:.1f} mm before, {after[-1] * 1e3:.1f} mm '
          f"after the post moved 5 cm; {last['obstacles']}; {unanswered} of {TICKS} states "
          'unanswered')
    # the resting arm (the posture holds it; the post stays outside the margin): the
    # distance drops by the 5 cm the post moved towards it, along y
    assert before and after and None not in before + after
    assert 0.13 < before[-1] < 0.15 and after[-1] == pytest.approx(before[-1] - 0.05,
                                                                   abs=2e-3)
    counts = last['obstacles']
    assert counts['moved'] == 1 and counts['accepted'] >= 0.8 * (TICKS - MOVE)
    rejected = counts['rejected']
    assert rejected['wrong_shape'] >= 0.8 * (TICKS - BAD) - 10
    assert rejected['unknown_obstacle'] == rejected['wrong_shape']
    assert sum(rejected.values()) == 2 * rejected['wrong_shape']
    assert 'obstacle marker rejected (wrong_shape)' in log
    # commands continued after the bad markers, to the last state
    assert stamp_ns(commands[-1]) == (TICKS - 1) * DT_NS
    assert last['state'] == 'running' and last['stack']['name'] == 'post_beside_the_elbow'
    # spg/markers draws the post where the SPG has it: declared, then moved
    ys = [mk.pose.position.y for mk in drawn]
    assert ys and ys[-1] == pytest.approx(moved[1]) and drawn[-1].type == drawn[-1].CYLINDER
    assert set(np.round(ys, 9)) <= {round(POST.position[1], 9), round(moved[1], 9)}
