"""Faults over loopback DDS, with real processes: ``spg_node``, ``task_publisher``,
``sim_bridge`` (realtime) and ``ifc-spg bag record``. While a CPU-hog process loads the
machine, the task publisher is killed (its latched stack must keep running), the bridge
stops and a new one starts from t = 0 (watchdog, then a restart from the measured q). The
bag recorded meanwhile must hold every command the SPG published and close cleanly on
SIGINT; the SPG must exit cleanly on SIGTERM."""

import json
import re
import signal
import subprocess
import time

from helpers import BIN, CONFIG, TARGET, reach_stack, use_loopback
import numpy as np
import pytest
from ros_testing import ProcessGroup, loopback_env, stamp_ns

from ifc_spg import ros
from ifc_spg.model import RobotModel
from ifc_spg.offline.bag import BagReader
from ifc_spg.ros import msg as ros_msg

pytestmark = [pytest.mark.dds, pytest.mark.ros]

DT = 0.002
HOG_SECONDS = 5.0
STOP_TIMEOUT = 10.0    # [s] from a signal to SIGKILL
STACK = reach_stack('lbr_iiwa14')
# a busy loop pinned to the last core, ending by itself after HOG_SECONDS (and killed by PID)
HOG = ('import os, time\n'
       'os.sched_setaffinity(0, {max(os.sched_getaffinity(0))})\n'
       f't = time.monotonic() + {HOG_SECONDS}\n'
       'while time.monotonic() < t:\n'
       '    pass\n')


@pytest.mark.realtime
def test_faults_over_dds_keep_commands_safe_and_the_bag_complete(tmp_path, monkeypatch):
    env = use_loopback(monkeypatch)
    stack = tmp_path / 'reach.yaml'
    stack.write_text(STACK)
    bag_path = tmp_path / 'bag'
    robot = RobotModel.from_config('lbr_iiwa14')
    ros.init(['test'])
    node = ros.Node('listener')
    status = []
    node.create_subscription(ros_msg.String, 'spg/status',
                             lambda m: status.append(json.loads(m.data)), 10000)
    procs = ProcessGroup(tmp_path, env)
    start, log = procs.start, procs.log

    def stop(name, sig=signal.SIGTERM, timeout=STOP_TIMEOUT):
        return procs.stop(name, sig, timeout)

    def spin_until(condition, timeout):
        return ros.spin_until(condition, timeout, nodes=node)

    def event(kind):
        return any(s.get('event', {}).get('type') == kind for s in status)

    try:
        rec = start('recorder', 'bag', 'record', '-o', str(bag_path), 'command/joint_position',
                    'joint_states', 'spg/status', exe='ifc-spg')
        assert spin_until(lambda: 'recording' in log('recorder') or rec.poll() is not None,
                          60.0) and rec.poll() is None, log('recorder')
        spg = start('spg_node', '--ros-args', '--params-file', str(CONFIG / 'lbr_iiwa14.yaml'),
                    '-p', 'status.decimation:=50')
        # the stack_accepted event is volatile: connect to the node's status first
        assert spin_until(lambda: node.count_publishers('spg/status') >= 1 or
                          spg.poll() is not None, 60.0), log('spg_node')
        # and the recorder (another process: not observable here) gets 1 s to match it too
        spin_until(lambda: False, 1.0)
        start('task_publisher', str(stack))
        assert spin_until(lambda: event('stack_accepted') or spg.poll() is not None, 60.0), \
            log('spg_node')
        # the task publisher disappears (SIGKILL: no goodbye); the stack stays latched
        assert stop('task_publisher', signal.SIGKILL) == -signal.SIGKILL
        # run 1: realtime bridge while a CPU hog loads the machine (bounded, killed by PID)
        start('hog', '-c', HOG, exe='python')
        # the SPG and the recorder subscribe to joint_states: start once both know us
        bridge = start('bridge1', '--ros-args', '-p', 'robot:=lbr_iiwa14', '-p', 'scene:=free',
                       '-p', 'mode:=realtime', '-p', 'duration:=3.0',
                       '-p', 'wait_for_subscribers:=2', exe='sim_bridge')
        assert spin_until(lambda: bridge.poll() is not None, 60.0), log('bridge1')
        stop('hog', signal.SIGKILL)
        # the SPG's commands reached the bridge (with Fast DDS' shared-memory transport they
        # once reached neither bridge after the SIGKILL: config/fastdds_loopback.xml)
        assert bridge.returncode == 0 and 'no command received' not in log('bridge1'), \
            log('bridge1')
        # the joint states stopped: the watchdog trips and reports it
        assert spin_until(lambda: event('watchdog'), 10.0), log('spg_node')
        # run 2: a restarted bridge (clock from 0 again, robot back at home)
        # the SPG and the recorder subscribe to joint_states: start once both know us
        # 10 s: the restarted run must reach the target (a loaded rclpy run once stopped at
        # 0.15 of 0.3 rad after 3 s; on a 2x slower VM, 0.14 rad short after 6 s: in realtime
        # the SPG answers fewer states when its ticks take longer)
        bridge = start('bridge2', '--ros-args', '-p', 'robot:=lbr_iiwa14', '-p', 'scene:=free',
                       '-p', 'mode:=realtime', '-p', 'duration:=10.0',
                       '-p', 'wait_for_subscribers:=2', exe='sim_bridge')
        assert spin_until(lambda: bridge.poll() is not None, 60.0), log('bridge2')
        assert bridge.returncode == 0 and 'no command received' not in log('bridge2'), \
            log('bridge2')
        assert spin_until(lambda: event('resumed'), 10.0), log('spg_node')
        spin_until(lambda: False, 0.5)
        assert stop('spg_node', signal.SIGTERM) == 0, log('spg_node')  # clean exit on SIGTERM
        time.sleep(0.3)  # let time pass: the recorder writes what spg_node sent last
        assert stop('recorder', signal.SIGINT, 30.0) == 0, log('recorder')  # closes the bag
    finally:
        procs.close(signal.SIGKILL, STOP_TIMEOUT)
        ros.shutdown()

    # the commands the SPG published are in the bag (the SPG's count from its exit line):
    # all, or nearly - Fast DDS' reliable KEEP_LAST(10) writers may drop a sample the
    # recorder missed (rmw_fastrtps#338; a CI run's bag lost 18 of 7000 joint states)
    match = re.search(r'spg_node: (\d+) ticks, (\d+) commands', log('spg_node'))
    assert match, log('spg_node')
    sent = int(match.group(2))
    with BagReader(bag_path) as bag:
        recorded = bag.topics['/command/joint_position'][1]
        assert 0.99 * sent <= recorded <= sent and sent > 2000, (recorded, sent)
        commands = [msg for _, _, msg in bag.messages({'/command/joint_position'})]
        states = [msg for _, _, msg in bag.messages({'/joint_states'})]
        docs = [json.loads(msg.data) for _, _, msg in bag.messages({'/spg/status'})]
    # the latched stack survived its publisher for both bridge runs
    assert [d['event']['type'] for d in docs if 'event' in d].count('stack_accepted') == 1
    assert all(d['stack']['name'] == 'reach' for d in docs if d.get('tick', 0) > 0)
    # every command safe; within a session q_v moves at most v_max dT per tick
    q_v = np.array([c.position for c in commands])
    v = np.array([c.velocity for c in commands])
    stamps = np.array([stamp_ns(c) for c in commands])
    assert np.all(np.isfinite(q_v)) and np.all(np.isfinite(v))
    assert np.all(q_v >= robot.q_min) and np.all(q_v <= robot.q_max)
    assert np.all(np.abs(v) <= robot.v_max * (1 + 1e-9))
    same = (np.diff(stamps) > 0) & (np.diff(stamps) <= 50_000_000)
    steps = np.abs(np.diff(q_v, axis=0))[same]
    assert np.all(steps <= robot.v_max * DT + 1e-9)
    restarts = np.flatnonzero(np.diff(stamps) < 0)
    assert restarts.size == 1                            # the second bridge
    first = restarts[0] + 1
    q_meas = {stamp_ns(s): np.array(s.position) for s in states}
    assert np.all(np.abs(q_v[first] - q_meas[stamps[first]]) <= robot.v_max * DT + 1e-9)
    # the restarted run still drives to the stack's target: within 0.02 rad, or at least half
    # of the way from where it restarted (realtime: on a 2x slower VM the SPG answers fewer
    # states; runs ended 0.03 and 0.12 of 0.37 rad short after 10 s); a stopped stack fails
    last = max(states, key=stamp_ns)
    start_err = float(np.max(np.abs(q_meas[stamps[first]] - TARGET)))
    end_err = float(np.max(np.abs(np.array(last.position) - TARGET)))
    assert end_err <= max(0.02, 0.5 * start_err), (end_err, start_err)


@pytest.mark.parametrize('param, message', [
    ('dt:=fast', "'dt': value 'fast' has type"),   # wrong type
    ('dt:=5.0', "'dt': value 5.0 is outside its range"),  # out of range
    ('solver:=qpoases', "'qpoases' is not one of"),
    ('watchdog.timout:=0.1', "did you mean 'watchdog.timeout'"),
])
def test_bad_start_up_parameters_exit_nonzero_with_a_clear_message(param, message):
    """The spg_node process (not just main()) refuses bad parameters: exit code 2."""
    proc = subprocess.run([str(BIN / 'spg_node'), '--ros-args', '-p', param],
                          env=loopback_env(), capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert message in proc.stderr and 'Traceback' not in proc.stderr, proc.stderr
