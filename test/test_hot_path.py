"""``ros.HotPath``: one subscription served without the executor, one wait at a time (the
bridge's command path, ``spg_node``'s joint states), the rest of the node beside it.

On the active backend (rclpy in the first pass, the built-in one in the second)."""

import time

import pytest

from ifc_spg import ros
from ifc_spg.ros import msg as ros_msg

pytestmark = [pytest.mark.dds, pytest.mark.ros]


def _spin(hot, until, timeout=20.0):
    deadline = time.monotonic() + timeout
    while not until() and time.monotonic() < deadline:
        hot.spin_once(0.01)
    return until()


def _state(i):
    return ros_msg.JointState(name=['a1'], position=[float(i)])


def test_hot_path_serves_its_subscription_the_timers_and_the_rest(domain):
    ros.init(['test'])
    node, talker = ros.Node('hot'), ros.Node('talker')
    states, strings, ticks = [], [], []
    sub = node.create_subscription(ros_msg.JointState, 'joint_states', states.append, 100)
    node.create_subscription(ros_msg.String, 'other', strings.append, 100)
    node.create_timer(0.01, lambda: ticks.append(time.monotonic()))
    pub_state = talker.create_publisher(ros_msg.JointState, 'joint_states', 100)
    pub_other = talker.create_publisher(ros_msg.String, 'other', 100)
    hot = ros.HotPath(node, sub)
    rest_spins = []
    if ros.BACKEND == 'rclpy':  # count the spins of the executor of the rest of the node
        spin_rest = hot.rest.spin_once
        hot.rest.spin_once = lambda timeout_sec=None: (rest_spins.append(1),
                                                       spin_rest(timeout_sec))
    try:
        assert _spin(hot, lambda: pub_state.get_subscription_count() == 1 and
                     pub_other.get_subscription_count() == 1)
        for i in range(50):
            pub_state.publish(_state(i))
            if i % 5 == 0:
                pub_other.publish(ros_msg.String(data=str(i)))
        assert _spin(hot, lambda: len(states) == 50 and len(strings) == 10), \
            (len(states), len(strings))
        assert [s.position[0] for s in states] == [float(i) for i in range(50)]
        assert [s.data for s in strings] == [str(i) for i in range(0, 50, 5)]
        # the timer runs from the hot path's own wait: the executor of the rest spins at
        # most every REST_PERIOD (0.1 s) for what the wait set leaves out, not per timer event
        n0, spins0, t0 = len(ticks), len(rest_spins), time.monotonic()
        assert _spin(hot, lambda: len(ticks) >= n0 + 30)
        if ros.BACKEND == 'rclpy':
            elapsed = time.monotonic() - t0
            assert len(rest_spins) - spins0 <= elapsed / hot.REST_PERIOD + 3, \
                (len(rest_spins) - spins0, elapsed)
    finally:
        hot.close()
    # closed: the subscription is the executor's again
    pub_state.publish(_state(50))
    assert ros.spin_until(lambda: len(states) == 51, 20.0, nodes=node)
