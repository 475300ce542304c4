"""Replay recomputes the SPG output from an offline bag exactly; a tampered bag fails."""

import pytest

from ifc_spg.bag import BagReader, BagWriter
from ifc_spg.replay import main, replay
from ifc_spg.runner import find_config_dir, load_scenario, run_scenario


@pytest.fixture(scope='module')
def bag(tmp_path_factory):
    out = tmp_path_factory.mktemp('replay')
    sc = load_scenario(find_config_dir() / 'scenarios' / 'surface_short.yaml',
                       {'duration': 1.1, 'spg': {'status_decimation': 7}})
    return run_scenario(sc, out, quiet=True).bag


def test_offline_bag_replays_exactly(bag):
    res = replay(bag)
    assert res.ticks == 550 and res.compared == 550 and res.missing == 0
    assert res.stacks == 2
    assert res.max_abs_diff <= 1e-12
    assert main([str(bag)]) == 0


def _copy(src, dst, tamper=None):
    """Rewrite a bag; ``tamper(topic, index, data) -> data`` may alter a message."""
    from ifc_spg.ros.messages import REGISTRY, deserialize, serialize

    with BagReader(src) as r, BagWriter(dst) as w:
        for key, value in r.custom_data.items():
            w.set_custom_data(key, value)
        for topic, (msgtype, _, profiles) in r.topics.items():
            w.add_topic(topic, msgtype, profiles)
        seen = {}
        for topic, msgtype, t, data in r.raw():
            i = seen[topic] = seen.get(topic, -1) + 1
            if tamper is not None:
                msg = deserialize(REGISTRY[msgtype], data)
                if tamper(topic, i, msg):
                    data = serialize(msg)
            w.write(topic, t, data)


def test_tampered_command_fails(bag, tmp_path, capsys):
    _copy(bag, tmp_path / 'same')
    assert replay(tmp_path / 'same').max_abs_diff <= 1e-12

    def nudge(topic, i, msg):
        if topic == '/command/joint_position' and i == 400:
            msg.position[3] += 1e-8
            return True
        return False

    _copy(bag, tmp_path / 'bad', nudge)
    res = replay(tmp_path / 'bad')
    assert res.max_abs_diff == pytest.approx(1e-8, rel=1e-3)
    assert res.worst_joint == 'A4' and res.worst_stamp == pytest.approx(0.8)
    assert main([str(tmp_path / 'bad')]) == 1
    assert 'FAILED' in capsys.readouterr().out
    assert main([str(tmp_path / 'bad'), '--tolerance', '1e-7']) == 0


def test_changed_stack_changes_the_result(bag, tmp_path):
    def other_radius(topic, i, msg):
        if topic == '/spg/task_stack' and i == 1:
            assert '"radius": 0.03' in msg.data
            msg.data = msg.data.replace('"radius": 0.03', '"radius": 0.02')
            return True
        return False

    _copy(bag, tmp_path / 'other', other_radius)
    assert replay(tmp_path / 'other').max_abs_diff > 1e-6


def test_not_a_bag(tmp_path, capsys):
    assert main([str(tmp_path)]) == 2
    assert 'not a rosbag2 bag' in capsys.readouterr().err
