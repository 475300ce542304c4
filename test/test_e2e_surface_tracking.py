"""Issue 7 acceptance over loopback DDS, with real processes: ``sim_bridge`` (iiwa, FRI
emulation, table scene, lockstep), ``spg_node`` (config/lbr_iiwa14.yaml + the demo's PSPM
shuffle), ``task_publisher`` and ``ifc-spg bag record``, running the Table 3.2-like stack
of the README demo (config/scenarios/demo_lbr.yaml: press 8 N with include_damping, then a
5 cm circle at 0.2 Hz) for 10 s of simulated time.

Checked from the recorded bag (read with ``rosbags``): the contact force while pressing
and while drawing the circle, the circle tracking error (forward kinematics with
pinocchio of the measured and of the commanded joints), one command per joint-state
stamp, every recorded topic with its ROS type, and that ``ifc-spg replay`` recomputes
every recorded q_v within 1e-9 rad. A second test kills (SIGKILL) and restarts the bridge
mid-run and then kills and restarts the SPG, and checks the command never jumps.
"""

import ast
import json
import os
from pathlib import Path
import re
import signal
import time

from helpers import (
    CONFIG,
    once_per_session,
    reach_stack,
    record_spg_topics,
    replay_cli,
    use_loopback,
)
import numpy as np
import pytest
from ros_testing import LOOPBACK_KEYS, ProcessGroup, loopback_env, stamp_ns
import yaml

from ifc_spg import ros
from ifc_spg.model import RobotModel
from ifc_spg.ros import msg as ros_msg

pytestmark = [pytest.mark.dds, pytest.mark.ros]

DT = 0.002
# 18 s: the circle is judged over more than a revolution (5 s) from 1 s after it started,
# and the switch to it, published when this test's listener sees SWITCH_AT, came 5 s of sim
# time late in a CI run beside a CPU hog (the lockstep sim does not wait for the listener);
# 14 s left 4.5 s of circle there. 18 s leaves room for 8.5 s of lag
SIM_SECONDS = 18.0
SWITCH_AT = 3.5        # [s] sim time at which the test publishes the surface-tracking stack
TARGET_N = 8.0         # [N] pressing force (the tool pushes down: base fz = -8 N)
RADIUS, FREQ = 0.05, 0.2
# Settling: the press stack starts 1 cm above the table and approaches at 1 cm/s (a guarded
# move: z above a ramp), touches it at 1.09 s (first-contact peak 9.0 N; 67 N without the
# guard), and every sample is within +-1 N of 8 N from 2.82 s on (offline demo and live run
# alike, lockstep is deterministic): the force builds at the ramp's pace after contact.
SETTLE_PRESS = 2.9     # [s] after the press stack started
IMPACT_MAX_N = 12.0    # [N] the largest contact force before the circle starts
SETTLE_CIRCLE = 1.0    # [s] after the circle stack started
RECORDED = ['joint_states', 'command/joint_position', 'spg/task_stack', 'spg/status',
            'spg/config', 'spg/state',
            'sim/contact_wrench']  # the iiwa under FRI has no wrist F/T sensor
TYPES = {'/joint_states': 'sensor_msgs/msg/JointState',
         '/command/joint_position': 'sensor_msgs/msg/JointState',
         '/spg/task_stack': 'std_msgs/msg/String', '/spg/status': 'std_msgs/msg/String',
         '/spg/config': 'std_msgs/msg/String', '/spg/state': 'std_msgs/msg/Float64MultiArray',
         '/sim/contact_wrench': 'geometry_msgs/msg/WrenchStamped',
         # written by the recorder for Foxglove (README: "Seeing the robot in Foxglove")
         '/robot_description': 'std_msgs/msg/String', '/tf': 'tf2_msgs/msg/TFMessage',
         '/tf_static': 'tf2_msgs/msg/TFMessage'}


def _demo_stacks():
    """The two stacks of the README demo scenario (approach/press, surface tracking)."""
    doc = yaml.safe_load((CONFIG / 'scenarios' / 'demo_lbr.yaml').read_text())
    return doc, [entry['stack'] for entry in doc['stacks']]


def _bridge_args(q0=None, duration=SIM_SECONDS, scene='table'):
    args = ['--ros-args', '-p', 'robot:=lbr_iiwa14', '-p', 'interface:=lbr_fri', '-p',
            f'scene:={scene}', '-p', 'mode:=lockstep', '-p', f'duration:={duration}']
    if scene == 'table':
        args += ['-p', 'scene_options:=\'{"gap": 0.01}\'']  # the demo's start: 1 cm above
    if q0 is not None:
        args += ['-p', f'q0:={[float(x) for x in q0]}']
    return args


def _spg_args(doc):
    pspm = doc['spg']['pspm']
    return ['--ros-args', '--params-file', str(CONFIG / 'lbr_iiwa14.yaml'),
            '-p', f"pspm.shuffle:={pspm['shuffle']}",
            '-p', f"pspm.shuffle_budget:={pspm['shuffle_budget']}",
            '-p', f"status.decimation:={doc['spg']['status_decimation']}"]


@pytest.fixture(scope='module')
def live_run(tmp_path_factory):
    """The demo over DDS, run once per session (also when pytest-xdist splits this module
    between its workers): the bag path, the logs, the scenario document, the wall time."""
    return once_per_session(tmp_path_factory, 'e2e_surface_tracking_live_run',
                            lambda: _live_run(tmp_path_factory))


def _live_run(tmp_path_factory):
    """Run the demo over DDS (see ``live_run``)."""
    tmp_path = tmp_path_factory.mktemp('e2e')
    env = loopback_env()
    doc, stacks = _demo_stacks()
    files = []
    for i, stack in enumerate(stacks):
        files.append(tmp_path / f'stack_{i}.yaml')
        files[-1].write_text(yaml.safe_dump(stack, sort_keys=False))
    bag_path = tmp_path / 'bag'
    procs = ProcessGroup(tmp_path, env)
    old = {k: os.environ.get(k) for k in LOOPBACK_KEYS}
    for key in old:
        os.environ[key] = env[key]
    ros.init(['test'])
    node = ros.Node('listener')
    status, sim_t = [], [0.0]
    node.create_subscription(ros_msg.String, 'spg/status',
                             lambda m: status.append(json.loads(m.data)), 10000)
    node.create_subscription(ros_msg.JointState, 'joint_states',
                             lambda m: sim_t.__setitem__(0, stamp_ns(m) * 1e-9), 100)

    def spin_until(condition, timeout):
        return ros.spin_until(condition, timeout, nodes=node)

    def accepted(n):
        return sum(s.get('event', {}).get('type') == 'stack_accepted' for s in status) >= n

    wall = time.monotonic()
    try:
        rec = procs.start('recorder', 'bag', 'record', '-o', str(bag_path), *RECORDED,
                          exe='ifc-spg')
        spg = procs.start('spg_node', *_spg_args(doc))
        assert spin_until(lambda: 'recording' in procs.log('recorder') or
                          rec.poll() is not None, 60.0) and rec.poll() is None, \
            procs.log('recorder')
        # the stack_accepted event is volatile: connect to the node's status first
        assert spin_until(lambda: node.count_publishers('spg/status') >= 1 or
                          spg.poll() is not None, 60.0), procs.log('spg_node')
        procs.start('publisher_press', str(files[0]), '--robot', 'lbr_iiwa14',
                    exe='task_publisher')
        assert spin_until(lambda: accepted(1) or spg.poll() is not None, 60.0), \
            procs.log('spg_node')
        # The Table 3.2 stack, published by this test's node (matched with the SPG before
        # the bridge starts) when the sim passes SWITCH_AT: the lockstep sim does not wait,
        # and a second task_publisher process started then needed up to 5.4 s of sim time
        # to start and meet the SPG beside a CPU hog (CI, stop 40).
        track = node.create_publisher(ros_msg.String, 'spg/task_stack', ros.latched())
        assert spin_until(lambda: node.count_subscribers('spg/task_stack') >= 1 or
                          spg.poll() is not None, 60.0), procs.log('spg_node')
        # the SPG, the recorder and this test subscribe to joint_states
        bridge = procs.start('sim_bridge', *_bridge_args(), '-p', 'wait_for_subscribers:=3')
        assert spin_until(lambda: sim_t[0] >= SWITCH_AT or bridge.poll() is not None, 120.0)
        track.publish(ros_msg.String(data=files[1].read_text()))
        assert spin_until(lambda: bridge.poll() is not None, 180.0), procs.log('sim_bridge')
        assert bridge.returncode == 0, procs.log('sim_bridge')
        spin_until(lambda: False, 0.5)
        assert procs.stop('spg_node') == 0, procs.log('spg_node')
        time.sleep(0.3)  # let time pass: the recorder writes what spg_node sent last
        assert procs.stop('recorder', signal.SIGINT, 30.0) == 0, procs.log('recorder')
    finally:
        procs.close()
        ros.shutdown()
        for key, value in old.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value
    return {'bag': str(bag_path), 'logs': {n: procs.log(n) for n in procs.logs}, 'doc': doc,
            'wall': time.monotonic() - wall}


def _read(bag_path):
    """Every recorded message, read with rosbags (not our reader): {topic: [(type, msg)]}."""
    from rosbags.highlevel import AnyReader

    out, types = {}, {}
    with AnyReader([Path(bag_path)]) as reader:
        for conn in reader.connections:
            types[conn.topic] = conn.msgtype
        for conn, _, raw in reader.messages():
            out.setdefault(conn.topic, []).append(reader.deserialize(raw, conn.msgtype))
    return types, out


@pytest.fixture(scope='module')
def recorded(live_run):
    return _read(live_run['bag'])


def _since(statuses):
    """Stamp [s] at which each stack (by name) started, from spg/status."""
    out = {}
    for d in statuses:
        st = d.get('stack')
        if st and st.get('since') is not None:
            out.setdefault(st['name'], float(st['since']))
    return out


@pytest.mark.slow
def test_bag_has_every_topic_with_its_type_and_one_command_per_tick(live_run, recorded):
    types, msgs = recorded
    assert types == TYPES
    assert all(msgs[t] for t in TYPES), {t: len(msgs.get(t, [])) for t in TYPES}
    states, commands = msgs['/joint_states'], msgs['/command/joint_position']
    state_stamps = sorted({stamp_ns(m) for m in states})
    command_stamps = [stamp_ns(m) for m in commands]
    ticks = round(SIM_SECONDS / DT)
    grid = {round(k * DT * 1e9) for k in range(ticks)}
    # The recorder may miss a few samples: Fast DDS' reliable KEEP_LAST(10) writers drop a
    # sample a reader missed once ten newer ones are written (rmw_fastrtps#338; one CI run
    # lost 18 of 7000 joint states). At most 1 % here, and the replay detects each lost tick
    # from spg/state (test_replay_of_the_live_bag_reproduces_q_v).
    assert set(state_stamps) <= grid and set(command_stamps) <= grid
    assert len(state_stamps) >= 0.99 * ticks and len(set(command_stamps)) >= 0.99 * ticks
    print(f'bag: {len(state_stamps)} of {ticks} joint states, {len(set(command_stamps))} of '
          f'{ticks} commands')
    # repeats only for a state the lockstep bridge re-sent (answered with the same command,
    # unless the SPG had not matched the bridge yet when it was first sent)
    assert len(command_stamps) - len(set(command_stamps)) <= len(states) - len(state_stamps)
    # the SPG's own count (exit line): one command per tick, none missed, nothing rejected
    match = re.search(r'spg_node: (\d+) ticks, (\d+) commands, rejected (\{.*?\})',
                      live_run['logs']['spg_node'])
    assert match, live_run['logs']['spg_node']
    assert int(match.group(1)) == ticks
    assert 0 <= int(match.group(2)) - len(command_stamps) <= 0.01 * ticks
    assert ticks <= int(match.group(2)) <= ticks + len(states) - len(state_stamps) + \
        (ticks - len(set(command_stamps)))
    rejected = ast.literal_eval(match.group(3))  # the printed dict of counts
    assert sum(v for k, v in rejected.items() if k != 'duplicate_stamp') == 0
    assert 'without a command' not in live_run['logs']['sim_bridge']
    docs = [json.loads(m.data) for m in msgs['/spg/status']]
    assert [d['stack']['name'] for d in docs if d.get('stack')][-1] == 'surface_tracking'
    assert not {d['spg']['status'] for d in docs if d.get('spg')} & {'hold', 'bad_input'}


def _force(msgs):
    """(t [s], force the tool exerts along base z [N]; pressing down is negative)."""
    w = msgs['/sim/contact_wrench']
    t = np.array([stamp_ns(m) * 1e-9 for m in w])
    # sim/contact_wrench is the environment on the robot: the tool exerts the opposite
    fz = -np.array([m.wrench.force.z for m in w])
    order = np.argsort(t)
    return t[order], fz[order]


def _moving_average(t, x, window=0.05):
    """Causal moving average over ``window`` [s] (the offline runner's metric window)."""
    n = max(1, round(window / DT))
    c = np.cumsum(np.insert(x, 0, 0.0))
    out = np.empty_like(x)
    for i in range(len(x)):
        lo = max(0, i + 1 - n)
        out[i] = (c[i + 1] - c[lo]) / (i + 1 - lo)
    return out


def test_contact_force_settles_at_8_newton(recorded):
    types, msgs = recorded
    docs = [json.loads(m.data) for m in msgs['/spg/status']]
    since = _since(docs)
    t, f = _force(msgs)
    # most samples arrive (best-effort QoS on loopback): at least 95 % of the ticks
    assert len(t) >= 0.95 * SIM_SECONDS / DT
    press = (t >= since['approach'] + SETTLE_PRESS) & (t < since['surface_tracking'])
    assert press.sum() > 100
    # the guarded approach: the first contact is gentle (no impact far above the target)
    first = np.max(np.abs(f[t < since['surface_tracking']]))
    assert first <= IMPACT_MAX_N, first
    # pressing (before the circle): every sample within +-1 N of 8 N
    err_press = f[press] + TARGET_N
    assert np.max(np.abs(err_press)) <= 1.0, np.max(np.abs(err_press))
    # while drawing the circle (force gain 20/s, include_damping): every 50 ms average
    # within +-1 N of 8 N
    track = t >= since['surface_tracking'] + SETTLE_CIRCLE
    err = f[track] + TARGET_N
    rms, peak = np.sqrt(np.mean(err ** 2)), np.max(np.abs(_moving_average(t, f)[track] + TARGET_N))
    print(f'force error: pressing max {np.max(np.abs(err_press)):.3f} N; circle mean '
          f'{np.mean(err):.3f} N, RMS {rms:.3f} N, peak (50 ms average) {peak:.3f} N')
    assert abs(np.mean(err)) <= 0.2
    assert rms <= 0.5
    assert peak <= 1.0
    assert np.all(f[t > since['approach'] + SETTLE_PRESS] < 0)  # contact kept throughout


def _tool_xy(robot, data, q):
    import pinocchio as pin

    pin.framesForwardKinematics(robot.model, data, np.asarray(q, dtype=float))
    return data.oMf[robot.frame_id('tool')].translation[:2].copy()


def test_circle_is_tracked(recorded):
    robot = RobotModel.from_config('lbr_iiwa14')
    data = robot.model.createData()
    _, msgs = recorded
    since = _since([json.loads(m.data) for m in msgs['/spg/status']])
    t0 = since['surface_tracking']
    states = {stamp_ns(m): m for m in msgs['/joint_states']}
    commands = {stamp_ns(m): m for m in msgs['/command/joint_position']}
    # the ticks whose state and command the recorder both has (it may miss up to 1 % of
    # either, test_bag_has_every_topic...: a loaded CI run lacked one command here)
    stamps = sorted(states.keys() & commands.keys())
    # the circle starts where the virtual tool was at activation (start: init)
    before = max(s for s in stamps if s < round(t0 * 1e9))
    start = _tool_xy(robot, data, commands[before].position)
    center = start - [RADIUS, 0.0]
    w = 2 * np.pi * FREQ
    err_m, err_v = [], []
    for s in stamps:
        tt = s * 1e-9 - t0
        if tt < SETTLE_CIRCLE:
            continue
        want = center + RADIUS * np.array([np.cos(w * tt), np.sin(w * tt)])
        err_m.append(np.linalg.norm(_tool_xy(robot, data, states[s].position) - want))
        err_v.append(np.linalg.norm(_tool_xy(robot, data, commands[s].position) - want))
    assert len(err_m) > (1.0 / FREQ) / DT  # more than a full revolution (5 s)
    rms_m, rms_v = np.sqrt(np.mean(np.square(err_m))), np.sqrt(np.mean(np.square(err_v)))
    # The SPG's virtual tool follows the circle within 2 mm RMS (first-order task dynamics,
    # gain 5/s: lag R w / gain = 6 mm would be the open-loop bound; the feed-forward rate
    # removes most of it). The measured tool lags behind under joint impedance with 8 N of
    # contact and table friction (mu 0.3): 2.4 N of friction on the K = 200 Nm/rad...1000
    # joints gives ~1-2 cm; the offline demo measures 14 mm. Threshold 25 mm = R / 2: a tool
    # that leaves the circle or stops on the table fails it.
    print(f'circle tracking error RMS: virtual {rms_v * 1e3:.2f} mm, measured '
          f'{rms_m * 1e3:.2f} mm')
    assert rms_v <= 0.002, rms_v
    assert rms_m <= 0.025, rms_m


def test_replay_of_the_live_bag_reproduces_q_v(live_run, capsys, monkeypatch):
    from ifc_spg.offline.replay import replay

    res = replay(live_run['bag'])
    ticks = round(SIM_SECONDS / DT)
    print(res)
    # every tick the SPG ran is replayed, or before the first recorded spg/state, or lost
    # by the recorder and detected (spg/state counts the ticks)
    assert res.skipped + res.ticks + res.lost == ticks, res
    assert res.missing == 0 and res.compared + res.unverified + res.unanswered == res.ticks
    assert res.compared >= 0.98 * ticks and res.stacks >= 1, res
    assert res.max_abs_diff <= 1e-9, res
    assert replay_cli([str(live_run['bag']), '--tolerance', '1e-9'], res, monkeypatch) == 0
    assert 'OK' in capsys.readouterr().out


REACH = reach_stack('lbr_iiwa14')


@pytest.mark.slow
def test_killed_bridge_and_killed_spg_restart_without_a_jump(tmp_path, monkeypatch):
    """SIGKILL the lockstep bridge mid-run and start a new one where the robot stood (q0 =
    the last measured q; its clock starts at 0 again), then SIGKILL the SPG mid-run and
    start a new one: each first command after a restart is the measured q plus at most one
    v_max step, and no command ever moves more than v_max dT from the one before (within a
    session) — the command does not jump."""
    env = use_loopback(monkeypatch)
    stack = tmp_path / 'reach.yaml'
    stack.write_text(REACH)
    robot = RobotModel.from_config('lbr_iiwa14')
    ros.init(['test'])
    node = ros.Node('listener')
    states, commands, status = record_spg_topics(node)
    procs = ProcessGroup(tmp_path, env)

    def spin_until(condition, timeout):
        return ros.spin_until(condition, timeout, nodes=node)

    def events(kind):
        return sum(s.get('event', {}).get('type') == kind for s in status)

    def sim_t():
        return stamp_ns(states[-1]) * 1e-9 if states else 0.0

    def drained():
        # once the killed process's last commands are in: under load this listener lags
        # the SPG by up to a second (a 0.5 s quiet spell once ended a session before its
        # last command, stamp 1.21 s, came in), so 3 s without one
        n = -1
        while n != len(commands):
            n = len(commands)
            spin_until(lambda: False, 3.0)
        return n

    spg_args = ['--ros-args', '--params-file', str(CONFIG / 'lbr_iiwa14.yaml'),
                '-p', 'status.decimation:=50']
    try:
        spg = procs.start('spg_node', *spg_args)
        assert spin_until(lambda: node.count_publishers('spg/status') >= 1 or
                          spg.poll() is not None, 60.0), procs.log('spg_node')
        procs.start('task_publisher', str(stack))
        assert spin_until(lambda: events('stack_accepted') or spg.poll() is not None, 60.0), \
            procs.log('spg_node')
        # the SPG and this test subscribe to joint_states: start once both know the bridge
        bridge = procs.start('bridge1', *_bridge_args(duration=0.0, scene='free'),
                             '-p', 'wait_for_subscribers:=2', exe='sim_bridge')
        assert spin_until(lambda: sim_t() >= 1.0 or bridge.poll() is not None, 60.0), \
            procs.log('bridge1')
        assert procs.stop('bridge1', signal.SIGKILL) == -signal.SIGKILL  # mid-run, no goodbye
        assert spin_until(lambda: events('watchdog') >= 1, 10.0), procs.log('spg_node')
        n_before = drained()
        q_last = np.array(max(states, key=stamp_ns).position)
        n_states = len(states)
        # runs until stopped: under load the second SPG needs seconds to start, and a bridge
        # of fixed duration had finished before it commanded (spg_node2 "stopped by SIGTERM
        # during start-up")
        bridge = procs.start('bridge2', *_bridge_args(q0=q_last, duration=0.0, scene='free'),
                             '-p', 'wait_for_subscribers:=2', exe='sim_bridge')
        assert spin_until(lambda: events('resumed') >= 1 or bridge.poll() is not None, 60.0), \
            procs.log('spg_node')
        # 0.8 s of the restarted session (its stamps start from 0 again)
        assert spin_until(lambda: (any(stamp_ns(c) < 0.5e9 for c in commands[n_before:]) and
                                   stamp_ns(commands[-1]) >= 0.8e9)
                          or bridge.poll() is not None, 60.0), procs.log('bridge2')
        assert procs.stop('spg_node', signal.SIGKILL) == -signal.SIGKILL  # SPG dies mid-run
        n_spg1 = drained()  # the lockstep bridge waits for the next SPG meanwhile
        spg = procs.start('spg_node2', *spg_args, exe='spg_node')
        assert spin_until(lambda: len(commands) - n_spg1 >= 200 or bridge.poll() is not None
                          or spg.poll() is not None, 90.0), procs.log('spg_node2')
        assert procs.stop('bridge2') == 0, procs.log('bridge2')  # SIGTERM: a clean exit
        spin_until(lambda: False, 0.5)
        assert procs.stop('spg_node2') == 0, procs.log('spg_node2')
    finally:
        procs.close()
        ros.shutdown()

    # the latched stack reached the new SPG
    assert "task stack 'reach' (id 1) accepted" in procs.log('spg_node2')
    v_step = robot.v_max * DT + 1e-9
    q_meas = {}  # the second bridge's states (the first one used the same stamps)
    for s in states[n_states:]:
        q_meas.setdefault(stamp_ns(s), []).append(np.array(s.position))
    # sessions: bridge1 + spg1, bridge2 + spg1 (restart: stamps from 0, so the first two are
    # split where the stamps go back, whenever the first session's last command came in),
    # bridge2 + spg2
    stamps_in = [stamp_ns(c) for c in commands[:n_spg1]]
    restart = next((i for i in range(1, n_spg1) if stamps_in[i] < stamps_in[i - 1]), n_before)
    sessions = [commands[:restart], commands[restart:n_spg1], commands[n_spg1:]]
    assert all(len(c) > 50 for c in sessions), [len(c) for c in sessions]
    jumps = []
    for k, cmds in enumerate(sessions):
        q_v = np.array([c.position for c in cmds])
        stamps = np.array([stamp_ns(c) for c in cmds])
        assert np.all(np.diff(stamps) >= 0)
        # never a jump in a session: at most v_max dT per tick. The test's own subscriber
        # (keep-last history) may miss a command when this machine is loaded, so the bound
        # is per tick between the commands it did receive.
        ticks = np.maximum(np.round(np.diff(stamps) / (DT * 1e9)), 1.0)[:, None]
        assert np.all(np.abs(np.diff(q_v, axis=0)) <= v_step * ticks)
        assert np.all(q_v >= robot.q_min) and np.all(q_v <= robot.q_max)
        if k:
            # the first command after a restart: the measured q it answers + one step
            first = min(np.max(np.abs(q_v[0] - q)) for q in q_meas[stamps[0]])
            assert first <= np.max(v_step), first
            jumps.append(float(np.max(np.abs(q_v[0] - sessions[k - 1][-1].position))))
    # and relative to the last command before the fault: only the impedance offset q_v - q
    # of a robot moving at <= 5/s towards its target (the FRI emulation holds q_v - q small)
    print(f'|first command after restart - last command before| = {jumps} rad')
    assert max(jumps) <= 0.05, jumps
    # the second bridge started where the first one stopped (its clock from 0 again)
    assert stamp_ns(sessions[1][0]) < stamp_ns(sessions[0][-1])
    np.testing.assert_allclose(q_meas[stamp_ns(sessions[1][0])][0], q_last, atol=1e-3)


@pytest.mark.realtime
def test_latency_bench_smoke():
    """``python -m benchmarks.latency_bench`` (realtime bridge + SPG over DDS, on this process's
    backend), 3 s at 500 Hz (the SPG's default hot path, this process listening) and 2 s at
    1 kHz (rclpy: the executor path; unobserved): the bridge measures every command's latency
    on its own clock; the machine baseline paces a sleep loop."""
    from benchmarks.latency_bench import baseline, run
    from ifc_spg import ros

    for seconds, rate, path, ticks, listen in ((3.0, 500.0, 'wait_set', 1500, True),
                                               (2.0, 1000.0, 'executor', 2000, False)):
        res = run(seconds, rate=rate, spg_path=path, listen=listen)
        assert res['bridge_backend'] == res['spg_backend'] == ros.BACKEND
        # a listening run saw states and commands on its own subscriptions; a quiet one none
        assert (min(res['states'], res['commands']) > 0) if listen else \
            res['states'] is res['commands'] is None, res
        assert res['expected_ticks'] == ticks
        lat = res['latency_ms']
        assert lat is not None, res['logs']
        assert 0 < lat['p50'] <= lat['p99'] <= lat['max']
        # the mechanics only: the miss rate is the benchmark's to measure, on an idle machine
        # (a loaded CI run missed 16 % of 1500 periods in this 3 s realtime run)
        assert 0 <= res['bridge_missed_commands'] < res['expected_ticks'], res['logs']
    base = baseline(1000.0, 0.2)
    assert base['periods'] == 200 and 0 <= base['missed'] < 200
    over = base['overshoot_us']
    assert 0 <= over['p50'] <= over['p99'] <= over['max']


def test_latency_bench_refuses_a_fifo_priority_outside_1_to_99(capsys):
    """``--fifo 0`` (SCHED_FIFO takes 1-99) stops with a usage error naming the option, before
    any run starts."""
    from benchmarks.latency_bench import main

    with pytest.raises(SystemExit) as exc:
        main(['--fifo', '0', '--seconds', '1', '--baseline-seconds', '0'])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert '--fifo 0' in err and '1-99' in err
    assert 'latency_bench: realtime run' not in err
