"""Across vendors, as separate processes on one loopback domain: rclpy (Fast DDS) nodes and
nodes on the built-in Cyclone DDS backend in one loop.

- the bridge on one backend, the SPG on the other (both ways): lockstep for 10 s, every joint
  state answered by exactly one command, the contact force regulated as in the single-backend
  end-to-end test (test_e2e_surface_tracking: pressing, every sample within +-1 N of 8 N);
- a task stack published (latched, transient local) before the SPG on the other backend
  starts: the late joiner gets it;
- ``ifc-spg bag record`` (built-in backend) records what rclpy nodes publish, and every
  message deserializes with rosbags.
"""

import re
import signal

from helpers import CONFIG, reach_stack, start_recorder
from helpers import wait_for as _wait
import numpy as np
import pytest
from ros_testing import ProcessGroup, loopback_env, random_domain_id
import yaml

pytestmark = [pytest.mark.dds, pytest.mark.backend_pinned, pytest.mark.slow]

SIM_SECONDS = 10.0
DT = 0.002
TARGET_N = 8.0
SETTLE_PRESS = 2.9       # [s] the single-backend e2e test's settling time (same stack)
IMPACT_MAX_N = 12.0      # [N] its first-contact bound


@pytest.fixture(autouse=True)
def _needs_rclpy():
    try:
        import rclpy  # noqa: F401
        import sensor_msgs.msg  # noqa: F401
    except ImportError:
        pytest.skip('mixes rclpy with the built-in backend: rclpy is not installed (the '
                    'ros-jazzy wheels exist for Linux x86_64, CPython 3.10-3.13 only)')


def _press_stack(tmp_path):
    """The demo's approach/press stack (config/scenarios/demo_lbr.yaml, first entry)."""
    doc = yaml.safe_load((CONFIG / 'scenarios' / 'demo_lbr.yaml').read_text())
    path = tmp_path / 'press.yaml'
    path.write_text(yaml.safe_dump(doc['stacks'][0]['stack'], sort_keys=False))
    return path


def _envs(spg_backend, bridge_backend):
    domain = random_domain_id()
    return (loopback_env(domain, backend=spg_backend),
            loopback_env(domain, backend=bridge_backend),
            loopback_env(domain, backend='cyclonedds'))


@pytest.mark.parametrize('spg_backend, bridge_backend', [('rclpy', 'cyclonedds'),
                                                         ('cyclonedds', 'rclpy')])
def test_bridge_and_spg_on_different_backends(tmp_path, spg_backend, bridge_backend):
    from ros_testing import stamp_ns

    from ifc_spg.offline.bag import BagReader

    spg_env, bridge_env, rec_env = _envs(spg_backend, bridge_backend)
    stack = _press_stack(tmp_path)
    bag_path = tmp_path / 'bag'
    spg_procs = ProcessGroup(tmp_path, spg_env)
    bridge_procs = ProcessGroup(tmp_path, bridge_env)
    rec_procs = ProcessGroup(tmp_path, rec_env)
    try:
        start_recorder(rec_procs, bag_path, 'joint_states', 'command/joint_position',
                       'sim/contact_wrench')
        spg = spg_procs.start('spg_node', '--ros-args', '--params-file',
                              str(CONFIG / 'lbr_iiwa14.yaml'), '-p',
                              f'task_stack_file:={stack}')
        assert _wait(lambda: 'waiting for' in spg_procs.log('spg_node') or
                     spg.poll() is not None, 60) and spg.poll() is None, \
            spg_procs.log('spg_node')
        assert f'backend: {spg_backend}' in spg_procs.log('spg_node')
        bridge = bridge_procs.start(
            'sim_bridge', '--ros-args', '-p', 'robot:=lbr_iiwa14', '-p', 'interface:=lbr_fri',
            '-p', 'scene:=table', '-p', 'scene_options:=\'{"gap": 0.01}\'', '-p',
            'mode:=lockstep', '-p', f'duration:={SIM_SECONDS}',
            '-p', 'wait_for_subscribers:=2')  # the SPG and the recorder
        assert _wait(lambda: bridge.poll() is not None, 240), bridge_procs.log('sim_bridge')
        assert bridge.returncode == 0, bridge_procs.log('sim_bridge')
        assert f'backend: {bridge_backend}' in bridge_procs.log('sim_bridge')
        _wait(lambda: False, 1.0)  # the last command reaches the recorder
        assert rec_procs.stop('recorder', signal.SIGINT) == 0, rec_procs.log('recorder')
        assert spg_procs.stop('spg_node') == 0, spg_procs.log('spg_node')
    finally:
        for group in (bridge_procs, spg_procs, rec_procs):
            group.close()
    match = re.search(r'spg_node: (\d+) ticks, (\d+) commands', spg_procs.log('spg_node'))
    assert match, spg_procs.log('spg_node')
    ticks, sent = int(match.group(1)), int(match.group(2))
    with BagReader(bag_path) as bag:
        states = [stamp_ns(m) for _, _, m in bag.messages({'/joint_states'})]
        commands = [stamp_ns(m) for _, _, m in bag.messages({'/command/joint_position'})]
        wrench = [(stamp_ns(m) * 1e-9, -m.wrench.force.z)
                  for _, _, m in bag.messages({'/sim/contact_wrench'})]
    # lockstep: every state answered by exactly one command. The bridge republishes the
    # first state until the SPG's subscription has matched, so a stamp may be in the bag twice
    # (once unheard by the SPG); each stamp has one command and the SPG sent one per tick.
    n_steps = round(SIM_SECONDS / DT)
    assert len(set(states)) >= n_steps
    # one command per state heard; a re-sent state is answered with the same command again
    # (counted as sent, not as a tick)
    assert sent == len(commands) and ticks == len(set(commands)) >= n_steps
    assert len(commands) - len(set(commands)) <= len(states) - len(set(states))
    assert set(commands) == set(states)
    # the contact force, as in the single-backend e2e test
    t, f = np.array(wrench).T
    assert len(t) >= 0.95 * n_steps  # best effort on loopback
    assert np.max(np.abs(f)) <= IMPACT_MAX_N, np.max(np.abs(f))
    press = t >= SETTLE_PRESS
    assert press.sum() > 1000
    err = f[press] + TARGET_N
    print(f'\nspg on {spg_backend}, bridge on {bridge_backend}: {ticks} ticks, force error '
          f'after {SETTLE_PRESS} s: max {np.max(np.abs(err)):.3f} N, RMS '
          f'{np.sqrt(np.mean(err ** 2)):.3f} N')
    assert np.max(np.abs(err)) <= 1.0


@pytest.mark.parametrize('publisher_backend, spg_backend', [('rclpy', 'cyclonedds'),
                                                            ('cyclonedds', 'rclpy')])
def test_latched_stack_reaches_a_late_spg_on_the_other_backend(tmp_path, publisher_backend,
                                                               spg_backend):
    pub_env, spg_env, _ = _envs(publisher_backend, spg_backend)
    stack = tmp_path / 'reach.yaml'
    stack.write_text(reach_stack('lbr_iiwa14', name='late_join'))
    pubs, spgs = ProcessGroup(tmp_path, pub_env), ProcessGroup(tmp_path, spg_env)
    try:
        pub = pubs.start('task_publisher', str(stack))
        assert _wait(lambda: 'published' in pubs.log('task_publisher') or
                     pub.poll() is not None, 60) and pub.poll() is None, \
            pubs.log('task_publisher')
        assert f'backend: {publisher_backend}' in pubs.log('task_publisher')
        spg = spgs.start('spg_node', '--ros-args', '--params-file',
                         str(CONFIG / 'lbr_iiwa14.yaml'))
        assert _wait(lambda: "task stack 'late_join'" in spgs.log('spg_node') or
                     spg.poll() is not None, 60), spgs.log('spg_node')
        assert "task stack 'late_join' (id 1) accepted" in spgs.log('spg_node')
        assert f'backend: {spg_backend}' in spgs.log('spg_node')
    finally:
        spgs.close()
        pubs.close()


@pytest.mark.realtime
def test_bag_record_of_rclpy_nodes_deserializes_with_rosbags(tmp_path):
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore

    domain = random_domain_id()
    talk_env = loopback_env(domain, backend='rclpy')
    rec_env = loopback_env(domain, backend='cyclonedds')
    talkers, recs = ProcessGroup(tmp_path, talk_env), ProcessGroup(tmp_path, rec_env)
    bag_path = tmp_path / 'bag'
    count = 500
    try:
        start_recorder(recs, bag_path, 'joint_states', 'spg/task_stack')
        stack = tmp_path / 'reach.yaml'
        stack.write_text(reach_stack('lbr_iiwa14'))
        pub = talkers.start('task_publisher', str(stack))
        assert _wait(lambda: 'published' in talkers.log('task_publisher') or
                     pub.poll() is not None, 60), talkers.log('task_publisher')
        talker = talkers.start('talker', 'ros', 'talker', '--ros-args', '-p', 'rate:=500.0',
                               '-p', f'count:={count}', '-p', 'wait_for_subscribers:=1',
                               exe='ifc-spg')
        assert _wait(lambda: talker.poll() is not None, 60), talkers.log('talker')
        assert talker.returncode == 0, talkers.log('talker')
        _wait(lambda: False, 4.0)  # the latched stack reaches the recorder when it matches (Fast
        # DDS discovery of a process can take one 3 s announcement period)
        assert recs.stop('recorder', signal.SIGINT) == 0, recs.log('recorder')
    finally:
        talkers.close()
        recs.close()
    store = get_typestore(Stores.ROS2_JAZZY)
    counts = {}
    with Reader(bag_path) as reader:
        for conn, _, raw in reader.messages():
            msg = store.deserialize_cdr(raw, conn.msgtype)
            counts[conn.topic] = counts.get(conn.topic, 0) + 1
            if conn.topic == '/joint_states':
                assert len(msg.position) == 7 and np.all(np.isfinite(msg.position))
            else:
                assert 'name: reach' in msg.data
    assert counts == {'/joint_states': count, '/spg/task_stack': 1}
