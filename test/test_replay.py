"""Replay recomputes the SPG output from an offline bag exactly; a tampered bag fails."""

import pytest

from ifc_spg.cli.replay import main
from ifc_spg.offline.bag import BagReader, BagWriter
from ifc_spg.offline.replay import replay
from ifc_spg.offline.runner import find_config_dir, load_scenario, run_scenario


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


def _copy(src, dst, tamper=None, custom=None):
    """Rewrite a bag; ``tamper(topic, index, msg) -> changed`` may alter a message and
    ``custom(key, value) -> value`` a custom-data entry (None: drop it)."""
    from ifc_spg.ros.messages import REGISTRY, deserialize, serialize

    with BagReader(src) as r, BagWriter(dst) as w:
        for key, value in r.custom_data.items():
            value = value if custom is None else custom(key, value)
            if value is not None:
                w.set_custom_data(key, value)
        for topic, (msgtype, _, profiles) in r.topics.items():
            w.add_topic(topic, msgtype, profiles)
        seen = {}
        for topic, msgtype, t, data in r.raw():
            i = seen[topic] = seen.get(topic, -1) + 1
            if tamper is not None and msgtype in REGISTRY:  # (not the rosbags-only tf, markers)
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


# -- the robot's IFC gains and the SPG settings of the run are in the bag ----------------

K_RUN = [350.0, 300.0, 250.0, 320.0, 150.0, 120.0, 100.0]   # lbr_iiwa14 default: 200 each
D_RUN = [40.0, 45.0, 20.0, 22.0, 4.0, 3.5, 2.5]


@pytest.fixture(scope='module')
def tuned_bag(tmp_path_factory):
    """A run with scenario overrides of K, D (sim:) and of rho and the PSPM tanks (spg:)."""
    out = tmp_path_factory.mktemp('tuned')
    sc = load_scenario(find_config_dir() / 'scenarios' / 'surface_short.yaml', {
        'duration': 1.1, 'sim': {'stiffness': K_RUN, 'damping': D_RUN},
        'spg': {'status_decimation': 7, 'rho': 0.05,
                'pspm': {'initial_energy': 0.3, 'max_energy': 1.5}}})
    return run_scenario(sc, out, quiet=True).bag


def _strip_robot_params(src, dst):
    """Copy a bag without its robot-parameter record (as bags written before it existed)."""
    import json

    from ifc_spg.offline.runner import ROBOT_PARAMS_KEY

    def drop(topic, i, msg):
        if topic != '/spg/status':
            return False
        doc = json.loads(msg.data)
        if doc.pop('robot_params', None) is None:
            return False
        msg.data = json.dumps(doc)
        return True

    _copy(src, dst, drop, custom=lambda key, value: None if key == ROBOT_PARAMS_KEY else value)


def test_overridden_gains_and_spg_settings_replay_exactly(tuned_bag, capsys):
    res = replay(tuned_bag)
    assert res.ticks == 550 and res.compared == 550 and res.missing == 0
    assert res.max_abs_diff <= 1e-12
    assert res.warnings == []
    assert res.robot_params['stiffness'] == K_RUN and res.robot_params['damping'] == D_RUN
    assert res.config['rho'] == 0.05 and res.config['pspm_initial_energy'] == 0.3
    assert res.config['pspm_max_energy'] == 1.5
    assert main([str(tuned_bag)]) == 0
    captured = capsys.readouterr()
    assert 'warning' not in captured.err and 'K, D from the bag' in captured.out


def test_the_recorded_gains_matter(tuned_bag, tmp_path):
    """Without the record the replay uses the default K, D and misses: the record is needed."""
    _strip_robot_params(tuned_bag, tmp_path / 'old')
    res = replay(tmp_path / 'old')
    assert res.max_abs_diff > 1e-4
    assert res.robot_params['stiffness'] == [200.0] * 7


def test_bag_without_gains_replays_with_defaults_and_a_warning(bag, tmp_path, capsys):
    _strip_robot_params(bag, tmp_path / 'old')
    res = replay(tmp_path / 'old')
    assert res.max_abs_diff <= 1e-12 and res.compared == 550
    assert len(res.warnings) == 1
    assert 'no robot parameters' in res.warnings[0]
    assert "default K, D of 'lbr_iiwa14'" in res.warnings[0]
    assert main([str(tmp_path / 'old')]) == 0
    err = capsys.readouterr().err
    assert 'ifc-spg replay: warning: ' in err and 'ifc_spg.robot_params' in err


def test_bad_gain_record_is_an_error_naming_the_key(bag, tmp_path, capsys):
    import json

    from ifc_spg.offline.runner import ROBOT_PARAMS_KEY

    def short_k(key, value):
        if key != ROBOT_PARAMS_KEY:
            return value
        doc = json.loads(value)
        doc['stiffness'] = doc['stiffness'][:3]
        return json.dumps(doc)

    _copy(bag, tmp_path / 'bad', custom=short_k)
    assert main([str(tmp_path / 'bad')]) == 2
    err = capsys.readouterr().err
    assert ROBOT_PARAMS_KEY in err and 'stiffness' in err and '7 values' in err


def test_gains_from_the_status_when_the_metadata_lacks_them(tuned_bag, tmp_path):
    """A bag recorded live (``ifc-spg bag record``) has no custom_data: spg/status has them."""
    from ifc_spg.offline.runner import ROBOT_PARAMS_KEY

    _copy(tuned_bag, tmp_path / 'live', custom=lambda k, v: None if k == ROBOT_PARAMS_KEY else v)
    res = replay(tmp_path / 'live')
    assert res.max_abs_diff <= 1e-12 and res.warnings == [] and res.gains_recorded


def test_a_last_state_without_its_command_is_the_recordings_edge(bag, tmp_path, capsys):
    """The recorder stopped after the last joint state but before its command: not a failure
    (a command missing in the middle still is)."""
    with BagReader(bag) as r:
        n = r.topics['/command/joint_position'][1]

    def drop(index):
        dst = tmp_path / f'drop_{index}'
        with BagReader(bag) as r, BagWriter(dst) as w:
            for key, value in r.custom_data.items():
                w.set_custom_data(key, value)
            for topic, (msgtype, _, profiles) in r.topics.items():
                w.add_topic(topic, msgtype, profiles)
            seen = -1
            for topic, _, t, data in r.raw():
                if topic == '/command/joint_position':
                    seen += 1
                    if seen == index:
                        continue
                w.write(topic, t, data)
        return dst

    res = replay(drop(n - 1))
    assert res.unanswered == 1 and res.missing == 0 and res.compared == n - 1
    assert main([str(tmp_path / f'drop_{n - 1}')]) == 0
    assert 'recording ended' in capsys.readouterr().out
    res = replay(drop(100))
    assert res.missing == 1 and main([str(tmp_path / 'drop_100')]) == 1
