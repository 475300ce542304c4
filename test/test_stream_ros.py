"""A PoseStamped stream over DDS into a running SPG: ``sim_bridge`` (lockstep, free scene) and
``spg_node`` as processes, this test streams a circle at 100 Hz of sim time with 10 % of the
messages dropped and some NaN ones, then stops; it also reads ``spg/markers``."""

import math
import signal
import time

from helpers import CONFIG, record_spg_topics, start_recorder, use_loopback
import numpy as np
import pinocchio as pin
import pytest

from ifc_spg import ros
from ifc_spg.model import RobotModel
from ifc_spg.offline.bag import BagReader
from ifc_spg.ros import msg as ros_msg
from ifc_spg.ros.testing import ProcessGroup, stamp_ns

pytestmark = [pytest.mark.dds, pytest.mark.ros]

SIM_SECONDS = 4.5
T_START, T_STOP = 0.5, 3.0   # [s] sim time: the stream runs in between
RADIUS, FREQ = 0.05, 0.25    # [m], [Hz]
STACK = CONFIG / 'examples' / 'teleop_pose_stream.yaml'  # the README's example stack


def test_pose_stream_over_dds_is_followed_counted_and_held(tmp_path, monkeypatch):
    env = use_loopback(monkeypatch)
    stack = STACK
    bag = tmp_path / 'bag'
    robot = RobotModel.from_config('lbr_iiwa14')
    data, tool = robot.create_data(), robot.frame_id('tool')

    def fk(q):
        pin.framesForwardKinematics(robot.model, data, np.asarray(q, float))
        return data.oMf[tool].translation.copy(), data.oMf[tool].rotation.copy()

    ros.init(['test'])
    node = ros.Node('streamer')
    states, commands, status = record_spg_topics(node)
    pub = node.create_publisher(ros_msg.PoseStamped, 'spg/reference/tool', 10)
    rng = np.random.default_rng(5)
    sent = {'n': 0, 'dropped': 0, 'nan': 0}
    ref = {}  # sim stamp [ns] -> the pose sent
    anchor = {}

    def on_state(message):  # the streamer: one message per 10 ms of sim time
        t = stamp_ns(message) * 1e-9
        if 'p0' not in anchor:
            anchor['p0'], anchor['R0'] = fk(message.position)
        k = round(t / 0.01)
        if not T_START <= t < T_STOP or abs(t - k * 0.01) > 1e-6 or k in anchor:
            return
        anchor[k] = True
        sent['n'] += 1
        r = rng.random()
        if r < 0.10:
            sent['dropped'] += 1
            return
        p = _circle(anchor['p0'], t)
        out = ros_msg.PoseStamped()
        out.header.stamp = message.header.stamp
        out.header.frame_id = 'world'
        out.pose.position.x, out.pose.position.y, out.pose.position.z = (float(v) for v in p)
        qx, qy, qz, qw = pin.Quaternion(anchor['R0']).coeffs()
        o = out.pose.orientation
        o.x, o.y, o.z, o.w = float(qx), float(qy), float(qz), float(qw)
        if r < 0.13:
            sent['nan'] += 1
            out.pose.position.z = float('nan')
        else:
            ref[stamp_ns(message)] = p
        pub.publish(out)

    node.create_subscription(ros_msg.JointState, 'joint_states', on_state, 10000)
    markers = []
    if ros_msg.MarkerArray is not None:  # rclpy without visualization_msgs: no markers
        node.create_subscription(ros_msg.MarkerArray, 'spg/markers',
                                 lambda m: markers.append((time.monotonic(), m)), 1000)
    procs = ProcessGroup(tmp_path, env)
    try:
        spg = procs.start('spg_node', '--ros-args', '--params-file',
                          str(CONFIG / 'lbr_iiwa14.yaml'), '-p', 'status.decimation:=50',
                          '-p', f'task_stack_file:={stack}')
        # the recorder (default topics) records the streamed reference too
        start_recorder(procs, bag)
        assert ros.spin_until(lambda: node.count_publishers('spg/status') >= 1 and
                              node.count_subscribers('spg/reference/tool') >= 2 or
                              spg.poll() is not None, 60.0, nodes=node), \
            procs.log('spg_node') + procs.log('recorder')
        bridge = procs.start('sim_bridge', '--ros-args', '-p', 'robot:=lbr_iiwa14', '-p',
                             'scene:=free', '-p', 'mode:=lockstep', '-p',
                             f'duration:={SIM_SECONDS}', '-p', 'wait_for_subscribers:=2')
        deadline = time.monotonic() + 120.0
        while bridge.poll() is None and time.monotonic() < deadline:
            ros.spin_until(lambda: False, 0.1, nodes=node)
        assert bridge.returncode == 0, procs.log('sim_bridge')
        ticks = round(SIM_SECONDS / 0.002)
        ros.spin_until(lambda: len({stamp_ns(c) for c in commands}) >= ticks, 10.0,
                       nodes=node)
        # a last status after the stream stopped (the node publishes every 50 ticks)
        ros.spin_until(lambda: False, 0.5, nodes=node)
        assert procs.stop('recorder', signal.SIGINT) == 0, procs.log('recorder')
    finally:
        procs.close()
        ros.shutdown()
    assert "following 'spg/reference/tool'" in procs.log('spg_node')
    with BagReader(bag) as reader:
        recorded = {t: c for t, (_, c, _) in reader.topics.items()}
    published = sent['n'] - sent['dropped']
    # (best effort: the recorder can miss some, as the SPG can)
    assert published >= recorded.get('/spg/reference/tool', 0) >= 0.5 * published, recorded
    assert recorded.get('/tf', 0) > 100, recorded  # the robot named by spg/config
    q_v = {stamp_ns(c): np.array(c.position) for c in commands}
    q = {stamp_ns(s): np.array(s.position) for s in states}
    stamps = sorted(set(q_v) & set(q))
    # this listener can match the SPG's command topic a little after the run starts (the
    # first 12 and 84 ticks missed in two runs): the rest of the run is what is checked
    assert len(stamps) >= 0.9 * ticks
    p0 = anchor['p0']
    center = p0 - [RADIUS, 0.0, 0.0]
    err_v, err_m, path_v = [], [], []
    for s in stamps:
        t = s * 1e-9
        if T_START + 1.0 <= t < T_STOP:
            target = _circle(p0, t)
            p_v = fk(q_v[s])[0]
            err_v.append(np.linalg.norm(p_v - target))
            err_m.append(np.linalg.norm(fk(q[s])[0] - target))
            d = p_v - center  # distance from the circle's curve: free of the phase lag
            path_v.append(np.hypot(np.hypot(d[0], d[1]) - RADIUS, d[2]))
    last_status = [d for d in status if d.get('streams')][-1]
    (stream,) = last_status['streams']
    lat = stream['latency']
    print(f'DDS stream: commanded tool max {max(err_v) * 1e3:.1f} mm from the circle point '
          f'of its stamp, {max(path_v) * 1e3:.2f} mm from the circle; measured tool max '
          f'{max(err_m) * 1e3:.1f} mm; {sent} sent, {stream["received"]} '
          f'received; receipt -> command tick p50 {lat["p50"] * 1e3:.2f} ms, p99 '
          f'{lat["p99"] * 1e3:.2f} ms, max {lat["max"] * 1e3:.2f} ms')
    # q_v stays on the circle (a first-order follower at 10/s shrinks it by 1.2 %: 0.6 mm;
    # 1.6 mm seen, 3.1 mm on a loaded machine, where a streamer that stalls makes q_v cut a
    # chord) and lags v / gain = 7.9 mm behind, plus the messages' delay in sim time: a
    # lockstep loop runs as fast as it can and the streamer is not part of it (11 to 26 mm
    # seen); the simulated robot lags q_v behind its joint impedance (24 to 34 mm seen)
    # How closely q_v follows depends on the streamer, which runs outside the lockstep loop:
    # when this process stalls, the simulation runs ahead of the stream and the target jumps
    # (q_v then cuts a chord: 1.6 mm to 16.5 mm off the circle's curve, and from 2.4 rad of
    # the circle covered down to 0.2 rad, in runs on one machine). Printed, not asserted; the
    # following itself is tested without DDS (test_stream.py: within 9.9 mm of the point).
    def angle(p):
        return math.atan2(p[1] - center[1], p[0] - center[0])

    window = [s for s in stamps if T_START + 1.0 <= s * 1e-9 < T_STOP]
    moved = np.unwrap([angle(fk(q_v[s])[0]) for s in window])
    print(f'DDS stream: {moved[-1] - moved[0]:.2f} rad of the circle covered in the last '
          f'{T_STOP - T_START - 1.0:g} s of the stream, at most {max(path_v) * 1e3:.1f} mm off '
          'its curve')
    # NaNs counted, the rest accepted (best effort on loopback: nearly all arrive)
    # (a best-effort sample can be lost on the way, a NaN one too: 4 of 5 seen)
    nan = stream['rejected']['nonfinite']
    assert 0 < nan <= sent['nan'] and sum(stream['rejected'].values()) == nan
    delivered = sent['n'] - sent['dropped']
    # best effort, depth 10: a streamer that stalls and then bursts loses some (198 of 220)
    assert 0.5 * delivered <= stream['received'] <= delivered
    assert stream['accepted'] == stream['received'] - nan
    # the stream stopped at 3 s: stale after stale_after, the last target held (a streamer
    # that stalls > 0.2 s of wall time mid-stream, e.g. on a loaded machine, is reported too)
    assert stream['state'] == 'stale' and stream['stale_episodes'] >= 1
    last_ref = ref[max(ref)]
    p_end, _ = fk(q_v[stamps[-1]])
    assert np.linalg.norm(p_end - last_ref) < 1e-3
    # every command inside the joint limits and never faster than v_max
    traj = np.array([q_v[s] for s in stamps])
    assert np.all(traj >= robot.q_min) and np.all(traj <= robot.q_max)
    assert np.all(np.abs(np.diff(traj, axis=0)) <= robot.v_max * 0.002 + 1e-12)

    # spg/markers (default 30 Hz): the tool task's target, on the streamed circle
    if ros_msg.MarkerArray is None:
        assert 'spg/markers is off' in procs.log('spg_node')
        return
    assert len(markers) > 10
    wall = markers[-1][0] - markers[0][0]
    # never faster than markers.rate (30 Hz), timed by their arrival here, which bunches
    # (230 in 7.46 s seen: 30.7 Hz): a second's worth of slack
    assert len(markers) - 1 <= 30 * (wall + 1.0)
    on_circle = []
    for _, arr in markers:
        assert arr.markers[0].action == arr.markers[0].DELETEALL
        spheres = [mk for mk in arr.markers[1:] if mk.type == mk.SPHERE]
        assert [mk.ns for mk in spheres] == ['tool'] and spheres[0].header.frame_id == 'world'
        t = stamp_ns(spheres[0]) * 1e-9
        if T_START + 0.1 < t < T_STOP:
            p = spheres[0].pose.position
            d = np.array([p.x, p.y, p.z]) - center
            on_circle.append(np.hypot(np.hypot(d[0], d[1]) - RADIUS, d[2]))
    assert len(on_circle) > 5 and max(on_circle) < 1e-6


def _circle(p0, t):
    a = 2 * np.pi * FREQ * (t - T_START)
    return p0 + RADIUS * np.array([np.cos(a) - 1.0, np.sin(a), 0.0])
