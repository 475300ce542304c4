"""ifc-spg sweep: sweep files, serial vs Dask engines, a killed worker, --resume, errors."""

import csv
import os
import signal
import subprocess
import sys
import textwrap
import time

import pytest

from ifc_spg.cli import sweep as sweep_cli
from ifc_spg.errors import ParameterError
from ifc_spg.offline.runner import find_config_dir
from ifc_spg.offline.sweep import FIXED_COLUMNS, run_point, run_sweep
from ifc_spg.offline.sweep_spec import SweepError, load_sweep

distributed = pytest.importorskip('distributed')

# 3 grid values x 4 random draws = 12 points of 0.2 s simulated time each
SWEEP = """\
version: 1
name: test_push
scenario: free_push.yaml
set: {duration: 0.2, progress: 0, pushes.0.at: 0.05, pushes.0.duration: 0.1}
axes:
  sim.stiffness: {values: [150, 300, 600]}
  pushes.0.wrench.1: {uniform: [5.0, 25.0]}
samples: 4
seed: 11
metrics:
  - task_error_rms.physical
  - final_task_errors.pose.physical
  - tank_energy_min_j
"""
# wall time differs run to run; everything else must be bit-identical
COMPARED = [c for c in FIXED_COLUMNS if c != 'wall_time_s']


def _table(out_dir):
    with open(out_dir / 'results.csv', newline='') as f:
        rows = list(csv.DictReader(f))
    return [{k: v for k, v in r.items() if k != 'wall_time_s'} for r in rows]


@pytest.fixture(scope='module')
def sweep_file(tmp_path_factory):
    path = tmp_path_factory.mktemp('sweep') / 'push.yaml'
    path.write_text(SWEEP)
    return path


@pytest.fixture(scope='module')
def serial(sweep_file, tmp_path_factory):
    out = tmp_path_factory.mktemp('serial')
    summary = run_sweep(load_sweep(sweep_file), out, workers=1, stream=None)
    return out, summary


@pytest.fixture(scope='module')
def client():
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                       host='127.0.0.1', dashboard_address=None)
    c = distributed.Client(cluster)
    yield c
    c.close()
    cluster.close()


def test_serial_sweep_rows_and_draws(serial, sweep_file):
    out, summary = serial
    assert summary == {'points': 12, 'ran': 12, 'skipped': 0, 'failed': 0,
                       'table': out / 'results.csv'}
    rows = _table(out)
    assert [int(r['point']) for r in rows] == list(range(12))
    assert all(r['status'] == 'ok' and r['error'] == '' for r in rows)
    assert len({r['key'] for r in rows}) == 12
    fy = [float(r['pushes.0.wrench.1']) for r in rows]
    assert all(5.0 <= f <= 25.0 for f in fy) and len(set(fy)) == 4  # common random numbers
    assert fy[:4] == fy[4:8] == fy[8:]
    # physics: for the same push, a stiffer joint impedance gives a smaller pose error
    err = {(float(r['sim.stiffness']), float(r['pushes.0.wrench.1'])):
           float(r['task_error_rms.physical']) for r in rows}
    for f in set(fy):
        assert err[(150, f)] > err[(300, f)] > err[(600, f)] > 0
    # the same file planned again: the same keys (the resume key is stable)
    assert [p.key for p in load_sweep(sweep_file).points()] == [r['key'] for r in rows]


def test_local_cluster_equals_serial_row_by_row(serial, sweep_file, client, tmp_path):
    # through its address, as --scheduler tcp://HOST:8786 connects
    address = client.scheduler.address
    assert address.startswith('tcp://127.0.0.1:')
    summary = run_sweep(load_sweep(sweep_file), tmp_path, scheduler=address, stream=None)
    assert summary['ran'] == 12 and summary['failed'] == 0
    assert _table(tmp_path) == _table(serial[0])


def test_killed_worker_loses_no_row(serial, sweep_file, client, tmp_path):
    pids = client.run(os.getpid)
    killed = {}

    def kill_a_busy_worker(record):
        if killed:
            return
        busy = [w for w, keys in client.processing().items() if keys and w in pids]
        worker = busy[0] if busy else next(iter(pids))
        killed['keys'] = list(client.processing().get(worker, ()))
        killed['pid'] = pids[worker]
        os.kill(pids[worker], signal.SIGKILL)  # a worker process this test's cluster started

    summary = run_sweep(load_sweep(sweep_file), tmp_path, client=client, stream=None,
                        on_record=kill_a_busy_worker)
    assert killed['keys'] and summary['ran'] == 12 and summary['failed'] == 0
    assert _table(tmp_path) == _table(serial[0])
    assert killed['pid'] not in client.run(os.getpid).values()


def test_resume_runs_only_the_missing_points(serial, sweep_file, tmp_path):
    spec = load_sweep(sweep_file)
    done = []

    def interrupt_after_five(record):
        done.append(record['key'])
        if len(done) == 5:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_sweep(spec, tmp_path, workers=1, stream=None, on_record=interrupt_after_five)
    assert len(_table(tmp_path)) == 5  # the table holds what finished
    with pytest.raises(ParameterError, match='--resume'):
        run_sweep(spec, tmp_path, workers=1, stream=None)
    again = []
    summary = run_sweep(spec, tmp_path, workers=1, stream=None, resume=True,
                        on_record=lambda r: again.append(r['key']))
    assert summary['ran'] == 7 and summary['skipped'] == 5
    assert not set(again) & set(done) and len(set(again) | set(done)) == 12
    assert _table(tmp_path) == _table(serial[0])


def test_sigterm_mid_sweep_keeps_the_finished_runs(sweep_file, tmp_path):
    """The CLI turns SIGTERM into an orderly stop: exit 130, the table of what finished."""
    out = tmp_path / 'out'
    proc = subprocess.Popen(
        [sys.executable, '-m', 'ifc_spg.cli.sweep', str(sweep_file), '-o', str(out),
         '--workers', '1', '--no-figures'], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
        text=True)
    try:
        deadline = time.monotonic() + 120
        while not list((out / 'runs').glob('*.json')) and time.monotonic() < deadline:
            assert proc.poll() is None, proc.communicate()
            time.sleep(0.05)
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, err
    assert 'interrupted' in err and '--resume' in err
    done = len(list((out / 'runs').glob('*.json')))
    assert 1 <= done < 12 and len(_table(out)) == done


def test_a_failing_run_is_a_row_with_its_error(tmp_path, capsys):
    path = tmp_path / 'bad_gain.yaml'
    path.write_text(textwrap.dedent("""\
        scenario: free_push.yaml
        set: {duration: 0.1, progress: 0}
        axes:
          sim.stiffness: {values: [200, -5]}
        metrics: [tank_energy_min_j]
        """))
    assert sweep_cli.main([str(path), '-o', str(tmp_path / 'out'), '--workers', '1']) == 1
    rows = _table(tmp_path / 'out')
    assert [r['status'] for r in rows] == ['ok', 'error']
    assert rows[0]['tank_energy_min_j'] != '' and rows[1]['tank_energy_min_j'] == ''
    assert 'stiffness' in rows[1]['error'] and 'ParameterError' in rows[1]['error']
    assert (tmp_path / 'out' / 'tank_energy_min_j.png').is_file()
    assert '2/2 runs (1 failed' in capsys.readouterr().err


BASE = """\
scenario: free_push.yaml
axes:
  sim.stiffness: {values: [200, 400]}
metrics: [tank_energy_min_j]
"""


@pytest.mark.parametrize('text, line, field, fix', [
    (BASE + 'axis: {}\n', 5, 'axis', "did you mean 'axes'"),
    (BASE.replace('values', 'valuse'), 3, 'axes.sim.stiffness.valuse', "did you mean 'values'"),
    (BASE.replace('{values: [200, 400]}', '{uniform: [400, 200]}'), 3,
     'axes.sim.stiffness.uniform', 'swap them'),
    (BASE.replace('{values: [200, 400]}', '{normal: [200, 0]}'), 3,
     'axes.sim.stiffness.normal', 'STD > 0'),
    (BASE.replace('{values: [200, 400]}', '{uniform: [200, 400]}'), 3, 'axes.sim.stiffness',
     'add samples: N'),
    (BASE.replace('sim.stiffness', 'pushes.2.wrench.1'), 3, 'axes.pushes.2.wrench.1',
     'index 2 is out of range: the list has 1 entries'),
    (BASE.replace('sim.stiffness', 'sim.stifness'), 3, 'axes.sim.stifness',
     "did you mean 'stiffness'"),
    (BASE.replace('sim.stiffness', 'q0_deg.3'), 3, 'axes.q0_deg.3',
     "vary the whole value ('q0_deg')"),
    (BASE.replace('sim.stiffness', 'stiffness'), 3, 'axes.stiffness', 'is not a scenario key'),
    (BASE.replace('[tank_energy_min_j]', '[tank_energy_min]'), 4, 'metrics[0]',
     "did you mean 'tank_energy_min_j'"),
    (BASE.replace('[tank_energy_min_j]', '[force_error_rms_n]'), 4, 'metrics[0]',
     "add it to the scenario's metrics"),
    (BASE.replace('free_push.yaml', 'no_such.yaml'), 1, 'scenario', 'not found; looked in'),
    (BASE.replace('scenario: free_push.yaml\n', ''), 1, '', 'add scenario:'),
    (BASE + 'samples: 3\n', 5, 'samples', 'needs a random axis'),
    (BASE.replace('[200, 400]', '[200, 400, 200]'), 3, 'axes.sim.stiffness.values',
     'values lists 200 twice; remove one'),
    (BASE + 'keep_bags: maybe\n', 5, 'keep_bags', 'true or false'),
])
def test_bad_sweep_files_name_field_line_and_fix(tmp_path, text, line, field, fix):
    path = tmp_path / 'bad.yaml'
    path.write_text(text)
    with pytest.raises(SweepError) as info:
        load_sweep(path)
    err = info.value
    assert err.line == line and err.location == field and fix in str(err), str(err)
    assert str(path) in str(err) and (line is None or f'line {line}' in str(err))


def test_cli_reports_a_bad_file_with_exit_2(tmp_path, capsys):
    path = tmp_path / 'bad.yaml'
    path.write_text(BASE.replace('values', 'valuse'))
    assert sweep_cli.main([str(path), '-o', str(tmp_path / 'o')]) == 2
    err = capsys.readouterr().err
    assert 'line 3' in err and "did you mean 'values'" in err
    assert not (tmp_path / 'o').exists()


@pytest.mark.parametrize('name, count', [('free_push_gains.yaml', 12),
                                         ('free_push_monte_carlo.yaml', 40)])
def test_shipped_sweeps_are_valid(name, count):
    spec = load_sweep(find_config_dir() / 'sweeps' / name)
    points = spec.points()
    assert spec.count() == len(points) == count
    assert len({p.key for p in points}) == count


def test_stack_files_are_read_in_so_their_fields_are_paths(tmp_path):
    path = tmp_path / 'gain.yaml'
    path.write_text(textwrap.dedent("""\
        scenario: thesis_4_4_free_ee_z.yaml
        axes:
          stacks.0.stack.tasks.0.gain: {values: [2.0, 8.0]}
        metrics: [limit_violations]
        """))
    points = load_sweep(path).points()
    tasks = [p.scenario['stacks'][0]['stack']['tasks'][0] for p in points]
    assert [t['gain'] for t in tasks] == [2.0, 8.0]
    assert all(t['name'] == 'pose_but_ee_z' for t in tasks)  # the file's task, its gain set
    assert 'file' not in points[0].scenario['stacks'][0]


def test_a_worker_with_other_code_runs_nothing(serial):
    spec = load_sweep(serial[0].parent / 'missing.yaml', text=SWEEP.replace(
        'free_push.yaml', str(find_config_dir() / 'scenarios' / 'free_push.yaml')))
    point = spec.points()[0]
    task = {'key': point.key, 'index': 0, 'scenario': point.scenario, 'where': 'w',
            'base_dir': spec.scenario_dir, 'bag_dir': None, 'code_version': '0.0.0+gother'}
    record = run_point(task)
    assert record['status'] == 'error' and record['metrics'] is None
    assert '0.0.0+gother' in record['error'] and 'same ifc_spg' in record['error']
