"""Bags: rosbag2 MCAP round trip (rosbags and mcap readers), DDS record, SIGTERM, play."""

import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from ifc_spg.bag import TOPICS, BagReader, BagWriter, info
from ifc_spg.ros import messages as m
from ifc_spg.ros.testing import loopback_env


def _write_sample(path, n=50, seed=0):
    rng = np.random.default_rng(seed)
    sent = []
    with BagWriter(path) as w:
        for topic in ('joint_states', 'spg/task_stack', 'sim/contact_wrench'):
            w.add_topic('/' + topic, *TOPICS[topic])
        w.write_msg('/spg/task_stack', 0, m.String(data='version: 1\nname: x\ntasks: []\n'))
        for i in range(n):
            js = m.JointState(name=['a', 'b'], position=rng.normal(size=2),
                              velocity=rng.normal(size=2), effort=rng.normal(size=2))
            js.header.stamp = m.Time(sec=i // 500, nanosec=(i % 500) * 2_000_000)
            w.write_msg('/joint_states', i * 2_000_000, js)
            ws = m.WrenchStamped()
            ws.header.frame_id = 'tool'
            ws.wrench.force.z = float(rng.normal())
            w.write_msg('/sim/contact_wrench', i * 2_000_000, ws)
            sent.append((js, ws))
        w.set_custom_data('note', 'hello')
    return sent


def test_round_trip_rosbags_and_mcap(tmp_path):
    path = tmp_path / 'bag'
    sent = _write_sample(path)
    # rosbags: its own reader and deserializer agree with what we wrote
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    with Reader(path) as r:
        assert r.message_count == 101 and r.duration == 49 * 2_000_000 + 1
        got = {}
        for c, t, data in r.messages():
            got.setdefault(c.topic, []).append((t, store.deserialize_cdr(data, c.msgtype)))
        qos = {c.topic: c.ext.offered_qos_profiles[0] for c in r.connections}
    assert [t for t, _ in got['/joint_states']] == [i * 2_000_000 for i in range(50)]
    for (js, ws), (_, a), (_, b) in zip(sent, got['/joint_states'], got['/sim/contact_wrench']):
        assert np.array_equal(a.position, np.asarray(js.position))
        assert np.array_equal(a.effort, np.asarray(js.effort))
        assert list(a.name) == ['a', 'b'] and a.header.stamp.nanosec == js.header.stamp.nanosec
        assert b.wrench.force.z == ws.wrench.force.z and b.header.frame_id == 'tool'
    assert got['/spg/task_stack'][0][1].data.startswith('version: 1')
    assert qos['/spg/task_stack'].durability.name == 'TRANSIENT_LOCAL'
    assert qos['/sim/contact_wrench'].reliability.name == 'BEST_EFFORT'
    # mcap: profile ros2, ros2msg schemas (Foxglove), cdr messages, same bytes
    from mcap.reader import make_reader

    (mcap_file,) = path.glob('*.mcap')
    with open(mcap_file, 'rb') as f:
        reader = make_reader(f)
        assert reader.get_header().profile == 'ros2'
        counts, schemas = {}, {}
        for schema, channel, message in reader.iter_messages(log_time_order=True):
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
            schemas[channel.topic] = (schema.name, schema.encoding, channel.message_encoding)
            if channel.topic == '/joint_states' and counts[channel.topic] == 3:
                assert message.data == m.serialize(sent[2][0])
    assert counts == {'/joint_states': 50, '/sim/contact_wrench': 50, '/spg/task_stack': 1}
    assert schemas['/joint_states'] == ('sensor_msgs/msg/JointState', 'ros2msg', 'cdr')
    # our reader and info
    with BagReader(path) as bag:
        assert bag.custom_data == {'note': 'hello'} and bag.message_count == 101
    text = info(path)
    assert 'sensor_msgs/msg/JointState' in text and '50' in text and '0.098 s' in text


def test_writer_refuses_existing_directory(tmp_path):
    from ifc_spg.errors import ParameterError

    with pytest.raises(ParameterError, match='cannot create bag'):
        BagWriter(tmp_path)


def _start(args, env):
    return subprocess.Popen([sys.executable, '-m', 'ifc_spg.cli', *args], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _wait_line(proc, word, timeout=20.0):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        line = proc.stdout.readline()
        if word in line:
            return line
        if not line and proc.poll() is not None:
            break
    raise AssertionError(f'no "{word}" from {proc.args}: {proc.stderr.read()}')


@pytest.fixture()
def dds_env(tmp_path):
    return loopback_env()


@pytest.mark.ros
def test_record_over_dds_counts_match_and_sigterm_closes(tmp_path, dds_env):
    path = tmp_path / 'rec'
    rec = _start(['bag', 'record', '-o', str(path), 'joint_states'], dds_env)
    talker = None
    try:
        _wait_line(rec, 'recording')
        talker = _start(['ros', 'talker', '--ros-args', '-p', 'rate:=1000.0', '-p', 'count:=400',
                         '-p', 'wait_for_subscribers:=1'], dds_env)
        assert talker.wait(60) == 0, talker.stderr.read()
        time.sleep(0.3)  # the talker waited for acks: everything is in the reader
        rec.send_signal(signal.SIGTERM)
        assert rec.wait(20) == 0, rec.stderr.read()
    finally:
        for p in (rec, talker):
            if p is not None and p.poll() is None:
                os.kill(p.pid, signal.SIGKILL)
                p.wait()
    with BagReader(path) as bag:
        assert bag.topics['/joint_states'][:2] == ('sensor_msgs/msg/JointState', 400)
        seqs = [int(msg.header.frame_id) for _, _, msg in bag.messages()]
    assert seqs == list(range(400))
    from mcap.reader import make_reader

    (mcap_file,) = path.glob('*.mcap')
    with open(mcap_file, 'rb') as f:
        assert sum(1 for _ in make_reader(f).iter_messages()) == 400


@pytest.mark.ros
def test_play_republishes_with_qos_and_timing(tmp_path, dds_env):
    src = tmp_path / 'src'
    _write_sample(src, n=100)
    dst = tmp_path / 'dst'
    rec = _start(['bag', 'record', '-o', str(dst)], dds_env)
    try:
        _wait_line(rec, 'recording')
        t0 = time.monotonic()
        # a fixed delay is not enough on rclpy: Fast DDS' discovery of two processes took
        # longer than 2 s in half of the tries here (the next announcement, 3 s, finds it)
        player = _start(['bag', 'play', str(src), '--rate', '0.5', '--delay', '2.0',
                         '--wait-for-subscribers', '1'], dds_env)
        assert player.wait(60) == 0, player.stderr.read()
        elapsed = time.monotonic() - t0
        time.sleep(0.3)
        rec.send_signal(signal.SIGINT)
        assert rec.wait(20) == 0, rec.stderr.read()
    finally:
        for p in (rec,):
            if p.poll() is None:
                os.kill(p.pid, signal.SIGKILL)
                p.wait()
    # 0.198 s of bag at rate 0.5 lasts ~0.4 s after the 2 s discovery delay
    assert elapsed > 2.0 + 0.198 / 0.5 - 0.05
    with BagReader(dst) as bag:
        assert bag.topics['/joint_states'][1] == 100
        assert bag.topics['/spg/task_stack'][1] == 1
        assert bag.topics['/spg/task_stack'][2][0].durability.name == 'TRANSIENT_LOCAL'
        got = [msg for _, _, msg in bag.messages({'/joint_states'})]
        times = [t for _, _, t, _ in bag.raw({'/joint_states'})]
    with BagReader(src) as bag:
        sent = [msg for _, _, msg in bag.messages({'/joint_states'})]
    assert got == sent
    # receive times keep the original spacing (x2 at rate 0.5), loosely
    span = (times[-1] - times[0]) * 1e-9
    assert 0.3 < span < 1.5
