"""A live bag recorded mid-run replays with ``ifc-spg replay BAG`` and no flags.

``sim_bridge`` (lockstep, table scene), ``spg_node`` and ``task_publisher`` run over DDS; the
recorder (``ifc-spg bag record``, default topics) starts after the stack is running, a
second stack arrives while it records, and it stops before the run ends. The bag is
self-contained: the SPG's latched ``spg/config`` (settings, K, D, limits, the running stack
and where its tasks captured their ``init`` values) and ``spg/state`` (the state after each
tick). The replay starts from the first recorded state and must reproduce every recorded
q_v after it to 1e-9 rad (DAQP is warm-started differently there: measured 0 here).
"""

import json
import signal
import sys

from helpers import CONFIG, reach_stack, replay_cli, use_loopback
import pytest
from ros_testing import ProcessGroup, stamp_ns

from ifc_spg import ros
from ifc_spg.offline.bag import BagReader, BagWriter
from ifc_spg.ros import msg as ros_msg

pytestmark = [pytest.mark.dds, pytest.mark.ros]

TOLERANCE = 1e-9  # [rad]



def _listener():
    """This test's node on spg/status and joint_states (after ``ros.init``).

    Returns:
        (the node, status documents, [the bridge's latest sim time s],
        spin_until(condition, timeout), accepted(n): True once n stacks were accepted).
    """
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

    return node, status, sim_t, spin_until, accepted

@pytest.mark.slow
def test_bag_recorded_mid_run_replays_without_flags(tmp_path, monkeypatch, capsys):
    from ifc_spg.offline.replay import replay

    env = use_loopback(monkeypatch)
    first = tmp_path / 'first.yaml'
    first.write_text(reach_stack('lbr_iiwa14', name='reach'))
    second = tmp_path / 'second.yaml'
    second.write_text(reach_stack('lbr_iiwa14', name='reach_again'))
    bag = tmp_path / 'bag'
    procs = ProcessGroup(tmp_path, env)
    node, status, sim_t, spin_until, accepted = _listener()

    try:
        spg = procs.start('spg_node', '--ros-args', '--params-file',
                          str(CONFIG / 'lbr_iiwa14.yaml'))
        assert spin_until(lambda: node.count_publishers('spg/status') >= 1 or
                          spg.poll() is not None, 60.0), procs.log('spg_node')
        procs.start('publisher_1', str(first), '--robot', 'lbr_iiwa14', exe='task_publisher')
        assert spin_until(lambda: accepted(1) or spg.poll() is not None, 60.0), \
            procs.log('spg_node')
        bridge = procs.start('sim_bridge', '--ros-args', '-p', 'robot:=lbr_iiwa14', '-p',
                             'interface:=lbr_fri', '-p', 'scene:=table', '-p',
                             'mode:=lockstep', '-p', 'duration:=60.0', '-p',
                             'wait_for_subscribers:=2')
        assert spin_until(lambda: sim_t[0] >= 1.0 or bridge.poll() is not None, 120.0), \
            procs.log('sim_bridge')
        # mid-run: the stack has been running for a second of sim time
        rec = procs.start('recorder', 'bag', 'record', '-o', str(bag), exe='ifc-spg')
        assert spin_until(lambda: 'recording' in procs.log('recorder') or
                          rec.poll() is not None, 60.0) and rec.poll() is None, \
            procs.log('recorder')
        # the recorder matches the SPG's latched topics within a discovery period (Fast DDS
        # announces every 3 s); then a second stack, while it records
        t_rec = sim_t[0]
        assert spin_until(lambda: sim_t[0] >= t_rec + 4.0 or bridge.poll() is not None,
                          120.0)
        procs.start('publisher_2', str(second), '--robot', 'lbr_iiwa14', exe='task_publisher')
        assert spin_until(lambda: accepted(2) or spg.poll() is not None, 60.0), \
            procs.log('spg_node')
        t2 = sim_t[0]
        assert spin_until(lambda: sim_t[0] >= t2 + 1.0 or bridge.poll() is not None, 120.0)
        # and it stops while the loop still runs: the last state's command may be missing
        assert procs.stop('recorder', signal.SIGINT, 30.0) == 0, procs.log('recorder')
        assert bridge.poll() is None, procs.log('sim_bridge')
    finally:
        procs.close()
        ros.shutdown()
    with BagReader(bag) as reader:
        counts = {t: c for t, (_, c, _) in reader.topics.items()}
        assert reader.custom_data == {}  # nothing but the topics
    assert counts.get('/spg/config', 0) >= 2, counts  # latched one + the second stack
    assert counts.get('/spg/state', 0) > 100, counts
    res = replay(bag)
    assert res.resumed and res.missing == 0 and res.stacks == 1, res
    # every recorded state is compared, or an edge: before the first recorded SPG state
    # (skipped) or after the last recorded command (unanswered). The recorder may match the
    # SPG's commands before the bridge's states (discovery): commands without a recorded
    # state are not compared (one run: 2948 commands, 2631 states, 2629 compared).
    # Ticks the recorder missed (res.lost, detected from spg/state) are resynchronised over;
    # the commands computed across them are not compared (unverified)
    assert res.compared + res.skipped + res.unanswered + res.unverified + res.not_ticked == \
        counts['/joint_states'], (res, counts)
    assert res.compared > 1000, res
    assert res.max_abs_diff <= TOLERANCE, res
    print(f'mid-run replay: {res.compared} commands, {res.skipped} states before the first '
          f'spg/state, {res.unanswered} unanswered, max |dq_v| {res.max_abs_diff:.3e} rad',
          file=sys.stderr)
    assert replay_cli([str(bag)], res, monkeypatch) == 0
    assert 'OK' in capsys.readouterr().out
    _lost_states_are_detected_and_resynchronised(bag, res, tmp_path, capsys, monkeypatch)


GAP = 18  # joint states in a burst the recorder missed (a CI run lost 18 of 7000)


def _stamp(msg):
    return msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec


def _copy_without(src, dst, drop):
    """Rewrite bag ``src`` to ``dst`` without the messages ``drop(topic, msg)`` selects."""
    from ifc_spg.ros.messages import REGISTRY, deserialize

    with BagReader(src) as r, BagWriter(dst) as w:
        for key, value in r.custom_data.items():
            w.set_custom_data(key, value)
        for topic, (msgtype, _, profiles) in r.topics.items():
            w.add_topic(topic, msgtype, profiles)
        for topic, msgtype, t, data in r.raw():
            if msgtype not in REGISTRY or not drop(topic, deserialize(REGISTRY[msgtype], data)):
                w.write(topic, t, data)


def _lost_states_are_detected_and_resynchronised(bag, res, tmp_path, capsys, monkeypatch):
    """A burst of joint states missing from the bag, where q_v moves fastest: spg/state's tick
    count shows the loss, the replay resynchronises from it and reproduces the rest; without
    the recorded states after the burst the loss goes unnoticed."""
    from ifc_spg.offline.replay import replay

    with BagReader(bag) as r:
        commands = {_stamp(m): m for _, _, m in r.messages(['/command/joint_position'])}
        states = sorted({_stamp(m) for _, _, m in r.messages(['/joint_states'])})
        first = min(round(m.data[1] * 1e9 + m.data[2]) for _, _, m in r.messages(['/spg/state']))
    # where the commanded joint velocity is largest, after the state the replay starts from
    # (the first spg/state, or the first joint state where the recorder matched spg/state
    # first: 0.6 s earlier in a loaded run) and away from the recording's end
    first = max(first, states[0])
    inner = [s for s in states[:-50] if s > first + 20_000_000 and s in commands]
    start = max(inner, key=lambda s: max(abs(v) for v in commands[s].velocity))
    gap = set(states[states.index(start): states.index(start) + GAP])
    lossy = tmp_path / 'lossy'
    _copy_without(bag, lossy, lambda topic, m: topic == '/joint_states' and _stamp(m) in gap)
    got = lossy_got = replay(lossy)
    assert got.lost == res.lost + GAP and got.resyncs == res.resyncs + 1, got
    assert got.max_abs_diff <= TOLERANCE and got.missing == 0, got
    assert got.compared + got.unverified == res.compared + res.unverified - GAP, (got, res)
    assert replay_cli([str(lossy)], got, monkeypatch) == 0
    assert f'lacks {got.lost} tick(s)' in capsys.readouterr().out
    blind = tmp_path / 'blind'
    _copy_without(bag, blind, lambda topic, m: (topic == '/joint_states' and _stamp(m) in gap)
                  or (topic == '/spg/state' and round(m.data[1] * 1e9 + m.data[2]) >= start))
    got = replay(blind)
    # without them the loss goes unnoticed (how far q_v then drifts depends on how fast the
    # arm moves there: 5e-9 rad and 3e-12 rad in two runs), and so does any the recorder
    # itself caused after it (a loaded run lost 18 states there: 1 resync in the bag, 0 here)
    assert got.resyncs <= res.resyncs and got.lost <= res.lost, got
    print(f'{GAP} lost states where |qdot_v| is largest: resynchronised, max |dq_v| '
          f'{lossy_got.max_abs_diff:.1e} rad; without spg/state after them '
          f'{got.max_abs_diff:.1e} rad', file=sys.stderr)


# issue 31: a wrench (-8 N), a circle and a zero-torque posture without power_budget: the
# tanks empty and the SPG reports PSPM stalls (intended); with 0.05 J instead of 0.5 J in
# each tank at the start they do so within a second
STALLING = """version: 1
name: {name}
robot: lbr_iiwa14
tasks:
  - {{name: contact_force, type: wrench, frame: tool, subspace: [fz], equal: -8.0, gain: 5.0,
     include_damping: true}}
  - {{name: circle, type: cartesian_pose, frame: tool, subspace: [x, y, rx, ry, rz],
     equal: {{trajectory: circle, plane: xy, radius: 0.05, frequency: 0.16, start: init}},
     gain: 5.0}}
  - {{name: {posture}, type: {posture_type}, equal: 0.0{posture_gain}}}
"""


@pytest.mark.realtime
def test_live_bags_of_a_stalling_stack_and_a_switch_replay_exactly(tmp_path, monkeypatch,
                                                                    capsys):
    """The issue-31 case on a realtime bridge: a bag of a stalling stack (empty tanks clip
    the cascade, whose lowest level is then degenerate: a cold-started replay solved it
    elsewhere, 5.7e-4 rad of q_v) and one during which a second stack replaces it. Both
    replay with max |dq_v| = 0, every command compared."""
    from ifc_spg.offline.replay import replay

    env = use_loopback(monkeypatch)
    first = tmp_path / 'stalling.yaml'
    first.write_text(STALLING.format(name='stalling', posture='min_torque',
                                     posture_type='joint_torque', posture_gain=''))
    second = tmp_path / 'switched.yaml'  # the same level sizes: the same solver models
    second.write_text(STALLING.format(name='switched', posture='posture',
                                      posture_type='joint_position',
                                      posture_gain=', gain: 1.0'))
    bags = tmp_path / 'stall', tmp_path / 'switch'
    procs = ProcessGroup(tmp_path, env)
    node, status, sim_t, spin_until, accepted = _listener()
    node.create_publisher(ros_msg.Float64MultiArray, 'spg/state', ros.latched(1))  # as the SPG's

    def stalled():
        return any((s.get('pspm') or {}).get('stall') for s in status[-5:])

    def record(bag):
        rec = procs.start(bag.name, 'bag', 'record', '-o', str(bag), exe='ifc-spg')
        assert spin_until(lambda: 'recording' in procs.log(bag.name) or
                          rec.poll() is not None, 60.0) and rec.poll() is None, \
            procs.log(bag.name)
        # and its reader of spg/state is on the graph (the replay starts from the first
        # recorded SPG state: seen on a loaded machine, 350 joint states, 0.7 s, recorded
        # before the first spg/state, and 88 commands left in the window)
        # (this node's publisher on spg/state, which never publishes, sees the readers on
        # both backends; the built-in one counts the readers its own writers matched)
        assert spin_until(lambda: node.count_subscribers('spg/state') >= 1, 30.0), \
            procs.log(bag.name)

    def run_for(seconds):
        t0 = sim_t[0]
        assert spin_until(lambda: sim_t[0] >= t0 + seconds or bridge.poll() is not None,
                          120.0) and bridge.poll() is None, procs.log('sim_bridge')

    try:
        spg = procs.start('spg_node', '--ros-args', '--params-file',
                          str(CONFIG / 'lbr_iiwa14.yaml'), '-p', 'pspm.initial_energy:=0.05')
        assert spin_until(lambda: node.count_publishers('spg/status') >= 1 or
                          spg.poll() is not None, 60.0), procs.log('spg_node')
        procs.start('publisher_1', str(first), '--robot', 'lbr_iiwa14', exe='task_publisher')
        assert spin_until(lambda: accepted(1) or spg.poll() is not None, 60.0), \
            procs.log('spg_node')
        bridge = procs.start('sim_bridge', '--ros-args', '-p', 'robot:=lbr_iiwa14', '-p',
                             'interface:=lbr_fri', '-p', 'scene:=table', '-p',
                             'mode:=realtime', '-p', 'duration:=120.0', '-p',
                             'wait_for_subscribers:=2')
        # once the stack runs: record until the SPG has reported a stall and a second more
        # (the tanks refill from the damping, so a stall comes and goes)
        run_for(0.5)
        record(bags[0])
        assert spin_until(lambda: stalled() or bridge.poll() is not None, 120.0) and \
            bridge.poll() is None, (procs.log('sim_bridge'), status[-1:])
        run_for(1.0)
        assert procs.stop(bags[0].name, signal.SIGINT, 30.0) == 0, procs.log(bags[0].name)
        # then a bag during which the second stack replaces it
        record(bags[1])
        run_for(1.0)
        procs.start('publisher_2', str(second), '--robot', 'lbr_iiwa14', exe='task_publisher')
        assert spin_until(lambda: accepted(2) or spg.poll() is not None, 60.0), \
            procs.log('spg_node')
        run_for(1.5)
        assert procs.stop(bags[1].name, signal.SIGINT, 30.0) == 0, procs.log(bags[1].name)
    finally:
        procs.close()
        ros.shutdown()
    with BagReader(bags[0]) as reader:
        energies = [min(m.data[3 + 3 * 7:3 + 4 * 7]) for _, _, m in
                    reader.messages(['/spg/state'])]
    assert sum(e <= 1e-9 for e in energies) > 20, ('no stall in the recording',
                                                   sorted(energies)[:5])
    for bag, stacks in zip(bags, (0, 1)):
        res = replay(bag)
        assert res.resumed and res.missing == 0 and res.stacks == stacks, res
        # a second or more of ticks (277 compared where the machine was loaded: the SPG answers
        # fewer states then; the states it did not tick on are counted, not compared)
        assert res.compared > 100, res
        assert res.max_abs_diff == 0.0, res
        print(f'{bag.name}: {res.compared} commands, {res.not_ticked} states the SPG did not '
              f'tick on, {res.lost} lost, max |dq_v| {res.max_abs_diff:.3e} rad',
              file=sys.stderr)
        assert replay_cli([str(bag)], res, monkeypatch) == 0
        assert 'OK' in capsys.readouterr().out
