"""Offline runner: a short scenario writes the bag a live run would, plus sane metrics."""

import json

from helpers import wait_for
import numpy as np
import pytest

from ifc_spg.cli.run import main
from ifc_spg.errors import ParameterError
from ifc_spg.offline.bag import BagReader, stamp_ns
from ifc_spg.offline.runner import find_config_dir, load_scenario, run_scenario

SCENARIO = find_config_dir() / 'scenarios' / 'surface_short.yaml'


@pytest.fixture(scope='module')
def short_run(tmp_path_factory):
    out = tmp_path_factory.mktemp('run')
    return run_scenario(load_scenario(SCENARIO, {'duration': 1.2}), out, quiet=True)


def test_bag_topics_counts_and_stamps(short_run):
    with BagReader(short_run.bag) as bag:
        assert bag.version == 9 and bag.storage == 'mcap'
        topics = {t: (typ, n) for t, (typ, n, _) in bag.topics.items()}
        assert topics['/joint_states'] == ('sensor_msgs/msg/JointState', 600)
        assert topics['/command/joint_position'] == ('sensor_msgs/msg/JointState', 600)
        assert topics['/sim/contact_wrench'] == ('geometry_msgs/msg/WrenchStamped', 600)
        assert topics['/spg/task_stack'] == ('std_msgs/msg/String', 2)
        assert topics['/spg/status'][1] == 601  # status_decimation 1 + the config message
        js = [(t, stamp_ns(m.header.stamp), m) for _, t, m in bag.messages({'/joint_states'})]
        cmd = {stamp_ns(m.header.stamp): m for _, _, m in
               bag.messages({'/command/joint_position'})}
    stamps = np.array([s for _, s, _ in js])
    # header stamps are sim time: k * dt, and the log time equals the stamp
    assert np.all(np.abs(stamps - np.arange(600) * 2_000_000) <= 1)
    assert all(t == s for t, s, _ in js)
    assert set(cmd) == set(stamps.tolist())
    names = list(js[0][2].name)
    assert names == ['A1', 'A2', 'A3', 'A4', 'A5', 'A6', 'A7']
    assert list(cmd[int(stamps[0])].name) == names


def test_metrics_are_sane(short_run):
    m = json.loads(short_run.metrics_path.read_text())
    assert m == short_run.metrics
    assert m['ticks'] == 600 and m['limit_violations'] == 0 and m['missed_ticks'] == 0
    assert 0.0 <= m['tank_energy_min_j'] <= 2.0
    t = m['tick_time_ms']
    assert 0 < t['p50'] <= t['p99'] <= t['max']
    # the tool reached the table and pressed: some contact, not a crash through it
    assert 2.0 < m['max_contact_force_n'] < 200.0
    # the virtual (static) force converged to 8 N at the end
    assert m['final_task_errors']['contact_force']['virtual'] < 0.5
    assert set(m['final_task_errors']) == {'contact_force', 'circle', 'posture'}


def test_status_carries_config_and_stack_activation(short_run):
    with BagReader(short_run.bag) as bag:
        docs = [json.loads(m.data) for _, _, m in bag.messages({'/spg/status'})]
        cfg = json.loads(bag.custom_data['ifc_spg.node.config'])
    assert docs[0]['config'] == cfg and cfg['robot'] == 'lbr_iiwa14'
    ticks = [d for d in docs if d.get('stamp') is not None]
    switch = [d for d in ticks if d['stack']['id'] == 2]
    assert switch[0]['stack']['since'] == pytest.approx(1.0, abs=1e-9)
    assert switch[0]['stamp'] == pytest.approx(1.0, abs=1e-9)
    assert {t['name'] for t in switch[0]['tasks']} == {'contact_force', 'circle', 'posture'}


def test_scenario_errors_name_the_key(tmp_path):
    bad = tmp_path / 's.yaml'
    bad.write_text('robot: lbr_iiwa14\nduraton: 1.0\n')
    with pytest.raises(ParameterError, match="unknown key 'duraton'.*duration"):
        load_scenario(bad)
    bad.write_text('robot: lbr_iiwa14\nstacks: [{at: 0, file: nope.yaml}]\n')
    with pytest.raises(ParameterError, match="task-stack file 'nope.yaml' not found"):
        load_scenario(bad)
    bad.write_text('robot: lbr_iiwa14\nmetrics: [max_contact_forces]\n')
    with pytest.raises(ParameterError, match='max_contact_force'):
        load_scenario(bad)


def test_stack_file_relative_to_scenario_and_cli(tmp_path, capsys):
    (tmp_path / 'hold.yaml').write_text(
        'version: 1\nname: hold\ntasks:\n'
        '  - {name: pose, type: cartesian_pose, frame: tool, equal: init, gain: 5.0}\n')
    sc = tmp_path / 'sc.yaml'
    sc.write_text('robot: lbr_iiwa14\nscene: free\nduration: 0.1\nprogress: 50\n'
                  'stacks: [{at: 0, file: hold.yaml}]\n'
                  'pushes: [{at: 0.02, target: tool, wrench: [0, 5, 0, 0, 0, 0], '
                  'duration: 0.05}]\n')
    assert main([str(sc), '-o', str(tmp_path / 'out')]) == 0
    out = capsys.readouterr().out
    assert '100.0 %' in out and 'real-time factor' in out
    with BagReader(tmp_path / 'out' / 'bag') as bag:
        assert bag.topics['/sim/apply_wrench'][1] == 1
        (_, _, push), = bag.messages({'/sim/apply_wrench'})
        assert push.header.frame_id == 'tool;duration=0.05' and push.wrench.force.y == 5.0
    assert main([str(sc), '-o', str(tmp_path / 'out')]) == 2  # bag exists: refuses


def test_sigterm_stops_the_run_with_a_closed_bag_and_metrics(tmp_path):
    """A terminated offline run still closes its bag (readable) and writes metrics.json."""
    import os
    import signal
    import subprocess
    import sys

    scenario = find_config_dir() / 'scenarios' / 'surface_short.yaml'
    out = tmp_path / 'run'
    exe = os.path.join(os.path.dirname(sys.executable), 'ifc-spg')
    proc = subprocess.Popen([exe, 'run', str(scenario), '-o', str(out), '--duration', '600'],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        # the first MCAP chunk (~1 MB, a few hundred ticks) reached the file: the run is ticking
        assert wait_for(lambda: any(p.stat().st_size > 0 for p in (out / 'bag').glob('*.mcap')),
                        60)
        proc.send_signal(signal.SIGTERM)
        output, _ = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 130, output
    assert 'stopped by SIGTERM' in output
    metrics = json.loads((out / 'metrics.json').read_text())
    done = metrics['interrupted']['ticks_done']
    assert 0 < done < metrics['interrupted']['ticks_planned']
    with BagReader(out / 'bag') as bag:
        assert bag.topics['/command/joint_position'][1] == done


def test_robot_params_recorded_in_metadata_and_first_status(short_run):
    """K, D and limits the SPG ran with are in metadata.yaml and the first spg/status."""
    from ifc_spg.model import RobotModel
    from ifc_spg.offline.runner import ROBOT_PARAMS_KEY

    robot = RobotModel.from_config('lbr_iiwa14')
    with BagReader(short_run.bag) as bag:
        docs = [json.loads(m.data) for _, _, m in bag.messages({'/spg/status'})]
        rec = json.loads(bag.custom_data[ROBOT_PARAMS_KEY])
    assert rec['robot'] == 'lbr_iiwa14' and rec['joint_names'] == list(robot.joint_names)
    assert rec['stiffness'] == robot.stiffness.tolist()
    assert rec['damping'] == robot.damping.tolist()
    assert rec['tau_max'] == robot.tau_max.tolist() and rec['stiff_joints'] == []
    assert docs[0]['robot_params'] == rec and docs[1]['robot_params'] == rec
    assert all('robot_params' not in d for d in docs[2:])


def test_scenario_gains_reach_the_record(tmp_path):
    k = [300.0, 250.0, 200.0, 150.0, 100.0, 80.0, 60.0]
    sc = load_scenario(SCENARIO, {'duration': 0.01, 'sim': {'stiffness': k, 'damping': 12.5},
                                  'progress': 0})
    run_scenario(sc, tmp_path, quiet=True)
    with BagReader(tmp_path / 'bag') as bag:
        rec = json.loads(bag.custom_data['ifc_spg.robot_params'])
    assert rec['stiffness'] == k and rec['damping'] == [12.5] * 7
    bad = SCENARIO.read_text().replace('duration: 1.5', 'duration: 1.5\nsim: {stiffness: [1, 2]}')
    (tmp_path / 'bad.yaml').write_text(bad)
    with pytest.raises(ParameterError, match=r'sim\.stiffness must be > 0 \(scalar or 7 values'):
        run_scenario(load_scenario(tmp_path / 'bad.yaml'), tmp_path / 'o2', quiet=True)


def test_scenario_fri_delay_reaches_the_simulation_and_the_record(tmp_path):
    """sim.fri_delay: 0 is today's run bit for bit; n > 0 is recorded in the metadata; a bad
    value names the scenario, the key and the fix."""
    def commands(overrides, out):
        sc = load_scenario(SCENARIO, {'duration': 0.1, 'progress': 0, **overrides})
        run_scenario(sc, out, quiet=True)
        with BagReader(out / 'bag') as bag:
            meta = json.loads(bag.custom_data['ifc_spg.scenario'])
            q_v = [list(m.position) for _, _, m in bag.messages({'/command/joint_position'})]
        return meta, np.array(q_v)

    meta0, default = commands({}, tmp_path / 'a')
    meta1, zero = commands({'sim': {'fri_delay': 0}}, tmp_path / 'b')
    meta2, delayed = commands({'sim': {'fri_delay': 2}}, tmp_path / 'c')
    assert np.array_equal(default, zero) and 'fri_delay' not in meta0 | meta1
    assert meta2['fri_delay'] == 2 and not np.array_equal(default, delayed)
    for bad in ('-1', '1.5', 'true'):
        (tmp_path / 'bad.yaml').write_text(SCENARIO.read_text() + f'sim: {{fri_delay: {bad}}}\n')
        with pytest.raises(ParameterError, match=r'bad\.yaml: sim\.fri_delay must be a whole '
                                                 r'number of FRI periods >= 0'):
            load_scenario(tmp_path / 'bad.yaml')
